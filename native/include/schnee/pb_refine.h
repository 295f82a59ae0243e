/* Schnee probes — error-driven refinement of a corner octree, pass by pass (issue 12,
 * docs/placement.md, "Error-driven refinement").
 *
 * How to use it (the bake drives it; this code never renders):
 *   1. Start with a corner octree of Max Cell Size leaves over the volumes (pb_cotree_create, drop the
 *      leaves outside), pb_cotree_finalize, bake its probes (pb_cotree_probe_positions).
 *   2. pb_refine_tests_create(): the test points of every leaf that may still split (level > 0): its
 *      centre and 6 face centres. They are lattice points and become corners of the children when the
 *      leaf splits, so a test bake is never wasted. Points that already are probes are marked (no bake).
 *   3. Bake the test points that need it, then pb_refine_decide(): per leaf, the relative irradiance
 *      error (RMS over directions) between each test point's baked SH and the leaf's interpolation there;
 *      a leaf splits when some error exceeds sqrt(tolerance² + (k·noise)²), noise being the Monte-Carlo
 *      noise of the two sides (per-probe estimates passed in; independent noise adds to the light's
 *      own error in quadrature). Leaves at Min Cell Size (level 0) never split.
 *   4. pb_cotree_split(split flags), pb_cotree_finalize; the new probes are old probes, test points or
 *      new edge midpoints (look old values up by lattice point); bake the new ones; back to 2 until no
 *      leaf splits.
 */
#ifndef SCHNEE_PB_REFINE_H
#define SCHNEE_PB_REFINE_H

#include "schnee/pb_interp.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PB_REFINE_TESTS_PER_LEAF 7 /* centre, −x, +x, −y, +y, −z, +z face centres */

typedef struct pb_refine_tests {
    uint32_t point_count; /* unique test points */
    uint32_t *lattice;    /* point_count × 3, lattice coordinates (min cells) */
    double *positions;    /* point_count × 3, engine space */
    int32_t *probe; /* point_count: index of the probe already at that point (its value is used, no bake), or −1 */
    uint32_t leaf_count;
    int32_t *leaf_tests; /* leaf_count × per_leaf test point indices, −1 for none */
    uint32_t per_leaf;   /* columns of leaf_tests: 7 (or 0 in a struct filled by hand) the octree's tests
                            (PB_REFINE_TESTS_PER_LEAF); 14 (PB_REFINE_AXIS_TESTS) per-axis tests */
} pb_refine_tests;

/* Test points of a finalized tree, optionally only for leaves whose `active` flag is set (NULL = all
 * leaves), e.g. leaves that split in the previous pass and their neighbours. A tree of cubes only
 * (a box leaf is refused: pb_refine_tests_create_axes). */
pb_result pb_refine_tests_create(const pb_cotree *tree, const uint8_t *active, pb_refine_tests **out, pb_error *err);
void pb_refine_tests_destroy(pb_refine_tests *tests);

typedef struct pb_refine_desc {
    uint32_t max_band;           /* 0..4: band of the SH values below */
    const double *probe_coeffs;  /* probe_count × pb_sh_count(max_band) × 3: radiance SH of the tree's probes */
    const double *test_coeffs;   /* point_count × ... : baked at the test points (rows of points with probe ≥ 0
                                    are not read) */
    const float *probe_noise;    /* probe_count: relative RMS irradiance noise of each probe, or NULL = 0 */
    const float *test_noise;     /* point_count, or NULL = 0 */
    const float *probe_validity; /* probe_count, or NULL: probes with validity <= 0 (inside solids) are left out of
                                    the interpolation (as pb_interp_options.validity) */
    const uint8_t *test_valid;   /* point_count, or NULL: 0 = the test point is inside a solid; not compared */
    double tolerance;            /* 0 = 0.05: relative irradiance error a leaf may have */
    double noise_k;              /* 0 = 2: refine only when error > sqrt(tolerance² + (noise_k · noise)²) */
} pb_refine_desc;

