/* Schnee probes — float image I/O through OpenImageIO (the only C++ in the core, behind extern "C").
 * Used by the bake (panoramas) and by the engine (frame output). */
#ifndef SCHNEE_PB_IMAGE_H
#define SCHNEE_PB_IMAGE_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct pb_image {
    uint32_t width, height, channels; /* row 0 at the top, channels interleaved */
    float *pixels;                    /* width * height * channels, owned; free with pb_image_free */
} pb_image;

/* Documented limits of pb_image_read (docs/python-api.md, "Limits"), checked on the file size and on
 * the image header before any pixel is allocated or read; larger inputs fail with PB_ERROR_TOO_LARGE. */
#define PB_IMAGE_MAX_FILE_BYTES (UINT64_C(1) << 32) /* 4 GiB on disk */
#define PB_IMAGE_MAX_DIM        65536u              /* pixels per side */
#define PB_IMAGE_MAX_CHANNELS   64u
#define PB_IMAGE_MAX_VALUES     (UINT64_C(1) << 29) /* width x height x channels: 2 GiB of float */

/* Reads an EXR, HDR, PNG, JPEG, TIFF or PFM file (chosen by content, else by extension; other
 * formats OpenImageIO knows by extension) as 32-bit float, converted to linear as stored in the
 * file. Opens without blocking, regular files only (a FIFO, device, directory or symbolic-link loop
 * fails at once with PB_ERROR_IO), and checks the limits above before reading pixels. */
pb_result pb_image_read(const char *path, pb_image *out, pb_error *err);

/* Reads an image held in memory (`size` bytes at `data`, e.g. a glTF bufferView or data: URI), with
 * the checks and limits of pb_image_read: the format by content, else by the extension of `name`;
 * `name` (NULL: "(image in memory)") names the image in messages. Truncated or garbage bytes fail
 * with PB_ERROR_FORMAT; the buffer is only read, and may be freed once this returns. Builds
 * without OpenImageIO fail with PB_ERROR_IO, as pb_image_read does. */
pb_result pb_image_read_memory(const void *data, size_t size, const char *name, pb_image *out, pb_error *err);

/* Writes `pixels` (row 0 at the top). The format follows the extension: .exr keeps float values;
 * 8-bit formats (.png, ...) take values already in display encoding [0, 1]. Atomic: temp + rename. */
pb_result pb_image_write(const char *path, uint32_t width, uint32_t height, uint32_t channels, const float *pixels,
                         pb_error *err);

void pb_image_free(pb_image *image);

#ifdef __cplusplus
}
#endif
#endif
