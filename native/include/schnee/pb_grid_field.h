/* Schnee probes — the dense probe grid's field (issue 30 item 2, docs/grid-field.md): the one C definition
 * of how a dense grid (.shprobe versions 1/2, version 3 structure "grid") is interpolated at a point, which
 * shaders/shading.glsl grid_irradiance() and shaders/bricks.glsl grid_tex_irradiance() mirror line by
 * line, plus the grid's 3D-texture form (cell-centred texels N = v·s·c, D = v) and its trilinear sample.
 *
 * How to use it, step by step:
 *   1. Fill a pb_grid_field_desc: the grid (dims, origin, spacing, optional rotated axes), its cells
 *      (probe index or −1), per-probe colours in float64 (coeff_count × RGB: SH coefficients, or the 6
 *      faces of an ambient cube), optional validity, scale and 27-bit neighbour-visibility masks.
 *   2. pb_grid_field_build(&desc, &field, &err). The field copies what it needs.
 *   3. pb_grid_field_query(field, p, n, &opts, &w): the 8 corner weights (probe indices and weights summing
 *      to 1), or step 5's plain trilinear fallback; pb_grid_field_sample(): Σ w s c (scale folded in).
 *   4. For an upload: pb_grid_field_get_info(), pb_grid_field_texture_f32() / _f16() (RGBA channel groups);
 *      pb_grid_field_sample_texture() is the trilinear texture sample (exact or quantised fractions).
 *   5. pb_grid_field_destroy().
 *
 * The rule (normative; docs/grid-field.md "The rule"), for a surface point p_s with unit normal n (zero
 * for a point without one) and options {static_surface, normal_bias}:
 *   1. p = p_s + normal_bias·h·n; u = R (p − origin) / h (R: rows = the grid's unit axes). Not in this grid
 *      when some u_a < −0.01 or u_a > dims_a + 0.01 (PB_GRID_FIELD_MARGIN).
 *   2. c = u − ½, i0 = floor(c), f = c − i0 (u is not clamped: outside the centres both corners of an axis
 *      clamp to the face cell).
 *   3. home = clamp(floor(R (p − origin + 0.01·h·n) / h), 0, dims − 1); mask = masks[home] (all visible
 *      without masks).
 *   4. For each corner k (bit a of k = +1 on axis a): cell ci = clamp(i0 + bits(k), 0, dims − 1); skipped when
 *      the cell is empty (−1) or when d = ci − home lies in {−1,0,1}³ and mask bit (d.x+1) + 3(d.y+1) +
 *      9(d.z+1) is clear; w = Π_a (bit ? f_a : 1 − f_a) × (static_surface ? smoothstep(−0.1, 0.1,
 *      dot(centre(ci) − p_s, n) / h) : 1) × validity; skipped when w <= 0.
 *   5. W = Σ w > 1e-6 (PB_GRID_FIELD_MIN_WEIGHT): weights w / W. Else the plain trilinear × validity
 *      weights of the 8 corners (no mask, no back face: the texture's own N / D at the point), divided by
 *      their sum D when D > 1e-6; else no value (the caller tries the next grid, then probe 0).
 * Texture form (normative; docs/grid-field.md "Texture"): texel (x, y, z) at the centre of cell (x, y, z),
 * channels at the colour count C: 0–2 = N_0 RGB, 3 = D, then N_1 … N_{C−1} RGB consecutively, RGBA groups of
 * 4 (ceil((3C + 1) / 4)); N_i = v·s·c_i and D = v with v = max(validity, 0) of the cell's probe, 0 for an
 * empty cell. Sampled at t = clamp(u − ½, 0, dims − 1) (clamp to edge), trilinear, N / D: equal to the rule
 * when every corner kept its mask bit and (movable, or) every back-face weight is 1, and to step 5. The
 * engine (pb_grid_field_sample_surface_texture) filters in hardware where the kept weights trilinear × mask
 * × back face are separable (one tap at their per-axis mean f', e.g. an axis-aligned floor or wall) and
 * D >= PB_GRID_FIELD_FILTER_MIN_D; elsewhere it takes 8 texel fetches with the rule's exact weights.
 * Coordinates: engine space, metres, double.
 */
