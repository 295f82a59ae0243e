/* Independent SH reference for the tests: the real basis from the associated-Legendre recurrence
 * (√2·K·P_l^|m|(cos θ)·trig(|m|φ), no Condon–Shortley phase), the Cycles equirect mapping and the
 * Blender → engine conversion written out from DESIGN.md §2–3, and exact pixel solid angles.
 * Deliberately shares no code with native/src/pb_sh.c. */
#ifndef SCHNEE_TEST_SH_REFERENCE_H
#define SCHNEE_TEST_SH_REFERENCE_H

#include <math.h>
#include <stdint.h>

#define REF_PI 3.14159265358979323846

/* Associated Legendre P_l^m(x), m >= 0, WITHOUT the Condon–Shortley (−1)^m. */
static inline double ref_legendre(int l, int m, double x)
{
    double pmm = 1.0;
    const double s = sqrt(fmax(0.0, (1.0 - x) * (1.0 + x)));
    for (int i = 1; i <= m; i++) pmm *= (2.0 * i - 1.0) * s; /* (2m−1)!! s^m */
    if (l == m) return pmm;
    double pm1 = x * (2.0 * m + 1.0) * pmm;
    if (l == m + 1) return pm1;
    double pl = 0.0;
    for (int ll = m + 2; ll <= l; ll++) {
        pl = ((2.0 * ll - 1.0) * x * pm1 - (ll + m - 1.0) * pmm) / (ll - m);
        pmm = pm1;
        pm1 = pl;
    }
    return pl;
}

static inline double ref_factorial(int n)
{
    double f = 1.0;
    for (int i = 2; i <= n; i++) f *= i;
    return f;
}

/* Y_lm at unit direction d (engine space), index l*l + l + m. */
static inline double ref_sh(int l, int m, const double d[3])
{
    const int am = m < 0 ? -m : m;
    const double k = sqrt((2.0 * l + 1.0) / (4.0 * REF_PI) * ref_factorial(l - am) / ref_factorial(l + am));
    const double z = fmax(-1.0, fmin(1.0, d[2]));
    const double phi = atan2(d[1], d[0]);
    const double p = ref_legendre(l, am, z);
    if (m == 0) return k * p;
    if (m > 0) return sqrt(2.0) * k * p * cos(am * phi);
    return sqrt(2.0) * k * p * sin(am * phi);
}

static inline void ref_basis(int max_band, const double d[3], double *out)
{
    for (int l = 0; l <= max_band; l++)
        for (int m = -l; m <= l; m++) out[l * l + l + m] = ref_sh(l, m, d);
}

/* DESIGN.md §3: Cycles equirect pixel (i, r) of W×H → Blender world direction. */
static inline void ref_pixel_dir_blender(uint32_t i, uint32_t r, uint32_t w, uint32_t h, double d[3])
{
    const double phi = REF_PI - 2.0 * REF_PI * (i + 0.5) / w;
    const double theta = REF_PI * (r + 0.5) / h;
    d[0] = sin(theta) * cos(phi);
    d[1] = sin(theta) * sin(phi);
    d[2] = cos(theta);
}

/* DESIGN.md §2: Blender (x, y, z) → engine (x, z, −y). */
static inline void ref_blender_to_engine(const double b[3], double e[3])
{
    e[0] = b[0];
    e[1] = b[2];
    e[2] = -b[1];
}

static inline void ref_pixel_dir_engine(uint32_t i, uint32_t r, uint32_t w, uint32_t h, double e[3])
{
    double b[3];
    ref_pixel_dir_blender(i, r, w, h, b);
    ref_blender_to_engine(b, e);
}

/* Exact solid angle of a pixel in row r: Δφ·(cos θ_top − cos θ_bottom). */
static inline double ref_pixel_solid_angle(uint32_t r, uint32_t w, uint32_t h)
{
    return (2.0 * REF_PI / w) * (cos(REF_PI * r / h) - cos(REF_PI * (r + 1.0) / h));
}

/* Lambert kernel A_l = 2π ∫₀¹ P_l(t) t dt for l ≤ 4, in closed form (Ramamoorthi–Hanrahan). */
static inline double ref_lambert(int l)
{
    static const double a[5] = {REF_PI, 2.0 * REF_PI / 3.0, REF_PI / 4.0, 0.0, -REF_PI / 24.0};
    return a[l];
}

/* Gauss–Legendre nodes/weights on [−1, 1] by Newton iteration on P_n (n ≤ 64). */
static inline void ref_gauss_legendre(int n, double *x, double *w)
{
    for (int i = 0; i < n; i++) {
        double z = cos(REF_PI * (i + 0.75) / (n + 0.5)), dp = 1.0;
        for (int it = 0; it < 100; it++) {
            double p0 = 1.0, p1 = z;
            for (int k = 2; k <= n; k++) {
                const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
                p0 = p1;
                p1 = p2;
            }
            const double pn = n == 0 ? 1.0 : (n == 1 ? z : p1);
            const double pn1 = n == 1 ? 1.0 : p0;
            dp = n * (z * pn - pn1) / (z * z - 1.0);
            const double dz = pn / dp;
            z -= dz;
            if (fabs(dz) < 1e-16) break;
        }
        x[i] = z;
        w[i] = 2.0 / ((1.0 - z * z) * dp * dp);
    }
}

/* Deterministic uniform random unit vectors (LCG; tests must not depend on libc rand). */
static inline double ref_rand01(uint64_t *state)
{
    *state = *state * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*state >> 11) * (1.0 / 9007199254740992.0);
}

static inline void ref_rand_dir(uint64_t *state, double d[3])
{
    const double z = 2.0 * ref_rand01(state) - 1.0, a = 2.0 * REF_PI * ref_rand01(state);
    const double s = sqrt(1.0 - z * z);
    d[0] = s * cos(a);
    d[1] = s * sin(a);
    d[2] = z;
}

#endif
