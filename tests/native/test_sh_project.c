/* Equirect SH projection against closed forms and independent per-pixel references.
 *
 * Expected values come from: Funk–Hecke (a zonal g(ω·a) projects to λ_l Y_lm(a), λ_l = 2π∫g P_l),
 * which gives the clamped cosine (λ_l = A_l) and sky/ground hemispheres; the definition of the
 * discrete projection for single pixels (value · exact solid angle · Y(pixel centre)); and a brute
 * force per-pixel sum using test_sh_reference.h (recurrence basis, DESIGN.md mapping).
 *
 * Discretisation: the projection samples each pixel at its centre, so smooth environments differ
 * from their continuous integrals by the midpoint-rule error, O((π/H)²); tolerances below that
 * involve it say so and were set at ~2–4× the measured error (printed by the test).
 */
#include "schnee/pb_image.h"
#include "schnee/pb_sh.h"
#include "test_sh_reference.h"
#include "testutil.h"

#include <stdlib.h>
#include <unistd.h>

typedef void (*env_fn)(const double e[3], void *user, float rgb[3]);

/* W×H×ch panorama whose pixel centres take env(engine-space direction). */
static float *make_env(uint32_t w, uint32_t h, uint32_t ch, env_fn env, void *user)
{
    float *p = calloc((size_t)w * h * ch, sizeof(float));
    if (!p) return NULL;
    for (uint32_t r = 0; r < h; r++)
        for (uint32_t i = 0; i < w; i++) {
            double e[3];
            ref_pixel_dir_engine(i, r, w, h, e);
            env(e, user, p + ((size_t)r * w + i) * ch);
        }
    return p;
}

static pb_result project(const float *px, uint32_t w, uint32_t h, uint32_t ch, uint32_t L, double *out, pb_error *err)
{
    pb_sh_project_desc d = {.pixels = px, .width = w, .height = h, .channels = ch, .max_band = L};
    return pb_sh_project_equirect(&d, out, err);
}

static void env_constant(const double e[3], void *user, float rgb[3])
{
    (void)e;
    const float *c = user;
    rgb[0] = c[0], rgb[1] = c[1], rgb[2] = c[2];
}

/* Constant radiance c: L_00 = 2√π·c exactly (the weights sum to 4π); every other coefficient is
 * pure discretisation error, bounded by 0.8·(π/H)²·c (measured ≤ 0.36·(π/H)²·c). */
static void test_constant(void)
{
    float c[3] = {0.5f, 1.0f, 2.0f};
    const uint32_t sizes[3][2] = {{20, 10}, {64, 32}, {256, 128}};
    for (int s = 0; s < 3; s++) {
        const uint32_t w = sizes[s][0], h = sizes[s][1];
        float *px = make_env(w, h, 3, env_constant, c);
        TU_REQUIRE(px);
        for (uint32_t L = 0; L <= 4; L++) {
            double out[75];
            pb_error err = {0};
            TU_CHECK_EQ_INT(project(px, w, h, 3, L, out, &err), PB_SUCCESS);
            double worst = 0.0;
            for (int k = 0; k < 3; k++) {
                TU_CHECK_REL(out[k], 2.0 * sqrt(REF_PI) * c[k], 1e-13);
                for (uint32_t i = 1; i < pb_sh_count(L); i++) {
                    TU_CHECK_NEAR(out[i * 3 + k], 0.0, 0.8 * pow(REF_PI / h, 2) * c[k]);
                    worst = fmax(worst, fabs(out[i * 3 + k]) / c[k] / pow(REF_PI / h, 2));
                }
            }
            if (L == 4) printf("  %ux%u: max |L_i>0| / (c (pi/H)^2) = %.3f\n", w, h, worst);
        }
        free(px);
    }
}

/* A single pixel of radiance P: L_i = P·Ω_r·Y_i(e) with e the pixel centre in engine space
 * (the definition of the discrete projection; DESIGN.md convention written out independently).
 * Tolerance 1e-12 relative to P·Ω (rounding only). Covers both poles' rows and the seam columns. */
