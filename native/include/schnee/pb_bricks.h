/* Schnee probes — probe bricks (issue 30, docs/probe-bricks.md): the corner octree's / kd corner tree's
 * field resampled into bricks of 5 × 5 × 5 texels at the finest level each region overlaps, with an
 * indirection grid, so that a GPU samples it with one indirection fetch and filtered fetches. This module
 * is the C definition of that field: it builds the bricks and samples them exactly (float64 texels, exact
 * trilinear fractions), and the GLSL is to mirror pb_bricks_sample() line by line.
 *
 * How to use it, step by step:
 *   1. A finalized pb_cotree (pb_cotree.h; octree or kd tree) and per-probe SH coefficients in float64
 *      (probe_count × coeff_count × 3), optionally validity and scale per probe.
 *   2. pb_bricks_build(&desc, &bricks, &err): the level rule, the brick pool, the indirection grid, and
 *      the texels N = Σ W m s c and D = Σ W m (W the file's expanded weights from pb_interp without
 *      validity, m = 1 for validity > 0 else 0, s the scale, c the colours). N / D is the file's rule.
 *   3. pb_bricks_sample(bricks, p, coeffs, &d): the field at an engine-space point (the sampling rule of
 *      docs/probe-bricks.md, steps 1–4, exact weights). pb_bricks_locate() gives the brick and the
 *      brick-local texel coordinate the GPU would filter at.
 *   4. For an upload: pb_bricks_get_info() (pool and indirection dimensions), pb_bricks_indirection()
 *      (RGBA32UI texels), pb_bricks_pool_f32() / pb_bricks_pool_f16() (the channel textures).
 *   5. pb_bricks_destroy(). The bricks do not refer to the tree or the coefficients after the build.
 * With the static scene (desc.segment, docs/probe-bricks.md "Back faces and visibility"): the build also
 * traces the leaves' pair-visibility tables (pb_cotree_pair_visibility), computes the texels with the
 * visibility-ramped weights (the "visibility texels") and one 64-B record per blocked brick cell, found
 * through the brick table; pb_bricks_sample_surface() applies step 5 (back faces, the visibility ramp,
 * 1 or 8 taps); pb_bricks_table() / pb_bricks_vis_records() are the arrays for an upload.
 *
 * Layout (normative, docs/probe-bricks.md "Layout"):
 *   - Lattice: the tree's origin, min cell h and extent E (min cells). A brick of level L has texels at
 *     the lattice points r + 2^L (i, j, k), 0 ≤ i, j, k ≤ 4; its region is [r, r + 4·2^L) per axis, r a
 *     multiple of 2^(L+2). Level rule: regions top down from the root level R; a region overlapping no
 *     leaf has no brick; one whose overlapped leaves all have every axis level ≥ L is a brick of level
 *     L (isotropic bricks: a kd box counts with its smallest axis level); otherwise its 8 children.
 *   - Brick order: the level-R regions (x fastest, then y, z), each depth first with its children in the
 *     order of their bits (bit 0 = +x, 1 = +y, 2 = +z).
 *   - Channels at the file's band, C = coeff_count: channel 0–2 = N_0 (RGB), 3 = D, then N_1 … N_{C−1}
 *     RGB consecutively; channels = 3C + 1, groups = ceil(channels / 4) RGBA textures (unused channels
 *     of the last group are 0). L2: 28 channels, 7 groups.
 *   - Pool: bricks side by side on a grid of pool_bricks[0] × [1] × [2] = X × Y × Z bricks: Z = the
 *     fewest layers of PB_BRICKS_POOL_SIDE² bricks that hold them, then Y = the fewest rows of
 *     PB_BRICKS_POOL_SIDE, X = the fewest columns (fewer than Y · Z slots stay empty); brick b's texel
 *     origin is 5 · (b mod X, (b / X) mod Y, b / (X Y)). Texels of the pool past the last brick are 0.
 *   - Indirection: one RGBA32UI entry per level-0 region (4³ min cells), ceil(E/4) per axis, x fastest:
 *     x = brick | level << 27 (PB_BRICKS_NONE = no brick), y / z = the occupancy bits of the region's
 *     64 unit cells (bit i + 4j + 16k, bits 0–31 in y, 32–63 in z: a leaf holds that min cell), w = 0.
 *   - Brick table: 4 uint32 per brick (16 B): x = its first visibility record, y / z = the blocked-cell
 *     bits of its 64 cells (bit i + 4j + 16k of brick cell (i, j, k), bits 0–31 in y, 32–63 in z), w = 0.
 *     A blocked cell's record is vis_records[64 · (x + popcount of the blocked bits below the cell)].
 *   - Visibility record (64 B): the pair table of the brick cell's 8 corners, byte 8k + c = round(255 t)
 *     for corner k looking at corner c, traced exactly as pb_cotree_pair_visibility traces a leaf (read
 *     with pb_vis_pair_value, the GLSL's pair_vis()). Which cells get one: a cell inside a leaf whose own
 *     table is not all clear ("blocked" leaf), and only when the cell's own table is not all clear. A cell
 *     in a clear leaf gets none (today's per-leaf rule does not see such a surface either).
 * Coordinates: engine space, metres, double; octree axes are the identity.
 * Not here yet (docs/probe-bricks.md "Implemented in the core"): dense v1/v2 grids.
 */
