/* Error-driven refinement (pb_refine.h) on synthetic light fields given as C functions (no Cycles):
 * - a sharp shadow boundary (an oblique plane where a sun's irradiance switches on) draws refinement
 *   to the leaves the plane crosses and nowhere else, pass after pass, down to Min Cell Size;
 * - a field linear in position refines nothing (trilinear reproduces it exactly);
 * - bounded Monte-Carlo noise does not trigger refinement when its estimate is passed in, and does
 *   when it is not (so the noise term is what prevents it);
 * - test points become probes of the finer level (every test point of a split leaf is a probe after
 *   the split), and points that already are probes are not baked again. */
#include "schnee/pb_refine.h"
#include "schnee/pb_sh.h"

#include "testutil.h"

#include <stdint.h>
#include <stdlib.h>

#define BAND 1
#define NC   4 /* pb_sh_count(1) */

static const double plane_n[3] = {0.6, 0.0, 0.8};
static const double plane_c = 2.3123; /* lit where n·p < c; n·p of lattice points are multiples of 0.05 */

/* Radiance SH (band 1) of a constant sky plus, where lit, a sun from direction (0.3, 0.9, 0.3). */
static void shadow_field(const double p[3], double *c)
{
    memset(c, 0, NC * 3 * sizeof(double));
    for (int ch = 0; ch < 3; ch++) c[ch] = 1.0 + 0.1 * ch; /* L00 */
    bool lit = plane_n[0] * p[0] + plane_n[1] * p[1] + plane_n[2] * p[2] < plane_c;
    if (!lit) return;
    const double d[3] = {0.3, 0.9, 0.3}, s = 2.0;
    double y[NC];
    pb_sh_eval_basis(BAND, d, y);
    for (int i = 0; i < NC; i++)
        for (int ch = 0; ch < 3; ch++) c[3 * i + ch] += s * y[i];
}

static void linear_field(const double p[3], double *c)
{
    for (int i = 0; i < NC; i++)
        for (int ch = 0; ch < 3; ch++)
            c[3 * i + ch] = (i == 0 ? 2.0 : 0.1) + 0.3 * p[0] - 0.2 * p[1] + 0.1 * (i + 1) * p[2] + 0.05 * ch;
}

typedef void (*field_fn)(const double p[3], double *c);

/* 4 × 1 × 4 roots of 8 min cells (0.25 m): a 8 m × 2 m × 8 m box at the origin. */
static pb_cotree *make_roots(void)
{
    const double o[3] = {0, 0, 0};
    const uint32_t roots[3] = {4, 1, 4};
    pb_cotree *t = NULL;
    pb_error err = {0};
    if (pb_cotree_create(o, 0.25, 3, roots, &t, &err) != PB_SUCCESS) return NULL;
    if (pb_cotree_finalize(t, &err) != PB_SUCCESS) return NULL;
    return t;
}

static bool leaf_crossed(const pb_cotree *t, uint32_t i)
{
    const uint32_t *l = pb_cotree_leaves(t) + 4 * i;
    double h, o[3];
    pb_cotree_frame(t, o, &h, NULL);
    double s = h * (1u << l[3]), mn = INFINITY, mx = -INFINITY;
    for (int c = 0; c < 8; c++) {
        double p[3] = {o[0] + h * l[0] + (c & 1 ? s : 0), o[1] + h * l[1] + (c & 2 ? s : 0),
                       o[2] + h * l[2] + (c & 4 ? s : 0)};
        double v = plane_n[0] * p[0] + plane_n[1] * p[1] + plane_n[2] * p[2];
        mn = fmin(mn, v), mx = fmax(mx, v);
    }
    return mn < plane_c && mx > plane_c;
}

/* One pass: bake probes and tests from the field (noise: relative amplitude per point, bounded),
 * decide. Returns the number of leaves split; checks test points → probes after the split. */