#ifndef SCHNEE_PB_GRID_FIELD_H
#define SCHNEE_PB_GRID_FIELD_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PB_GRID_FIELD_MARGIN       0.01         /* cells: the box's margin, and the home cell's offset along n */
#define PB_GRID_FIELD_FILTER_MIN_D (1.0 / 64.0) /* the engine filters only where D >= this (else exact taps) */
#define PB_GRID_FIELD_MIN_WEIGHT   1e-6         /* Σ w at or below this: step 5's fallback */
#define PB_GRID_FIELD_BACK_RAMP    0.1          /* back-face weight smoothstep(−0.1, 0.1, dot(c − p, n) / h) */
#define PB_GRID_FIELD_ALL_VISIBLE  UINT32_C(0x7FFFFFF) /* a mask with all 27 neighbour bits set */
#define PB_GRID_FIELD_MAX_COLOURS  25u                 /* L4 SH; an ambient cube has 6 */
#define PB_GRID_FIELD_MAX_CELLS    (UINT64_C(1) << 31) /* cells one grid may have */

typedef struct pb_grid_field pb_grid_field;

/* Zero-initialise; 0 / NULL fields take the defaults written beside them. */
typedef struct pb_grid_field_desc {
    uint32_t dims[3];      /* required: X, Y, Z cells, each >= 1 */
    double origin[3];      /* min corner of cell (0, 0, 0), engine space, metres */
    double spacing;        /* required: cell size h > 0, metres */
    const double *axes;    /* NULL = identity; else 9: rows = the unit X, Y, Z axes in engine space (orthonormal) */
    const int32_t *cells;  /* required: X·Y·Z, flat x + y·X + z·X·Y, probe index in [0, probe_count) or −1 */
    uint32_t probe_count;  /* probes the cells index */
    uint32_t coeff_count;  /* required: colours per probe, 1..25 (SH (band + 1)², or 6 for an ambient cube) */
    const double *coeffs;  /* required: probe_count × coeff_count × 3 (probe-major, colour, RGB), finite */
    const float *validity; /* NULL = 1; else probe_count finite values, <= 0 drops the probe from the weights */
    const float *scale;    /* NULL = 1; else probe_count finite scales (the file's probe_scale) */
    const uint32_t
        *masks;         /* NULL = every neighbour visible; else X·Y·Z 27-bit masks (bit (dx+1) + 3(dy+1) + 9(dz+1)) */
    uint64_t max_bytes; /* 0 = 1 GiB: refuse (PB_ERROR_TOO_LARGE) a texture in float32 larger than this */
} pb_grid_field_desc;

typedef struct pb_grid_field_info {
    uint32_t dims[3];
    double origin[3], spacing, axes[9];
    uint32_t probe_count, coeff_count;
    uint32_t channels;          /* 3C + 1 */
    uint32_t groups;            /* RGBA textures: ceil(channels / 4) */
    uint64_t texture_bytes_f16; /* every group, X·Y·Z texels of 8 B */
    uint64_t texture_bytes_f32;
} pb_grid_field_info;

/* Per-query options; zero = a movable object's rule without normal bias. */
typedef struct pb_grid_field_opts {
    bool static_surface; /* back-face weights (the bake saw the surface); false: a movable object */
    double normal_bias;  /* grid spacings the sample point moves along n (the engine's --normal-bias) */
} pb_grid_field_opts;

typedef enum pb_grid_field_status {
    PB_GRID_FIELD_OUTSIDE = 0, /* not in the grid's box (with the margin) */
    PB_GRID_FIELD_NONE,        /* in the box, no weight and no valid corner (D <= 1e-6): no value */
    PB_GRID_FIELD_WEIGHTS,     /* weight[] over the 8 corners, summing to 1 */
    PB_GRID_FIELD_FALLBACK,    /* step 5: weight[] = the plain trilinear × validity weights / D, summing to 1 */
} pb_grid_field_status;

typedef struct pb_grid_field_weights {
    pb_grid_field_status status;
    uint32_t cell[8][3]; /* corner k's clamped cell */
    int32_t probe[8];    /* its probe or −1 (empty) */
    double weight[8];    /* normalised, 0 where skipped (corners clamped onto one cell keep separate weights) */
    double raw[8];       /* step 4's, before normalisation (trilinear × back face × validity; 0 where skipped) */
    double backface[8];  /* the back-face factor (1 for a movable object), also of skipped corners */
    bool masked[8];      /* the home cell's mask dropped this corner */
    uint32_t home[3];    /* the home cell */
    double u[3];         /* grid coordinates of the (biased) sample point, in cells */
} pb_grid_field_weights;