#ifndef SCHNEE_PB_BRICKS_H
#define SCHNEE_PB_BRICKS_H

#include "schnee/pb_common.h"
#include "schnee/pb_cotree.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PB_BRICK_TEXELS_AXIS 5u                  /* B: texels per axis of a brick */
#define PB_BRICK_CELLS_AXIS  4u                  /* B − 1: cells per axis of a brick */
#define PB_BRICK_TEXELS      125u                /* B³ */
#define PB_BRICKS_INDEX_BITS 27u                 /* indirection x: brick index bits, then the level */
#define PB_BRICKS_MAX        (UINT32_C(1) << 27) /* bricks one pool may hold */
#define PB_BRICKS_POOL_SIDE                                                                                            \
    51u /* pool bricks along x and y at most: 255 texels, within Vulkan's minimum
                                           maxImageDimension3D (256) */
#define PB_BRICKS_NONE              UINT32_C(0xFFFFFFFF) /* indirection x of a region without a brick */
#define PB_BRICKS_MARGIN            0.01                 /* min cells: the lattice's and the faces' margin */
#define PB_BRICKS_MAX_COEFFS        25u                  /* L4 */
#define PB_BRICKS_DEFAULT_MAX_BYTES (UINT64_C(1) << 30)  /* the build's memory cap when desc.max_bytes = 0 */
#define PB_HALF_MAX                 65504.0              /* the largest binary16 */
#define PB_BRICKS_RECORD_BYTES      64u                  /* one visibility record: 8 × 8 pair bytes */
#define PB_BRICKS_SEPARABLE_EPS     1e-5                 /* pb_bricks_separable's relative tolerance */

/* pb_bricks_sample_surface() flags. */
#define PB_BRICKS_STATIC 1u /* a static surface of the bake: back-face weights (0 = movable: none) */
#define PB_BRICKS_8TAP   2u /* 8 texel fetches everywhere (0 = one filtered tap where the weights are separable) */

typedef struct pb_bricks pb_bricks;

/* Zero-initialise; 0 / NULL fields take the defaults written beside them. */
typedef struct pb_bricks_desc {
    const pb_cotree *tree; /* required: finalized (pb_cotree_finalize) */
    uint32_t coeff_count;  /* required: SH coefficients per probe, (band + 1)²: 1, 4, 9, 16 or 25 */
    const double *coeffs;  /* required: probe_count × coeff_count × 3 (probe-major, coeff, RGB), finite */
    const float *validity; /* NULL = every probe valid; else probe_count, a probe with validity <= 0 has m = 0 */
    const float *scale;    /* NULL = 1; else probe_count finite scales (the file's probe_scale) */
    uint64_t max_bytes;    /* 0 = PB_BRICKS_DEFAULT_MAX_BYTES: refuse (PB_ERROR_TOO_LARGE) past this; it
                            * covers the leaves' tables, the brick table and the records too */
    /* NULL = no static scene: plain texels, an all-zero brick table, no records (steps 1–4 only). Else
     * the occluders (pb_cotree.h): 152 calls per leaf, and 152 per brick cell inside a blocked leaf. */
    pb_segment_fn segment;
    void *segment_user; /* passed to segment */
} pb_bricks_desc;

