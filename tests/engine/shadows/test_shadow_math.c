/* The shadow maps' fitting math (engine/src/sv_shadow_math.c) on the CPU, no Vulkan.
 *
 * Expected values: closed forms. A sun straight down over the cube [-1, 1]^3 has the basis x = +Z,
 * y = +X, f = -Y (sv_shadow_basis: up = +X when |f.y| > 0.99) and the padded half extent
 * h = 1 + 0.01 * 2 + 1e-3 = 1.021 on every axis, so its matrix is written out entry by entry; the
 * practical cascade split is d_i = 0.9 n (f/n)^(i/C) + 0.1 (n + (f - n) i/C); every fit must put what
 * it was fitted to (the scene's corners, a view slice's corners, a box under a lamp) inside Vulkan's
 * clip volume, x, y in [-1, 1] and z in [0, 1] after the divide by w. Tolerances: float32 rounding of
 * values of order 1 (1e-6), and 1e-5 on the clip bounds (products of a few float32 values). */
#include "sv_shadow_math.h"
#include "testutil.h"

#include <math.h>
#include <stdlib.h>

/* Column-major m times (p, 1): clip coordinates. */
static void transform(const float m[16], const float p[3], double clip[4])
{
    for (int r = 0; r < 4; ++r) clip[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
}

/* p lands inside the clip volume (x, y in [-1, 1], z in [0, 1], w > 0), within eps. */
static void check_inside(const float m[16], const float p[3], double eps)
{
    double c[4];
    transform(m, p, c);
    TU_CHECK(c[3] > 0.0);
    if (c[3] <= 0.0) return;
    double x = c[0] / c[3], y = c[1] / c[3], z = c[2] / c[3];
    TU_CHECK(fabs(x) <= 1.0 + eps && fabs(y) <= 1.0 + eps);
    TU_CHECK(z >= -eps && z <= 1.0 + eps);
    if (!(fabs(x) <= 1.0 + eps && fabs(y) <= 1.0 + eps && z >= -eps && z <= 1.0 + eps))
        fprintf(stderr, "  (%g, %g, %g) -> clip (%g, %g, %g)\n", p[0], p[1], p[2], x, y, z);
}

static void box_corner(const float lo[3], const float hi[3], int c, float p[3])
{
    for (int k = 0; k < 3; ++k) p[k] = (c >> k) & 1 ? hi[k] : lo[k];
}

static uint32_t rng_state = 12345u;
static float rnd(float a, float b) /* uniform in [a, b) (an LCG: reproducible) */
{
    rng_state = rng_state * 1664525u + 1013904223u;
    return a + (b - a) * (float)(rng_state >> 8) / 16777216.0f;
}

/* The symmetric case: the closed-form matrix and params of a sun straight down over [-1, 1]^3. */
static void test_ortho_straight_down_closed_form(void)
{
    const float lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1}, dir[3] = {0, -1, 0};
    float m[16], params[4];
    sv_shadow_fit_ortho(dir, lo, hi, 1024, m, params);
    const double h = 1.021, depth = 2.0 * h;
    const double expected[16] = {0, 1 / h, 0, 0, 0, 0, -1 / depth, 0, 1 / h, 0, 0, 0, 0, 0, 0.5, 1};
    for (int i = 0; i < 16; ++i) TU_CHECK_NEAR(m[i], expected[i], 1e-6);
    TU_CHECK_NEAR(params[0], 2.0 * h / 1024.0, 1e-9); /* texel size in metres */
    TU_CHECK_NEAR(params[1], 1.0 / depth, 1e-6);      /* 1 / depth range */
    TU_CHECK_NEAR(params[2], 1.0 / 1024.0, 1e-12);
    TU_CHECK_EQ_INT((int)params[3], SV_SHADOW_ORTHO);
    /* the top of the cube is nearest the sun (z = 0 side), the bottom farthest */
    double top[4], bottom[4];
    transform(m, (const float[3]){0, 1, 0}, top);
    transform(m, (const float[3]){0, -1, 0}, bottom);
    TU_CHECK_NEAR(top[2], 0.5 - 1.0 / depth, 1e-6);
    TU_CHECK_NEAR(bottom[2], 0.5 + 1.0 / depth, 1e-6);
}