/* Builds the field. Errors (with a message): NULL desc / cells / coeffs, a zero dimension, more than
 * PB_GRID_FIELD_MAX_CELLS cells, a non-finite or non-positive spacing, non-finite origin, axes that are not
 * orthonormal within 1e-3, a cell index outside [−1, probe_count), coeff_count outside 1..25, non-finite
 * coefficients, validity or scales (PB_ERROR_NON_FINITE), a float32 texture past max_bytes (TOO_LARGE). */
pb_result pb_grid_field_build(const pb_grid_field_desc *desc, pb_grid_field **out, pb_error *err);
void pb_grid_field_destroy(pb_grid_field *field);
void pb_grid_field_get_info(const pb_grid_field *field, pb_grid_field_info *out);

/* The rule above at surface point p (engine space) with normal n (NULL = none: the point itself, no
 * back faces, home = the cell of p). opts NULL = zero options. Returns out->status (OUTSIDE for NULL). */
pb_grid_field_status pb_grid_field_query(const pb_grid_field *field, const double p[3], const double n[3],
                                         const pb_grid_field_opts *opts, pb_grid_field_weights *out);
/* Σ_k weight_k · s · c of the query (coeff_count × 3 doubles, 0 without a value); returns the status. */
pb_grid_field_status pb_grid_field_sample(const pb_grid_field *field, const double p[3], const double n[3],
                                          const pb_grid_field_opts *opts, double *coeffs_out);

/* ---- texture form ---------------------------------------------------------------------------------- */

/* The texel coordinate t = clamp(u − ½, 0, dims − 1) of point p (the GPU's is (t + ½) / size within the
 * grid's texture); false outside the box (margin as the rule). */
bool pb_grid_field_texel_coord(const pb_grid_field *field, const double p[3], double t[3]);
/* Trilinear sample of the texels at point p (no normal: the caller moves p by its bias): cell i0 =
 * min(floor(t), dims − 1), i1 = min(i0 + 1, dims − 1), f = t − i0, rounded to the nearest multiple of
 * 2^−bits per axis when 0 < subtexel_bits <= 24 (the filter's weight quantisation; the device's rounding
 * mode is not emulated). channels_out (optional): `channels` doubles; coeffs_out (optional): N / D
 * (coeff_count × 3, 0 without a value); d_out (optional): D. True when in the box and D > 1e-6. */
bool pb_grid_field_sample_texture(const pb_grid_field *field, const double p[3], uint32_t subtexel_bits,
                                  double *channels_out, double *coeffs_out, double *d_out);
/* The rule in the texture form at surface point p_s with normal n (NULL = none) and opts, as the engine
 * samples it (shaders/bricks.glsl grid_tex_irradiance): steps 1–3 of the rule; corner k's weight
 * w_k = Π_a (bit ? f_a : 1 − f_a) × keep_k, keep_k = 0 where the mask drops it, else its back-face weight
 * (1 without static_surface); validity and empty cells are in the texels' N and D. Where w is separable
 * (pb_bricks_separable of pb_bricks.h, f') one trilinear sample at t = clamp(i0 + f', 0, dims − 1)
 * (fractions rounded to subtexel_bits), kept when its D >= PB_GRID_FIELD_FILTER_MIN_D; else 8 texels with
 * w exactly. Both give Σ w (N, D) / Σ w, so N / D is the rule's value. When Σ w D <= 1e-6, step 5: the 8
 * texels with the plain trilinear weights (exact). *taps_out (optional): 1 or 8 (0 outside the box); d_out
 * (optional): Σ w D (step 5's D where it was taken); coeffs_out (optional): N / D (coeff_count × 3, 0 without a
 * value). True when the rule has a value (WEIGHTS or FALLBACK). */
bool pb_grid_field_sample_surface_texture(const pb_grid_field *field, const double p_surface[3], const double n[3],
                                          const pb_grid_field_opts *opts, uint32_t subtexel_bits, double *coeffs_out,
                                          double *d_out, uint32_t *taps_out);
/* The float64 texels: X·Y·Z × channels, cell x fastest. */
const double *pb_grid_field_texels(const pb_grid_field *field);
/* The texture as `groups` RGBA textures, group-major, then z, y, x, then RGBA: out[((g·Z + z)·Y + y)·X + x)·4
 * + c]; capacity in elements at least groups·X·Y·Z·4. f16: binary16, round to nearest even;
 * PB_ERROR_TOO_LARGE when a value exceeds 65504 in magnitude (upload float32 then). */
pb_result pb_grid_field_texture_f32(const pb_grid_field *field, float *out, uint64_t capacity, pb_error *err);
pb_result pb_grid_field_texture_f16(const pb_grid_field *field, uint16_t *out, uint64_t capacity, pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
