/* Per-axis refinement tests and split decisions (pb_refine.h, docs/aniso-refinement.md "Tests and the
 * split rule") on closed-form light fields, no Cycles. Expected values are written out by hand:
 * - the column layout of pb_refine_axis_test_point for a cube, a box with one level-0 axis and a box
 *   with two, as literal lattice points;
 * - a field quadratic along y only splits along y only (mask 2), one quadratic in x and z along x and z
 *   (5), a linear field nowhere (trilinear is exact), a compact bump at a leaf's centre (no edge
 *   midpoint sees it) along all three; the leaf's error is the closed form of the trilinear's error;
 * - an error above the tolerance but within k·σ does not split, above it does;
 * - shared edge midpoints are one point (counts from the lattice's edges), `active` leaves only;
 * - pb_refine_decide on the same tests splits exactly where the mask is nonzero, and on cubes with
 *   pb_refine_tests_create (the octree path) is untouched by per_leaf. */
#include "schnee/pb_refine.h"
#include "schnee/pb_sh.h"

#include "testutil.h"

#include <stdint.h>
#include <stdlib.h>

#define BAND 1
#define NC   4 /* pb_sh_count(1) */

typedef double (*scalar_fn)(const double p[3]);

/* Radiance SH whose every coefficient and channel is f(p) times a fixed pattern: the relative
 * irradiance error of an interpolation is then |f_interp − f| / |f| exactly. */
static void fill(scalar_fn f, const double *pos, uint32_t n, double *out)
{
    for (uint32_t i = 0; i < n; i++) {
        double v = f(pos + 3 * i);
        for (int m = 0; m < NC * 3; m++) out[(size_t)i * NC * 3 + (size_t)m] = v * (1.0 + 0.05 * m);
    }
}

/* One cube of 4 min cells (1 m) at the origin, or dims roots of it. */
static pb_cotree *cubes(uint32_t nx, uint32_t ny, uint32_t nz)
{
    const double o[3] = {0, 0, 0};
    const uint32_t roots[3] = {nx, ny, nz};
    pb_cotree *t = NULL;
    pb_error err = {0};
    if (pb_cotree_create(o, 0.25, 2, roots, &t, &err) != PB_SUCCESS) return NULL;
    if (pb_cotree_finalize(t, &err) != PB_SUCCESS) {
        pb_cotree_destroy(t);
        return NULL;
    }
    return t;
}

typedef struct decided {
    uint8_t *axes, *split;
    double *err, *thr;
    pb_refine_tests *tests;
} decided;

static void decided_free(decided *d)
{
    free(d->axes), free(d->split), free(d->err), free(d->thr);
    pb_refine_tests_destroy(d->tests);
}

/* Per-axis tests of every leaf, baked from f (noise n on probes and tests when n > 0, passed in when
 * pass_noise), decided with tolerance tol. Also pb_refine_decide on the same tests into d->split. */
static bool decide(const pb_cotree *t, scalar_fn f, double tol, float n, bool pass_noise, decided *d)
{
    pb_error err = {0};
    memset(d, 0, sizeof *d);
    if (pb_refine_tests_create_axes(t, NULL, &d->tests, &err) != PB_SUCCESS) return false;
    uint32_t P = pb_cotree_probe_count(t), L = pb_cotree_leaf_count(t), T = d->tests->point_count;
    double *pos = malloc((size_t)P * 3 * sizeof(double)), *pc = malloc((size_t)P * NC * 3 * sizeof(double));
    double *tc = malloc(((size_t)T + 1) * NC * 3 * sizeof(double));
    float *pn = malloc(P * sizeof(float)), *tn = malloc(((size_t)T + 1) * sizeof(float));
    pb_cotree_probe_positions(t, pos);
    fill(f, pos, P, pc);
    fill(f, d->tests->positions, T, tc);
    for (uint32_t i = 0; i < P; i++) pn[i] = n;
    for (uint32_t j = 0; j < T; j++) tn[j] = n;
    pb_refine_desc desc = {.max_band = BAND, .probe_coeffs = pc, .test_coeffs = tc, .tolerance = tol};
    if (pass_noise) desc.probe_noise = pn, desc.test_noise = tn;
    d->axes = malloc(L), d->split = malloc(L);
    d->err = malloc(L * sizeof(double)), d->thr = malloc(L * sizeof(double));
    bool ok = pb_refine_decide_axes(t, d->tests, &desc, d->axes, d->err, d->thr, &err) == PB_SUCCESS &&
              pb_refine_decide(t, d->tests, &desc, d->split, NULL, NULL, &err) == PB_SUCCESS;
    free(pos), free(pc), free(tc), free(pn), free(tn);
    return ok;
}

