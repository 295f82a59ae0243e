/* Schnee probes — the sun of a sky image, split off as a directional light (docs/direct-light.md,
 * "The sky's sun").
 *
 * How to use it:
 *   1. Hold the world as an equirect of linear RGB radiance (float, `channels` per texel, RGB first,
 *      row 0 at the top), in the texel directions of pb_direct_sky_table: θ = π(row + ½)/H from
 *      Blender +Z, φ = π − 2π(col + ½)/W.
 *   2. pb_sky_sun_desc desc = {0};   (zero = the documented defaults)
 *      pb_sky_sun sun;
 *      pb_sky_sun_split(&desc, image, W, H, C, rest, &sun, &err);
 *   3. sun.found: the image has a compact bright sun. sun.direction / irradiance / angle describe
 *      it as a Cycles Sun lamp (pb_light: engine space, the direction its light travels, W/m² at
 *      normal incidence, angular diameter), and `rest` holds the image without it. Otherwise `rest`
 *      is the image unchanged.
 *
 * The split (all three criteria must hold, else no sun):
 *   - compact: the texels at least `peak_fraction` of the brightest texel's luminance that are
 *     8-connected to it (wrapping in φ and across the poles) all lie within `max_radius` of it;
 *   - the sun's texels are that region grown by one texel; they keep the surrounding sky's level
 *     (per channel the median of the ring of texels just outside them, never more than the texel
 *     itself): rest = min(image, ring median). The excess, image − rest, is the sun:
 *     irradiance = Σ excess · dω (each texel's exact solid angle), so sun + rest = the image by
 *     construction (energy conserved to the rounding of a double sum);
 *   - bright enough to matter: the sun's luminance flux is at least `min_share` of the image's
 *     (∫ Y dω over the sphere, Y = Rec. 709 luminance).
 * Direction: the excess-luminance-weighted mean of the sun texels' directions. Angle: the angular
 * diameter of the disc whose solid angle Ω = the sun's luminance flux / the peak texel's excess
 * luminance (a uniform disc of the peak's radiance carrying the same light: exact for a disc,
 * the size of a clipped sun's core otherwise).
 * No hidden state, no threads; one allocation of W·H bytes plus the region, freed before return.
 */
#ifndef SCHNEE_PB_SKY_SUN_H
#define SCHNEE_PB_SKY_SUN_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct pb_sky_sun_desc {
    double peak_fraction; /* region threshold, a fraction of the peak luminance in (0, 1); 0 = 0.01 */
    double max_radius;    /* rad, in (0, π/2]: the region must lie within this of the peak texel; 0 = 5° */
    double min_share;     /* in (0, 1): the least share of the image's luminance flux; 0 = 0.01 */
} pb_sky_sun_desc;

typedef enum pb_sky_sun_verdict {
    PB_SKY_SUN_FOUND = 0,
    PB_SKY_SUN_BLACK, /* the image is black: no light at all */
    PB_SKY_SUN_WIDE,  /* the bright region around the peak reaches beyond max_radius (a soft sky) */
    PB_SKY_SUN_FAINT, /* compact, but below min_share of the light (or no excess over its ring) */
    PB_SKY_SUN_VERDICT_COUNT_
} pb_sky_sun_verdict;

typedef struct pb_sky_sun {
    bool found;
    pb_sky_sun_verdict verdict;
    double direction[3];         /* engine space, unit: the direction the sun's light travels (to it: −this) */
    double irradiance[3];        /* RGB W/m² at normal incidence: Σ over the sun's texels of excess · dω */
    double angle;                /* angular diameter (rad) of the disc of the peak's excess radiance */
    double share;                /* the sun's luminance flux / the image's (0 when not found) */
    double background[3];        /* the ring median the sun's texels keep (RGB radiance) */
    double extent;               /* rad: how far the region reached from the peak (up to max_radius) */
    uint32_t peak_col, peak_row; /* the brightest texel */
    uint32_t texels;             /* texels of the sun (the region grown by one) */
} pb_sky_sun;

/* Finds the sun of `image` (width × height texels of `channels` floats, RGB first, finite, >= 0)
 * and writes the rest of the sky to `rest` (same layout; channels past RGB copied; may be `image`
 * itself, or NULL to only detect). `out` is always filled on success. Errors: NULL arguments,
 * an empty image, channels < 3, a desc value out of range (PB_ERROR_INVALID_ARGUMENT); a NaN/Inf
 * texel (PB_ERROR_NON_FINITE), a negative one (PB_ERROR_NEGATIVE), both naming the texel. */
pb_result pb_sky_sun_split(const pb_sky_sun_desc *desc, const float *image, uint32_t width, uint32_t height,
                           uint32_t channels, float *rest, pb_sky_sun *out, pb_error *err);

/* Static English name of a verdict ("found", "black", "wide", "faint"). */
const char *pb_sky_sun_verdict_string(pb_sky_sun_verdict verdict);

#ifdef __cplusplus
}
#endif
#endif
