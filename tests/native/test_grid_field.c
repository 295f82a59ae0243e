/* The dense grid's field (pb_grid_field.h, docs/grid-field.md). References: closed forms (a field linear in
 * position is reproduced exactly between the cell centres and clamped to the face centres' plane beyond
 * them, also on rotated axes), hand-derived weights of the documented rule (validity, empty cells, the
 * home cell's mask, back faces, the fallback), and the texture form against the weights form on random
 * grids (to rounding; binary16 texels within their rounding bound). Hostile input is refused. */
#include "schnee/pb_grid_field.h"

#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#define CC 4u /* L1: 4 colours */

typedef struct grid {
    uint32_t dims[3];
    int32_t *cells;
    double *coeffs;
    float *validity, *scale;
    uint32_t probes;
} grid;

static grid make_grid(uint32_t X, uint32_t Y, uint32_t Z, double empty, double invalid)
{
    grid g = {{X, Y, Z}, NULL, NULL, NULL, NULL, 0};
    uint32_t n = X * Y * Z;
    g.cells = malloc(n * sizeof *g.cells);
    g.coeffs = malloc((size_t)n * CC * 3 * sizeof *g.coeffs);
    g.validity = malloc(n * sizeof *g.validity);
    g.scale = malloc(n * sizeof *g.scale);
    for (uint32_t i = 0; i < n; i++) {
        g.cells[i] = tu_rnd() < empty ? -1 : (int32_t)g.probes++;
        g.validity[i] = tu_rnd() < invalid ? 0.0f : (float)(0.2 + 0.8 * tu_rnd());
        g.scale[i] = (float)(0.5 + 1.5 * tu_rnd());
    }
    for (uint32_t i = 0; i < n * CC * 3; i++) g.coeffs[i] = tu_rnd() * 4.0 - 1.0;
    return g;
}

static void free_grid(grid *g) { free(g->cells), free(g->coeffs), free(g->validity), free(g->scale); }

static pb_grid_field *build(const grid *g, const double *axes, const double origin[3], double h, const uint32_t *masks)
{
    pb_grid_field_desc d = {.dims = {g->dims[0], g->dims[1], g->dims[2]},
                            .origin = {origin[0], origin[1], origin[2]},
                            .spacing = h,
                            .axes = axes,
                            .cells = g->cells,
                            .probe_count = g->probes,
                            .coeff_count = CC,
                            .coeffs = g->coeffs,
                            .validity = g->validity,
                            .scale = g->scale,
                            .masks = masks};
    pb_grid_field *f = NULL;
    pb_error err = {0};
    pb_result r = pb_grid_field_build(&d, &f, &err);
    if (r != PB_SUCCESS) fprintf(stderr, "build: %s\n", err.message);
    return f;
}

/* A rotation about (1, 2, 3) by 0.7 rad: rows are the grid's axes in engine space. */
static void rotation(double R[9])
{
    double a[3] = {1, 2, 3}, l = sqrt(14.0), c = cos(0.7), s = sin(0.7);
    for (int i = 0; i < 3; i++) a[i] /= l;
    double K[9] = {0, -a[2], a[1], a[2], 0, -a[0], -a[1], a[0], 0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) R[3 * i + j] = (i == j ? c : 0.0) + s * K[3 * i + j] + (1 - c) * a[i] * a[j];
}

/* Colour 0, channel k of every probe linear in its cell centre's world position: f(x) = 0.5 + g_k·x; every
 * cell filled, validity 1: the field at p is f at p's grid coordinates clamped to [½, dims − ½]. */