/* ---- column layout ---------------------------------------------------------------------------- */

static void check_columns(const uint32_t corner[3], const uint32_t levels[3], const int64_t want[14][3])
{
    for (uint32_t c = 0; c < PB_REFINE_AXIS_TESTS; c++) {
        uint32_t p[3] = {0, 0, 0};
        bool has = pb_refine_axis_test_point(corner, levels, c, p);
        TU_CHECK(has == (want[c][0] >= 0));
        if (has && want[c][0] >= 0)
            for (int k = 0; k < 3; k++) TU_CHECK(p[k] == (uint32_t)want[c][k]);
    }
}

static void test_column_layout(void)
{
    /* A cube of 4 min cells at (4, 0, 4): edges along x at y, z in {0, 4} + {4, 8} (bit 0 = y max, bit 1
     * = z max), along y at x in {4, 8} (bit 0), z (bit 1), along z at x (bit 0), y (bit 1); the centre. */
    const uint32_t c0[3] = {4, 0, 4}, l0[3] = {2, 2, 2};
    const int64_t w0[14][3] = {{6, 0, 4}, {6, 4, 4}, {6, 0, 8}, {6, 4, 8}, {4, 2, 4}, {8, 2, 4}, {4, 2, 8},
                               {8, 2, 8}, {4, 0, 6}, {8, 0, 6}, {4, 4, 6}, {8, 4, 6}, {6, 2, 6}, {-1, 0, 0}};
    check_columns(c0, l0, w0);
    /* A slab: levels (2, 0, 1) at (4, 3, 2), sizes 4 × 1 × 2: no y edges; the faces across y (its
     * level-0 axis) at y = 3 and 4, each at the middle of x and z. */
    const uint32_t c1[3] = {4, 3, 2}, l1[3] = {2, 0, 1};
    const int64_t w1[14][3] = {{6, 3, 2},  {6, 4, 2}, {6, 3, 4}, {6, 4, 4}, {-1, 0, 0}, {-1, 0, 0}, {-1, 0, 0},
                               {-1, 0, 0}, {4, 3, 3}, {8, 3, 3}, {4, 4, 3}, {8, 4, 3},  {6, 3, 3},  {6, 4, 3}};
    check_columns(c1, l1, w1);
    /* A column: levels (0, 0, 3) at (1, 2, 8): only the 4 edges along z, at z = 12; no middle point. */
    const uint32_t c2[3] = {1, 2, 8}, l2[3] = {0, 0, 3};
    const int64_t w2[14][3] = {{-1, 0, 0}, {-1, 0, 0}, {-1, 0, 0}, {-1, 0, 0}, {-1, 0, 0}, {-1, 0, 0}, {-1, 0, 0},
                               {-1, 0, 0}, {1, 2, 12}, {2, 2, 12}, {1, 3, 12}, {2, 3, 12}, {-1, 0, 0}, {-1, 0, 0}};
    check_columns(c2, l2, w2);
    /* One level-0 axis x: the faces across x at x = 7 and 8. */
    const uint32_t c3[3] = {7, 0, 0}, l3[3] = {0, 1, 1};
    uint32_t p[3];
    TU_CHECK(pb_refine_axis_test_point(c3, l3, 12, p) && p[0] == 7 && p[1] == 1 && p[2] == 1);
    TU_CHECK(pb_refine_axis_test_point(c3, l3, 13, p) && p[0] == 8 && p[1] == 1 && p[2] == 1);
    const uint32_t zero[3] = {0, 0, 0};
    for (uint32_t c = 0; c < PB_REFINE_AXIS_TESTS; c++) TU_CHECK(!pb_refine_axis_test_point(c3, zero, c, p));
    TU_CHECK(!pb_refine_axis_test_point(c0, l0, 14, p));
}

