// Real spherical harmonics of DESIGN.md §3, a line-for-line mirror of native/src/pb_sh.c
// (pb_sh_eval_basis, pb_sh_lambert_band; pb_sh_irradiance's sum is sh_lambert_basis here, summed
// against a probe's coefficients in shading.glsl): no Condon-Shortley phase,
// index i = l*l + l + m, bands 0..4, unit directions in engine space (Y-up).
#ifndef SV_SH_GLSL
#define SV_SH_GLSL

#define SH_PI 3.14159265358979323846

// Y_0 .. Y_{(max_band+1)^2 - 1} at unit direction d; entries past the band are left untouched.
void sh_eval_basis(uint max_band, vec3 d, out float Y[25]) {
    float x = d.x, y = d.y, z = d.z;
    for (int i = 0; i < 25; ++i) Y[i] = 0.0;
    Y[0] = 0.282094792;
    if (max_band < 1u) return;
    Y[1] = 0.488602512 * y;
    Y[2] = 0.488602512 * z;
    Y[3] = 0.488602512 * x;
    if (max_band < 2u) return;
    Y[4] = 1.092548431 * x * y;
    Y[5] = 1.092548431 * y * z;
    Y[6] = 0.315391565 * (3.0 * z * z - 1.0);
    Y[7] = 1.092548431 * x * z;
    Y[8] = 0.546274215 * (x * x - y * y);
    if (max_band < 3u) return;
    Y[9] = 0.590043590 * y * (3.0 * x * x - y * y);
    Y[10] = 2.890611443 * x * y * z;
    Y[11] = 0.457045799 * y * (5.0 * z * z - 1.0);
    Y[12] = 0.373176333 * z * (5.0 * z * z - 3.0);
    Y[13] = 0.457045799 * x * (5.0 * z * z - 1.0);
    Y[14] = 1.445305721 * z * (x * x - y * y);
    Y[15] = 0.590043590 * x * (x * x - 3.0 * y * y);
    if (max_band < 4u) return;
    Y[16] = 2.503342942 * x * y * (x * x - y * y);
    Y[17] = 1.770130770 * y * z * (3.0 * x * x - y * y);
    Y[18] = 0.946174696 * x * y * (7.0 * z * z - 1.0);
    Y[19] = 0.669046544 * y * z * (7.0 * z * z - 3.0);
    Y[20] = 0.105785547 * (35.0 * z * z * z * z - 30.0 * z * z + 3.0);
    Y[21] = 0.669046544 * x * z * (7.0 * z * z - 3.0);
    Y[22] = 0.473087348 * (x * x - y * y) * (7.0 * z * z - 1.0);
    Y[23] = 1.770130770 * x * z * (x * x - 3.0 * y * y);
    Y[24] = 0.625835735 * (x * x * x * x - 6.0 * x * x * y * y + y * y * y * y);
}

// Lambert kernel factor A_l: pi, 2pi/3, pi/4, 0, -pi/24.
float sh_lambert_band(uint l) {
    if (l == 0u) return SH_PI;
    if (l == 1u) return 2.0 * SH_PI / 3.0;
    if (l == 2u) return SH_PI / 4.0;
    if (l == 3u) return 0.0;
    return -SH_PI / 24.0;
}

// A_l Y_i(d) for i < (max_band+1)^2, 0 past it: irradiance E(n) = sum_l A_l sum_m L_lm Y_lm(n) of any
// probe is then sum_i AY[i] c_i, which the probe lookups of shading.glsl (probe_irradiance_basis, the
// one irradiance sum of the engine) sum straight from the probe buffer: no array of coefficients (a
// dynamically indexed local array lives in slow local memory on GPUs).
void sh_lambert_basis(uint max_band, vec3 d, out float AY[25]) {
    sh_eval_basis(max_band, d, AY);
    for (uint i = 0u; i < 25u; ++i) {
        uint l = i < 1u ? 0u : i < 4u ? 1u : i < 9u ? 2u : i < 16u ? 3u : 4u;
        AY[i] = l <= max_band ? sh_lambert_band(l) * AY[i] : 0.0;
    }
}

#endif