static void test_linear_field(void)
{
    tu_rng_state = 11;
    for (int rot = 0; rot < 2; rot++) {
        grid g = make_grid(5, 4, 3, 0.0, 0.0);
        for (uint32_t i = 0; i < g.probes; i++) g.validity[i] = 1.0f, g.scale[i] = 1.0f;
        double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, o[3] = {-1.0, 0.25, 2.0}, h = 0.4;
        if (rot) rotation(R);
        const double gk[3][3] = {{0.3, -0.2, 0.7}, {1.1, 0.4, -0.5}, {-0.6, 0.9, 0.2}};
        for (uint32_t z = 0; z < 3; z++)
            for (uint32_t y = 0; y < 4; y++)
                for (uint32_t x = 0; x < 5; x++) {
                    double u[3] = {x + 0.5, y + 0.5, z + 0.5}, w[3];
                    for (int a = 0; a < 3; a++) w[a] = o[a] + h * (u[0] * R[a] + u[1] * R[3 + a] + u[2] * R[6 + a]);
                    int32_t pi = g.cells[x + 5 * (y + 4 * z)];
                    for (int k = 0; k < 3; k++)
                        g.coeffs[(size_t)pi * CC * 3 + k] = 0.5 + gk[k][0] * w[0] + gk[k][1] * w[1] + gk[k][2] * w[2];
                }
        pb_grid_field *f = build(&g, R, o, h, NULL);
        TU_REQUIRE(f);
        double worst = 0.0, worst_tex = 0.0;
        for (int i = 0; i < 4000; i++) {
            double u[3], uc[3], p[3], want[3], c[CC * 3], ch[CC * 3];
            const double hi[3] = {5, 4, 3};
            for (int a = 0; a < 3; a++) {
                u[a] = -0.0099 + tu_rnd() * (hi[a] + 0.0198);
                uc[a] = fmin(fmax(u[a], 0.5), hi[a] - 0.5);
            }
            for (int a = 0; a < 3; a++) p[a] = o[a] + h * (u[0] * R[a] + u[1] * R[3 + a] + u[2] * R[6 + a]);
            for (int k = 0; k < 3; k++) {
                double w[3];
                for (int a = 0; a < 3; a++) w[a] = o[a] + h * (uc[0] * R[a] + uc[1] * R[3 + a] + uc[2] * R[6 + a]);
                want[k] = 0.5 + gk[k][0] * w[0] + gk[k][1] * w[1] + gk[k][2] * w[2];
            }
            TU_CHECK_EQ_INT(pb_grid_field_sample(f, p, NULL, NULL, c), PB_GRID_FIELD_WEIGHTS);
            TU_CHECK(pb_grid_field_sample_texture(f, p, 0, NULL, ch, NULL));
            for (int k = 0; k < 3; k++) {
                worst = fmax(worst, fabs(c[k] - want[k]));
                worst_tex = fmax(worst_tex, fabs(ch[k] - want[k]));
            }
        }
        TU_CHECK(worst < 1e-12);
        TU_CHECK(worst_tex < 1e-12);
        printf("linear field (%s axes): max |query - closed form| %.3g, texture %.3g\n", rot ? "rotated" : "identity",
               worst, worst_tex);
        /* Outside the 0.01-cell margin: not in the grid. */
        double u[3] = {-0.0101, 1.0, 1.0}, p[3];
        for (int a = 0; a < 3; a++) p[a] = o[a] + h * (u[0] * R[a] + u[1] * R[3 + a] + u[2] * R[6 + a]);
        pb_grid_field_weights w;
        TU_CHECK_EQ_INT(pb_grid_field_query(f, p, NULL, NULL, &w), PB_GRID_FIELD_OUTSIDE);
        TU_CHECK(!pb_grid_field_sample_texture(f, p, 0, NULL, NULL, NULL));
        pb_grid_field_destroy(f);
        free_grid(&g);
    }
}