static uint32_t run_pass(pb_cotree **tp, field_fn f, double noise, bool pass_noise, double tol, int *bakes,
                         uint8_t **split_out)
{
    pb_cotree *t = *tp;
    pb_error err = {0};
    uint32_t P = pb_cotree_probe_count(t), L = pb_cotree_leaf_count(t);
    double *pos = malloc(P * 3 * sizeof(double)), *pc = malloc(P * NC * 3 * sizeof(double));
    float *pn = malloc(P * sizeof(float));
    pb_cotree_probe_positions(t, pos);
    for (uint32_t i = 0; i < P; i++) {
        f(pos + 3 * i, pc + i * NC * 3);
        double u = sin(12.9898 * i + 78.233 * pos[3 * i] + 37.719 * pos[3 * i + 2]); /* deterministic in [−1, 1] */
        for (int m = 0; m < NC * 3; m++) pc[i * NC * 3 + m] *= 1.0 + noise * u;
        pn[i] = (float)noise;
    }
    pb_refine_tests *tests = NULL;
    if (pb_refine_tests_create(t, NULL, &tests, &err) != PB_SUCCESS) return UINT32_MAX;
    double *tc = calloc((size_t)tests->point_count * NC * 3 + 1, sizeof(double));
    float *tn = malloc(((size_t)tests->point_count + 1) * sizeof(float));
    for (uint32_t j = 0; j < tests->point_count; j++) {
        tn[j] = (float)noise;
        if (tests->probe[j] >= 0) continue; /* already a probe: not baked */
        (*bakes)++;
        f(tests->positions + 3 * j, tc + j * NC * 3);
        double u = cos(3.1 * j + 5.7 * tests->positions[3 * j + 1]);
        for (int m = 0; m < NC * 3; m++) tc[j * NC * 3 + m] *= 1.0 + noise * u;
    }
    pb_refine_desc d = {.max_band = BAND, .probe_coeffs = pc, .test_coeffs = tc, .tolerance = tol};
    if (pass_noise) d.probe_noise = pn, d.test_noise = tn;
    uint8_t *split = malloc(L);
    double *le = malloc(L * sizeof(double));
    if (pb_refine_decide(t, tests, &d, split, le, NULL, &err) != PB_SUCCESS) return UINT32_MAX;
    uint32_t n = 0;
    for (uint32_t i = 0; i < L; i++) n += split[i];
    /* Keep a copy of which tests the split leaves had, to check them after the split. */
    uint32_t *must = malloc(((size_t)n * 7 + 1) * 3 * sizeof(uint32_t)), nm = 0;
    for (uint32_t i = 0; i < L; i++)
        if (split[i])
            for (int k = 0; k < 7; k++) {
                int32_t ti = tests->leaf_tests[7 * i + (uint32_t)k];
                memcpy(must + 3 * nm++, tests->lattice + 3 * ti, 3 * sizeof(uint32_t));
            }
    if (split_out) {
        *split_out = malloc(L);
        memcpy(*split_out, split, L);
    }
    if (n > 0) {
        TU_CHECK(pb_cotree_split(t, split, NULL, &err) == PB_SUCCESS);
        TU_CHECK(pb_cotree_finalize(t, &err) == PB_SUCCESS);
        /* Test probes become probes of the finer level. Hanging is impossible for a split leaf's
         * centre; a face centre may hang only on a coarser neighbour, which cannot be: the point was a
         * face centre of a leaf of that size, so it is a corner of its children on both sides or lies
         * on a face of a same-size unsplit neighbour (then it hangs). Count those that are probes. */
        uint32_t probes = 0, centres = 0;
        for (uint32_t j = 0; j < nm; j++) probes += pb_cotree_find_probe(t, must + 3 * j) >= 0;
        for (uint32_t j = 0; j < nm; j += 7) centres += pb_cotree_find_probe(t, must + 3 * j) >= 0;
        TU_CHECK(centres == n); /* every centre */
        TU_CHECK(probes >= n);
    }
    free(must);
    free(pos);
    free(pc);
    free(pn);
    free(tc);
    free(tn);
    free(split);
    free(le);
    pb_refine_tests_destroy(tests);
    return n;
}

