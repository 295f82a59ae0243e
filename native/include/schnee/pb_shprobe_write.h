/* Schnee probes — writing `.shprobe` files of versions 1 to 3 (docs/shprobe-format.md).
 * Part of pb_shprobe.h (the struct and the limits live there; include either).
 */
#ifndef SCHNEE_PB_SHPROBE_WRITE_H
#define SCHNEE_PB_SHPROBE_WRITE_H

#include "schnee/pb_shprobe.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Validates like the reader (finite values, grid entries in [−1, count), spacing > 0, ...), then
 * writes atomically. NULL probe_scale = all 1, NULL probe_ambient = all default_ambient.
 * Never replaces what is not a .shprobe: when `path` exists it must be a regular file whose first
 * 4 bytes are the magic; a directory, device, FIFO, socket, symbolic link (decided: refused, not
 * followed — rename would replace the link itself) or any other file is refused with
 * PB_ERROR_INVALID_ARGUMENT naming the path, and nothing is written. */
pb_result pb_shprobe_write(const char *path, const pb_shprobe *probes, pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
