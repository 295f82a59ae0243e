/* Schnee probes — the image I/O of pb_image.h for builds without OpenImageIO (the Python module that
 * runs inside Blender). Every call reports that this build reads and writes no image files; callers
 * hand pixels in memory instead (pb_sh_project_equirect), read through Blender or the add-on's EXR
 * reader. */
#include "schnee/pb_image.h"

#include <string.h>

pb_result pb_image_read(const char *path, pb_image *out, pb_error *err)
{
    if (out) memset(out, 0, sizeof *out);
    return pb_error_set(err, PB_ERROR_IO, "%s: this build of the bake core has no image reader (no OpenImageIO)",
                        path ? path : "(null)");
}

pb_result pb_image_write(const char *path, uint32_t width, uint32_t height, uint32_t channels, const float *pixels,
                         pb_error *err)
{
    (void)width;
    (void)height;
    (void)channels;
    (void)pixels;
    return pb_error_set(err, PB_ERROR_IO, "%s: this build of the bake core has no image writer (no OpenImageIO)",
                        path ? path : "(null)");
}

void pb_image_free(pb_image *image)
{
    if (image) memset(image, 0, sizeof *image);
}