static void test_shadow_edge_draws_refinement(void)
{
    pb_cotree *t = make_roots();
    TU_REQUIRE(t != NULL);
    int bakes = 0;
    for (int pass = 0; pass < 6; pass++) {
        uint32_t L = pb_cotree_leaf_count(t);
        bool *crossed = malloc(L);
        uint32_t want = 0;
        for (uint32_t i = 0; i < L; i++) {
            crossed[i] = leaf_crossed(t, i);
            want += crossed[i] && pb_cotree_leaves(t)[4 * i + 3] > 0;
        }
        uint8_t *split = NULL;
        uint32_t n = run_pass(&t, shadow_field, 0.0, false, 0.02, &bakes, &split);
        TU_REQUIRE(n != UINT32_MAX);
        /* Exactly the crossed leaves above Min Cell Size split, nowhere else. */
        uint32_t wrong = 0, missed = 0;
        for (uint32_t i = 0; i < L; i++) wrong += split[i] && !crossed[i];
        missed = want - (n - wrong);
        TU_CHECK(wrong == 0);
        TU_CHECK(missed == 0);
        TU_CHECK(n == want);
        free(split);
        free(crossed);
        if (n == 0) break;
    }
    /* Finally every leaf the plane crosses is at Min Cell Size. */
    uint32_t coarse_crossed = 0, fine = 0;
    for (uint32_t i = 0; i < pb_cotree_leaf_count(t); i++) {
        uint32_t lv = pb_cotree_leaves(t)[4 * i + 3];
        if (leaf_crossed(t, i) && lv > 0) coarse_crossed++;
        fine += lv == 0;
    }
    TU_CHECK(coarse_crossed == 0);
    TU_CHECK(fine > 0);
    /* The uniform grid at Min Cell Size would hold 33 × 9 × 33 = 9801 probes. */
    TU_CHECK(pb_cotree_probe_count(t) < 9801 / 2);
    printf("  shadow edge: %u probes, %u leaves, %d test bakes (no cache across passes)\n", pb_cotree_probe_count(t),
           pb_cotree_leaf_count(t), bakes);
    pb_cotree_destroy(t);
}

static void test_linear_field_refines_nothing(void)
{
    pb_cotree *t = make_roots();
    TU_REQUIRE(t != NULL);
    int bakes = 0;
    TU_CHECK(run_pass(&t, linear_field, 0.0, false, 1e-9, &bakes, NULL) == 0);
    TU_CHECK(bakes > 0);
    pb_cotree_destroy(t);
}

static void test_noise_accounted(void)
{
    /* The linear field with bounded relative noise n = 2 % per probe (each point scaled by 1 + n·u,
     * u in [−1, 1]): the threshold is at least sqrt(tol² + (2n)²·9/8) = 4.7 % with k = 2 and tol =
     * 2 %, and the error at a test point reaches that only if every corner's u and the test's are ±1
     * in opposite directions (the deterministic u here do not). */
    pb_cotree *t = make_roots();
    TU_REQUIRE(t != NULL);
    int bakes = 0;
    TU_CHECK(run_pass(&t, linear_field, 0.02, true, 0.02, &bakes, NULL) == 0);
    pb_cotree_destroy(t);
    t = make_roots();
    uint32_t n = run_pass(&t, linear_field, 0.02, false, 0.02, &bakes, NULL);
    TU_CHECK(n > 0 && n != UINT32_MAX); /* without the noise estimate, noise alone refines */
    pb_cotree_destroy(t);
}

/* Constant field c; every test point baked as c·(1 + δ) (relative error e = δ/(1 + δ) against the
 * interpolated c), noise n on every probe and test. The threshold is the tolerance and k·σ added in
 * quadrature, σ² = n_test² + Σ w_i² n_i²: for a leaf's centre (8 corners of weight 1/8, Σw² = 1/8)
 * sqrt(tol² + k²·n²·9/8); face centres (Σw² = 1/4) have the larger threshold, so the centre is each
 * leaf's worst margin. tol 3 %, n 1 %, k 2: 3.674 %. An error of 4 % splits (it would not under the
 * linear sum tol + k·σ = 5.12 %), 3.5 % does not. */
