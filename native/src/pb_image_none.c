/* Schnee probes — the image I/O of pb_image.h for builds without OpenImageIO (the Python module that
 * runs inside Blender, schnee-view-noimage). Reading reports that this build reads no image files;
 * callers hand pixels in memory instead (pb_sh_project_equirect), read through Blender or the
 * add-on's EXR reader. Writing knows one format, PFM (Portable Float Map: 1 or 3 float channels,
 * little-endian, rows bottom to top), so a viewer without OpenImageIO can still hand back its frames
 * losslessly; any other extension is refused. */
#include "schnee/pb_image.h"

#include "pb_file.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int ends_with_pfm(const char *path)
{
    size_t n = strlen(path);
    return n >= 4 && (strcmp(path + n - 4, ".pfm") == 0 || strcmp(path + n - 4, ".PFM") == 0);
}

pb_result pb_image_read(const char *path, pb_image *out, pb_error *err)
{
    if (out) memset(out, 0, sizeof *out);
    return pb_error_set(err, PB_ERROR_IO, "%s: this build of the bake core has no image reader (no OpenImageIO)",
                        path ? path : "(null)");
}

pb_result pb_image_read_memory(const void *data, size_t size, const char *name, pb_image *out, pb_error *err)
{
    (void)data;
    (void)size;
    if (out) memset(out, 0, sizeof *out);
    return pb_error_set(err, PB_ERROR_IO,
                        "%s: this build of the bake core has no image reader (no OpenImageIO); cannot decode an image "
                        "from memory",
                        name && *name ? name : "(image in memory)");
}

pb_result pb_image_write(const char *path, uint32_t width, uint32_t height, uint32_t channels, const float *pixels,
                         pb_error *err)
{
    if (!path || !pixels || width == 0 || height == 0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_image_write: no path, pixels or size");
    if (!ends_with_pfm(path))
        return pb_error_set(err, PB_ERROR_IO,
                            "%s: this build of the bake core writes PFM only (no OpenImageIO); name a .pfm file", path);
    if (channels != 1 && channels != 3)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "%s: PFM holds 1 or 3 channels, not %u", path, channels);
    char head[64];
    int hn = snprintf(head, sizeof head, "%s\n%u %u\n-1.0\n", channels == 3 ? "PF" : "Pf", width, height);
    size_t row = (size_t)width * channels * sizeof(float), size = (size_t)hn + row * height;
    uint8_t *buf = malloc(size);
    if (!buf) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "%s: out of memory for %zu bytes", path, size);
    memcpy(buf, head, (size_t)hn);
    for (uint32_t y = 0; y < height; ++y) /* bottom row first; -1.0: little-endian (x86, Arm) */
        memcpy(buf + hn + row * y, pixels + (size_t)(height - 1 - y) * width * channels, row);
    pb_result r = pb_write_atomic_(path, buf, size, NULL, err);
    free(buf);
    return r;
}

void pb_image_free(pb_image *image)
{
    if (image) memset(image, 0, sizeof *image);
}
