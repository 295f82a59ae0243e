/* Schnee probes — the ambient cube (Valve's six-colour irradiance basis) derived from a probe's SH.
 *
 * How to use it:
 *   1. Have a probe's radiance SH (DESIGN.md §3: L_i = ∫ L(ω) Y_i(ω) dω, engine space, RGB,
 *      coefficient-major `double[count * 3]`), e.g. from pb_sh_project_equirect or a .shprobe file.
 *   2. pb_ambient_cube_from_sh(max_band, coeffs, PB_AMBIENT_CUBE_LEAST_SQUARES, cube, &err) gives the
 *      six colours C_{+x}, C_{-x}, C_{+y}, C_{-y}, C_{+z}, C_{-z} (face-major RGB, `double[18]`).
 *   3. pb_ambient_cube_irradiance(cube, n, rgb) evaluates E_cube(n) = Σ_i n_i² C_{sign(n_i) i} for a
 *      unit normal n in engine space; shade as DESIGN.md §3 with E replaced:
 *      diffuse = albedo · (shScale · max(E_cube(n), 0) / π + ambientTerm).
 *
 * The colours are irradiance (W/m², the units of E), not radiance. The least-squares fit is the one
 * the project ships (docs/ambient-cube.md derives it and measures both fits): it minimises
 * ∫ (E − E_cube)² dω over the sphere, depends only on bands 0..2 (bands 3 and 4 contribute exactly
 * nothing: A_3 = 0 and the cube basis is orthogonal to band 4), and is therefore the least-squares
 * cube of the true irradiance whenever the probe holds L ≥ 2. The cube is linear in the SH, so
 * interpolating cubes between probes equals the cube of the interpolated SH.
 * shaders/ambient_cube.glsl mirrors pb_ambient_cube_irradiance line by line.
 */
#ifndef SCHNEE_PB_AMBIENT_CUBE_H
#define SCHNEE_PB_AMBIENT_CUBE_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Six faces, in this order (engine space, Vulkan cube-map order): +X, −X, +Y, −Y, +Z, −Z. */
#define PB_AMBIENT_CUBE_FACES 6

typedef enum pb_ambient_cube_fit {
    /* default: least-squares fit of the six colours to the irradiance over the sphere (shipped) */
    PB_AMBIENT_CUBE_LEAST_SQUARES = 0,
    /* Valve's definition: C_{±i} = E(±e_i), the probe's SH irradiance at the six axis directions
     * (uses every band the probe holds; kept for comparison, docs/ambient-cube.md) */
    PB_AMBIENT_CUBE_AXIS_SAMPLES,
    PB_AMBIENT_CUBE_FIT_COUNT_
} pb_ambient_cube_fit;

/* Six irradiance colours from radiance SH of band max_band (0..4). coeffs: pb_sh_count(max_band)*3
 * doubles; cube: 18 doubles (face-major RGB, caller-owned). Errors: invalid argument (NULL, band,
 * fit), non-finite value (a NaN/Inf coefficient, named). With max_band < 2 the missing bands count
 * as zero (then the fit is to the band-limited irradiance, not the true one). */
pb_result pb_ambient_cube_from_sh(uint32_t max_band, const double *coeffs, pb_ambient_cube_fit fit, double cube[18],
                                  pb_error *err);

/* E_cube(n) = Σ_i n_i² C_{sign(n_i) i}, RGB, not clamped, for a unit normal n (engine space).
 * n_i = 0 takes the + face (its weight is 0 either way). */
void pb_ambient_cube_irradiance(const double cube[18], const double n[3], double out_rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
