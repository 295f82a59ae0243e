/* SH basis, Lambert factors and irradiance against independent references (test_sh_reference.h). */
#include "schnee/pb_sh.h"
#include "test_sh_reference.h"
#include "testutil.h"

/* pb_sh_eval_basis == √2·K·P_l^|m|(cos θ)·trig(|m|φ) (recurrence) at 2000 random directions plus
 * the poles and axes, L = 0..4. Both are double-precision evaluations of the same function, so the
 * difference is rounding: 1e-13 absolute on values of magnitude ≤ 2.5. */
static void test_basis_matches_recurrence(void)
{
    uint64_t rng = 12345;
    double dirs[2006][3] = {{0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}};
    for (int i = 6; i < 2006; i++) ref_rand_dir(&rng, dirs[i]);
    double worst = 0.0;
    for (uint32_t L = 0; L <= 4; L++)
        for (int i = 0; i < 2006; i++) {
            double got[PB_SH_MAX_COEFFS], want[PB_SH_MAX_COEFFS];
            for (int k = 0; k < PB_SH_MAX_COEFFS; k++) got[k] = 1e300; /* detect unwritten slots */
            pb_sh_eval_basis(L, dirs[i], got);
            ref_basis((int)L, dirs[i], want);
            for (uint32_t k = 0; k < pb_sh_count(L); k++) {
                worst = fmax(worst, fabs(got[k] - want[k]));
                if (fabs(got[k] - want[k]) > 1e-13) {
                    TU_CHECK_NEAR(got[k], want[k], 1e-13);
                    return;
                }
            }
            /* Nothing past the requested band is written. */
            if (L < 4) TU_CHECK(got[pb_sh_count(L)] == 1e300);
        }
    TU_CHECK(worst < 1e-13);
    printf("  max |basis - recurrence| = %.2e\n", worst);
}

/* The DESIGN.md §3 literal values (9 digits) at a couple of directions: catches a sign/ordering slip
 * that a shared misreading could put into both implementations. */
static void test_basis_design_literals(void)
{
    const double x = 0.48, y = -0.6, z = 0.64; /* unit: 0.2304 + 0.36 + 0.4096 = 1 */
    const double d[3] = {x, y, z};
    double v[25];
    pb_sh_eval_basis(4, d, v);
    const double want[25] = {0.282094792,
                             0.488602512 * y,
                             0.488602512 * z,
                             0.488602512 * x,
                             1.092548431 * x * y,
                             1.092548431 * y * z,
                             0.315391565 * (3 * z * z - 1),
                             1.092548431 * x * z,
                             0.546274215 * (x * x - y * y),
                             0.590043590 * y * (3 * x * x - y * y),
                             2.890611443 * x * y * z,
                             0.457045799 * y * (5 * z * z - 1),
                             0.373176333 * z * (5 * z * z - 3),
                             0.457045799 * x * (5 * z * z - 1),
                             1.445305721 * z * (x * x - y * y),
                             0.590043590 * x * (x * x - 3 * y * y),
                             2.503342942 * x * y * (x * x - y * y),
                             1.770130770 * y * z * (3 * x * x - y * y),
                             0.946174696 * x * y * (7 * z * z - 1),
                             0.669046544 * y * z * (7 * z * z - 3),
                             0.105785547 * (35 * z * z * z * z - 30 * z * z + 3),
                             0.669046544 * x * z * (7 * z * z - 3),
                             0.473087348 * (x * x - y * y) * (7 * z * z - 1),
                             1.770130770 * x * z * (x * x - 3 * y * y),
                             0.625835735 * (x * x * x * x - 6 * x * x * y * y + y * y * y * y)};
    /* 9 significant digits in the document: 5e-9 relative on constants ≤ 3. */
    for (int i = 0; i < 25; i++) TU_CHECK_NEAR(v[i], want[i], 2e-8);
}

/* ∫ Y_i Y_j dω = δ_ij by a quadrature exact for the degree ≤ 8 products: 12-point Gauss–Legendre
 * in z × 24 uniform φ (exact to degree 23 in both). Tolerance 1e-13. */