/* The tests of a cube tree follow the layout: every column of leaf 1 of 2 × 1 × 1 cubes (at x = 4). */
static void test_tree_columns_and_dedup(void)
{
    pb_cotree *t = cubes(2, 1, 1);
    TU_REQUIRE(t != NULL);
    pb_refine_tests *tests = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_SUCCESS);
    TU_CHECK(tests->per_leaf == PB_REFINE_AXIS_TESTS && tests->leaf_count == 2);
    /* 2 × 13 tests; the 2 y edges and 2 z edges on the shared face x = 4 are common: 22 points. */
    TU_CHECK(tests->point_count == 22);
    const uint32_t *lv = pb_cotree_leaves(t);
    uint32_t leaf = lv[0] == 4 ? 0 : 1, levels[3] = {2, 2, 2};
    TU_REQUIRE(lv[4 * leaf] == 4);
    for (uint32_t c = 0; c < PB_REFINE_AXIS_TESTS; c++) {
        int32_t ti = tests->leaf_tests[PB_REFINE_AXIS_TESTS * leaf + c];
        uint32_t p[3];
        TU_CHECK((ti >= 0) == pb_refine_axis_test_point(lv + 4 * leaf, levels, c, p));
        if (ti < 0) continue;
        for (int k = 0; k < 3; k++) {
            TU_CHECK(tests->lattice[3 * ti + k] == p[k]);
            TU_CHECK_NEAR(tests->positions[3 * ti + k], 0.25 * p[k], 1e-15);
        }
        TU_CHECK(tests->probe[ti] == -1); /* edge midpoints and the centre are no corners here */
    }
    /* The y edge at x = 4 (low z) is column 5 (x max) of leaf 0 and column 4 (x min) of leaf 1. */
    TU_CHECK(tests->leaf_tests[PB_REFINE_AXIS_TESTS * (1 - leaf) + 5] ==
             tests->leaf_tests[PB_REFINE_AXIS_TESTS * leaf + 4]);
    /* Sorted lattice order (z, then y, then x), each point once. */
    for (uint32_t j = 1; j < tests->point_count; j++) {
        const uint32_t *a = tests->lattice + 3 * (j - 1), *b = tests->lattice + 3 * j;
        uint64_t ka = a[0] | (uint64_t)a[1] << 21 | (uint64_t)a[2] << 42,
                 kb = b[0] | (uint64_t)b[1] << 21 | (uint64_t)b[2] << 42;
        TU_CHECK(ka < kb);
    }
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);

    /* 2 × 2 × 2 cubes: the midpoints of the lattice edges of a 3 × 3 × 3 grid of corners (3 axes × 2
     * segments × 3 × 3 lines = 54) and 8 centres: 62 points for 104 tests. Only the active leaf 0: 13. */
    t = cubes(2, 2, 2);
    TU_REQUIRE(t != NULL);
    TU_REQUIRE(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_SUCCESS);
    TU_CHECK(tests->point_count == 62);
    pb_refine_tests_destroy(tests);
    uint8_t active[8] = {1, 0, 0, 0, 0, 0, 0, 0};
    TU_REQUIRE(pb_refine_tests_create_axes(t, active, &tests, &err) == PB_SUCCESS);
    TU_CHECK(tests->point_count == 13);
    for (uint32_t c = 0; c < 8 * PB_REFINE_AXIS_TESTS; c++)
        TU_CHECK((tests->leaf_tests[c] >= 0) == (c < PB_REFINE_AXIS_TESTS && c != 13));
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);
}

/* A tree with leaves at Min Cell Size gets no tests for them; an unfinalized tree is refused. */
static void test_level0_and_errors(void)
{
    const double o[3] = {0, 0, 0};
    const uint32_t dims[3] = {2, 1, 1}, leaves[8] = {0, 0, 0, 0, 1, 0, 0, 0};
    pb_cotree *t = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_cotree_create_leaves(o, 1.0, dims, leaves, 2, &t, &err) == PB_SUCCESS);
    pb_refine_tests *tests = NULL;
    TU_CHECK(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_ERROR_INVALID_ARGUMENT && tests == NULL);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_SUCCESS);
    TU_CHECK(tests->point_count == 0);
    for (int c = 0; c < 2 * PB_REFINE_AXIS_TESTS; c++) TU_CHECK(tests->leaf_tests[c] == -1);
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);
    /* pb_refine_decide_axes refuses the octree's 7 columns. */
    t = cubes(1, 1, 1);
    TU_REQUIRE(t != NULL);
    TU_REQUIRE(pb_refine_tests_create(t, NULL, &tests, &err) == PB_SUCCESS);
    TU_CHECK(tests->per_leaf == PB_REFINE_TESTS_PER_LEAF);
    double pc[8 * NC * 3] = {0}, tc[7 * NC * 3] = {0};
    pb_refine_desc d = {.max_band = BAND, .probe_coeffs = pc, .test_coeffs = tc};
    uint8_t axes = 9;
    TU_CHECK(pb_refine_decide_axes(t, tests, &d, &axes, NULL, NULL, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(axes == 9);
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);
}

