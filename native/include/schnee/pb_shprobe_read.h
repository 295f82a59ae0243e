/* Schnee probes — reading `.shprobe` files of versions 1 to 3 (docs/shprobe-format.md).
 * Part of pb_shprobe.h (the struct and the limits live there; include either).
 */
#ifndef SCHNEE_PB_SHPROBE_READ_H
#define SCHNEE_PB_SHPROBE_READ_H

#include "schnee/pb_shprobe.h"

#ifdef __cplusplus
extern "C" {
#endif

pb_result pb_shprobe_read(const char *path, pb_shprobe **out, pb_error *err);
pb_result pb_shprobe_read_memory(const void *data, size_t size, pb_shprobe **out, pb_error *err);

/* The file readers open without blocking and read regular files only (a FIFO, device, directory or
 * symbolic-link loop fails at once with PB_ERROR_IO), check the header first and then read exactly
 * the size it implies (limits in pb_shprobe.h). Errors never quote the content of a file that is not ours. */

/* Reads and validates only the header (for exporters): fills every scalar field, array pointers NULL. */
pb_result pb_shprobe_read_header(const char *path, pb_shprobe *out_header, pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