/* Split flags (leaf_count bytes, 1 = split) and optionally each leaf's worst error and the
 * threshold it was held to (NULL to skip). Leaves without tests get error 0 and flag 0. Tests with
 * per_leaf 14 (per-axis) are read too: a leaf splits when any of its tests fails. */
pb_result pb_refine_decide(const pb_cotree *tree, const pb_refine_tests *tests, const pb_refine_desc *desc,
                           uint8_t *split, double *leaf_error, double *leaf_threshold, pb_error *err);

/* ---- per-axis refinement (issue 29 item 3, docs/aniso-refinement.md "Tests and the split rule") ----
 * For trees of boxes with per-axis levels (pb_cotree_leaf_levels); on a tree of cubes they are valid too
 * (12 edge midpoints and the centre, all lattice points). Steps as above, with
 * pb_refine_tests_create_axes, pb_refine_decide_axes and pb_cotree_split_axes.
 * Test columns of a leaf (per_leaf = 14): 4a + e for the 4 edges along axis a (e: bit 0 = the first other
 * axis at its max, bit 1 = the second; other axes in x, y, z order), the edge's midpoint, −1 where
 * l_a = 0; column 12 the middle of all splittable axes (the centre when all three levels are > 0; with
 * one level-0 axis the centre of the face across it at its min) and 13 (one level-0 axis: the face
 * centre at its max; else −1). With two level-0 axes only the one axis' edges. Shared points are one
 * test point (lattice order), a point that is a probe is marked as in pb_refine_tests_create. */
#define PB_REFINE_AXIS_TESTS 14
pb_result pb_refine_tests_create_axes(const pb_cotree *tree, const uint8_t *active, pb_refine_tests **out,
                                      pb_error *err);
/* Axis masks (leaf_count bytes: bit a = split along axis a) by the rule of docs/aniso-refinement.md: a
 * failing edge midpoint along a splits along a; a failing middle point splits along all its axes only
 * when no edge test of the leaf failed; level-0 axes are never set. A test fails, and errors and
 * thresholds are measured, exactly as in pb_refine_decide (the worst margin over the leaf's compared
 * tests); the mask is nonzero exactly where pb_refine_decide on the same tests gives 1. Needs tests with
 * per_leaf 14. */
pb_result pb_refine_decide_axes(const pb_cotree *tree, const pb_refine_tests *tests, const pb_refine_desc *desc,
                                uint8_t *axes, double *leaf_error, double *leaf_threshold, pb_error *err);
/* The lattice point of test column `column` (0..13, layout above) of the box with min corner `corner`
 * and levels `levels` (lattice units); false where the column has no test (e.g. an edge along a level-0
 * axis). What pb_refine_tests_create_axes places, for a caller that reads tests by column. */
bool pb_refine_axis_test_point(const uint32_t corner[3], const uint32_t levels[3], uint32_t column, uint32_t out[3]);

/* Relative irradiance error, RMS over directions and RGB, of SH `a` against reference `ref`
 * (radiance SH, band max_band): ‖A·(a − ref)‖ / ‖A·ref‖ with A the Lambert band factors (exact, by
 * the orthonormality of the basis). 0 when both are 0; `a` ≠ 0 against ref 0 gives 1. */
double pb_refine_irradiance_error(uint32_t max_band, const double *a, const double *ref);

/* The same for `count` points: a, ref hold count × pb_sh_count(max_band) × 3 values, out count errors
 * (the refinement's metric for the add-on: addon/schnee_probes/metric.py calls it). */
void pb_refine_irradiance_error_many(uint32_t max_band, size_t count, const double *a, const double *ref, double *out);

/* ‖A·c‖ of each of `count` radiance SH c (count × pb_sh_count(max_band) × 3 values): the irradiance's
 * RMS over directions times √(4π), summed in the order of pb_refine_irradiance_error (whose error is
 * the ratio of two such norms, squared then divided). */
void pb_refine_irradiance_norm_many(uint32_t max_band, size_t count, const double *c, double *out);

#ifdef __cplusplus
}
#endif
#endif
