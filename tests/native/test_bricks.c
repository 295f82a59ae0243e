/* Probe bricks (pb_bricks.h, docs/probe-bricks.md). Closed forms and the core's own query as references:
 * a field linear in position is reproduced exactly (trilinear bricks hold a linear field); on random
 * octrees and kd trees the bricks equal pb_interp_query_cotree at random points (same "no probe" points,
 * values to rounding), with invalid probes as N / D; points ε either side of every brick border agree
 * (the field is C0 and the texels on a face are its values there); every brick cell lies in one leaf or
 * none (the level rule); the pool holds the texels; hostile input is refused with a message. */
#include "schnee/pb_bricks.h"
#include "schnee/pb_interp.h"

#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

static const double ORIGIN[3] = {-1.0, 0.5, 2.0};
#define H 0.25
#define C 9u /* L2 */

/* Roots of 8 min cells, 4 × 3 × 4 (lattice 32 × 24 × 32), three passes of random splits (kd: random axis masks),
 * optionally a third of the leaves dropped (outer faces inside the lattice). */
static pb_cotree *random_tree(uint64_t seed, bool kd, bool drop)
{
    tu_rng_state = seed;
    const uint32_t roots[3] = {4, 3, 4};
    pb_cotree *t = NULL;
    pb_error err = {0};
    if (pb_cotree_create(ORIGIN, H, 3, roots, &t, &err) != PB_SUCCESS) return NULL;
    for (int pass = 0; pass < 3; pass++) {
        uint32_t n = pb_cotree_leaf_count(t);
        uint8_t *f = calloc(n, 1);
        for (uint32_t i = 0; i < n; i++) f[i] = tu_rnd() < 0.35 ? (kd ? (uint8_t)(1 + (int)(tu_rnd() * 7)) : 1) : 0;
        pb_result r = kd ? pb_cotree_split_axes(t, f, NULL, &err) : pb_cotree_split(t, f, NULL, &err);
        if (r == PB_SUCCESS) r = pb_cotree_finalize(t, &err);
        free(f);
        if (r != PB_SUCCESS) return pb_cotree_destroy(t), NULL;
    }
    if (drop) {
        uint32_t n = pb_cotree_leaf_count(t);
        uint8_t *f = calloc(n, 1);
        for (uint32_t i = 0; i < n; i += 3) f[i] = 1;
        pb_result r = pb_cotree_drop(t, f, &err);
        free(f);
        if (r != PB_SUCCESS || pb_cotree_finalize(t, &err) != PB_SUCCESS) return pb_cotree_destroy(t), NULL;
    }
    return t;
}

/* Linear field, closed form: coefficient c, colour k at engine-space p. */
static double linear(uint32_t c, uint32_t k, const double p[3])
{
    double j = (double)(3u * c + k);
    return 0.5 + 0.05 * j + (0.3 - 0.02 * j) * p[0] + (0.01 * j - 0.2) * p[1] + 0.07 * p[2];
}

static double *linear_coeffs(const pb_cotree *t)
{
    uint32_t P = pb_cotree_probe_count(t);
    double *pos = malloc(3u * P * sizeof *pos), *c = malloc((size_t)P * C * 3u * sizeof *c);
    pb_cotree_probe_positions(t, pos);
    for (uint32_t i = 0; i < P; i++)
        for (uint32_t j = 0; j < C; j++)
            for (uint32_t k = 0; k < 3; k++) c[(i * C + j) * 3u + k] = linear(j, k, pos + 3u * i);
    free(pos);
    return c;
}

static double *random_coeffs(uint32_t P)
{
    double *c = malloc((size_t)P * C * 3u * sizeof *c);
    for (uint32_t i = 0; i < P * C * 3u; i++) c[i] = i % (3u * C) < 3u ? 0.5 + 1.5 * tu_rnd() : -0.3 + 0.6 * tu_rnd();
    return c;
}

