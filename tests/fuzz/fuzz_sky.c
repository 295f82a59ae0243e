/* libFuzzer entry over the engine's sky path (sv_sky_load): the input is written to a file (in the
 * folder $SCHNEE_FUZZ_DIR, which run_sky_fuzz.sh sets to its build folder) that a
 * VULKAN_SCHNEE_engine_properties.sky entry names, then checked (regular file, size, image
 * signature, EXR dataWindow / PNG IHDR against the pixel limit), decoded by OpenImageIO through the
 * core's pb_image_read, and GGX-prefiltered into the mip chain. Built and run by
 * tests/fuzz/run_sky_fuzz.sh with a small SV_SKY_MAX_PIXELS so that each run stays fast. */
#define _DEFAULT_SOURCE /* mkstemps */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sv_sky.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static char path[4096];
    if (!path[0]) {
        const char *dir = getenv("SCHNEE_FUZZ_DIR");
        if (!dir || !*dir) {
            fprintf(stderr, "fuzz_sky: set SCHNEE_FUZZ_DIR to a writable folder (run_sky_fuzz.sh does)\n");
            abort();
        }
        if (snprintf(path, sizeof path, "%s/sv-fuzz-sky-XXXXXX.exr", dir) >= (int)sizeof path) abort();
        int fd = mkstemps(path, 4);
        if (fd < 0) abort();
        close(fd);
    }
    FILE *f = fopen(path, "wb");
    if (!f) abort();
    if (size && fwrite(data, 1, size, f) != size) abort();
    fclose(f);
    sv_ext ext = {0};
    ext.sky.present = true;
    ext.sky.path = path;
    ext.sky.uri = path;
    ext.sky.max_band = 2;
    ext.sky.sh[0][0] = 1.0f;
    sv_sky sky;
    if (sv_sky_load(&ext, &sky)) {
        /* Every level the renderer would upload: finite, non-negative texels. */
        for (uint32_t l = 0; l < sky.mip_count; ++l)
            for (size_t t = 0; t < (size_t)sky.width[l] * sky.height[l] * 4; ++t)
                if (!(sky.rgba[l][t] >= 0.0f) || !isfinite(sky.rgba[l][t])) __builtin_trap();
        sv_sky_destroy(&sky);
    }
    return 0;
}