static void test_orthonormality(void)
{
    double gx[12], gw[12];
    ref_gauss_legendre(12, gx, gw);
    double gram[25][25] = {{0}};
    for (int a = 0; a < 12; a++)
        for (int b = 0; b < 24; b++) {
            const double phi = 2.0 * REF_PI * (b + 0.25) / 24.0, s = sqrt(1.0 - gx[a] * gx[a]);
            const double d[3] = {s * cos(phi), s * sin(phi), gx[a]};
            double y[25];
            pb_sh_eval_basis(4, d, y);
            for (int i = 0; i < 25; i++)
                for (int j = 0; j < 25; j++) gram[i][j] += gw[a] * (2.0 * REF_PI / 24.0) * y[i] * y[j];
        }
    double worst = 0.0;
    for (int i = 0; i < 25; i++)
        for (int j = 0; j < 25; j++) worst = fmax(worst, fabs(gram[i][j] - (i == j ? 1.0 : 0.0)));
    TU_CHECK_NEAR(worst, 0.0, 1e-13);
    printf("  max |gram - I| = %.2e\n", worst);
}

/* A_l = 2π ∫₀¹ P_l(t) t dt by 16-point Gauss–Legendre on [0, 1] (exact for degree ≤ 31). */
static void test_lambert_bands(void)
{
    double gx[16], gw[16];
    ref_gauss_legendre(16, gx, gw);
    for (int l = 0; l <= 4; l++) {
        double a = 0.0;
        for (int k = 0; k < 16; k++) {
            const double t = 0.5 * (gx[k] + 1.0);
            a += 0.5 * gw[k] * ref_legendre(l, 0, t) * t;
        }
        a *= 2.0 * REF_PI;
        TU_CHECK_NEAR(pb_sh_lambert_band((uint32_t)l), a, 1e-14);
    }
}

/* Irradiance. (1) constant radiance c: L_00 = c·2√π → E(n) = π·c for every n (closed form).
 * (2) clamped-cosine radiance max(0, ω·a): L_lm = A_l Y_lm(a) (Funk–Hecke), so by the addition
 * theorem E(n) = Σ_l A_l² (2l+1)/(4π) P_l(a·n). Tolerance 1e-12 (rounding only). */
static void test_irradiance_closed_forms(void)
{
    uint64_t rng = 777;
    const double c[3] = {0.25, 1.0, 3.5};
    for (uint32_t L = 0; L <= 4; L++) {
        double coeffs[25 * 3] = {0};
        for (int k = 0; k < 3; k++) coeffs[k] = c[k] * 2.0 * sqrt(REF_PI);
        for (int t = 0; t < 50; t++) {
            double n[3], e[3];
            ref_rand_dir(&rng, n);
            pb_sh_irradiance(L, coeffs, n, e);
            for (int k = 0; k < 3; k++) TU_CHECK_NEAR(e[k], REF_PI * c[k], 1e-12);
        }
    }
    double a[3];
    ref_rand_dir(&rng, a);
    for (uint32_t L = 0; L <= 4; L++) {
        double coeffs[25 * 3];
        for (int l = 0; l <= (int)L; l++)
            for (int m = -l; m <= l; m++)
                for (int k = 0; k < 3; k++)
                    coeffs[(l * l + l + m) * 3 + k] = (k + 1) * ref_lambert(l) * ref_sh(l, m, a);
        for (int t = 0; t < 50; t++) {
            double n[3], e[3];
            ref_rand_dir(&rng, n);
            pb_sh_irradiance(L, coeffs, n, e);
            const double cg = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
            double want = 0.0;
            for (int l = 0; l <= (int)L; l++)
                want += ref_lambert(l) * ref_lambert(l) * (2 * l + 1) / (4.0 * REF_PI) * ref_legendre(l, 0, cg);
            for (int k = 0; k < 3; k++) TU_CHECK_NEAR(e[k], (k + 1) * want, 1e-12);
        }
    }
}

int main(void)
{
    TU_RUN(test_basis_matches_recurrence);
    TU_RUN(test_basis_design_literals);
    TU_RUN(test_orthonormality);
    TU_RUN(test_lambert_bands);
    TU_RUN(test_irradiance_closed_forms);
    return TU_EXIT();
}