static void test_single_pixel(void)
{
    const uint32_t w = 64, h = 32;
    const uint32_t spots[6][2] = {{0, 0}, {63, 31}, {17, 5}, {40, 16}, {31, 15}, {5, 30}};
    float *px = calloc((size_t)w * h * 3, sizeof(float));
    TU_REQUIRE(px);
    for (int s = 0; s < 6; s++) {
        const uint32_t i = spots[s][0], r = spots[s][1];
        const float val[3] = {7.0f, 0.5f, 100.0f};
        for (int k = 0; k < 3; k++) px[((size_t)r * w + i) * 3 + k] = val[k];
        double e[3], y[25];
        ref_pixel_dir_engine(i, r, w, h, e);
        ref_basis(4, e, y);
        const double omega = ref_pixel_solid_angle(r, w, h);
        for (uint32_t L = 0; L <= 4; L++) {
            double out[75];
            pb_error err = {0};
            TU_CHECK_EQ_INT(project(px, w, h, 3, L, out, &err), PB_SUCCESS);
            for (uint32_t q = 0; q < pb_sh_count(L); q++)
                for (int k = 0; k < 3; k++)
                    TU_CHECK_NEAR(out[q * 3 + k], val[k] * omega * y[q], 1e-12 * val[k] * omega);
        }
        for (int k = 0; k < 3; k++) px[((size_t)r * w + i) * 3 + k] = 0.0f;
    }
    free(px);
}

typedef struct lobe {
    double axis[3];
    double scale[3];
} lobe;

static void env_clamped_cosine(const double e[3], void *user, float rgb[3])
{
    const lobe *lb = user;
    const double c = fmax(0.0, e[0] * lb->axis[0] + e[1] * lb->axis[1] + e[2] * lb->axis[2]);
    for (int k = 0; k < 3; k++) rgb[k] = (float)(lb->scale[k] * c);
}

/* Clamped cosine max(0, ω·a): L_lm = A_l·Y_lm(a) (Funk–Hecke with λ_l = A_l). The kink at the
 * terminator makes the pixel sampling error O(1/H²)·log-ish: measured 1.4e-5 of L_00 at 512×256;
 * tolerance 1e-4·L_00. Axis chosen off every coordinate plane. */
static void test_clamped_cosine(void)
{
    lobe lb = {{0.3, 0.5, -0.8}, {1.0, 2.0, 0.25}};
    const double n = sqrt(0.09 + 0.25 + 0.64);
    for (int k = 0; k < 3; k++) lb.axis[k] /= n;
    const uint32_t w = 512, h = 256;
    float *px = make_env(w, h, 3, env_clamped_cosine, &lb);
    TU_REQUIRE(px);
    double out[75];
    pb_error err = {0};
    TU_CHECK_EQ_INT(project(px, w, h, 3, 4, out, &err), PB_SUCCESS);
    double worst = 0.0;
    for (int l = 0; l <= 4; l++)
        for (int m = -l; m <= l; m++)
            for (int k = 0; k < 3; k++) {
                const double want = lb.scale[k] * ref_lambert(l) * ref_sh(l, m, lb.axis);
                const double l00 = lb.scale[k] * REF_PI * ref_sh(0, 0, lb.axis);
                TU_CHECK_NEAR(out[(l * l + l + m) * 3 + k], want, 1e-4 * l00);
                worst = fmax(worst, fabs(out[(l * l + l + m) * 3 + k] - want) / l00);
            }
    printf("  max error / L00 = %.2e\n", worst);
    free(px);
}

static void env_hemispheres(const double e[3], void *user, float rgb[3])
{
    const float *sg = user; /* sky rgb, ground rgb */
    for (int k = 0; k < 3; k++) rgb[k] = e[1] > 0.0 ? sg[k] : sg[3 + k];
}

/* Sky S above the engine horizon (y > 0), ground G below. Zonal about up = (0,1,0):
 * L_lm = λ_l Y_lm(up) with λ_0 = 2π(S+G), λ_1 = π(S−G), λ_2 = 0, λ_3 = −π(S−G)/4, λ_4 = 0
 * (∫₀¹P_l = 1, ½, 0, −⅛, 0). The horizon falls on a row boundary (H even), so the error is the
 * midpoint rule in θ: tolerance 0.5·(π/H)²·max(S, G) (measured 0.22). */