typedef struct pb_bricks_info {
    double origin[3];     /* the lattice (the tree's frame) */
    double min_cell;      /* h, metres */
    uint32_t dims[3];     /* E, min cells */
    uint32_t root_level;  /* R: the coarsest brick level the rule starts from */
    uint32_t coeff_count; /* C */
    uint32_t channels;    /* 3C + 1 */
    uint32_t groups;      /* RGBA textures: ceil(channels / 4) */
    uint32_t brick_count;
    uint32_t level_counts[PB_COTREE_MAX_LEVEL + 1]; /* bricks per level */
    uint32_t pool_bricks[3];                        /* the pool's grid of bricks */
    uint32_t pool_texels[3];                        /* 5 × pool_bricks: each channel texture's size */
    uint32_t indirection_dims[3];                   /* ceil(E / 4) */
    uint64_t texel_count;                           /* brick_count × 125 (used texels; the pool may hold a few more) */
    uint64_t indirection_bytes;                     /* 16 per entry */
    uint64_t pool_bytes_f16;                        /* every pool texel of every group, RGBA16F */
    uint64_t pool_bytes_f32;                        /* RGBA32F */
    uint32_t blocked_leaves;                        /* leaves whose pair table is not all clear (0 without segment) */
    uint32_t traced_cells;                          /* brick cells inside blocked leaves (traced) */
    uint32_t vis_record_count;                      /* of those, the cells whose own table is not all clear */
    uint64_t table_bytes;                           /* brick table: 16 per brick */
    uint64_t vis_record_bytes;                      /* 64 per record */
} pb_bricks_info;

/* Builds the bricks (the layout above). Errors: NULL or unfinalized tree, coeff_count not a square in
 * 1..25, non-finite coefficients or scales (PB_ERROR_NON_FINITE), more than PB_BRICKS_MAX bricks or more
 * memory than max_bytes (PB_ERROR_TOO_LARGE, the message gives the size). *out owned by the caller. */
pb_result pb_bricks_build(const pb_bricks_desc *desc, pb_bricks **out, pb_error *err);
void pb_bricks_destroy(pb_bricks *bricks);

void pb_bricks_get_info(const pb_bricks *bricks, pb_bricks_info *out);

/* The sampling rule (docs/probe-bricks.md steps 1–3): u = (p − origin)/h; outside the lattice by more
 * than PB_BRICKS_MARGIN on an axis: false; u clamped into [0, E]; its unit cell q (max faces closed);
 * when no leaf holds q, the face margin of pb_interp.c's locate_point_cell (within PB_BRICKS_MARGIN
 * above q's lower faces, masks x, y, xy, z, ...: the cell below, u clamped into it); none: false.
 * Else *brick and the brick-local texel coordinate x in [0, 4]³ (the GPU's texture coordinate is
 * (texel origin + 0.5 + x) / pool_texels). Unlike pb_interp_query_cotree, points within the margin
 * outside the lattice's box take the value on its face. */
bool pb_bricks_locate(const pb_bricks *bricks, const double p[3], uint32_t *brick, double x[3]);
/* Trilinear sample of the brick's channels at brick-local x in [0, 4]³: cell k0 = min(floor(x), 3),
 * fraction f = x − k0, the 8 texels of the cell weighted (step 4). subtexel_bits 0 (or > 24): exact f;
 * else f rounded to the nearest multiple of 2^−bits per axis (step 6, the filter's weight quantisation,
 * e.g. 8 = subTexelPrecisionBits of desktop GPUs and lavapipe; the device's rounding mode and its fp32
 * texture coordinate are not emulated). out: `channels` doubles in the channel order above. */
void pb_bricks_filter(const pb_bricks *bricks, uint32_t brick, const double x[3], uint32_t subtexel_bits, double *out);
/* The field at engine-space point p: locate, filter (exact), N / D. Returns whether the point has a
 * value (a brick, and D > 0; false also where every probe with weight is invalid, as the CPU's "no
 * probe"). coeffs_out (optional): coeff_count × 3 doubles, N / D (0 without a value); d_out (optional): D. */
bool pb_bricks_sample(const pb_bricks *bricks, const double p[3], double *coeffs_out, double *d_out);
/* pb_bricks_sample with quantised filter weights (pb_bricks_filter's subtexel_bits; 0 = exact). */
bool pb_bricks_sample_bits(const pb_bricks *bricks, const double p[3], uint32_t subtexel_bits, double *coeffs_out,
                           double *d_out);