/* ---- closed-form fields ----------------------------------------------------------------------- */

/* On the 1 m cube at the origin: f = 1 + q·y² (y in m). The trilinear at y = 1/2 is the mean of the
 * ends, 1 + q/2, against 1 + q/4: error (q/4) / (1 + q/4), at the y edges' midpoints and the centre;
 * every x and z edge is exact (y at a corner). q = 1: 0.2. */
static double quad_y(const double p[3]) { return 1.0 + p[1] * p[1]; }
/* f = 1 + 0.6·x² + 0.3·z²: x edges 0.15 / (1.15 + 0.3 z²) with z in {0, 1}, worst 0.15 / 1.15 = 0.130;
 * z edges 0.075 / (1.075 + 0.6 x²), worst 0.075 / 1.075 = 0.070; y edges exact; the centre the sum of
 * both, 0.225 / 1.225 = 0.184 (1.45 interpolated against 1.225). */
static double quad_xz(const double p[3]) { return 1.0 + 0.6 * p[0] * p[0] + 0.3 * p[2] * p[2]; }
static double linear(const double p[3]) { return 2.0 + 0.3 * p[0] - 0.7 * p[1] + 0.5 * p[2]; }
/* A bump of height 1 and radius 0.4 m at the cube's centre: zero at the edge midpoints (0.71 m away)
 * and corners: the centre's error is 1 / 2 (f = 2 against 1 interpolated). */
static double bump(const double p[3])
{
    double r2 = 0.0;
    for (int k = 0; k < 3; k++) r2 += (p[k] - 0.5) * (p[k] - 0.5);
    double s = 1.0 - r2 / 0.16;
    return 1.0 + (s > 0.0 ? s * s : 0.0);
}

