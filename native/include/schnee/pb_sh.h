/* Schnee probes — real spherical harmonics (DESIGN.md §3).
 *
 * How to use it:
 *   1. Render or load an equirectangular float panorama (row 0 at the top, as Cycles writes it).
 *   2. Fill a pb_sh_project_desc (zero = defaults) and call pb_sh_project_equirect(), or call
 *      pb_sh_project_file() for an EXR/HDR on disk. You get the radiance projection
 *      L_i = ∫ L(ω) Y_i(ω) dω, RGB, in engine space (Y-up), `pb_sh_count(max_band)` coefficients.
 *   3. Optionally pb_sh_window() against ringing; pb_sh_irradiance() evaluates E(n).
 *
 * Convention: real SH, no Condon–Shortley phase, index i = l*l + l + m, l = 0..4, evaluated on unit
 * directions in engine space. Coefficient arrays are flat `double[count * 3]`, coefficient-major
 * (coeff i, channel c at [i*3 + c]). The same code is used by the bake (through Python) and by the
 * engine, so the CPU evaluation here is the reference the GLSL include is tested against.
 */
#ifndef SCHNEE_PB_SH_H
#define SCHNEE_PB_SH_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PB_SH_MAX_BAND   4
#define PB_SH_MAX_COEFFS 25

/* (max_band + 1)^2 */
static inline uint32_t pb_sh_count(uint32_t max_band) { return (max_band + 1u) * (max_band + 1u); }

/* Basis values Y_0..Y_{count-1} at the unit direction dir (engine space). max_band <= 4. */
void pb_sh_eval_basis(uint32_t max_band, const double dir[3], double *out);

/* Lambert kernel factor A_l (π, 2π/3, π/4, 0, −π/24) for band l <= 4. */
double pb_sh_lambert_band(uint32_t l);

/* Irradiance E(n) = Σ_l A_l Σ_m L_lm Y_lm(n), RGB, for a unit normal n in engine space. */
void pb_sh_irradiance(uint32_t max_band, const double *coeffs, const double n[3], double out_rgb[3]);

typedef enum pb_negative_policy {
    PB_NEGATIVE_ERROR = 0, /* default: a negative or non-finite pixel is an error naming the pixel */
    PB_NEGATIVE_CLAMP,     /* negatives become 0 (non-finite is still an error) */
    PB_NEGATIVE_ALLOW,     /* negatives are integrated as they are (non-finite is still an error) */
} pb_negative_policy;

typedef struct pb_sh_project_desc {
    const float *pixels; /* required for pb_sh_project_equirect; ignored by pb_sh_project_file */
    uint32_t width;      /* columns; ignored by pb_sh_project_file */
    uint32_t height;     /* rows, row 0 at the top; ignored by pb_sh_project_file */
    uint32_t channels;   /* floats per pixel, >= 3, RGB first; 0 = 4 (RGBA) */
    size_t row_stride;   /* floats between rows; 0 = width * channels */
    uint32_t max_band;   /* 0..4; the panorama must be large enough (else PB_ERROR_TOO_SMALL) */
    /* Row-major 3×3 matrix R taking the canonical Cycles panorama direction d (Blender world space,
     * camera rotated (90°, 0, −90°): φ = π − 2π(i+½)/W, θ = π(r+½)/H,
     * d = (sin θ cos φ, sin θ sin φ, cos θ)) to the output space: out = R·d.
     * NULL = the Blender → engine conversion (x, y, z) → (x, z, −y). */
    const double *rotation;
    pb_negative_policy negative; /* 0 = PB_NEGATIVE_ERROR */
} pb_sh_project_desc;

/* Minimum panorama size (width, height) that can represent band max_band. */
void pb_sh_min_panorama_size(uint32_t max_band, uint32_t *min_width, uint32_t *min_height);

/* Projects an in-memory panorama. out: pb_sh_count(max_band) * 3 doubles (caller-owned). Exact
 * per-pixel solid angles Δφ·(cos θ_top − cos θ_bottom), double accumulation. */
pb_result pb_sh_project_equirect(const pb_sh_project_desc *desc, double *out, pb_error *err);

/* Same, reading an EXR/HDR/... through OpenImageIO (desc->pixels/width/height/channels ignored). */
pb_result pb_sh_project_file(const char *path, const pb_sh_project_desc *desc, double *out, pb_error *err);

typedef enum pb_sh_window_kind {
    PB_SH_WINDOW_NONE = 0,
    PB_SH_WINDOW_SINC4,     /* Filament's sinc^4 window; strength = cutoff band (0 = auto) */
    PB_SH_WINDOW_LAPLACIAN, /* Sloan's Laplacian deringing; strength = lambda (0 = auto) */
} pb_sh_window_kind;

/* Applies a ringing window in place. `strength` 0 chooses the smallest window for which the
 * irradiance is non-negative over the sphere (within search bounds). If min_irradiance is non-NULL it
 * receives the minimum over the sphere of the windowed irradiance (per channel minimum, RGB). */
pb_result pb_sh_window(uint32_t max_band, pb_sh_window_kind kind, double strength, double *coeffs,
                       double min_irradiance[3], pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