/* The basis is orthonormal and right-handed for any direction, and degenerate input points down. */
static void test_basis_orthonormal(void)
{
    for (int t = 0; t < 200; ++t) {
        float dir[3] = {rnd(-1, 1), rnd(-1, 1), rnd(-1, 1)}, x[3], y[3], f[3];
        if (t == 0) dir[0] = 0, dir[1] = 5, dir[2] = 0; /* |f.y| > 0.99: the other up vector */
        sv_shadow_basis(dir, x, y, f);
        const float *a[3] = {x, y, f};
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                TU_CHECK_NEAR(a[i][0] * a[j][0] + a[i][1] * a[j][1] + a[i][2] * a[j][2], i == j, 1e-5);
        /* x x y = -f: (x, y, f) spans the light's view with f the depth axis */
        TU_CHECK_NEAR(x[1] * y[2] - x[2] * y[1], -f[0], 1e-5);
    }
    float x[3], y[3], f[3];
    sv_shadow_basis((const float[3]){0, 0, 0}, x, y, f);
    TU_CHECK(f[0] == 0.0f && f[1] == -1.0f && f[2] == 0.0f);
}

/* A sun's single map over random boxes from random directions: all 8 corners inside clip space. */
static void test_ortho_corners_inside(void)
{
    for (int t = 0; t < 500; ++t) {
        float lo[3], hi[3], dir[3] = {rnd(-1, 1), rnd(-1, 1), rnd(-1, 1)};
        for (int k = 0; k < 3; ++k) lo[k] = rnd(-50, 10), hi[k] = lo[k] + rnd(0.01f, 40);
        float m[16], params[4];
        sv_shadow_fit_ortho(dir, lo, hi, 2048, m, params);
        for (int c = 0; c < 8; ++c) {
            float p[3];
            box_corner(lo, hi, c, p);
            check_inside(m, p, 1e-5);
        }
    }
}

/* The practical split against its closed form, ends exact. */
static void test_cascade_split_closed_form(void)
{
    sv_cascade_view cv = {.near = 1.0f, .far = 100.0f};
    TU_CHECK(sv_cascade_split(&cv, 0, 4) == 1.0f);
    TU_CHECK(sv_cascade_split(&cv, 4, 4) == 100.0f);
    for (uint32_t i = 1; i < 4; ++i) {
        double t = i / 4.0, expected = 0.9 * pow(100.0, t) + 0.1 * (1.0 + 99.0 * t);
        TU_CHECK_REL(sv_cascade_split(&cv, i, 4), expected, 1e-6);
    }
    TU_CHECK_REL(sv_cascade_split(&cv, 2, 4), 14.05, 1e-6); /* 0.9 * 10 + 0.1 * 50.5 */
    cv.near = -2.0f; /* an orthographic camera whose near plane is behind it: uniform */
    TU_CHECK_REL(sv_cascade_split(&cv, 1, 2), 49.0, 1e-6);
}

/* A perspective camera inside a scene box that holds its whole view (to 55 m) under an oblique sun:
 * every cascade's view slice (its 8 corners) lies inside that cascade's clip volume, the cascade's centre sits on whole texels, and
 * nearer cascades have finer texels. */