static void test_hemispheres(void)
{
    float sg[6] = {2.0f, 1.0f, 0.5f, 0.1f, 0.3f, 0.0f};
    const double up[3] = {0.0, 1.0, 0.0};
    const uint32_t sizes[2][2] = {{64, 32}, {512, 256}};
    for (int s = 0; s < 2; s++) {
        const uint32_t w = sizes[s][0], h = sizes[s][1];
        float *px = make_env(w, h, 3, env_hemispheres, sg);
        TU_REQUIRE(px);
        double out[75];
        pb_error err = {0};
        TU_CHECK_EQ_INT(project(px, w, h, 3, 4, out, &err), PB_SUCCESS);
        double worst = 0.0;
        for (int k = 0; k < 3; k++) {
            const double S = sg[k], G = sg[3 + k];
            const double lambda[5] = {2 * REF_PI * (S + G), REF_PI * (S - G), 0.0, -REF_PI / 4 * (S - G), 0.0};
            for (int l = 0; l <= 4; l++)
                for (int m = -l; m <= l; m++) {
                    const double want = lambda[l] * ref_sh(l, m, up), got = out[(l * l + l + m) * 3 + k];
                    TU_CHECK_NEAR(got, want, 0.5 * pow(REF_PI / h, 2) * fmax(S, G));
                    worst = fmax(worst, fabs(got - want) / pow(REF_PI / h, 2) / fmax(S, G));
                }
            /* L_00 is exact: each hemisphere's weights sum to 2π exactly. */
            TU_CHECK_REL(out[k], 2 * REF_PI * (S + G) * ref_sh(0, 0, up), 1e-13);
        }
        printf("  %ux%u: max error / (max(S,G) (pi/H)^2) = %.3f\n", w, h, worst);
        free(px);
    }
}

/* Irradiance of the projected constant environment = π·c (closed form), up to the discretisation of
 * the l > 0 coefficients (≤ 0.36(π/H)² c each, test_constant): summed over bands with |A_l|·|Y| this
 * stays below 2e-3·c at 256×128. */
static void test_irradiance_of_constant_env(void)
{
    float c[3] = {0.5f, 1.0f, 2.0f};
    const uint32_t w = 256, h = 128;
    float *px = make_env(w, h, 3, env_constant, c);
    TU_REQUIRE(px);
    double out[75];
    pb_error err = {0};
    TU_CHECK_EQ_INT(project(px, w, h, 3, 4, out, &err), PB_SUCCESS);
    uint64_t rng = 99;
    for (int t = 0; t < 100; t++) {
        double n[3], e[3];
        ref_rand_dir(&rng, n);
        pb_sh_irradiance(4, out, n, e);
        for (int k = 0; k < 3; k++) TU_CHECK_NEAR(e[k], REF_PI * c[k], 2e-3 * c[k]);
    }
    free(px);
}

/* Brute-force reference: L_i = Σ_p L_p Ω_p Y_i(R d_p) with the recurrence basis. R = NULL means
 * Blender → engine. */
static void brute_force(const float *px, uint32_t w, uint32_t h, uint32_t ch, int L, const double *rot, double *out)
{
    const uint32_t n = (uint32_t)((L + 1) * (L + 1));
    for (uint32_t q = 0; q < n * 3; q++) out[q] = 0.0;
    for (uint32_t r = 0; r < h; r++) {
        const double om = ref_pixel_solid_angle(r, w, h);
        for (uint32_t i = 0; i < w; i++) {
            double b[3], e[3], y[25];
            ref_pixel_dir_blender(i, r, w, h, b);
            if (rot)
                for (int k = 0; k < 3; k++) e[k] = rot[k * 3] * b[0] + rot[k * 3 + 1] * b[1] + rot[k * 3 + 2] * b[2];
            else
                ref_blender_to_engine(b, e);
            ref_basis(L, e, y);
            const float *p = px + ((size_t)r * w + i) * ch;
            for (uint32_t q = 0; q < n; q++)
                for (int k = 0; k < 3; k++) out[q * 3 + k] += (double)p[k] * om * y[q];
        }
    }
}

/* Rotation from axis–angle (Rodrigues), row-major. */
static void rotation_matrix(const double axis[3], double angle, double r[9])
{
    const double c = cos(angle), s = sin(angle), t = 1 - c, x = axis[0], y = axis[1], z = axis[2];
    const double m[9] = {t * x * x + c,     t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c,
                         t * y * z - s * x, t * x * z - s * y, t * y * z + s * x, t * z * z + c};
    for (int i = 0; i < 9; i++) r[i] = m[i];
}

