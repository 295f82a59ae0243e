/* Ambient cube (pb_ambient_cube.h) against closed forms: the least-squares fit against an
 * independent numerical least-squares solve, and the irradiance of a constant environment, a single
 * directional light and a hemisphere light against the exact irradiance, with the error figures
 * derived in docs/ambient-cube.md §3 (exact fractions; the sympy lines there reproduce the axis-light ones).
 *
 * Error measures (the sweep's, bench/sweep/metrics.py): relative RMS = RMS(E_a − E) / RMS(E) and
 * relative max = max |E_a − E| / RMS(E) over the sphere. RMS by per-octant Gauss–Legendre
 * quadrature (the cube's kinks lie on the octant boundaries), max on a dense latitude–longitude
 * grid that contains the six axis directions. */
#include "schnee/pb_ambient_cube.h"
#include "schnee/pb_sh.h"
#include "test_sh_reference.h"
#include "testutil.h"

#include <stdlib.h>

#define PI 3.14159265358979323846

/* ---- quadrature ------------------------------------------------------------------------------- */

enum { GL_N = 200 }; /* nodes per segment: 2 segments in z × 4 in φ, 1.28 M nodes */
static double gl_x_[GL_N], gl_w_[GL_N];

/* Gauss–Legendre nodes/weights on [−1, 1] by Newton on P_n (independent of the code under test). */
static void gl_init(void)
{
    for (int i = 0; i < GL_N; i++) {
        double x = cos(PI * (i + 0.75) / (GL_N + 0.5)), dp = 1.0;
        for (int it = 0; it < 100; it++) {
            double p0 = 1.0, p1 = x;
            for (int k = 2; k <= GL_N; k++) {
                const double p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            dp = GL_N * (x * p1 - p0) / (x * x - 1.0);
            const double dx = p1 / dp;
            x -= dx;
            if (fabs(dx) < 1e-16) break;
        }
        gl_x_[i] = x;
        gl_w_[i] = 2.0 / ((1.0 - x * x) * dp * dp);
    }
}

typedef void (*sphere_fn)(const double n[3], void *user, double *out);

/* ∫ f dω over the sphere, f returning `k` values: z ∈ [−1,0], [0,1] × φ in four quarters. */
static void integrate(sphere_fn f, void *user, int k, double *acc)
{
    double v[64];
    for (int j = 0; j < k; j++) acc[j] = 0.0;
    for (int zs = 0; zs < 2; zs++)
        for (int a = 0; a < GL_N; a++) {
            const double z = 0.5 * (gl_x_[a] + (zs ? 1.0 : -1.0)), wz = 0.5 * gl_w_[a], s = sqrt(1.0 - z * z);
            for (int q = 0; q < 4; q++)
                for (int b = 0; b < GL_N; b++) {
                    const double phi = (q + 0.5 * (gl_x_[b] + 1.0)) * (PI / 2.0), w = wz * gl_w_[b] * (PI / 4.0);
                    const double n[3] = {s * cos(phi), s * sin(phi), z};
                    f(n, user, v);
                    for (int j = 0; j < k; j++) acc[j] += w * v[j];
                }
        }
}

/* The six basis functions b_{±i}(n) = n_i² where ±n_i > 0, face order of the header. */
static void cube_basis(const double n[3], double b[6])
{
    for (int i = 0; i < 3; i++) {
        b[2 * i] = n[i] > 0 ? n[i] * n[i] : 0.0;
        b[2 * i + 1] = n[i] < 0 ? n[i] * n[i] : 0.0;
    }
}

/* ---- the least-squares fit -------------------------------------------------------------------- */

static void gram_fn(const double n[3], void *user, double *out)
{
    (void)user;
    double b[6];
    cube_basis(n, b);
    for (int j = 0; j < 6; j++)
        for (int k = 0; k < 6; k++) out[j * 6 + k] = b[j] * b[k];
}

/* Gram matrix of the cube basis: 2π/5 on the diagonal, 0 between ±(same axis), π/15 otherwise
 * (∫_{x>0} x⁴ = ½·4π/5; ∫_{x>0,y>0} x²y² = ¼·4π/15). */
static void test_gram_matrix(void)
{
    double g[36];
    integrate(gram_fn, NULL, 36, g);
    for (int j = 0; j < 6; j++)
        for (int k = 0; k < 6; k++) {
            const double want = j == k ? 2.0 * PI / 5.0 : (j / 2 == k / 2 ? 0.0 : PI / 15.0);
            TU_CHECK_NEAR(g[j * 6 + k], want, 1e-12);
        }
}

typedef struct rhs_user {
    uint32_t band;
    const double *coeffs;
} rhs_user;

/* b_j(n) · E_L(n) per face j and channel: the right-hand side of the normal equations. */
static void rhs_fn(const double n[3], void *user, double *out)
{
    const rhs_user *u = user;
    double b[6], e[3];
    cube_basis(n, b);
    pb_sh_irradiance(u->band, u->coeffs, n, e);
    for (int j = 0; j < 6; j++)
        for (int c = 0; c < 3; c++) out[j * 3 + c] = b[j] * e[c];
}

/* Solves G x = r (6×6, three right-hand sides) by Gaussian elimination with partial pivoting. */
static void solve6(double g[36], double r[18])
{
    for (int col = 0; col < 6; col++) {
        int p = col;
        for (int row = col + 1; row < 6; row++)
            if (fabs(g[row * 6 + col]) > fabs(g[p * 6 + col])) p = row;
        for (int k = 0; k < 6; k++) {
            const double t = g[col * 6 + k];
            g[col * 6 + k] = g[p * 6 + k];
            g[p * 6 + k] = t;
        }
        for (int c = 0; c < 3; c++) {
            const double t = r[col * 3 + c];
            r[col * 3 + c] = r[p * 3 + c];
            r[p * 3 + c] = t;
        }
        for (int row = col + 1; row < 6; row++) {
            const double f = g[row * 6 + col] / g[col * 6 + col];
            for (int k = col; k < 6; k++) g[row * 6 + k] -= f * g[col * 6 + k];
            for (int c = 0; c < 3; c++) r[row * 3 + c] -= f * r[col * 3 + c];
        }
    }
    for (int row = 5; row >= 0; row--)
        for (int c = 0; c < 3; c++) {
            double s = r[row * 3 + c];
            for (int k = row + 1; k < 6; k++) s -= g[row * 6 + k] * r[k * 3 + c];
            r[row * 3 + c] = s / g[row * 6 + row];
        }
}

/* The closed-form fit equals the numerical least-squares solution (quadrature Gram matrix and
 * right-hand side ∫ b_j E_L) for random L = 4 coefficients, and bands 3, 4 change nothing:
 * the L = 4 probe's cube equals its L = 2 truncation's (A_3 = 0; b_j ⊥ band 4). Quadrature error
 * ~1e-10 on values of order 1: tolerance 1e-8. */
static void test_least_squares_matches_numerical_fit(void)
{
    uint64_t rng = 777;
    double coeffs[25 * 3];
    for (int i = 0; i < 75; i++) coeffs[i] = 2.0 * ref_rand01(&rng) - 1.0;
    coeffs[0] = coeffs[1] = coeffs[2] = 3.0;
    double g[36], r[18];
    integrate(gram_fn, NULL, 36, g);
    rhs_user u = {4, coeffs};
    integrate(rhs_fn, &u, 18, r);
    solve6(g, r);
    double cube[18], cube2[18];
    TU_REQUIRE(pb_ambient_cube_from_sh(4, coeffs, PB_AMBIENT_CUBE_LEAST_SQUARES, cube, NULL) == PB_SUCCESS);
    TU_REQUIRE(pb_ambient_cube_from_sh(2, coeffs, PB_AMBIENT_CUBE_LEAST_SQUARES, cube2, NULL) == PB_SUCCESS);
    double worst = 0.0;
    for (int i = 0; i < 18; i++) {
        TU_CHECK_NEAR(cube[i], r[i], 1e-8);
        TU_CHECK(cube[i] == cube2[i]);
        worst = fmax(worst, fabs(cube[i] - r[i]));
    }
    printf("  max |closed form - numerical least squares| = %.2e\n", worst);
}

/* ---- error figures ---------------------------------------------------------------------------- */

typedef enum approx_kind { APPROX_CUBE, APPROX_SH } approx_kind;

typedef struct err_user {
    approx_kind kind;
    const double *cube; /* APPROX_CUBE */
    uint32_t band;      /* APPROX_SH */
    const double *coeffs;
    double dir[3];  /* exact E: directional light of unit irradiance along dir ... */
    int hemisphere; /* ... or sky of radiance 1 over y > 0: E = π(1 + n_y)/2 */
} err_user;

static double exact_e(const err_user *u, const double n[3])
{
    if (u->hemisphere) return PI * (1.0 + n[1]) / 2.0;
    return fmax(0.0, n[0] * u->dir[0] + n[1] * u->dir[1] + n[2] * u->dir[2]);
}

static double approx_e(const err_user *u, const double n[3])
{
    double e[3];
    if (u->kind == APPROX_CUBE)
        pb_ambient_cube_irradiance(u->cube, n, e);
    else
        pb_sh_irradiance(u->band, u->coeffs, n, e);
    return e[0]; /* grey tests: the three channels are equal (checked in sq_fn) */
}

static void sq_fn(const double n[3], void *user, double *out)
{
    const err_user *u = user;
    const double t = exact_e(u, n), a = approx_e(u, n);
    out[0] = t * t;
    out[1] = (a - t) * (a - t);
}

/* (relative RMS, relative max, max |E_a − E|) of the approximation in u. */
static void error_figures(err_user *u, double *rel_rms, double *rel_max, double *max_abs)
{
    double acc[2];
    integrate(sq_fn, u, 2, acc);
    const double rms = sqrt(acc[0] / (4.0 * PI));
    enum { NT = 1200, NP = 2400 }; /* θ = πk/NT, φ = 2πj/NP: holds the poles and the six axes */
    double worst = 0.0;
    for (int k = 0; k <= NT; k++) {
        const double th = PI * k / NT;
        for (int j = 0; j < NP; j++) {
            const double ph = 2.0 * PI * j / NP;
            const double n[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
            worst = fmax(worst, fabs(approx_e(u, n) - exact_e(u, n)));
        }
    }
    *rel_rms = sqrt(acc[1] / acc[0]);
    *rel_max = worst / rms;
    *max_abs = worst;
}

/* Radiance SH of a directional light of unit irradiance along d: L_i = Y_i(d), grey. */
static void directional_sh(const double d[3], double coeffs[25 * 3])
{
    double y[25];
    pb_sh_eval_basis(4, d, y);
    for (int i = 0; i < 25; i++) coeffs[i * 3] = coeffs[i * 3 + 1] = coeffs[i * 3 + 2] = y[i];
}

/* Constant radiance c: L_0 = c·√(4π), E ≡ πc. Both fits give C = πc on every face and E_cube ≡ πc
 * exactly (Σ n_i² = 1), at every band. Tolerance: rounding, 1e-12 relative. */
static void test_constant_environment(void)
{
    const double rad[3] = {0.7, 1.3, 2.9};
    uint64_t rng = 99;
    for (uint32_t L = 0; L <= 4; L++)
        for (int fit = 0; fit < 2; fit++) {
            double coeffs[25 * 3] = {0}, cube[18];
            for (int c = 0; c < 3; c++) coeffs[c] = rad[c] * sqrt(4.0 * PI);
            TU_REQUIRE(pb_ambient_cube_from_sh(L, coeffs, (pb_ambient_cube_fit)fit, cube, NULL) == PB_SUCCESS);
            for (int f = 0; f < 6; f++)
                for (int c = 0; c < 3; c++) TU_CHECK_REL(cube[f * 3 + c], PI * rad[c], 1e-12);
            for (int i = 0; i < 200; i++) {
                double n[3], e[3];
                ref_rand_dir(&rng, n);
                pb_ambient_cube_irradiance(cube, n, e);
                for (int c = 0; c < 3; c++) TU_CHECK_REL(e[c], PI * rad[c], 1e-12);
            }
        }
}

/* Single directional light along an axis (here +y, and −z for the symmetry): E = max(0, n·d).
 * docs/ambient-cube.md §3, exact: least-squares cube C = 19/16 (towards the light), −1/16 (away),
 * 3/32 (the four others); relative RMS √10/16 = 19.76 %, max |error| 3/16 at n = d (relative max
 * 3√6/16 = 45.93 %). Valve's axis samples of the L2 SH: 17/16, 1/16, 3/32; relative RMS
 * √370/80 = 24.04 %, max 163/992 (40.25 %). L2 SH itself: √2/16 = 8.84 %, max 3/32 = 9.4 % of the
 * peak: Ramamoorthi & Hanrahan's published 9 % bound for a directional source. Tolerances: 1e-6
 * on coefficients (rounding), 2e-6 on RMS (quadrature), 1e-5 on max (grid spacing 2.6e-3 rad at a
 * smooth maximum; the axis maxima lie on the grid). */
static void test_directional_axis_light(void)
{
    const double dirs[2][3] = {{0, 1, 0}, {0, 0, -1}};
    const int towards[2] = {2, 5}, away[2] = {3, 4};
    for (int t = 0; t < 2; t++) {
        double coeffs[75], ls[18], axis[18];
        directional_sh(dirs[t], coeffs);
        TU_REQUIRE(pb_ambient_cube_from_sh(2, coeffs, PB_AMBIENT_CUBE_LEAST_SQUARES, ls, NULL) == PB_SUCCESS);
        TU_REQUIRE(pb_ambient_cube_from_sh(2, coeffs, PB_AMBIENT_CUBE_AXIS_SAMPLES, axis, NULL) == PB_SUCCESS);
        for (int f = 0; f < 6; f++) {
            const double want_ls = f == towards[t] ? 19.0 / 16.0 : (f == away[t] ? -1.0 / 16.0 : 3.0 / 32.0);
            const double want_ax = f == towards[t] ? 17.0 / 16.0 : (f == away[t] ? 1.0 / 16.0 : 3.0 / 32.0);
            for (int c = 0; c < 3; c++) {
                TU_CHECK_NEAR(ls[f * 3 + c], want_ls, 1e-12);
                TU_CHECK_NEAR(axis[f * 3 + c], want_ax, 1e-12);
            }
        }
        double rms, mx, mabs;
        err_user u = {APPROX_CUBE, ls, 0, NULL, {dirs[t][0], dirs[t][1], dirs[t][2]}, 0};
        error_figures(&u, &rms, &mx, &mabs);
        TU_CHECK_NEAR(rms, sqrt(10.0) / 16.0, 2e-6);
        TU_CHECK_NEAR(mabs, 3.0 / 16.0, 1e-5);
        TU_CHECK_NEAR(mx, 3.0 * sqrt(6.0) / 16.0, 1e-5);
        if (t == 0) printf("  axis light, least squares: rel RMS %.4f %%, rel max %.4f %%\n", 100 * rms, 100 * mx);
        u.cube = axis;
        error_figures(&u, &rms, &mx, &mabs);
        TU_CHECK_NEAR(rms, sqrt(370.0) / 80.0, 2e-6);
        TU_CHECK_NEAR(mabs, 163.0 / 992.0, 1e-5);
        if (t == 0) printf("  axis light, axis samples:  rel RMS %.4f %%, rel max %.4f %%\n", 100 * rms, 100 * mx);
        err_user s = {APPROX_SH, NULL, 2, coeffs, {dirs[t][0], dirs[t][1], dirs[t][2]}, 0};
        error_figures(&s, &rms, &mx, &mabs);
        TU_CHECK_NEAR(rms, sqrt(2.0) / 16.0, 2e-6);
        TU_CHECK_NEAR(mabs, 3.0 / 32.0, 1e-5);
        s.band = 1;
        error_figures(&s, &rms, &mx, &mabs);
        TU_CHECK_NEAR(rms, sqrt(2.0) / 4.0, 2e-6); /* L1 SH: √2/4 = 35.36 %, max 1/4 */
        TU_CHECK_NEAR(mabs, 0.25, 1e-5);
    }
}

/* Directional light along the diagonal (1,1,1)/√3, the cube's worst direction: least squares
 * C = 0.610844 / −0.110844 (towards / away faces), relative RMS √(5/32) = 39.53 %; axis samples of
 * the L2 SH √(7/40) = 41.83 %; L2 SH unchanged by the rotation (√2/16). The light's terminator is
 * not on the octant boundaries here, so the quadrature converges as O(h²): figures converged to
 * 1e-8 by the 1600-node run of docs/ambient-cube.md §3, tolerance 2e-5 at 200 nodes. */
static void test_directional_diagonal_light(void)
{
    const double s = 1.0 / sqrt(3.0), d[3] = {s, s, s};
    double coeffs[75], ls[18], axis[18];
    directional_sh(d, coeffs);
    TU_REQUIRE(pb_ambient_cube_from_sh(2, coeffs, PB_AMBIENT_CUBE_LEAST_SQUARES, ls, NULL) == PB_SUCCESS);
    TU_REQUIRE(pb_ambient_cube_from_sh(2, coeffs, PB_AMBIENT_CUBE_AXIS_SAMPLES, axis, NULL) == PB_SUCCESS);
    /* Closed form: Y6(d) = Y8(d) = 0, so s_i = K00·π·K00 = 1/4; d_i = (5/4)·K1·(2π/3)·K1/√3 = (5/8)/√3. */
    for (int f = 0; f < 6; f++) TU_CHECK_NEAR(ls[f * 3], 0.25 + (f % 2 ? -0.625 : 0.625) / sqrt(3.0), 1e-12);
    double rms, mx, mabs;
    err_user u = {APPROX_CUBE, ls, 0, NULL, {s, s, s}, 0};
    error_figures(&u, &rms, &mx, &mabs);
    TU_CHECK_NEAR(rms, sqrt(5.0 / 32.0), 2e-5);
    printf("  diagonal light, least squares: rel RMS %.4f %%, rel max %.4f %%\n", 100 * rms, 100 * mx);
    u.cube = axis;
    error_figures(&u, &rms, &mx, &mabs);
    TU_CHECK_NEAR(rms, sqrt(7.0 / 40.0), 2e-5);
    printf("  diagonal light, axis samples:  rel RMS %.4f %%, rel max %.4f %%\n", 100 * rms, 100 * mx);
    err_user sh = {APPROX_SH, NULL, 2, coeffs, {s, s, s}, 0};
    error_figures(&sh, &rms, &mx, &mabs);
    TU_CHECK_NEAR(rms, sqrt(2.0) / 16.0, 2e-5);
}

/* Sky of radiance 1 over the upper hemisphere (y > 0): E(n) = π(1 + n_y)/2 exactly, and its exact
 * radiance SH to L = 2 is L_0 = 2π·Y_0, L_1 (y) = π·K_1 (every other coefficient integrates to 0
 * over the half-sphere), so L2 SH is exact here. docs/ambient-cube.md §3: least squares
 * C = π/2 (x, z faces), 9π/8 (+y), −π/8 (−y), relative RMS 1/8 = 12.5 %; axis samples C = π/2, π,
 * 0, relative RMS √10/20 = 15.81 %; both max |error| π/8 (relative √3/8 = 21.65 %). */
static void test_hemisphere_light(void)
{
    double coeffs[27] = {0}, ls[18], axis[18];
    for (int c = 0; c < 3; c++) {
        coeffs[c] = 2.0 * PI * 0.28209479177387814;
        coeffs[3 + c] = PI * 0.4886025119029199;
    }
    TU_REQUIRE(pb_ambient_cube_from_sh(2, coeffs, PB_AMBIENT_CUBE_LEAST_SQUARES, ls, NULL) == PB_SUCCESS);
    TU_REQUIRE(pb_ambient_cube_from_sh(2, coeffs, PB_AMBIENT_CUBE_AXIS_SAMPLES, axis, NULL) == PB_SUCCESS);
    const double want_ls[6] = {PI / 2, PI / 2, 9 * PI / 8, -PI / 8, PI / 2, PI / 2};
    const double want_ax[6] = {PI / 2, PI / 2, PI, 0, PI / 2, PI / 2};
    for (int f = 0; f < 6; f++) {
        TU_CHECK_NEAR(ls[f * 3 + 1], want_ls[f], 1e-12);
        TU_CHECK_NEAR(axis[f * 3 + 1], want_ax[f], 1e-12);
    }
    double rms, mx, mabs;
    err_user u = {APPROX_CUBE, ls, 0, NULL, {0, 0, 0}, 1};
    error_figures(&u, &rms, &mx, &mabs);
    TU_CHECK_NEAR(rms, 0.125, 2e-6);
    TU_CHECK_NEAR(mabs, PI / 8, 1e-5);
    TU_CHECK_NEAR(mx, sqrt(3.0) / 8, 1e-5);
    u.cube = axis;
    error_figures(&u, &rms, &mx, &mabs);
    TU_CHECK_NEAR(rms, sqrt(10.0) / 20.0, 2e-6);
    TU_CHECK_NEAR(mabs, PI / 8, 1e-5);
    err_user sh = {APPROX_SH, NULL, 2, coeffs, {0, 0, 0}, 1};
    error_figures(&sh, &rms, &mx, &mabs);
    TU_CHECK_NEAR(rms, 0.0, 1e-12);
}

/* The fit is linear in the SH, so the cube of an interpolated probe equals the interpolation of the
 * cubes: the engine may interpolate cubes with the SH interpolation weights. Rounding: 1e-12. */
static void test_linear_in_sh(void)
{
    uint64_t rng = 4242;
    double a[75], b[75], mix[75], ca[18], cb[18], cm[18];
    for (int i = 0; i < 75; i++) {
        a[i] = 2.0 * ref_rand01(&rng) - 1.0;
        b[i] = 2.0 * ref_rand01(&rng) - 1.0;
        mix[i] = 0.3 * a[i] + 0.7 * b[i];
    }
    for (int fit = 0; fit < 2; fit++) {
        TU_REQUIRE(pb_ambient_cube_from_sh(4, a, (pb_ambient_cube_fit)fit, ca, NULL) == PB_SUCCESS);
        TU_REQUIRE(pb_ambient_cube_from_sh(4, b, (pb_ambient_cube_fit)fit, cb, NULL) == PB_SUCCESS);
        TU_REQUIRE(pb_ambient_cube_from_sh(4, mix, (pb_ambient_cube_fit)fit, cm, NULL) == PB_SUCCESS);
        for (int i = 0; i < 18; i++) TU_CHECK_NEAR(cm[i], 0.3 * ca[i] + 0.7 * cb[i], 1e-12);
    }
}

/* Invalid input: a clear error, nothing written past the output. */
static void test_errors(void)
{
    double coeffs[75] = {1.0}, cube[18];
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_ambient_cube_from_sh(2, NULL, 0, cube, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "NULL");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_ambient_cube_from_sh(5, coeffs, 0, cube, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "max band 5");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_ambient_cube_from_sh(2, coeffs, (pb_ambient_cube_fit)7, cube, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "unknown fit 7");
    err = (pb_error){0};
    coeffs[3 * 4 + 2] = NAN;
    TU_CHECK_EQ_INT(pb_ambient_cube_from_sh(2, coeffs, 0, cube, &err), PB_ERROR_NON_FINITE);
    TU_CHECK_CONTAINS(err.message, "coefficient 4 B is nan");
    /* A NaN past the band is not read. */
    TU_CHECK_EQ_INT(pb_ambient_cube_from_sh(1, coeffs, 0, cube, NULL), PB_SUCCESS);
}

int main(void)
{
    gl_init();
    TU_RUN(test_gram_matrix);
    TU_RUN(test_least_squares_matches_numerical_fit);
    TU_RUN(test_constant_environment);
    TU_RUN(test_directional_axis_light);
    TU_RUN(test_directional_diagonal_light);
    TU_RUN(test_hemisphere_light);
    TU_RUN(test_linear_in_sh);
    TU_RUN(test_errors);
    return TU_EXIT();
}