static void test_cascades_cover_their_slices(void)
{
    sv_shadow_camera cam = {.yfov = 0.8f, .znear = 0.1f, .zfar = 100.0f, .camera_pos = {0, 1, 5}};
    /* looking along -Z from (0, 1, 5): view = translate(-eye) */
    const float view[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, -5, 1};
    for (int i = 0; i < 16; ++i) cam.view[i] = view[i];
    const float lo[3] = {-50, -30, -50}, hi[3] = {50, 30, 5.5f}, dir[3] = {0.3f, -1.0f, 0.2f};
    const float aspect = 1.5f;
    const uint32_t count = 4, res = 1024;
    sv_cascade_view cv;
    TU_REQUIRE(sv_cascade_view_fit(&cam, aspect, lo, hi, &cv));
    TU_CHECK_NEAR(cv.near, 0.1, 1e-6);    /* the camera's own near plane (the eye is inside the box) */
    TU_CHECK_NEAR(cv.far, 55.0, 1e-4);    /* the box's far side, z = -50, 55 m ahead */
    TU_CHECK_NEAR(cv.hy, tan(0.4), 1e-6); /* half height per metre of depth */
    TU_CHECK_NEAR(cv.hx, 1.5 * tan(0.4), 1e-6);
    double prev_texel = 0.0;
    for (uint32_t k = 0; k < count; ++k) {
        float m[16], params[4];
        sv_shadow_fit_cascade(dir, lo, hi, &cv, k, count, res, m, params);
        for (int c = 0; c < 8; ++c) {
            float d = sv_cascade_split(&cv, k + (uint32_t)(c >> 2), count);
            float p[3] = {(c & 1 ? 1.0f : -1.0f) * cv.hx * d, 1.0f + (c & 2 ? 1.0f : -1.0f) * cv.hy * d, 5.0f - d};
            check_inside(m, p, 1e-5);
        }
        double texel = params[0];
        TU_CHECK(texel >= prev_texel);
        prev_texel = texel;
        /* m[12] = -c / h with h = texel * res / 2: the centre c is a whole number of texels */
        double centre = -m[12] * texel * res / 2.0, n = centre / texel;
        TU_CHECK_NEAR(n, round(n), 1e-3);
    }
    /* sv_shadow_fit_layers takes the same path for a sun's cascades */
    sv_shadow_layer layers[4];
    float m[4][16], params[4][4], one[16], one_params[4];
    for (uint32_t k = 0; k < 4; ++k)
        layers[k] =
            (sv_shadow_layer){.kind = SV_SHADOW_ORTHO, .dir = {dir[0], dir[1], dir[2]}, .cascade = k, .cascades = 4};
    sv_shadow_fit_layers(layers, 4, 4, &cam, aspect, lo, hi, res, m, params);
    sv_shadow_fit_cascade(dir, lo, hi, &cv, 2, 4, res, one, one_params);
    for (int i = 0; i < 16; ++i) TU_CHECK(m[2][i] == one[i]);
    /* one cascade asked for: the whole scene's fit */
    sv_shadow_fit_layers(layers, 1, 1, &cam, aspect, lo, hi, res, m, params);
    sv_shadow_fit_ortho(dir, lo, hi, res, one, one_params);
    for (int i = 0; i < 16; ++i) TU_CHECK(m[0][i] == one[i]);
}

/* A cube face under a lamp: closed-form w (depth below the lamp) and the box inside the frustum. */
static void test_perspective_cube_face(void)
{
    const float lo[3] = {-1, 0, -1}, hi[3] = {1, 4, 1};
    sv_shadow_layer layer = {.kind = SV_SHADOW_CUBE, .pos = {0, 5, 0}, .dir = {0, -1, 0}, .tan_half = 1.0f};
    float m[16], params[4];
    sv_shadow_fit_perspective(&layer, lo, hi, 512, m, params);
    double c[4];
    transform(m, (const float[3]){0, 0, 0}, c);
    TU_CHECK_NEAR(c[3], 5.0, 1e-6); /* w = depth along the face's axis */
    TU_CHECK_NEAR(c[0], 0.0, 1e-6);
    TU_CHECK_NEAR(c[1], 0.0, 1e-6);
    TU_CHECK_NEAR(params[0], 2.0 * (1.0 + 8.0 / 512.0) / 512.0, 1e-7);
    TU_CHECK_EQ_INT((int)params[3], SV_SHADOW_CUBE);
    for (int k = 0; k < 8; ++k) {
        float p[3];
        box_corner(lo, hi, k, p);
        check_inside(m, p, 1e-5);
    }
    /* near = 0.99 x the lamp's distance to the box (1 m): z/w = 0 there; far = the farthest
     * corner padded (sqrt(27) * 1.01 + 1 mm): z/w = 1 there */
    double near = 0.99, far = sqrt(27.0) * 1.01 + 1e-3;
    transform(m, (const float[3]){0, (float)(5.0 - near), 0}, c);
    TU_CHECK_NEAR(c[2] / c[3], 0.0, 1e-5);
    transform(m, (const float[3]){0, (float)(5.0 - far), 0}, c);
    TU_CHECK_NEAR(c[2] / c[3], 1.0, 1e-5);
}

int main(void)
{
    TU_RUN(test_ortho_straight_down_closed_form);
    TU_RUN(test_basis_orthonormal);
    TU_RUN(test_ortho_corners_inside);
    TU_RUN(test_cascade_split_closed_form);
    TU_RUN(test_cascades_cover_their_slices);
    TU_RUN(test_perspective_cube_face);
    return TU_EXIT();
}