/* Random noise image, every band, three rotations (NULL, identity, arbitrary) against the brute-force
 * per-pixel reference; and NULL == the explicit Blender → engine matrix. Tolerance 1e-12 relative to
 * Σ|L_p|Ω_p (rounding in a different summation order). */
static void test_rotation_against_brute_force(void)
{
    const uint32_t w = 48, h = 24, ch = 4;
    float *px = malloc(sizeof(float) * w * h * ch);
    TU_REQUIRE(px);
    uint64_t rng = 4242;
    for (uint32_t q = 0; q < w * h * ch; q++) px[q] = (float)ref_rand01(&rng);
    double axis[3], rot[9];
    ref_rand_dir(&rng, axis);
    rotation_matrix(axis, 1.234, rot);
    const double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    const double b2e[9] = {1, 0, 0, 0, 0, 1, 0, -1, 0};
    const double *rots[4] = {NULL, identity, rot, b2e};
    for (int L = 0; L <= 4; L++)
        for (int ri = 0; ri < 4; ri++) {
            double got[75], want[75];
            pb_sh_project_desc d = {
                .pixels = px, .width = w, .height = h, .channels = ch, .max_band = (uint32_t)L, .rotation = rots[ri]};
            pb_error err = {0};
            TU_CHECK_EQ_INT(pb_sh_project_equirect(&d, got, &err), PB_SUCCESS);
            brute_force(px, w, h, ch, L, rots[ri], want);
            for (int q = 0; q < (L + 1) * (L + 1) * 3; q++) TU_CHECK_NEAR(got[q], want[q], 1e-12 * 4 * REF_PI);
        }
    free(px);
}

/* Minimum size per band: pb_sh_min_panorama_size = 2(L+1) per axis (docs/sh.md). At the minimum the
 * projection runs, a constant is still exact (L_00 = 2√π c) and the projection of a pure basis
 * function Y_j returns e_j within the discrete Gram error measured for that size (≤ 0.061 at
 * H = 2(L+1), docs/sh.md; tolerance 0.07). One column or one row less is refused, naming the minimum. */
static void test_minimum_size(void)
{
    for (uint32_t L = 0; L <= 4; L++) {
        uint32_t mw = 0, mh = 0;
        pb_sh_min_panorama_size(L, &mw, &mh);
        TU_CHECK_EQ_INT(mw, 2 * (L + 1));
        TU_CHECK_EQ_INT(mh, 2 * (L + 1));
        float *px = malloc(sizeof(float) * mw * mh * 3);
        TU_REQUIRE(px);
        for (uint32_t j = 0; j < pb_sh_count(L); j++) {
            for (uint32_t r = 0; r < mh; r++)
                for (uint32_t i = 0; i < mw; i++) {
                    double e[3], y[25];
                    ref_pixel_dir_engine(i, r, mw, mh, e);
                    ref_basis((int)L, e, y);
                    for (int k = 0; k < 3; k++) px[((size_t)r * mw + i) * 3 + k] = (float)((k + 1) * y[j]);
                }
            double out[75];
            pb_error err = {0};
            pb_sh_project_desc d = {
                .pixels = px, .width = mw, .height = mh, .channels = 3, .max_band = L, .negative = PB_NEGATIVE_ALLOW};
            TU_CHECK_EQ_INT(pb_sh_project_equirect(&d, out, &err), PB_SUCCESS);
            for (uint32_t q = 0; q < pb_sh_count(L); q++)
                for (int k = 0; k < 3; k++)
                    TU_CHECK_NEAR(out[q * 3 + k], (k + 1) * (q == j ? 1.0 : 0.0), 0.07 * (k + 1));
        }
        for (uint32_t q = 0; q < mw * mh * 3; q++) px[q] = 1.5f;
        double out[75];
        pb_error err = {0};
        TU_CHECK_EQ_INT(project(px, mw, mh, 3, L, out, &err), PB_SUCCESS);
        TU_CHECK_REL(out[0], 1.5 * 2.0 * sqrt(REF_PI), 1e-13);

        char want[64];
        snprintf(want, sizeof want, "minimum is %ux%u", mw, mh);
        pb_error e1 = {0}, e2 = {0};
        TU_CHECK_EQ_INT(project(px, mw - 1, mh, 3, L, out, &e1), PB_ERROR_TOO_SMALL);
        TU_CHECK_EQ_INT(e1.code, PB_ERROR_TOO_SMALL);
        TU_CHECK_CONTAINS(e1.message, want);
        TU_CHECK_EQ_INT(project(px, mw, mh - 1, 3, L, out, &e2), PB_ERROR_TOO_SMALL);
        TU_CHECK_CONTAINS(e2.message, want);
        free(px);
    }
    /* The DESIGN.md example: an 8×4 panorama cannot represent l = 4. */
    float tiny[8 * 4 * 3] = {0};
    double out[75];
    pb_error err = {0};
    TU_CHECK_EQ_INT(project(tiny, 8, 4, 3, 4, out, &err), PB_ERROR_TOO_SMALL);
    TU_CHECK_CONTAINS(err.message, "8x4");
}