/* A 2 x 1 x 1 grid between the two centres: validity, empty cells, masks, back faces, fallback, by hand. */
static void test_rule_by_hand(void)
{
    grid g = make_grid(2, 1, 1, 0.0, 0.0);
    const double o[3] = {0, 0, 0}, h = 1.0;
    for (uint32_t i = 0; i < 2 * CC * 3; i++) g.coeffs[i] = i < CC * 3 ? 1.0 : 3.0; /* probe 0: 1, probe 1: 3 */
    g.validity[0] = 0.5f, g.validity[1] = 1.0f;
    g.scale[0] = g.scale[1] = 1.0f;
    pb_grid_field *f = build(&g, NULL, o, h, NULL);
    TU_REQUIRE(f);
    /* u.x = 0.75: trilinear 0.75 / 0.25 (centres 0.5, 1.5), times validity 0.5 / 1: 0.375 / 0.25 -> 0.6 / 0.4 */
    double p[3] = {0.75, 0.5, 0.5}, c[CC * 3];
    pb_grid_field_weights w;
    TU_CHECK_EQ_INT(pb_grid_field_query(f, p, NULL, NULL, &w), PB_GRID_FIELD_WEIGHTS);
    double w0 = 0, w1 = 0;
    for (int k = 0; k < 8; k++) *(w.probe[k] == 0 ? &w0 : &w1) += w.weight[k];
    TU_CHECK_NEAR(w0, 0.6, 1e-15);
    TU_CHECK_NEAR(w1, 0.4, 1e-15);
    pb_grid_field_sample(f, p, NULL, NULL, c);
    TU_CHECK_NEAR(c[0], 0.6 * 1 + 0.4 * 3, 1e-14);
    /* Back face: a static surface at x = 0.75 facing -x has probe 1's centre (x = 1.5) behind it:
     * dot(c - p, n) = -0.75 -> weight 0; probe 0's (0.5) in front: 1 -> probe 0 alone. */
    double n[3] = {-1, 0, 0};
    pb_grid_field_opts st = {.static_surface = true};
    TU_CHECK_EQ_INT(pb_grid_field_query(f, p, n, &st, &w), PB_GRID_FIELD_WEIGHTS);
    w0 = w1 = 0;
    for (int k = 0; k < 8; k++) *(w.probe[k] == 0 ? &w0 : &w1) += w.weight[k];
    TU_CHECK_NEAR(w0, 1.0, 1e-15);
    TU_CHECK_NEAR(w.backface[1], 0.0, 0.0);
    /* At x = 0.95 facing -x: probe 0 at dot = 0.45 -> 1, probe 1 at 0.55 behind... both sides: t_1 =
     * dot((1.5 - 0.95), -1) = -0.55 -> 0. Surface x = 1.49 facing +x: t_0 = -0.99 -> 0, t_1 = 0.01 ->
     * smoothstep(-0.1, 0.1, 0.01) = 0.5 + 0.075 - ... (closed form below). */
    double p2[3] = {1.49, 0.5, 0.5}, n2[3] = {1, 0, 0};
    pb_grid_field_query(f, p2, n2, &st, &w);
    double s = (0.01 + 0.1) / 0.2, ss = s * s * (3 - 2 * s);
    TU_CHECK_NEAR(w.backface[1], ss, 1e-12);
    TU_CHECK_NEAR(w.backface[0], 0.0, 0.0);
    /* The movable rule ignores back faces. */
    pb_grid_field_query(f, p, n, NULL, &w);
    TU_CHECK_NEAR(w.backface[1], 1.0, 0.0);
    /* Mask: home cell 0 cannot see +x (bit (1+1) + 3 + 9 = 14 clear): probe 1 dropped, probe 0 alone. */
    uint32_t masks[2] = {PB_GRID_FIELD_ALL_VISIBLE & ~(UINT32_C(1) << 14), PB_GRID_FIELD_ALL_VISIBLE};
    pb_grid_field *fm = build(&g, NULL, o, h, masks);
    TU_REQUIRE(fm);
    double p3[3] = {0.9, 0.5, 0.5};
    TU_CHECK_EQ_INT(pb_grid_field_query(fm, p3, NULL, NULL, &w), PB_GRID_FIELD_WEIGHTS);
    TU_CHECK(w.home[0] == 0);
    w0 = w1 = 0;
    for (int k = 0; k < 8; k++) *(w.probe[k] == 0 ? &w0 : &w1) += w.weight[k];
    TU_CHECK_NEAR(w0, 1.0, 1e-15);
    TU_CHECK(w.masked[1]);
    /* From cell 1 (its mask is full) both contribute. */
    double p4[3] = {1.1, 0.5, 0.5};
    pb_grid_field_query(fm, p4, NULL, NULL, &w);
    TU_CHECK(w.home[0] == 1 && !w.masked[0] && !w.masked[1]);
    /* The home cell moves 0.01 cells along n: at x = 0.995 facing +x it is cell 1. */
    double p5[3] = {0.995, 0.5, 0.5};
    pb_grid_field_query(fm, p5, n2, NULL, &w);
    TU_CHECK(w.home[0] == 1);
    /* Step 5, static surface at (0.75, 0.7, 0.5) facing +y: both centres (y = 0.5) lie 0.2 cells behind it,
     * back faces 0, W = 0: the plain trilinear x validity weights 0.75 x 0.5 / 0.25 x 1 -> 0.6 / 0.4 (y
     * clamps both its corners onto the one layer), value 0.6 + 1.2 = 1.8 (the old rule took the cell
     * holding u, probe 0: 1.0); the texture's own N / D at the point is the same. */
    double p6[3] = {0.75, 0.7, 0.5}, n6[3] = {0, 1, 0};
    TU_CHECK_EQ_INT(pb_grid_field_query(f, p6, n6, &st, &w), PB_GRID_FIELD_FALLBACK);
    TU_CHECK_NEAR(w.backface[0] + w.backface[1], 0.0, 0.0);
    w0 = w1 = 0;
    for (int k = 0; k < 8; k++) *(w.probe[k] == 0 ? &w0 : &w1) += w.weight[k];
    TU_CHECK_NEAR(w0, 0.6, 1e-15);
    TU_CHECK_NEAR(w1, 0.4, 1e-15);
    TU_CHECK_EQ_INT(pb_grid_field_sample(f, p6, n6, &st, c), PB_GRID_FIELD_FALLBACK);
    TU_CHECK_NEAR(c[0], 1.8, 1e-14);
    double ct[CC * 3], d6 = 0;
    uint32_t taps = 0;
    TU_CHECK(pb_grid_field_sample_surface_texture(f, p6, n6, &st, 0, ct, &d6, &taps));
    TU_CHECK_NEAR(ct[0], 1.8, 1e-14);
    TU_CHECK_NEAR(d6, 0.625, 1e-15); /* D = 0.75 x 0.5 + 0.25 x 1 */
    TU_CHECK(taps == 8);
    TU_CHECK(pb_grid_field_sample_texture(f, p6, 0, NULL, ct, NULL));
    TU_CHECK_NEAR(ct[0], 1.8, 1e-14);
    /* Step 5 with an invalid home probe: validity 0 / 1, home cell 0's mask drops probe 1 (fm's masks): at x
     * = 0.9 W = 0; the plain weights 0.6 x 0 / 0.4 x 1 leave probe 1 alone: 3 (the old rule: probe 0, 1.0,
     * whatever its validity). */
    g.validity[0] = 0.0f;
    pb_grid_field *fv = build(&g, NULL, o, h, masks);
    TU_REQUIRE(fv);
    TU_CHECK_EQ_INT(pb_grid_field_sample(fv, p3, NULL, NULL, c), PB_GRID_FIELD_FALLBACK);
    TU_CHECK_NEAR(c[0], 3.0, 1e-15);
    TU_CHECK(pb_grid_field_sample_surface_texture(fv, p3, NULL, NULL, 0, ct, NULL, NULL));
    TU_CHECK_NEAR(ct[0], 3.0, 1e-15);
    /* Both probes invalid: D = 0, no value (the old rule: the cell holding u, 3.0); the texture agrees. */
    g.validity[1] = 0.0f;
    pb_grid_field *fz = build(&g, NULL, o, h, NULL);
    TU_REQUIRE(fz);
    TU_CHECK_EQ_INT(pb_grid_field_sample(fz, p4, NULL, NULL, c), PB_GRID_FIELD_NONE);
    TU_CHECK_NEAR(c[0], 0.0, 0.0);
    TU_CHECK(!pb_grid_field_sample_texture(fz, p4, 0, NULL, NULL, NULL)); /* D = 0: the texture has no value */
    TU_CHECK(!pb_grid_field_sample_surface_texture(fz, p4, NULL, NULL, 0, NULL, NULL, NULL));
    /* Valid probe 0, empty cell 1: at x = 1.1 (c = 0.6) probe 0 keeps 0.4 x 1 -> its value; at x = 1.9 the
     * two corners clamp onto cell 1: no value. */
    g.validity[0] = 1.0f;
    g.cells[1] = -1;
    pb_grid_field *fe = build(&g, NULL, o, h, NULL);
    TU_REQUIRE(fe);
    TU_CHECK_EQ_INT(pb_grid_field_sample(fe, p4, NULL, NULL, c), PB_GRID_FIELD_WEIGHTS);
    TU_CHECK_NEAR(c[0], 1.0, 1e-15);
    double p7[3] = {1.9, 0.5, 0.5};
    TU_CHECK_EQ_INT(pb_grid_field_query(fe, p7, NULL, NULL, &w), PB_GRID_FIELD_NONE);
    pb_grid_field_destroy(f), pb_grid_field_destroy(fm), pb_grid_field_destroy(fz), pb_grid_field_destroy(fe);
    pb_grid_field_destroy(fv);
    free_grid(&g);
}