static pb_bricks *build(const pb_cotree *t, const double *coeffs, const float *validity, const float *scale)
{
    pb_bricks_desc d = {.tree = t, .coeff_count = C, .coeffs = coeffs, .validity = validity, .scale = scale};
    pb_bricks *b = NULL;
    pb_error err = {0};
    if (pb_bricks_build(&d, &b, &err) != PB_SUCCESS) fprintf(stderr, "build: %s\n", err.message);
    return b;
}

static void random_point(const pb_cotree *t, double p[3]) /* anywhere in the lattice's box */
{
    double o[3], h;
    uint32_t dims[3];
    pb_cotree_frame(t, o, &h, dims);
    for (int a = 0; a < 3; a++) p[a] = o[a] + tu_rnd() * dims[a] * h;
}

static void test_linear_field_exact(void)
{
    for (int kd = 0; kd < 2; kd++) {
        pb_cotree *t = random_tree(11 + (uint64_t)kd, kd, false);
        TU_REQUIRE(t);
        double *c = linear_coeffs(t);
        pb_bricks *b = build(t, c, NULL, NULL);
        TU_REQUIRE(b);
        pb_bricks_info in;
        pb_bricks_get_info(b, &in);
        TU_CHECK(in.level_counts[0] > 0 && in.level_counts[0] < in.brick_count); /* several levels */
        double worst = 0.0, out[3 * C];
        int values = 0;
        for (int n = 0; n < 4000; n++) {
            double p[3];
            random_point(t, p);
            if (!pb_bricks_sample(b, p, out, NULL)) continue; /* the tree covers its whole box */
            values++;
            for (uint32_t j = 0; j < C; j++)
                for (uint32_t k = 0; k < 3; k++) worst = fmax(worst, fabs(out[3 * j + k] - linear(j, k, p)));
        }
        printf("  %s: %u bricks (level 0: %u), linear field max error %.2e over %d points\n", kd ? "kd" : "octree",
               in.brick_count, in.level_counts[0], worst, values);
        TU_CHECK_EQ_INT(values, 4000);
        TU_CHECK(worst < 1e-12);
        pb_bricks_destroy(b);
        free(c);
        pb_cotree_destroy(t);
    }
}

/* Bricks against pb_interp_query_cotree at random points: the same points with a value, equal values. */
static void compare_with_query(const pb_cotree *t, const pb_bricks *b, const double *c, const float *val,
                               const float *scale, double *worst, int *mismatch)
{
    pb_interp_options opt = {.validity = val};
    double out[3 * C];
    for (int n = 0; n < 3000; n++) {
        double p[3], ref[3 * C] = {0};
        random_point(t, p);
        pb_interp_weights w;
        pb_interp_query_cotree(t, p, &opt, &w);
        for (uint32_t i = 0; i < w.count; i++)
            for (uint32_t j = 0; j < 3 * C; j++)
                ref[j] += w.weight[i] * (scale ? scale[w.probe[i]] : 1.0f) * c[w.probe[i] * 3 * C + j];
        bool has = pb_bricks_sample(b, p, out, NULL);
        if (has != (w.count > 0)) (*mismatch)++;
        for (uint32_t j = 0; has && w.count && j < 3 * C; j++) *worst = fmax(*worst, fabs(out[j] - ref[j]));
    }
}