/* 8192×4096, 3 channels (400 MB): R = hemispheres (S=3, G=1), G = clamped cosine about a tilted
 * axis, B = constant 0.75. Expected: the closed forms above; at H = 4096 the discretisation error
 * is 5.4e-8 of L_00 (measured), tolerance 1e-6 of each channel's L_00. Also a timing print; the
 * bound on time is the ctest timeout, figures live in bench/results/sh.md. */
static void test_huge_panorama(void)
{
    const uint32_t w = 8192, h = 4096;
    float *px = malloc(sizeof(float) * (size_t)w * h * 3);
    TU_REQUIRE(px);
    double axis[3] = {0.6, 0.0, 0.8}; /* engine space */
    double *cp = malloc(sizeof(double) * w * 2);
    if (!cp) {
        free(px);
        TU_REQUIRE(cp);
    }
    for (uint32_t i = 0; i < w; i++) {
        const double phi = REF_PI - 2 * REF_PI * (i + 0.5) / w;
        cp[2 * i] = cos(phi);
        cp[2 * i + 1] = sin(phi);
    }
    for (uint32_t r = 0; r < h; r++) {
        const double th = REF_PI * (r + 0.5) / h, st = sin(th), ct = cos(th);
        const float hemi = ct > 0.0 ? 3.0f : 1.0f; /* Blender z = engine y */
        float *row = px + (size_t)r * w * 3;
        for (uint32_t i = 0; i < w; i++) {
            /* engine e = (x, z, −y) of Blender (st cφ, st sφ, ct) */
            const double dot = axis[0] * st * cp[2 * i] + axis[1] * ct - axis[2] * st * cp[2 * i + 1];
            row[3 * i] = hemi;
            row[3 * i + 1] = (float)fmax(0.0, dot);
            row[3 * i + 2] = 0.75f;
        }
    }
    free(cp);
    double out[75];
    pb_error err = {0};
    const double t0 = tu_now_seconds();
    TU_CHECK_EQ_INT(project(px, w, h, 3, 4, out, &err), PB_SUCCESS);
    printf("  8192x4096 L=4 projection: %.2f s\n", tu_now_seconds() - t0);
    free(px);
    const double up[3] = {0, 1, 0};
    const double lam_h[5] = {2 * REF_PI * 4.0, REF_PI * 2.0, 0.0, -REF_PI / 4 * 2.0, 0.0};
    double worst = 0.0;
    for (int l = 0; l <= 4; l++)
        for (int m = -l; m <= l; m++) {
            const int q = l * l + l + m;
            const double want[3] = {lam_h[l] * ref_sh(l, m, up), ref_lambert(l) * ref_sh(l, m, axis),
                                    q == 0 ? 0.75 * 2 * sqrt(REF_PI) : 0.0};
            for (int k = 0; k < 3; k++) {
                const double l00 = k == 0   ? 8 * REF_PI * ref_sh(0, 0, up)
                                   : k == 1 ? REF_PI * ref_sh(0, 0, up)
                                            : 0.75 * 2 * sqrt(REF_PI);
                TU_CHECK_NEAR(out[q * 3 + k], want[k], 1e-6 * l00);
                worst = fmax(worst, fabs(out[q * 3 + k] - want[k]) / l00);
            }
        }
    printf("  max error / L00 = %.2e\n", worst);
}

/* Dynamic range: a dim sky of 1e-6 everywhere plus a 2×2-pixel sun of 1e6 (12 decades in one image).
 * Sun part = Σ P Ω Y(e) over its pixels (single-pixel closed form); sky part = constant closed form.
 * Subtracting the exact sun part, the sky's L_00 (≈3.5e-6 beside the sun's ≈10) must come back to
 * 1e-6 relative: a float accumulator would lose it entirely. */