/* Texture form == weights form (movable, no masks) on random grids with empty cells and invalid probes;
 * binary16 texels within |Σ w (N err)| / D bounds; quantised fractions move the point <= 2^-(bits+1). */
static void test_texture_equals_weights(void)
{
    tu_rng_state = 5;
    double R[9];
    rotation(R);
    for (int trial = 0; trial < 4; trial++) {
        grid g = make_grid(6 + trial, 5, 4, 0.15, 0.2);
        const double o[3] = {0.3, -0.7, 1.1}, h = 0.3;
        pb_grid_field *f = build(&g, trial & 1 ? R : NULL, o, h, NULL);
        TU_REQUIRE(f);
        pb_grid_field_info in;
        pb_grid_field_get_info(f, &in);
        TU_CHECK_EQ_INT(in.channels, 13u);
        TU_CHECK_EQ_INT(in.groups, 4u);
        uint64_t n = (uint64_t)in.dims[0] * in.dims[1] * in.dims[2] * in.groups * 4u;
        uint16_t *half = malloc(n * sizeof *half);
        float *full = malloc(n * sizeof *full);
        pb_error err = {0};
        TU_CHECK_EQ_INT(pb_grid_field_texture_f16(f, half, n, &err), PB_SUCCESS);
        TU_CHECK_EQ_INT(pb_grid_field_texture_f32(f, full, n, &err), PB_SUCCESS);
        TU_CHECK_EQ_INT(pb_grid_field_texture_f32(f, full, n - 1, &err), PB_ERROR_INVALID_ARGUMENT);
        /* Texel of cell (1, 2, 3), channel 3 (D) = its probe's validity (0 if empty). */
        uint32_t cell = 1 + in.dims[0] * (2 + in.dims[1] * 3);
        int32_t pi = g.cells[cell];
        TU_CHECK_NEAR(full[(uint64_t)cell * 4 + 3], pi >= 0 ? g.validity[pi] : 0.0f, 0.0);
        double worst = 0.0, worst_bits = 0.0;
        int mismatched = 0, compared = 0;
        for (int i = 0; i < 5000; i++) {
            double u[3] = {tu_rnd() * in.dims[0], tu_rnd() * in.dims[1], tu_rnd() * in.dims[2]}, p[3];
            const double *A = trial & 1 ? R : (const double[9]){1, 0, 0, 0, 1, 0, 0, 0, 1};
            for (int a = 0; a < 3; a++) p[a] = o[a] + h * (u[0] * A[a] + u[1] * A[3 + a] + u[2] * A[6 + a]);
            double c[CC * 3], t[CC * 3], tb[CC * 3];
            pb_grid_field_status s = pb_grid_field_sample(f, p, NULL, NULL, c);
            bool has = pb_grid_field_sample_texture(f, p, 0, NULL, t, NULL);
            bool has8 = pb_grid_field_sample_texture(f, p, 8, NULL, tb, NULL);
            if ((s == PB_GRID_FIELD_WEIGHTS) != has) {
                mismatched++;
                continue;
            }
            if (!has) continue;
            compared++;
            for (int k = 0; k < (int)(CC * 3); k++) worst = fmax(worst, fabs(c[k] - t[k]));
            if (has8)
                for (int k = 0; k < (int)(CC * 3); k++) worst_bits = fmax(worst_bits, fabs(tb[k] - t[k]));
        }
        TU_CHECK_EQ_INT(mismatched, 0);
        TU_CHECK(compared > 3000);
        TU_CHECK(worst < 1e-13);
        printf("texture vs weights (trial %d): %d points, max %.3g; 8-bit fractions move it by max %.3g\n", trial,
               compared, worst, worst_bits);
        /* Half texels: each within 2^-11 relative of the float64 (round to nearest). */
        const double *tx = pb_grid_field_texels(f);
        double worst_half = 0.0;
        for (uint64_t i = 0; i < (uint64_t)in.dims[0] * in.dims[1] * in.dims[2]; i++)
            for (uint32_t ch = 0; ch < in.channels; ch++) {
                uint16_t hv = half[((ch / 4) * (n / 4 / in.groups) + i) * 4 + ch % 4];
                int e = (hv >> 10) & 31, m = hv & 1023;
                double v = (e ? ldexp(1024 + m, e - 25) : ldexp(m, -24)) * (hv & 0x8000 ? -1 : 1);
                double ref = tx[i * in.channels + ch];
                if (fabs(ref) > 1e-3) worst_half = fmax(worst_half, fabs(v - ref) / fabs(ref));
            }
        TU_CHECK(worst_half <= ldexp(1.0, -11));
        free(half), free(full);
        pb_grid_field_destroy(f);
        free_grid(&g);
    }
}