static void test_noise_threshold_adds_in_quadrature(void)
{
    const double tol = 0.03, n = 0.01, k = 2.0;
    const double expect = sqrt(tol * tol + k * k * (n * n + n * n / 8.0));
    const double errors[2] = {0.04, 0.035};
    for (int c = 0; c < 2; c++) {
        pb_cotree *t = make_roots();
        TU_REQUIRE(t != NULL);
        pb_error err = {0};
        uint32_t P = pb_cotree_probe_count(t), L = pb_cotree_leaf_count(t);
        pb_refine_tests *tests = NULL;
        TU_REQUIRE(pb_refine_tests_create(t, NULL, &tests, &err) == PB_SUCCESS);
        double *pc = malloc((size_t)P * NC * 3 * sizeof(double));
        double *tc = malloc(((size_t)tests->point_count + 1) * NC * 3 * sizeof(double));
        float *pn = malloc(P * sizeof(float)), *tn = malloc(((size_t)tests->point_count + 1) * sizeof(float));
        const double delta = errors[c] / (1.0 - errors[c]);
        for (uint32_t i = 0; i < P; i++) {
            for (int m = 0; m < NC * 3; m++) pc[i * NC * 3 + m] = 1.0 + 0.1 * m;
            pn[i] = (float)n;
        }
        for (uint32_t j = 0; j < tests->point_count; j++) {
            for (int m = 0; m < NC * 3; m++) tc[j * NC * 3 + m] = (1.0 + 0.1 * m) * (1.0 + delta);
            tn[j] = (float)n;
        }
        pb_refine_desc d = {.max_band = BAND,
                            .probe_coeffs = pc,
                            .test_coeffs = tc,
                            .probe_noise = pn,
                            .test_noise = tn,
                            .tolerance = tol,
                            .noise_k = k};
        uint8_t *split = malloc(L);
        double *le = malloc(L * sizeof(double)), *lt = malloc(L * sizeof(double));
        TU_REQUIRE(pb_refine_decide(t, tests, &d, split, le, lt, &err) == PB_SUCCESS);
        for (uint32_t i = 0; i < L; i++) {
            TU_CHECK_NEAR(le[i], errors[c], 1e-12);
            TU_CHECK_NEAR(lt[i], expect, 1e-8); /* noise passed as float */
            TU_CHECK(split[i] == (c == 0));
        }
        free(split), free(le), free(lt), free(pc), free(tc), free(pn), free(tn);
        pb_refine_tests_destroy(tests);
        pb_cotree_destroy(t);
    }
}

static void test_error_metric(void)
{
    /* Closed form: a = 1.1·ref → error 0.1 exactly; a = ref + δ on L1 only → ‖A1 δ‖/‖A·ref‖. */
    double ref[NC * 3], a[NC * 3];
    for (int m = 0; m < NC * 3; m++) ref[m] = 0.5 + 0.1 * m, a[m] = 1.1 * ref[m];
    TU_CHECK_NEAR(pb_refine_irradiance_error(BAND, a, ref), 0.1, 1e-14);
    memcpy(a, ref, sizeof a);
    a[3] += 0.3; /* coefficient 1 (L1, y), red */
    double A0 = M_PI, A1 = 2.0 * M_PI / 3.0, den = 0.0;
    for (int m = 0; m < NC * 3; m++) den += pow((m < 3 ? A0 : A1) * ref[m], 2);
    TU_CHECK_NEAR(pb_refine_irradiance_error(BAND, a, ref), A1 * 0.3 / sqrt(den), 1e-14);
    double zero[NC * 3] = {0};
    TU_CHECK(pb_refine_irradiance_error(BAND, zero, zero) == 0.0);
    TU_CHECK(pb_refine_irradiance_error(BAND, a, zero) == 1.0);
}

static void test_error_metric_many(void)
{
    /* The vectorised forms are the single-point arithmetic, bit for bit: errors of three points (the
     * last against a zero reference), and norms whose squared ratio is the same error. */
    double a[3 * NC * 3], ref[3 * NC * 3] = {0}, err[3], norm[3];
    for (int m = 0; m < 3 * NC * 3; m++) a[m] = sin(0.7 * m) + 0.1;
    for (int m = 0; m < 2 * NC * 3; m++) ref[m] = cos(0.3 * m);
    pb_refine_irradiance_error_many(BAND, 3, a, ref, err);
    for (int p = 0; p < 3; p++) TU_CHECK(err[p] == pb_refine_irradiance_error(BAND, a + p * NC * 3, ref + p * NC * 3));
    TU_CHECK(err[2] == 1.0);
    pb_refine_irradiance_norm_many(BAND, 3, ref, norm);
    TU_CHECK(norm[2] == 0.0);
    double one[NC * 3] = {0};
    one[0] = 2.0;          /* L0, red: ‖A0 · 2‖ */
    one[3 * 3 + 2] = -1.0; /* L1, blue */
    pb_refine_irradiance_norm_many(BAND, 1, one, norm);
    TU_CHECK_NEAR(norm[0], sqrt(pow(2.0 * M_PI, 2) + pow(2.0 * M_PI / 3.0, 2)), 1e-14);
}

int main(void)
{
    TU_RUN(test_error_metric);
    TU_RUN(test_error_metric_many);
    TU_RUN(test_linear_field_refines_nothing);
    TU_RUN(test_noise_accounted);
    TU_RUN(test_noise_threshold_adds_in_quadrature);
    TU_RUN(test_shadow_edge_draws_refinement);
    return TU_EXIT();
}