static void test_dynamic_range(void)
{
    const uint32_t w = 1024, h = 512;
    const float sky = 1e-6f, sun = 1e6f;
    float *px = malloc(sizeof(float) * w * h * 3);
    TU_REQUIRE(px);
    for (size_t q = 0; q < (size_t)w * h * 3; q++) px[q] = sky;
    const uint32_t si = 300, sr = 100;
    double sun_part[75] = {0};
    for (uint32_t r = sr; r < sr + 2; r++)
        for (uint32_t i = si; i < si + 2; i++) {
            double e[3], y[25];
            ref_pixel_dir_engine(i, r, w, h, e);
            ref_basis(4, e, y);
            for (int k = 0; k < 3; k++) px[((size_t)r * w + i) * 3 + k] = sun;
            for (int q = 0; q < 25; q++)
                for (int k = 0; k < 3; k++)
                    sun_part[q * 3 + k] += ((double)sun - (double)sky) * ref_pixel_solid_angle(r, w, h) * y[q];
        }
    double out[75];
    pb_error err = {0};
    TU_CHECK_EQ_INT(project(px, w, h, 3, 4, out, &err), PB_SUCCESS);
    free(px);
    for (int k = 0; k < 3; k++) {
        const double sky00 = out[k] - sun_part[k];
        TU_CHECK_REL(sky00, (double)sky * 2 * sqrt(REF_PI), 1e-6);
        for (int q = 1; q < 25; q++) {
            /* sun part to 1e-12 relative; sky's l > 0 terms are discretisation, ≤ 0.5 (π/H)² sky */
            TU_CHECK_NEAR(out[q * 3 + k] - sun_part[q * 3 + k], 0.0,
                          1e-12 * fabs(sun_part[k]) + 0.5 * pow(REF_PI / h, 2) * sky);
        }
    }
    printf("  sky L00 recovered: %.9e (closed form %.9e)\n", out[0] - sun_part[0], (double)sky * 2 * sqrt(REF_PI));
}

/* NaN/±Inf anywhere in RGB is an error naming (x, y, channel) under every negative policy; a NaN in
 * an unused channel (alpha) is not radiance and is ignored. */
static void test_non_finite(void)
{
    const uint32_t w = 32, h = 16, ch = 4;
    float *px = malloc(sizeof(float) * w * h * ch);
    TU_REQUIRE(px);
    for (uint32_t q = 0; q < w * h * ch; q++) px[q] = 1.0f;
    const float bad[3] = {NAN, INFINITY, -INFINITY};
    const char *names[3] = {"nan", "inf", "-inf"};
    for (int b = 0; b < 3; b++)
        for (int pol = 0; pol < 3; pol++) {
            px[((size_t)7 * w + 5) * ch + 1] = bad[b];
            double out[75];
            pb_error err = {0};
            pb_sh_project_desc d = {.pixels = px,
                                    .width = w,
                                    .height = h,
                                    .channels = ch,
                                    .max_band = 2,
                                    .negative = (pb_negative_policy)pol};
            TU_CHECK_EQ_INT(pb_sh_project_equirect(&d, out, &err), PB_ERROR_NON_FINITE);
            TU_CHECK_CONTAINS(err.message, "pixel (x=5, y=7), channel 1 (G)");
            TU_CHECK_CONTAINS(err.message, names[b]);
            px[((size_t)7 * w + 5) * ch + 1] = 1.0f;
        }
    /* The first offending pixel in scan order is named. */
    px[((size_t)9 * w + 2) * ch + 0] = NAN;
    px[((size_t)9 * w + 20) * ch + 2] = NAN;
    px[((size_t)12 * w + 1) * ch + 0] = NAN;
    double out[75], ref[75];
    pb_error err = {0};
    TU_CHECK_EQ_INT(project(px, w, h, ch, 2, out, &err), PB_ERROR_NON_FINITE);
    TU_CHECK_CONTAINS(err.message, "pixel (x=2, y=9), channel 0 (R)");
    px[((size_t)9 * w + 2) * ch + 0] = 1.0f;
    px[((size_t)9 * w + 20) * ch + 2] = 1.0f;
    px[((size_t)12 * w + 1) * ch + 0] = 1.0f;
    pb_error e2 = {0};
    TU_CHECK_EQ_INT(project(px, w, h, ch, 2, ref, &e2), PB_SUCCESS);
    px[((size_t)3 * w + 3) * ch + 3] = NAN; /* alpha */
    TU_CHECK_EQ_INT(project(px, w, h, ch, 2, out, &e2), PB_SUCCESS);
    for (int q = 0; q < 27; q++) TU_CHECK(out[q] == ref[q]);
    free(px);
}