static void test_random_fields_equal_the_query(void)
{
    for (int kd = 0; kd < 2; kd++)
        for (int drop = 0; drop < 2; drop++) {
            pb_cotree *t = random_tree(21 + (uint64_t)(2 * kd + drop), kd, drop);
            TU_REQUIRE(t);
            uint32_t P = pb_cotree_probe_count(t);
            double *c = random_coeffs(P);
            float *val = malloc(P * sizeof *val), *scale = malloc(P * sizeof *scale);
            int invalid = 0;
            for (uint32_t i = 0; i < P; i++) {
                val[i] = tu_rnd() < 0.25 ? 0.0f : (float)(0.2 + tu_rnd());
                invalid += val[i] == 0.0f;
                scale[i] = (float)(0.5 + tu_rnd());
            }
            double worst = 0.0, worst_v = 0.0;
            int mismatch = 0, mismatch_v = 0;
            pb_bricks *b = build(t, c, NULL, NULL), *bv = build(t, c, val, scale);
            TU_REQUIRE(b && bv);
            compare_with_query(t, b, c, NULL, NULL, &worst, &mismatch);
            compare_with_query(t, bv, c, val, scale, &worst_v, &mismatch_v);
            printf("  %s%s: %u probes (%d invalid): max |bricks - query| %.2e, with validity and scale %.2e; "
                   "no-probe mismatches %d / %d\n",
                   kd ? "kd" : "octree", drop ? " (leaves dropped)" : "", P, invalid, worst, worst_v, mismatch,
                   mismatch_v);
            TU_CHECK(worst < 1e-12 && worst_v < 1e-12);
            TU_CHECK_EQ_INT(mismatch, 0);
            TU_CHECK_EQ_INT(mismatch_v, 0);
            pb_bricks_destroy(b);
            pb_bricks_destroy(bv);
            free(c), free(val), free(scale);
            pb_cotree_destroy(t);
        }
}

/* Points ε either side of every face of every brick region (where both sides lie in leaves). */
static void test_continuous_across_brick_borders(void)
{
    for (int kd = 0; kd < 2; kd++) {
        pb_cotree *t = random_tree(31 + (uint64_t)kd, kd, false);
        TU_REQUIRE(t);
        double *c = random_coeffs(pb_cotree_probe_count(t));
        pb_bricks *b = build(t, c, NULL, NULL);
        TU_REQUIRE(b);
        pb_bricks_info in;
        pb_bricks_get_info(b, &in);
        const uint32_t *reg = pb_bricks_regions(b);
        const double eps = 1e-11; /* lattice units */
        double worst = 0.0, lo_out[3 * C], hi_out[3 * C];
        int points = 0, across_levels = 0;
        for (uint32_t i = 0; i < in.brick_count; i++)
            for (int face = 0; face < 6; face++)
                for (int n = 0; n < 16; n++) {
                    int a = face / 2;
                    double u[3], ext = 4.0 * (double)(1u << reg[4 * i + 3]);
                    for (int k = 0; k < 3; k++) u[k] = reg[4 * i + k] + tu_rnd() * ext;
                    u[a] = reg[4 * i + a] + (face & 1 ? ext : 0.0);
                    if (u[a] <= 0.0 || u[a] >= in.dims[a]) continue;
                    double pl[3], ph[3];
                    for (int k = 0; k < 3; k++) pl[k] = ph[k] = ORIGIN[k] + u[k] * H;
                    pl[a] = ORIGIN[a] + (u[a] - eps) * H, ph[a] = ORIGIN[a] + (u[a] + eps) * H;
                    uint32_t bl, bh;
                    double xl[3], xh[3];
                    if (pb_cotree_locate(t, pl) < 0 || pb_cotree_locate(t, ph) < 0) continue;
                    TU_CHECK(pb_bricks_locate(b, pl, &bl, xl) && pb_bricks_locate(b, ph, &bh, xh));
                    bool hl = pb_bricks_sample(b, pl, lo_out, NULL), hh = pb_bricks_sample(b, ph, hi_out, NULL);
                    TU_CHECK(hl && hh);
                    points++;
                    across_levels += reg[4 * bl + 3] != reg[4 * bh + 3];
                    for (uint32_t j = 0; j < 3 * C; j++) worst = fmax(worst, fabs(lo_out[j] - hi_out[j]));
                }
        printf("  %s: %d border points (%d between levels), max jump %.2e\n", kd ? "kd" : "octree", points,
               across_levels, worst);
        TU_CHECK(points > 500 && across_levels > 50);
        TU_CHECK(worst < 1e-9);
        pb_bricks_destroy(b);
        free(c);
        pb_cotree_destroy(t);
    }
}