static void test_closed_form_fields(void)
{
    pb_cotree *t = cubes(1, 1, 1);
    TU_REQUIRE(t != NULL);
    decided d;
    TU_REQUIRE(decide(t, quad_y, 0.05, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 2);
    TU_CHECK(d.split[0] == 1);
    TU_CHECK_NEAR(d.err[0], 0.2, 1e-12);
    TU_CHECK_NEAR(d.thr[0], 0.05, 1e-15);
    decided_free(&d);
    /* A tolerance above the error (0.2) splits nothing. */
    TU_REQUIRE(decide(t, quad_y, 0.21, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 0 && d.split[0] == 0);
    TU_CHECK_NEAR(d.err[0], 0.2, 1e-12);
    decided_free(&d);

    TU_REQUIRE(decide(t, quad_xz, 0.05, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 5);
    TU_CHECK_NEAR(d.err[0], 0.225 / 1.225, 1e-12); /* the worst test: the centre */
    decided_free(&d);
    /* Between the two axes' edge errors: x only (the failing centre is explained by the x edges). */
    TU_REQUIRE(decide(t, quad_xz, 0.1, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 1);
    decided_free(&d);
    /* Above both edge errors, below the centre's: no edge fails, so the centre splits all three axes. */
    TU_REQUIRE(decide(t, quad_xz, 0.15, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 7);
    decided_free(&d);

    TU_REQUIRE(decide(t, linear, 1e-9, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 0 && d.split[0] == 0);
    TU_CHECK(d.err[0] < 1e-12);
    decided_free(&d);

    TU_REQUIRE(decide(t, bump, 0.05, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 7);
    TU_CHECK_NEAR(d.err[0], 0.5, 1e-12);
    decided_free(&d);
    pb_cotree_destroy(t);

    /* Four cubes along x, f quadratic in y: every leaf along y only, errors as on one cube. */
    t = cubes(4, 1, 1);
    TU_REQUIRE(t != NULL);
    TU_REQUIRE(decide(t, quad_y, 0.05, 0.0f, false, &d));
    for (uint32_t i = 0; i < 4; i++) {
        TU_CHECK(d.axes[i] == 2);
        TU_CHECK_NEAR(d.err[i], 0.2, 1e-12);
    }
    decided_free(&d);
    pb_cotree_destroy(t);
}

/* The mask is nonzero exactly where pb_refine_decide on the same 14 columns splits (the decide helper
 * ran both), on a mixed tree: a 2 × 1 × 2 layer of 1 m roots with root (0, 0, 0) split (its children's
 * corners on the unsplit neighbours' faces hang, so near them more axes fail), the bump moved to the
 * centre of root (1, 0, 1) and 0.2·y² where x < 1 m. Closed forms: root (1, 0, 1) sees only the bump
 * at its centre (7, error 1/2); root (1, 0, 0) sees a constant (0); the split root's children at
 * x < 0.5 m away from the hanging corners see y² alone (2). */
static double mixed(const double p[3])
{
    double r2 = (p[0] - 1.5) * (p[0] - 1.5) + (p[1] - 0.5) * (p[1] - 0.5) + (p[2] - 1.5) * (p[2] - 1.5);
    double s = 1.0 - r2 / 0.16;
    return 1.0 + 0.2 * p[1] * p[1] * (p[0] < 1.0) + (s > 0.0 ? s * s : 0.0);
}

static void test_decide_agrees_with_octree_decide(void)
{
    pb_cotree *t = cubes(2, 1, 2);
    TU_REQUIRE(t != NULL);
    pb_error err = {0};
    uint8_t flags[4] = {1, 0, 0, 0};
    TU_REQUIRE(pb_cotree_split(t, flags, NULL, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    decided d;
    TU_REQUIRE(decide(t, mixed, 0.01, 0.0f, false, &d));
    uint32_t L = pb_cotree_leaf_count(t), seen = 0;
    TU_CHECK(L == 11);
    for (uint32_t i = 0; i < L; i++) {
        TU_CHECK((d.axes[i] != 0) == (d.split[i] != 0));
        const uint32_t *lv = pb_cotree_leaves(t) + 4 * i;
        if (lv[3] == 2 && lv[0] == 4 && lv[2] == 4) {
            TU_CHECK(d.axes[i] == 7);
            TU_CHECK_NEAR(d.err[i], 0.5, 1e-12);
            seen++;
        } else if (lv[3] == 2 && lv[0] == 4) {
            TU_CHECK(d.axes[i] == 0);
            seen++;
        } else if (lv[3] == 1 && lv[0] == 0 && lv[2] == 0) {
            TU_CHECK(d.axes[i] == 2);
            seen++;
        }
    }
    TU_CHECK(seen == 4);
    decided_free(&d);
    pb_cotree_destroy(t);
}

/* ---- noise ------------------------------------------------------------------------------------ */

/* Constant probes c, the 4 y-edge midpoints baked as c·(1 + δ) (relative error δ/(1 + δ)), every other
 * test c; noise n on all. A y-edge midpoint is the mean of 2 corners: σ² = n² + 2·(n/2)², threshold
 * sqrt(tol² + k²·1.5 n²) = 3.873 % at tol 3 %, n 1 %, k 2. An error of 3.8 % splits nothing with the
 * noise passed, along y without it; 4 % splits along y either way. */
static double y_edge_delta;
static double y_edges_off(const double p[3])
{
    bool mid_y = fabs(p[1] - 0.5)<1e-9, x_end = fabs(p[0] - 0.5)> 0.4, z_end = fabs(p[2] - 0.5) > 0.4;
    return 1.0 + (mid_y && x_end && z_end ? y_edge_delta : 0.0);
}

static void test_noise_within_k_sigma(void)
{
    pb_cotree *t = cubes(1, 1, 1);
    TU_REQUIRE(t != NULL);
    const double tol = 0.03, n = 0.01, k = 2.0, thr = sqrt(tol * tol + k * k * 1.5 * n * n);
    const double errors[2] = {0.038, 0.04};
    for (int c = 0; c < 2; c++) {
        y_edge_delta = errors[c] / (1.0 - errors[c]);
        decided d;
        TU_REQUIRE(decide(t, y_edges_off, tol, (float)n, true, &d));
        TU_CHECK(d.axes[0] == (c == 0 ? 0 : 2));
        TU_CHECK_NEAR(d.err[0], errors[c], 1e-12);
        TU_CHECK_NEAR(d.thr[0], thr, 1e-8); /* noise passed as float */
        decided_free(&d);
        TU_REQUIRE(decide(t, y_edges_off, tol, (float)n, false, &d));
        TU_CHECK(d.axes[0] == 2);
        TU_CHECK_NEAR(d.thr[0], tol, 1e-15);
        decided_free(&d);
    }
    pb_cotree_destroy(t);
}

/* Invalid test points are not compared: the bump's centre marked invalid splits nothing. */
static void test_invalid_tests_skipped(void)
{
    pb_cotree *t = cubes(1, 1, 1);
    TU_REQUIRE(t != NULL);
    pb_error err = {0};
    pb_refine_tests *tests = NULL;
    TU_REQUIRE(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_SUCCESS);
    TU_REQUIRE(tests->point_count == 13);
    double pos[8 * 3], pc[8 * NC * 3], tc[13 * NC * 3];
    pb_cotree_probe_positions(t, pos);
    fill(bump, pos, 8, pc);
    fill(bump, tests->positions, 13, tc);
    uint8_t valid[13];
    for (int j = 0; j < 13; j++) valid[j] = j != tests->leaf_tests[12];
    pb_refine_desc d = {.max_band = BAND, .probe_coeffs = pc, .test_coeffs = tc, .test_valid = valid};
    uint8_t axes = 9;
    double e = -1.0;
    TU_REQUIRE(pb_refine_decide_axes(t, tests, &d, &axes, &e, NULL, &err) == PB_SUCCESS);
    TU_CHECK(axes == 0);
    TU_CHECK(e < 1e-12);
    d.test_valid = NULL;
    TU_REQUIRE(pb_refine_decide_axes(t, tests, &d, &axes, &e, NULL, &err) == PB_SUCCESS);
    TU_CHECK(axes == 7);
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);
}

/* ---- box trees -------------------------------------------------------------------------------- */

/* One box of levels (lx, ly, lz) at the origin, min cell 1 m, R = 2, lattice dims. */
static pb_cotree *boxes(const uint32_t dims[3], const uint32_t *leaves, uint32_t n)
{
    const double o[3] = {0, 0, 0};
    pb_cotree *t = NULL;
    pb_error err = {0};
    if (pb_cotree_create_boxes(o, 1.0, 2, dims, leaves, n, &t, &err) != PB_SUCCESS) return NULL;
    if (pb_cotree_finalize(t, &err) != PB_SUCCESS) {
        pb_cotree_destroy(t);
        return NULL;
    }
    return t;
}

/* The test points of a tree are exactly the `n` lattice points `want` (in any order). */
static void check_points(const pb_refine_tests *tests, const uint32_t want[][3], uint32_t n)
{
    TU_CHECK(tests->point_count == n);
    for (uint32_t w = 0; w < n; w++) {
        uint32_t found = 0;
        for (uint32_t j = 0; j < tests->point_count; j++)
            found += memcmp(tests->lattice + 3 * j, want[w], 3 * sizeof(uint32_t)) == 0;
        TU_CHECK(found == 1);
    }
}

static void test_box_test_points(void)
{
    pb_error err = {0};
    pb_refine_tests *tests = NULL;
    /* A slab 4 × 1 × 4 (levels 2, 0, 2): 4 x edges at x = 2 (y in {0, 1}, z in {0, 4}), 4 z edges at z =
     * 2, the centres of its two faces across y: 10 points, no y edge. */
    const uint32_t d1[3] = {4, 1, 4}, slab[4] = {0, 0, 0, PB_LEVELS_PACK(2, 0, 2)};
    const uint32_t w1[10][3] = {{2, 0, 0}, {2, 1, 0}, {2, 0, 4}, {2, 1, 4}, {0, 0, 2},
                                {4, 0, 2}, {0, 1, 2}, {4, 1, 2}, {2, 0, 2}, {2, 1, 2}};
    pb_cotree *t = boxes(d1, slab, 1);
    TU_REQUIRE(t != NULL);
    TU_REQUIRE(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_SUCCESS);
    check_points(tests, w1, 10);
    pb_refine_tests *octree = NULL; /* the octree's centre and face centres are not lattice points here */
    TU_CHECK(pb_refine_tests_create(t, NULL, &octree, &err) == PB_ERROR_INVALID_ARGUMENT && octree == NULL);
    for (uint32_t c = 4; c < 8; c++) TU_CHECK(tests->leaf_tests[c] == -1);
    TU_CHECK(tests->leaf_tests[12] >= 0 && tests->lattice[3 * tests->leaf_tests[12] + 1] == 0);
    TU_CHECK(tests->leaf_tests[13] >= 0 && tests->lattice[3 * tests->leaf_tests[13] + 1] == 1);
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);
    /* A column 1 × 1 × 4 (levels 0, 0, 2): its 4 z edges' midpoints only. */
    const uint32_t d2[3] = {1, 1, 4}, column[4] = {0, 0, 0, PB_LEVELS_PACK(0, 0, 2)};
    const uint32_t w2[4][3] = {{0, 0, 2}, {1, 0, 2}, {0, 1, 2}, {1, 1, 2}};
    t = boxes(d2, column, 1);
    TU_REQUIRE(t != NULL);
    TU_REQUIRE(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_SUCCESS);
    check_points(tests, w2, 4);
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);
    /* Two slabs side by side along x (8 × 1 × 4) share the 2 z edges of the face x = 4: 20 − 2. */
    const uint32_t d3[3] = {8, 1, 4}, two[8] = {0, 0, 0, PB_LEVELS_PACK(2, 0, 2), 4, 0, 0, PB_LEVELS_PACK(2, 0, 2)};
    t = boxes(d3, two, 2);
    TU_REQUIRE(t != NULL);
    TU_REQUIRE(pb_refine_tests_create_axes(t, NULL, &tests, &err) == PB_SUCCESS);
    TU_CHECK(tests->point_count == 18);
    pb_refine_tests_destroy(tests);
    pb_cotree_destroy(t);
}

/* On the 4 × 1 × 4 m slab: f quadratic in x splits along x; f = 1 + y² varies only along the level-0
 * axis, at whose two ends every test point lies: exact, nothing splits; a bump at the centre of the
 * face y = 0, seen by no edge midpoint (2 m away), fails the face centre: split along x and z, never
 * y. Error closed forms as on the cube: (q/4) / (1 + q/4) for f = 1 + q (x/4)², q = 1: 0.2. */
static double slab_x(const double p[3]) { return 1.0 + (p[0] / 4.0) * (p[0] / 4.0); }
static double slab_y(const double p[3]) { return 1.0 + p[1] * p[1]; }
static double slab_bump(const double p[3])
{
    double r2 = (p[0] - 2.0) * (p[0] - 2.0) + p[1] * p[1] + (p[2] - 2.0) * (p[2] - 2.0);
    return 1.0 + (r2 < 1.0 ? (1.0 - r2) * (1.0 - r2) : 0.0);
}

static void test_box_split_rule(void)
{
    const uint32_t dims[3] = {4, 1, 4}, slab[4] = {0, 0, 0, PB_LEVELS_PACK(2, 0, 2)};
    pb_cotree *t = boxes(dims, slab, 1);
    TU_REQUIRE(t != NULL);
    decided d;
    TU_REQUIRE(decide(t, slab_x, 0.05, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 1);
    TU_CHECK_NEAR(d.err[0], 0.2, 1e-12);
    decided_free(&d);
    TU_REQUIRE(decide(t, slab_y, 1e-9, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 0);
    TU_CHECK(d.err[0] < 1e-12);
    decided_free(&d);
    TU_REQUIRE(decide(t, slab_bump, 0.05, 0.0f, false, &d));
    TU_CHECK(d.axes[0] == 5);
    TU_CHECK_NEAR(d.err[0], 0.5, 1e-12); /* f = 2 at the face centre against 1 */
    TU_CHECK(d.split[0] == 1);
    decided_free(&d);
    pb_cotree_destroy(t);
}

/* The refinement loop's step: the 1 m cube split along y (pb_cotree_split_axes, mask 2) gives two boxes
 * of levels (2, 1, 2), 13 tests each, 4 shared (the x and z edges of the face y = 0.5 m): 22 points.
 * f = 1 + y² then splits the lower box along y again at a tolerance between the two boxes' errors. */
static void test_split_axes_then_test(void)
{
    pb_cotree *t = cubes(1, 1, 1);
    TU_REQUIRE(t != NULL);
    pb_error err = {0};
    uint8_t mask = 2;
    TU_REQUIRE(pb_cotree_split_axes(t, &mask, NULL, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_finalize(t, &err) == PB_SUCCESS);
    TU_REQUIRE(pb_cotree_leaf_count(t) == 2);
    uint32_t lv[6];
    pb_cotree_leaf_levels(t, lv);
    TU_CHECK(lv[0] == 2 && lv[1] == 1 && lv[2] == 2 && lv[3] == 2 && lv[4] == 1 && lv[5] == 2);
    decided d;
    /* Lower box y in [0, 0.5] m: at 0.25 m 1.0625 against (1 + 1.25) / 2 = 1.125, error 0.0625 / 1.0625;
     * upper [0.5, 1]: 1.5625 against 1.625, 0.0625 / 1.5625 = 0.04. */
    TU_REQUIRE(decide(t, quad_y, 0.05, 0.0f, false, &d));
    TU_CHECK(d.tests->point_count == 22);
    const uint32_t *leaves = pb_cotree_leaves(t);
    for (uint32_t i = 0; i < 2; i++) {
        bool lower = leaves[4 * i + 1] == 0;
        TU_CHECK(d.axes[i] == (lower ? 2 : 0));
        TU_CHECK_NEAR(d.err[i], lower ? 0.0625 / 1.0625 : 0.04, 1e-12);
    }
    decided_free(&d);
    pb_cotree_destroy(t);
}

/* Refinement pass after pass on 2 × 1 × 2 roots of 1 m (min cell 0.25 m) at tolerance 5 %: f = 1 + y²
 * varies along y only, so every pass splits along y only and every leaf keeps its x and z levels (2).
 * The error at the y edges' midpoint of a box [y0, y0 + s] is (s/2)² / f(y0 + s/2): 0.25 / 1.25 for the
 * root, then 0.0625 / 1.0625 = 5.9 % for [0, 0.5] (splits to Min Cell Size) and 0.0625 / 1.5625 = 4 %
 * for [0.5, 1] (stays): 2 passes, 3 boxes per root, y levels 0, 0, 1. A linear field on the final tree
 * splits nothing. */
static double linear_y(const double p[3]) { return 2.0 + 0.3 * p[0] - 0.7 * p[1] + 0.5 * p[2]; }

static void test_passes_split_y_only(void)
{
    pb_cotree *t = cubes(2, 1, 2);
    TU_REQUIRE(t != NULL);
    pb_error err = {0};
    uint32_t passes = 0;
    for (; passes < 8; passes++) {
        decided d;
        TU_REQUIRE(decide(t, quad_y, 0.05, 0.0f, false, &d));
        uint32_t L = pb_cotree_leaf_count(t), n = 0;
        for (uint32_t i = 0; i < L; i++) {
            TU_CHECK((d.axes[i] & 5u) == 0);
            n += d.axes[i] != 0;
        }
        if (n == 0) {
            decided_free(&d);
            break;
        }
        pb_result r = pb_cotree_split_axes(t, d.axes, NULL, &err);
        decided_free(&d);
        TU_REQUIRE(r == PB_SUCCESS && pb_cotree_finalize(t, &err) == PB_SUCCESS);
        TU_CHECK(pb_cotree_forced_splits(t) == 0);
    }
    TU_CHECK(passes == 2);
    uint32_t L = pb_cotree_leaf_count(t), *lv = malloc((size_t)L * 3 * sizeof(uint32_t));
    TU_CHECK(L == 12);
    pb_cotree_leaf_levels(t, lv);
    const uint32_t *leaves = pb_cotree_leaves(t);
    for (uint32_t i = 0; i < L; i++) {
        TU_CHECK(lv[3 * i] == 2 && lv[3 * i + 2] == 2);
        TU_CHECK(lv[3 * i + 1] == (leaves[4 * i + 1] < 2 ? 0u : 1u));
    }
    free(lv);
    decided d;
    TU_REQUIRE(decide(t, linear_y, 1e-9, 0.0f, false, &d));
    for (uint32_t i = 0; i < L; i++) {
        TU_CHECK(d.axes[i] == 0);
        TU_CHECK(d.err[i] < 1e-12);
    }
    decided_free(&d);
    pb_cotree_destroy(t);
}

int main(void)
{
    TU_RUN(test_column_layout);
    TU_RUN(test_tree_columns_and_dedup);
    TU_RUN(test_level0_and_errors);
    TU_RUN(test_closed_form_fields);
    TU_RUN(test_decide_agrees_with_octree_decide);
    TU_RUN(test_noise_within_k_sigma);
    TU_RUN(test_invalid_tests_skipped);
    TU_RUN(test_box_test_points);
    TU_RUN(test_box_split_rule);
    TU_RUN(test_split_axes_then_test);
    TU_RUN(test_passes_split_y_only);
    return TU_EXIT();
}
