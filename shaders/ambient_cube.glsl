// The ambient cube (docs/ambient-cube.md), a line-for-line mirror of native/src/pb_ambient_cube.c
// (pb_ambient_cube_from_sh with the least-squares fit, pb_ambient_cube_irradiance). Standalone: needs
// no other include. Faces in this order, engine space (Y-up): +X, -X, +Y, -Y, +Z, -Z; the colours
// are irradiance. Shade as DESIGN.md section 3 with E replaced:
//   diffuse = albedo * (shScale * max(ambient_cube_irradiance(cube, n), 0) / pi + ambientTerm).
// Tested against the C code by tests/engine/test_ambient_cube_glsl.py (compute shader on lavapipe).
#ifndef SV_AMBIENT_CUBE_GLSL
#define SV_AMBIENT_CUBE_GLSL

#define AMBIENT_CUBE_PI 3.14159265358979323846

// Basis constants of DESIGN.md section 3.
#define AMBIENT_CUBE_K00 0.282094792
#define AMBIENT_CUBE_K1  0.488602512
#define AMBIENT_CUBE_K2B 0.315391565
#define AMBIENT_CUBE_K2C 0.546274215

// Least-squares cube from radiance SH coeffs[0..(max_band+1)^2) (bands 3 and 4 drop out exactly):
// the symmetric part reproduces the diagonal of E's quadratic form, the antisymmetric part is the
// linear term times 5/4. For an engine that converts at load time; the bake-side C is the reference.
void ambient_cube_from_sh(uint max_band, vec3 coeffs[25], out vec3 cube[6]) {
    vec3 e[9];
    for (uint i = 0u; i < 9u; ++i) {
        uint l = i == 0u ? 0u : (i < 4u ? 1u : 2u);
        float a = l == 0u ? AMBIENT_CUBE_PI : (l == 1u ? 2.0 * AMBIENT_CUBE_PI / 3.0 : AMBIENT_CUBE_PI / 4.0);
        e[i] = i < (max_band + 1u) * (max_band + 1u) ? a * coeffs[i] : vec3(0.0);
    }
    vec3 s[3] = vec3[3](AMBIENT_CUBE_K00 * e[0] - AMBIENT_CUBE_K2B * e[6] + AMBIENT_CUBE_K2C * e[8],
                        AMBIENT_CUBE_K00 * e[0] - AMBIENT_CUBE_K2B * e[6] - AMBIENT_CUBE_K2C * e[8],
                        AMBIENT_CUBE_K00 * e[0] + 2.0 * AMBIENT_CUBE_K2B * e[6]);
    vec3 d[3] = vec3[3](1.25 * AMBIENT_CUBE_K1 * e[3], 1.25 * AMBIENT_CUBE_K1 * e[1], 1.25 * AMBIENT_CUBE_K1 * e[2]);
    for (int a = 0; a < 3; ++a) {
        cube[2 * a + 0] = s[a] + d[a];
        cube[2 * a + 1] = s[a] - d[a];
    }
}

// E_cube(n) = sum_i n_i^2 C_{sign(n_i) i}, RGB, not clamped, for a unit normal n (engine space).
// n_i = 0 takes the + face (its weight is 0 either way).
vec3 ambient_cube_irradiance(vec3 cube[6], vec3 n) {
    vec3 n2 = n * n;
    ivec3 face = ivec3(n.x < 0.0 ? 1 : 0, n.y < 0.0 ? 3 : 2, n.z < 0.0 ? 5 : 4);
    return n2.x * cube[face.x] + n2.y * cube[face.y] + n2.z * cube[face.z];
}

#endif