/* The level rule: every unit cell of a brick cell (2^L aligned) has the same leaf, or none. */
static void test_brick_cells_in_one_leaf(void)
{
    pb_cotree *t = random_tree(41, true, true);
    TU_REQUIRE(t);
    double *c = random_coeffs(pb_cotree_probe_count(t));
    pb_bricks *b = build(t, c, NULL, NULL);
    TU_REQUIRE(b);
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    const uint32_t *reg = pb_bricks_regions(b);
    int bad = 0, cells = 0;
    for (uint32_t i = 0; i < in.brick_count; i++) {
        uint32_t s = 1u << reg[4 * i + 3];
        for (uint32_t cell = 0; cell < 64; cell++) {
            int32_t leaf = -2;
            for (uint32_t v = 0; v < s * s * s; v++) {
                uint32_t q[3] = {reg[4 * i] + s * (cell & 3u) + v % s,
                                 reg[4 * i + 1] + s * (cell >> 2 & 3u) + v / s % s,
                                 reg[4 * i + 2] + s * (cell >> 4) + v / (s * s)};
                if (q[0] >= in.dims[0] || q[1] >= in.dims[1] || q[2] >= in.dims[2]) continue;
                double p[3];
                for (int a = 0; a < 3; a++) p[a] = ORIGIN[a] + (q[a] + 0.5) * H;
                int32_t l = pb_cotree_locate(t, p);
                if (leaf == -2) leaf = l;
                bad += l != leaf;
            }
            cells++;
        }
    }
    TU_CHECK(cells > 1000);
    TU_CHECK_EQ_INT(bad, 0);
    pb_bricks_destroy(b);
    free(c);
    pb_cotree_destroy(t);
}

