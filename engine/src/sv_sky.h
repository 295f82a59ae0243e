/* The sky (world) captured by the bake: VULKAN_SCHNEE_engine_properties.sky (docs/export.md).
 * Loads the equirect HDR image through OpenImageIO and prepares, on the CPU at load time, what
 * image-based lighting needs:
 *   - a GGX-prefiltered mip chain: level k = the sky convolved for roughness k / (mips - 1)
 *     (level 0 is the image itself, used for the background), importance-sampled with
 *     filtered importance sampling (Karis 2013 / Colbert & Krivanek 2007);
 *   - the split-sum BRDF lookup table (Karis 2013): (A, B) with F0 * A + B = the GGX specular
 *     integral for NoV (u) and roughness (v), Smith-Schlick G with k = alpha / 2, alpha = roughness^2.
 * Directions are engine space; the panorama mapping is DESIGN.md §3's.
 */
#ifndef SV_SKY_H
#define SV_SKY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "sv_ext.h"

#define SV_SKY_MAX_MIPS     7
#define SV_BRDF_LUT_SIZE    64
#define SV_BRDF_LUT_SAMPLES 4096

typedef struct sv_sky {
    bool present;
    uint32_t mip_count;
    uint32_t width[SV_SKY_MAX_MIPS], height[SV_SKY_MAX_MIPS];
    float *rgba[SV_SKY_MAX_MIPS]; /* per level, RGBA32F rows top to bottom */
    uint32_t max_band;
    float sh[25][3]; /* radiance SH from the glTF entry */
} sv_sky;

/* Reads the glTF's sky (if any) and prefilters it. No sky: out->present = false, true returned.
 * An unreadable image is an error (message names the file). */
bool sv_sky_load(const sv_ext *ext, sv_sky *out);

/* Image files (textures, the sky) are read through OpenImageIO only after this check: opened
 * without blocking, a regular file (sv_gltf_open_regular) of at most SV_MAX_IMAGE_FILE_BYTES whose
 * first bytes are the signature of an image format (EXR, PNG, JPEG, Radiance HDR, TIFF, PNM/PFM,
 * BMP, GIF, WebP); for EXR (dataWindow) and PNG (IHDR) the header's size must be at most
 * max_pixels (0 = no limit) before a pixel is decoded. False with a message in msg naming `what`
 * and the path, never the content. */
#define SV_MAX_IMAGE_FILE_BYTES (1ull << 30)
#ifndef SV_SKY_MAX_PIXELS
#define SV_SKY_MAX_PIXELS (8192ull * 4096ull) /* the sky image (prefiltered on the CPU at load) */
#endif
#define SV_TEXTURE_MAX_PIXELS (8192ull * 8192ull)
/* Sky radiance above this (far beyond any real HDRI: the sun is ~1e5-1e9) is clamped at load with
 * a warning, so that the prefilter's sums cannot overflow to Inf. */
#define SV_SKY_MAX_RADIANCE 1e20f
bool sv_image_file_check(const char *path, const char *what, uint64_t max_pixels, char *msg, size_t cap);
void sv_sky_destroy(sv_sky *sky);

/* Split-sum LUT, size x size texels of (A, B), texel (i, j) at NoV = (i + 0.5) / size, roughness
 * = (j + 0.5) / size; `samples` Hammersley GGX samples each. Caller frees. */
float *sv_brdf_lut(uint32_t size, uint32_t samples);

/* Equirect lookup (bilinear, u wraps, v clamps) of an engine-space unit direction in level `l`. */
void sv_sky_sample(const sv_sky *sky, uint32_t level, const float dir[3], float out[3]);

#endif