/* pb_grid_field_build with a fresh error (pb_error keeps the first error it is given). */
static pb_result build_err(const pb_grid_field_desc *d, pb_grid_field **f, pb_error *err)
{
    *err = (pb_error){0};
    return pb_grid_field_build(d, f, err);
}

static void test_refusals(void)
{
    grid g = make_grid(2, 2, 2, 0.0, 0.0);
    pb_grid_field_desc d = {.dims = {2, 2, 2},
                            .spacing = 1.0,
                            .cells = g.cells,
                            .probe_count = g.probes,
                            .coeff_count = CC,
                            .coeffs = g.coeffs};
    pb_grid_field *f = NULL;
    pb_error err = {0};
    TU_CHECK_EQ_INT(build_err(NULL, &f, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_EQ_INT(build_err(&d, NULL, &err), PB_ERROR_INVALID_ARGUMENT);
    pb_grid_field_desc b = d;
    b.dims[1] = 0;
    TU_CHECK_EQ_INT(build_err(&b, &f, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "zero axis");
    b = d, b.dims[0] = b.dims[1] = b.dims[2] = 2000;
    TU_CHECK_EQ_INT(build_err(&b, &f, &err), PB_ERROR_TOO_LARGE);
    b = d, b.spacing = NAN;
    TU_CHECK_EQ_INT(build_err(&b, &f, &err), PB_ERROR_INVALID_ARGUMENT);
    b = d, b.coeff_count = 26;
    TU_CHECK_EQ_INT(build_err(&b, &f, &err), PB_ERROR_INVALID_ARGUMENT);
    double skew[9] = {1, 0, 0, 0.1, 1, 0, 0, 0, 1};
    b = d, b.axes = skew;
    TU_CHECK_EQ_INT(build_err(&b, &f, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "orthonormal");
    g.cells[3] = (int32_t)g.probes;
    TU_CHECK_EQ_INT(build_err(&d, &f, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "outside [-1");
    g.cells[3] = 3;
    g.coeffs[7] = INFINITY;
    TU_CHECK_EQ_INT(build_err(&d, &f, &err), PB_ERROR_NON_FINITE);
    g.coeffs[7] = 0.0;
    g.validity[2] = NAN;
    b = d, b.validity = g.validity;
    TU_CHECK_EQ_INT(build_err(&b, &f, &err), PB_ERROR_NON_FINITE);
    g.validity[2] = 1.0f;
    b = d, b.max_bytes = 100;
    TU_CHECK_EQ_INT(build_err(&b, &f, &err), PB_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "GiB");
    TU_CHECK(f == NULL);
    /* Past binary16: the f16 texture refuses, f32 takes it. */
    g.coeffs[0] = 1e5;
    TU_REQUIRE(build_err(&d, &f, &err) == PB_SUCCESS);
    uint16_t h[2 * 2 * 2 * 4 * 4];
    float fl[2 * 2 * 2 * 4 * 4];
    TU_CHECK_EQ_INT((err = (pb_error){0}, pb_grid_field_texture_f16(f, h, 128, &err)), PB_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "upload float32");
    TU_CHECK_EQ_INT(pb_grid_field_texture_f32(f, fl, 128, &err), PB_SUCCESS);
    double p[3] = {1, 1, 1};
    pb_grid_field_weights w;
    TU_CHECK_EQ_INT(pb_grid_field_query(NULL, p, NULL, NULL, &w), PB_GRID_FIELD_OUTSIDE);
    pb_grid_field_destroy(f);
    free_grid(&g);
}

int main(void)
{
    TU_RUN(test_linear_field);
    TU_RUN(test_rule_by_hand);
    TU_RUN(test_texture_equals_weights);
    TU_RUN(test_refusals);
    return TU_EXIT();
}