/* The pool holds the texels at 5·(brick's grid position) + (i, j, k); binary16 within half an ulp. */
static void test_pool_layout(void)
{
    pb_cotree *t = random_tree(51, false, false);
    TU_REQUIRE(t);
    double *c = random_coeffs(pb_cotree_probe_count(t));
    pb_bricks *b = build(t, c, NULL, NULL);
    TU_REQUIRE(b);
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    TU_CHECK_EQ_INT(in.channels, 28);
    TU_CHECK_EQ_INT(in.groups, 7);
    TU_CHECK((uint64_t)in.pool_bricks[0] * in.pool_bricks[1] * in.pool_bricks[2] >= in.brick_count);
    /* The layout rule (pb_bricks.h): at most 51 along x and y, the fewest z layers, then y rows, then x columns,
     * so fewer than y·z slots stay empty. */
    const uint64_t X = in.pool_bricks[0], Y = in.pool_bricks[1], Z = in.pool_bricks[2], nb = in.brick_count;
    TU_CHECK(X <= PB_BRICKS_POOL_SIDE && Y <= PB_BRICKS_POOL_SIDE);
    TU_CHECK_EQ_INT(Z, (nb + 51 * 51 - 1) / (51 * 51));
    TU_CHECK(X * Y * Z - nb < Y * Z && (X - 1) * Y * Z < nb && X * (Y - 1) * Z < nb);
    uint64_t px = in.pool_texels[0], py = in.pool_texels[1], pz = in.pool_texels[2], n = px * py * pz * 4 * in.groups;
    float *f = malloc(n * sizeof *f);
    uint16_t *h = malloc(n * sizeof *h);
    pb_error err = {0};
    TU_REQUIRE(pb_bricks_pool_f32(b, f, n, &err) == PB_SUCCESS && pb_bricks_pool_f16(b, h, n, &err) == PB_SUCCESS);
    const double *tex = pb_bricks_texels(b);
    double worst32 = 0.0, worst16 = 0.0;
    for (uint32_t i = 0; i < in.brick_count; i += 7)
        for (uint32_t t5 = 0; t5 < 125; t5 += 3) {
            uint64_t x = 5 * (i % in.pool_bricks[0]) + t5 % 5,
                     y = 5 * (i / in.pool_bricks[0] % in.pool_bricks[1]) + t5 / 5 % 5,
                     z = 5 * (i / (in.pool_bricks[0] * in.pool_bricks[1])) + t5 / 25;
            for (uint32_t ch = 0; ch < in.channels; ch++) {
                double v = tex[((size_t)i * 125 + t5) * in.channels + ch];
                uint64_t k = ((ch / 4 * pz + z) * py + y) * px + x, e = k * 4 + ch % 4;
                uint16_t q = h[e];
                int ex = q >> 10 & 31;
                double hv = (ex ? ldexp(1024 + (q & 1023), ex - 25) : ldexp(q & 1023, -24)) * (q & 0x8000 ? -1 : 1);
                worst32 = fmax(worst32, fabs(f[e] - v) / fmax(fabs(v), 1e-30));
                worst16 = fmax(worst16, fabs(hv - v) / fmax(fabs(v), 6.1e-5));
            }
        }
    TU_CHECK(worst32 <= ldexp(1.0, -24));
    TU_CHECK(worst16 <= ldexp(1.0, -11));
    TU_CHECK(pb_bricks_pool_f32(b, f, n - 1, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "capacity");
    free(f), free(h);
    pb_bricks_destroy(b);
    free(c);
    pb_cotree_destroy(t);
}

/* The filter's weight quantisation (step 6): a fraction off by ≤ 2^−(bits+1) per axis moves the sample by
 * ≤ 2^L h / 2^(bits+1) per axis, so a linear field errs by at most that times its gradient (closed form). */
static void test_quantised_weights_bound(void)
{
    pb_cotree *t = random_tree(81, true, false);
    TU_REQUIRE(t);
    double *c = linear_coeffs(t);
    pb_bricks *b = build(t, c, NULL, NULL);
    TU_REQUIRE(b);
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    uint32_t top = 0;
    for (uint32_t L = 0; L <= PB_COTREE_MAX_LEVEL; L++)
        if (in.level_counts[L]) top = L;
    const double grad = 0.3 + 0.2 + 0.07; /* linear(): the largest sum of |gradient| per metre over j */
    double bound = grad * ldexp(1.0, (int)top) * H / 512.0, worst = 0.0, exact_diff = 0.0, q[3 * C], e[3 * C];
    for (int n = 0; n < 4000; n++) {
        double p[3];
        random_point(t, p);
        TU_CHECK(pb_bricks_sample_bits(b, p, 8, q, NULL) && pb_bricks_sample_bits(b, p, 0, e, NULL));
        for (uint32_t j = 0; j < C; j++)
            for (uint32_t k = 0; k < 3; k++) worst = fmax(worst, fabs(q[3 * j + k] - linear(j, k, p)));
        TU_CHECK(pb_bricks_sample(b, p, q, NULL));
        for (uint32_t j = 0; j < 3 * C; j++) exact_diff = fmax(exact_diff, fabs(q[j] - e[j]));
    }
    printf("  8-bit weights: linear field max error %.2e, bound %.2e (top level %u)\n", worst, bound, top);
    TU_CHECK(worst > 1e-6 && worst <= bound + 1e-12);
    TU_CHECK(exact_diff == 0.0);
    pb_bricks_destroy(b);
    free(c);
    pb_cotree_destroy(t);
}

/* Within the margin outside the lattice's box: the face's value (docs/probe-bricks.md step 1); beyond: none. */
static void test_lattice_margin(void)
{
    pb_cotree *t = random_tree(61, false, false);
    TU_REQUIRE(t);
    double *c = linear_coeffs(t);
    pb_bricks *b = build(t, c, NULL, NULL);
    TU_REQUIRE(b);
    double out[3 * C], p[3] = {ORIGIN[0] - 0.005 * H, ORIGIN[1] + 3.3 * H, ORIGIN[2] + 7.7 * H};
    TU_CHECK(pb_bricks_sample(b, p, out, NULL));
    double face[3] = {ORIGIN[0], p[1], p[2]};
    TU_CHECK_NEAR(out[5], linear(1, 2, face), 1e-12);
    p[0] = ORIGIN[0] - 0.02 * H;
    TU_CHECK(!pb_bricks_sample(b, p, out, NULL));
    pb_bricks_destroy(b);
    free(c);
    pb_cotree_destroy(t);
}

static void test_hostile_input(void)
{
    pb_cotree *t = random_tree(71, false, false);
    TU_REQUIRE(t);
    uint32_t P = pb_cotree_probe_count(t);
    double *c = random_coeffs(P);
    pb_bricks *b = NULL;
    pb_error err = {0};
    TU_CHECK(pb_bricks_build(NULL, &b, &err) == PB_ERROR_INVALID_ARGUMENT && !b);
    TU_CHECK_CONTAINS(err.message, "NULL desc");
    pb_bricks_desc d = {.tree = t, .coeff_count = 5, .coeffs = c};
    err = (pb_error){0};
    TU_CHECK(pb_bricks_build(&d, &b, &err) == PB_ERROR_INVALID_ARGUMENT && !b);
    TU_CHECK_CONTAINS(err.message, "coeff_count 5");
    d.coeff_count = 36, err = (pb_error){0};
    TU_CHECK(pb_bricks_build(&d, &b, &err) == PB_ERROR_INVALID_ARGUMENT);
    d.coeff_count = C, d.coeffs = NULL, err = (pb_error){0};
    TU_CHECK(pb_bricks_build(&d, &b, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "NULL coeffs");
    d.coeffs = c, c[3 * C * 5 + 4] = NAN, err = (pb_error){0};
    TU_CHECK(pb_bricks_build(&d, &b, &err) == PB_ERROR_NON_FINITE);
    TU_CHECK_CONTAINS(err.message, "probe 5");
    c[3 * C * 5 + 4] = 0.1;
    float *scale = malloc(P * sizeof *scale);
    for (uint32_t i = 0; i < P; i++) scale[i] = 1.0f;
    scale[2] = INFINITY, d.scale = scale, err = (pb_error){0};
    TU_CHECK(pb_bricks_build(&d, &b, &err) == PB_ERROR_NON_FINITE);
    TU_CHECK_CONTAINS(err.message, "scale of probe 2");
    d.scale = NULL, d.max_bytes = 100000, err = (pb_error){0};
    TU_CHECK(pb_bricks_build(&d, &b, &err) == PB_ERROR_TOO_LARGE && !b);
    TU_CHECK_CONTAINS(err.message, "MiB");
    /* binary16 overflow: refused, the caller uploads float32 */
    c[0] = 1e6, d.max_bytes = 0, err = (pb_error){0};
    TU_REQUIRE(pb_bricks_build(&d, &b, &err) == PB_SUCCESS);
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    uint64_t n = (uint64_t)in.pool_texels[0] * in.pool_texels[1] * in.pool_texels[2] * 4 * in.groups;
    uint16_t *h = malloc(n * sizeof *h);
    TU_CHECK(pb_bricks_pool_f16(b, h, n, &err) == PB_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "float32");
    free(h);
    const double far[3] = {1e9, 0, 0}, nan3[3] = {NAN, NAN, NAN};
    TU_CHECK(!pb_bricks_sample(b, far, NULL, NULL) && !pb_bricks_sample(b, nan3, NULL, NULL));
    pb_bricks_destroy(b);
    /* an unfinalized tree */
    uint8_t *f = calloc(pb_cotree_leaf_count(t), 1);
    f[0] = 1;
    TU_REQUIRE(pb_cotree_split(t, f, NULL, &err) == PB_SUCCESS);
    err = (pb_error){0}, b = NULL;
    TU_CHECK(pb_bricks_build(&d, &b, &err) == PB_ERROR_INVALID_ARGUMENT && !b);
    TU_CHECK_CONTAINS(err.message, "not finalized");
    free(f), free(scale), free(c);
    pb_cotree_destroy(t);
}

int main(void)
{
    TU_RUN(test_linear_field_exact);
    TU_RUN(test_random_fields_equal_the_query);
    TU_RUN(test_continuous_across_brick_borders);
    TU_RUN(test_brick_cells_in_one_leaf);
    TU_RUN(test_pool_layout);
    TU_RUN(test_quantised_weights_bound);
    TU_RUN(test_lattice_margin);
    TU_RUN(test_hostile_input);
    return TU_EXIT();
}
