/* The ambient cube from radiance SH, and its evaluator. Derivation: docs/ambient-cube.md. */
#include "schnee/pb_ambient_cube.h"
#include "schnee/pb_sh.h"

#include <math.h>
#include <string.h>

#define PB_PI 3.14159265358979323846

/* Basis constants of pb_sh.c (DESIGN.md §3 at full precision). */
#define K00 0.28209479177387814 /* 1/(2√π) */
#define K1  0.4886025119029199  /* √(3/4π) */
#define K2B 0.31539156525252005 /* ¼√(5/π) */
#define K2C 0.5462742152960396  /* ¼√(15/π) */

static const double pb_cube_axes_[PB_AMBIENT_CUBE_FACES][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                                               {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};

static const char *const pb_cube_channels_[3] = {"R", "G", "B"};

/* Least-squares cube (docs/ambient-cube.md §2). With e_i = A_l L_i the irradiance coefficients:
 * - the symmetric part s_i = (C_{+i} + C_{-i})/2 reproduces the diagonal of E's quadratic form
 *   exactly (span{x², y², z²} on the sphere = span{Y0, Y6, Y8}; xy, yz, xz are orthogonal to it);
 * - the antisymmetric part d_i = (C_{+i} − C_{-i})/2 is the projection of the linear term onto
 *   n_i|n_i|: ∫ n_i · n_i|n_i| / ∫ n_i⁴ = π / (4π/5) = 5/4.
 * Bands 3 and 4 drop out exactly (A_3 = 0; the cube basis is even + odd parts of degree ≤ 2 and
 * ⊥ band 4), so only coefficients 0..8 are read. */
static void pb_cube_least_squares_(uint32_t max_band, const double *coeffs, double cube[18])
{
    for (int c = 0; c < 3; c++) {
        double e[9] = {0};
        for (uint32_t i = 0; i < 9 && i < pb_sh_count(max_band); i++) {
            const uint32_t l = i == 0 ? 0u : (i < 4 ? 1u : 2u);
            e[i] = pb_sh_lambert_band(l) * coeffs[i * 3 + c];
        }
        const double s[3] = {K00 * e[0] - K2B * e[6] + K2C * e[8], K00 * e[0] - K2B * e[6] - K2C * e[8],
                             K00 * e[0] + 2.0 * K2B * e[6]};
        const double d[3] = {1.25 * K1 * e[3], 1.25 * K1 * e[1], 1.25 * K1 * e[2]};
        for (int a = 0; a < 3; a++) {
            cube[(2 * a + 0) * 3 + c] = s[a] + d[a];
            cube[(2 * a + 1) * 3 + c] = s[a] - d[a];
        }
    }
}

pb_result pb_ambient_cube_from_sh(uint32_t max_band, const double *coeffs, pb_ambient_cube_fit fit, double cube[18],
                                  pb_error *err)
{
    if (!coeffs || !cube) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "ambient cube: coeffs or cube is NULL");
    if (max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "ambient cube: max band %u is out of range 0..%d", max_band,
                            PB_SH_MAX_BAND);
    if ((unsigned)fit >= (unsigned)PB_AMBIENT_CUBE_FIT_COUNT_)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "ambient cube: unknown fit %d", (int)fit);
    for (uint32_t i = 0; i < pb_sh_count(max_band); i++)
        for (int c = 0; c < 3; c++)
            if (!isfinite(coeffs[i * 3 + c]))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "ambient cube: SH coefficient %u %s is %g", i,
                                    pb_cube_channels_[c], coeffs[i * 3 + c]);
    if (fit == PB_AMBIENT_CUBE_LEAST_SQUARES) {
        pb_cube_least_squares_(max_band, coeffs, cube);
    } else {
        for (int f = 0; f < PB_AMBIENT_CUBE_FACES; f++)
            pb_sh_irradiance(max_band, coeffs, pb_cube_axes_[f], cube + 3 * f);
    }
    return PB_SUCCESS;
}

void pb_ambient_cube_irradiance(const double cube[18], const double n[3], double out_rgb[3])
{
    const double n2[3] = {n[0] * n[0], n[1] * n[1], n[2] * n[2]};
    const int face[3] = {n[0] < 0.0 ? 1 : 0, n[1] < 0.0 ? 3 : 2, n[2] < 0.0 ? 5 : 4};
    for (int c = 0; c < 3; c++)
        out_rgb[c] = n2[0] * cube[face[0] * 3 + c] + n2[1] * cube[face[1] * 3 + c] + n2[2] * cube[face[2] * 3 + c];
}