/* Negative radiance: ERROR names the pixel; CLAMP equals the image with that value set to 0;
 * ALLOW equals the base plus the single-pixel closed form of the negative value. */
static void test_negative_policies(void)
{
    const uint32_t w = 32, h = 16, ch = 3;
    float *px = malloc(sizeof(float) * w * h * ch);
    TU_REQUIRE(px);
    uint64_t rng = 5;
    for (uint32_t q = 0; q < w * h * ch; q++) px[q] = (float)ref_rand01(&rng);
    const size_t at = ((size_t)4 * w + 3) * ch + 2;
    const float orig = px[at];
    px[at] = 0.0f;
    double zeroed[75];
    pb_error err = {0};
    TU_CHECK_EQ_INT(project(px, w, h, ch, 4, zeroed, &err), PB_SUCCESS);
    px[at] = -2.0f;
    double out[75];
    TU_CHECK_EQ_INT(project(px, w, h, ch, 4, out, &err), PB_ERROR_NEGATIVE);
    TU_CHECK_CONTAINS(err.message, "pixel (x=3, y=4), channel 2 (B)");
    TU_CHECK_CONTAINS(err.message, "-2");

    pb_sh_project_desc d = {
        .pixels = px, .width = w, .height = h, .channels = ch, .max_band = 4, .negative = PB_NEGATIVE_CLAMP};
    pb_error e2 = {0};
    TU_CHECK_EQ_INT(pb_sh_project_equirect(&d, out, &e2), PB_SUCCESS);
    for (int q = 0; q < 75; q++) TU_CHECK_NEAR(out[q], zeroed[q], 1e-14);

    d.negative = PB_NEGATIVE_ALLOW;
    TU_CHECK_EQ_INT(pb_sh_project_equirect(&d, out, &e2), PB_SUCCESS);
    double e[3], y[25];
    ref_pixel_dir_engine(3, 4, w, h, e);
    ref_basis(4, e, y);
    const double om = ref_pixel_solid_angle(4, w, h);
    for (int q = 0; q < 25; q++) {
        TU_CHECK_NEAR(out[q * 3 + 0], zeroed[q * 3 + 0], 1e-14);
        TU_CHECK_NEAR(out[q * 3 + 2], zeroed[q * 3 + 2] - 2.0 * om * y[q], 1e-14);
    }
    px[at] = orig;
    free(px);
}

/* Every argument is validated with a message naming the problem. */
static void test_invalid_arguments(void)
{
    float px[20 * 10 * 4] = {0};
    double out[75];
    const pb_sh_project_desc ok = {.pixels = px, .width = 20, .height = 10, .channels = 4, .max_band = 4};
    pb_sh_project_desc d;
    pb_error err;

#define EXPECT_FAIL(desc_ptr, out_ptr, code, text)                                                                     \
    do {                                                                                                               \
        err = (pb_error){0};                                                                                           \
        TU_CHECK_EQ_INT(pb_sh_project_equirect(desc_ptr, out_ptr, &err), code);                                        \
        TU_CHECK_CONTAINS(err.message, text);                                                                          \
    } while (0)

    EXPECT_FAIL(NULL, out, PB_ERROR_INVALID_ARGUMENT, "desc is NULL");
    EXPECT_FAIL(&ok, NULL, PB_ERROR_INVALID_ARGUMENT, "out is NULL");
    d = ok, d.pixels = NULL;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "pixels is NULL");
    d = ok, d.max_band = 5;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "max_band 5");
    d = ok, d.channels = 2;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "2 channel(s)");
    d = ok, d.channels = 1;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "1 channel(s)");
    d = ok, d.width = 0;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "empty panorama");
    d = ok, d.row_stride = 79;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "row_stride 79");
    d = ok, d.negative = (pb_negative_policy)7;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "negative policy 7");
    d = ok, d.width = UINT32_MAX, d.height = UINT32_MAX, d.channels = UINT32_MAX;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "overflow");
    d = ok, d.width = UINT32_MAX, d.height = UINT32_MAX, d.channels = 4;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "overflow");
    const double scaled[9] = {2, 0, 0, 0, 2, 0, 0, 0, 2};
    d = ok, d.rotation = scaled;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "not orthonormal");
    const double nanrot[9] = {1, 0, 0, 0, NAN, 0, 0, 0, 1};
    d = ok, d.rotation = nanrot;
    EXPECT_FAIL(&d, out, PB_ERROR_INVALID_ARGUMENT, "rotation[4] is not finite");