/* Step 5 of the sampling rule for a shaded surface point (docs/probe-bricks.md), in this order, which
 * the GLSL mirrors line by line:
 *   1–3. locate p_lookup (the point moved by the normal bias): brick, L, region min r, x; no brick: false.
 *   a. cell k0 = min(floor(x), 3), f = x − k0, cell index i + 4j + 16k; table entry of the brick;
 *      blocked = the cell's bit. Neither STATIC nor blocked: the plain sample at x (b. to e. skipped).
 *   b. w_k = trilinear(f) (corner k = bits x, y, z of k).
 *   c. back faces (STATIC): wb_k = w_k · smoothstep(−0.1, 0.1, dot((r + 2^L (k0 + bits(k)) − u_s) / 2^L, n)),
 *      u_s = (p_surface − origin) / h; else wb_k = w_k. wbsum = Σ wb_k.
 *   d. visibility (blocked): v_c = Σ_k wb_k V(k, c) / wbsum (V = pb_vis_pair_value of the cell's record;
 *      v_c = 0 when wbsum = 0), w'_c = wb_c · smoothstep(½, ½ + PB_VIS_RAMP, v_c); else w' = wb.
 *      sw = Σ w'_c.
 *   e. sw > 0: f'_a = Σ_k w'_k bit_a(k) / sw; where w' is separable (pb_bricks_separable: w'_k / sw =
 *      Π_a (bit_a(k) ? f'_a : 1 − f'_a) for all 8 k, within PB_BRICKS_SEPARABLE_EPS relative; e.g. an
 *      axis-aligned surface, or no corner dropped) and not 8TAP, one filtered sample at k0 + f' (fractions rounded to
 *      subtexel_bits): exactly the 8 weights w' / sw on N and D alike, so N / D is the 8 taps' N' / D';
 *      else N' = Σ w'_k T_k, D' = Σ w'_k D_k over the cell's 8 texels. D > 0: N / D.
 *   f. Else the plain sample at x (the shader's second pass); D ≤ 0: false (no value).
 * The plain sample: 8TAP exact weights (= pb_bricks_sample), else pb_bricks_filter with subtexel_bits
 * (= pb_bricks_sample_bits). subtexel_bits applies to filtered fetches only (8TAP is exact).
 * p_surface: NULL = p_lookup; n: the unit surface normal (not normalised here), needed for STATIC
 * only. Returns PB_SUCCESS with *has_value; PB_ERROR_INVALID_ARGUMENT (message in err) for NULL bricks
 * or p_lookup, unknown flags, or (STATIC) a NULL, non-finite or zero normal or a non-finite p_surface.
 * coeffs_out (optional): coeff_count × 3 (0 without a value); d_out (optional): the D divided by. */
pb_result pb_bricks_sample_surface(const pb_bricks *bricks, const double p_lookup[3], const double p_surface[3],
                                   const double n[3], uint32_t flags, uint32_t subtexel_bits, double *coeffs_out,
                                   double *d_out, bool *has_value, pb_error *err);

/* Whether 8 nonnegative corner weights w (corner k = bits x, y, z of k) are trilinear ones up to scale:
 * with M_a(b) = Σ_{bit_a(k) = b} w_k, w_k (Σ w)² = Π_a M_a(bit_a(k)) within PB_BRICKS_SEPARABLE_EPS
 * relative for every k (so exactly 0 where w_k = 0: a dropped corner stays dropped). f_out[a] = M_a(1) /
 * Σ w, the fraction whose trilinear weights are then w / Σ w (step 5e's one tap). False when Σ w <= 0. */
bool pb_bricks_separable(const double w[8], double f_out[3]);

/* ---- arrays for an upload and for tests --------------------------------------------------------- */

/* The brick table: brick_count × 4 uint32 (layout above); all zero without a segment function. */
const uint32_t *pb_bricks_table(const pb_bricks *bricks);
/* vis_record_count × 64 bytes (layout above); NULL when there are none. */
const uint8_t *pb_bricks_vis_records(const pb_bricks *bricks);

/* Indirection: indirection_dims product × 4 uint32 (x fastest), as described above. */
const uint32_t *pb_bricks_indirection(const pb_bricks *bricks);
/* brick_count × 4 uint32: the region's min corner x, y, z (lattice) and the level. */
const uint32_t *pb_bricks_regions(const pb_bricks *bricks);
/* The float64 texels: brick_count × 125 × channels, brick-local texel i + 5j + 25k (i along x). */
const double *pb_bricks_texels(const pb_bricks *bricks);
/* The pool as `groups` RGBA textures, group-major, then z, y, x, then RGBA: out[(((g · pz + z) · py + y)
 * · px + x) · 4 + c] with (px, py, pz) = pool_texels; capacity in elements (floats / halves) must be at
 * least groups × pool texels × 4. f16: IEEE binary16, round to nearest even; PB_ERROR_TOO_LARGE when a
 * value exceeds PB_HALF_MAX in magnitude (then upload f32 for the whole pool, docs/probe-bricks.md). */
pb_result pb_bricks_pool_f32(const pb_bricks *bricks, float *out, uint64_t capacity, pb_error *err);
pb_result pb_bricks_pool_f16(const pb_bricks *bricks, uint16_t *out, uint64_t capacity, pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