#undef EXPECT_FAIL
    /* channels 0 = RGBA default; row_stride larger than a row is honoured (padding ignored). */
    float padded[10][20 * 3 + 7];
    for (int r = 0; r < 10; r++)
        for (int q = 0; q < 20 * 3 + 7; q++) padded[r][q] = q < 60 ? 1.0f : NAN;
    d = ok, d.pixels = &padded[0][0], d.channels = 3, d.row_stride = 67;
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_sh_project_equirect(&d, out, &err), PB_SUCCESS);
    TU_CHECK_REL(out[0], 2 * sqrt(REF_PI), 1e-13);
    d = ok, d.channels = 0;
    TU_CHECK_EQ_INT(pb_sh_project_equirect(&d, out, &err), PB_SUCCESS);
}

/* pb_sh_project_file == pb_sh_project_equirect on the same pixels (float EXR is lossless); a
 * two-channel file and a missing file are refused naming the file. */
static void test_project_file(void)
{
    char dir[] = "/tmp/schnee_test_sh_XXXXXX";
    TU_REQUIRE(mkdtemp(dir));
    char path[256], path2[256];
    snprintf(path, sizeof path, "%s/env.exr", dir);
    snprintf(path2, sizeof path2, "%s/two.exr", dir);
    const uint32_t w = 64, h = 32;
    float *px = malloc(sizeof(float) * w * h * 3);
    TU_REQUIRE(px);
    uint64_t rng = 11;
    for (uint32_t q = 0; q < w * h * 3; q++) px[q] = (float)(10.0 * ref_rand01(&rng));
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_image_write(path, w, h, 3, px, &err), PB_SUCCESS);
    double a[75], b[75];
    pb_sh_project_desc d = {.max_band = 4};
    TU_CHECK_EQ_INT(pb_sh_project_file(path, &d, a, &err), PB_SUCCESS);
    TU_CHECK_EQ_INT(project(px, w, h, 3, 4, b, &err), PB_SUCCESS);
    for (int q = 0; q < 75; q++) TU_CHECK(a[q] == b[q]);
    TU_CHECK_EQ_INT(pb_sh_project_file(path, NULL, a, &err), PB_SUCCESS); /* NULL desc = defaults (L=0) */
    TU_CHECK(a[0] == b[0]);

    TU_CHECK_EQ_INT(pb_image_write(path2, w, h, 2, px, &err), PB_SUCCESS);
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_sh_project_file(path2, &d, a, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "2 channel(s)");
    TU_CHECK_CONTAINS(err.message, "two.exr");
    err = (pb_error){0};
    char missing[300];
    snprintf(missing, sizeof missing, "%s/missing.exr", dir);
    TU_CHECK_EQ_INT(pb_sh_project_file(missing, &d, a, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "missing.exr");
    /* A too-small file: the error names the file and the minimum. */
    TU_CHECK_EQ_INT(pb_image_write(path, 8, 4, 3, px, &err), PB_SUCCESS);
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_sh_project_file(path, &d, a, &err), PB_ERROR_TOO_SMALL);
    TU_CHECK_CONTAINS(err.message, "env.exr");
    TU_CHECK_CONTAINS(err.message, "minimum is 10x10");
    free(px);
    unlink(path);
    unlink(path2);
    rmdir(dir);
}

int main(void)
{
    TU_RUN(test_constant);
    TU_RUN(test_single_pixel);
    TU_RUN(test_clamped_cosine);
    TU_RUN(test_hemispheres);
    TU_RUN(test_irradiance_of_constant_env);
    TU_RUN(test_rotation_against_brute_force);
    TU_RUN(test_minimum_size);
    TU_RUN(test_dynamic_range);
    TU_RUN(test_non_finite);
    TU_RUN(test_negative_policies);
    TU_RUN(test_invalid_arguments);
    TU_RUN(test_project_file);
    TU_RUN(test_huge_panorama);
    return TU_EXIT();
}
