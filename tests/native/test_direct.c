/* Direct light (pb_direct.h) against closed forms: zonal SH of a cap rotated onto the lamp's
 * direction, the solid angle of a rectangle, occlusion by edges and walls, extremes, sky tables.
 * Tolerances are stated per check; docs/direct-light.md gives the quadrature error bounds. */
#include "schnee/pb_direct.h"
#include "schnee/pb_sh.h"
#include "testutil.h"

#include <stdlib.h>

#define PI  3.14159265358979323846
#define K00 0.28209479177387814
#define K1  0.4886025119029199
#define K2B 0.31539156525252005

/* Zonal coefficients z_0..z_2 (coefficient of Y_l0 about the axis) → the 9 coefficients of the
 * function rotated onto the unit axis a: f_lm = z_l · √(4π/(2l+1)) · Y_lm(a). */
static void rotate_zonal(const double z[3], const double a[3], double out[9])
{
    double y[9];
    pb_sh_eval_basis(2, a, y);
    for (int l = 0; l < 3; l++)
        for (int i = l * l; i < (l + 1) * (l + 1); i++) out[i] = z[l] * sqrt(4.0 * PI / (2 * l + 1)) * y[i];
}

/* Uniform radiance L over a cap of half-angle with cosine c: z_l = L·2π ∫_c^1 Y_l0(u) du. */
static void cap_zonal(double L, double c, double z[3])
{
    z[0] = L * 2.0 * PI * K00 * (1.0 - c);
    z[1] = L * 2.0 * PI * K1 * 0.5 * (1.0 - c * c);
    z[2] = L * 2.0 * PI * K2B * c * (1.0 - c * c);
}

static pb_light sun(double strength, double angle, const double dir[3])
{
    pb_light l;
    memset(&l, 0, sizeof l);
    l.type = PB_LIGHT_SUN;
    for (int k = 0; k < 3; k++) {
        l.direction[k] = dir[k];
        l.color[k] = strength;
    }
    l.radius = angle;
    return l;
}

static void project(const pb_light *l, uint32_t n, const pb_direct_scene *scene, const double probe[3],
                    uint32_t samples, double out[27])
{
    pb_direct_desc d = {0};
    d.max_band = 2;
    d.samples = samples;
    d.scene = scene;
    memset(out, 0, 27 * sizeof(double));
    pb_error err = {0};
    pb_result r = pb_direct_project(&d, l, n, probe, out, &err);
    TU_CHECK(r == PB_SUCCESS);
    if (r) fprintf(stderr, "%s\n", err.message);
}

static void check_coeffs(const double got[27], const double want[9], double rel_of_l0, const char *what)
{
    const double tol = rel_of_l0 * fabs(want[0]);
    for (int i = 0; i < 9; i++)
        for (int c = 0; c < 3; c++)
            if (!(fabs(got[i * 3 + c] - want[i]) <= tol)) {
                TU_CHECK_NEAR(got[i * 3 + c], want[i], tol);
                fprintf(stderr, "  (%s, coefficient %d)\n", what, i);
                return;
            }
    tu_checks_++;
}

/* A delta sun (angle 0) of strength S from direction −d: L_i = S · Y_i(d), to rounding. */
static void test_delta_sun(void)
{
    const double dir[3] = {0.48, -0.8, 0.36}; /* unit: 0.2304 + 0.64 + 0.1296 */
    const double to_sun[3] = {-0.48, 0.8, -0.36};
    pb_light l = sun(3.0, 0.0, dir);
    double out[27], y[9];
    const double probe[3] = {0, 0, 0};
    project(&l, 1, NULL, probe, 0, out);
    pb_sh_eval_basis(2, to_sun, y);
    for (int i = 0; i < 9; i++) y[i] *= 3.0;
    check_coeffs(out, y, 1e-12, "delta sun");
    TU_CHECK_REL(out[0], 3.0 * K00, 1e-12); /* the 0.846 */
}

/* A sun disc of angle 2α: Cycles' radiance S/(π tan²α cos³θ). Zonal closed forms:
 * z0 = S·K00, z1 = 2S/tan²α · K1 (1/c − 1), z2 = 2S/tan²α · K2B (−3 ln c − tan²α/2), c = cos α. */
static void test_sun_disc(void)
{
    const double angles[3] = {0.00930842267730309 /* 0.5333° */, 0.2, 1.0};
    const double dir[3] = {0.0, -0.6, -0.8};
    const double axis[3] = {0.0, 0.6, 0.8};
    for (int k = 0; k < 3; k++) {
        const double a = 0.5 * angles[k], c = cos(a), t2 = tan(a) * tan(a), S = 5.0;
        const double z[3] = {S * K00, 2.0 * S / t2 * K1 * (1.0 / c - 1.0),
                             2.0 * S / t2 * K2B * (-3.0 * log(c) - 0.5 * t2)};
        double want[9], out[27];
        rotate_zonal(z, axis, want);
        pb_light l = sun(S, angles[k], dir);
        const double probe[3] = {10, 20, 30};
        project(&l, 1, NULL, probe, 256, out);
        /* 256 cells, midpoint in each: error ≤ 1e-4 of L0 up to an 11° disc, 1e-3 for 57°. */
        check_coeffs(out, want, k < 2 ? 1e-4 : 1e-3, "sun disc");
        TU_CHECK_REL(out[0], S * K00, 1e-12); /* energy exact by construction */
    }
}

static pb_light point(double power, double radius, const double pos[3], bool legacy)
{
    pb_light l;
    memset(&l, 0, sizeof l);
    l.type = PB_LIGHT_POINT;
    for (int k = 0; k < 3; k++) {
        l.position[k] = pos[k];
        l.color[k] = power;
    }
    l.direction[1] = -1.0;
    l.radius = radius;
    l.legacy_point = legacy;
    l.spot_cosine = legacy;
    return l;
}

/* Point lamp of power P, radius r at distance d: a cap of radiance P/(4π²r²) and half-angle
 * atan(r/d) (Cycles ≤ 3.6, disc facing the probe) or asin(r/d) (sphere); radius 0: P/(4π d²)·Y. */
static void test_point(void)
{
    const double probe[3] = {1, 2, 3}, axis[3] = {0.6, 0.0, -0.8};
    const double d = 2.5, r = 0.5, P = 100.0;
    const double pos[3] = {probe[0] + d * axis[0], probe[1] + d * axis[1], probe[2] + d * axis[2]};
    for (int legacy = 0; legacy < 2; legacy++) {
        const double c = legacy ? d / hypot(d, r) : sqrt(d * d - r * r) / d;
        double z[3], want[9], out[27];
        cap_zonal(P / (4.0 * PI * PI * r * r), c, z);
        rotate_zonal(z, axis, want);
        pb_light l = point(P, r, pos, legacy);
        project(&l, 1, NULL, probe, 256, out);
        check_coeffs(out, want, 1e-4, legacy ? "point disc" : "point sphere");
        TU_CHECK_REL(out[0], want[0], 1e-12); /* uniform cap: L0 exact by construction */
    }
    double y[9], out[27];
    pb_light l = point(P, 0.0, pos, true);
    project(&l, 1, NULL, probe, 256, out);
    pb_sh_eval_basis(2, axis, y);
    for (int i = 0; i < 9; i++) y[i] *= P / (4.0 * PI * d * d);
    check_coeffs(out, y, 1e-12, "delta point");
}

/* Spot lamp: a delta spot seen at angle γ off its axis inside the blend region gets
 * P/(4π d²) · smoothstep((cos γ − cos(s/2)) / ((1 − cos(s/2))·blend)) · (cos γ, Cycles ≤ 3.6); outside
 * the cone nothing. A spot of radius r aimed at the probe (wide cone, blend 0): legacy radiance
 * L·cos θ over the cap, zonal z_l = L·2π ∫_c^1 Y_l0(u) u du. */
static void test_spot(void)
{
    const double probe[3] = {0, 0, 0}, d = 3.0, P = 50.0;
    const double pos[3] = {0, 0, -d}; /* probe on the lamp's +Z side */
    const double size = 1.0, blend = 0.6, ch = cos(0.5 * size);
    const double gammas[3] = {0.1, 0.45, 0.6};
    for (int g = 0; g < 3; g++) {
        const double gam = gammas[g];
        for (int legacy = 0; legacy < 2; legacy++) {
            pb_light l = point(P, 0.0, pos, legacy);
            l.type = PB_LIGHT_SPOT;
            l.spot_size = size;
            l.spot_blend = blend;
            /* Axis tilted by γ away from the direction lamp → probe (+Z) in the XZ plane. */
            l.direction[0] = sin(gam);
            l.direction[1] = 0.0;
            l.direction[2] = cos(gam);
            double t = (cos(gam) - ch) / ((1.0 - ch) * blend), f;
            if (cos(gam) <= ch)
                f = 0.0;
            else
                f = t >= 1.0 ? 1.0 : t * t * (3.0 - 2.0 * t);
            if (legacy) f *= cos(gam);
            double out[27];
            project(&l, 1, NULL, probe, 0, out);
            const double want0 = P / (4.0 * PI * d * d) * f * K00;
            TU_CHECK_NEAR(out[0], want0, 1e-12 * P);
        }
    }
    /* Radius 0.6 at distance 3, aimed at the probe, cone 170°, blend 0, legacy: L cos θ over the cap. */
    pb_light l = point(P, 0.6, pos, true);
    l.type = PB_LIGHT_SPOT;
    l.spot_size = 170.0 * PI / 180.0;
    l.direction[1] = 0.0;
    l.direction[2] = 1.0;
    const double c = d / hypot(d, 0.6), L = P / (4.0 * PI * PI * 0.36);
    const double z[3] = {L * 2.0 * PI * K00 * 0.5 * (1.0 - c * c), L * 2.0 * PI * K1 * (1.0 - c * c * c) / 3.0,
                         L * 2.0 * PI * K2B * (0.75 * (1.0 - pow(c, 4)) - 0.5 * (1.0 - c * c))};
    const double axis[3] = {0, 0, -1};
    double want[9], out[27];
    rotate_zonal(z, axis, want);
    project(&l, 1, NULL, probe, 256, out);
    check_coeffs(out, want, 1e-4, "spot with radius");
}

/* Rectangle a × b of power P seen head-on from distance h on its axis: L0 = P/(4ab) · K00 · Ω,
 * Ω = 4 asin(ab / √((a² + 4h²)(b² + 4h²))). Also the disk (ellipse a = b): Ω = 2π(1 − h/√(h² + a²/4)). */
static void test_area(void)
{
    const double probe[3] = {0, 0, 0}, P = 80.0;
    const double hs[3] = {3.0, 1.0, 0.2};
    for (int k = 0; k < 3; k++) {
        const double h = hs[k], a = 2.0, b = 1.0;
        pb_light l;
        memset(&l, 0, sizeof l);
        l.type = PB_LIGHT_AREA_RECT;
        l.position[1] = h; /* above the probe, emitting down */
        l.direction[1] = -1.0;
        l.axis_u[0] = 1.0;
        l.size_u = a;
        l.size_v = b;
        for (int c = 0; c < 3; c++) l.color[c] = P;
        const double omega = 4.0 * asin(a * b / sqrt((a * a + 4 * h * h) * (b * b + 4 * h * h)));
        double out[27];
        project(&l, 1, NULL, probe, 256, out);
        /* Midpoint quadrature with the close-range sub-grid: measured < 4e-4 at h = 0.2, stated 1e-3. */
        TU_CHECK_REL(out[0], P / (4.0 * a * b) * K00 * omega, 1e-3);
        /* Behind the lamp (one-sided): nothing. */
        const double below[3] = {0, 2.0 * h, 0};
        project(&l, 1, NULL, below, 256, out);
        for (int i = 0; i < 27; i++) TU_CHECK(out[i] == 0.0);

        l.type = PB_LIGHT_AREA_ELLIPSE;
        l.size_v = a;
        const double omega_disk = 2.0 * PI * (1.0 - h / sqrt(h * h + a * a / 4.0));
        project(&l, 1, NULL, probe, 256, out);
        TU_CHECK_REL(out[0], P / (PI * a * a) * K00 * omega_disk, 1e-3);
    }
}

/* A quad (two triangles) as an occluder mesh. */
static void quad_mesh(double v[12], uint32_t idx[6], const double c0[3], const double e1[3], const double e2[3])
{
    for (int k = 0; k < 3; k++) {
        v[k] = c0[k];
        v[3 + k] = c0[k] + e1[k];
        v[6 + k] = c0[k] + e1[k] + e2[k];
        v[9 + k] = c0[k] + e2[k];
    }
    const uint32_t t[6] = {0, 1, 2, 0, 2, 3};
    memcpy(idx, t, sizeof t);
}

/* Half of a sun disc hidden by an edge through its centre: L0 is exactly half (the sectors pair up
 * across any line through the centre), irradiance of the visible half checked against 0.5·E. A
 * point lamp behind a wall: exactly zero. */
static void test_occlusion(void)
{
    double v[12];
    uint32_t idx[6];
    /* Half-plane x > 0 at height y = 1 (a 100 m quad), sun straight overhead with angle 5°. */
    const double c0[3] = {0, 1, -50}, e1[3] = {50, 0, 0}, e2[3] = {0, 0, 100};
    quad_mesh(v, idx, c0, e1, e2);
    pb_mesh_desc m = {"edge", v, 4, idx, 2};
    pb_direct_scene *scene = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_direct_scene_create(&m, 1, &scene, &err) == PB_SUCCESS);
    const double down[3] = {0, -1, 0}, probe[3] = {0, 0, 0};
    pb_light l = sun(2.0, 5.0 * PI / 180.0, down);
    double out[27], full[27];
    project(&l, 1, scene, probe, 256, out);
    project(&l, 1, NULL, probe, 256, full);
    TU_CHECK_REL(out[0], 0.5 * full[0], 1e-12);
    /* Visible half lies at x < 0: L1x (index 3) negative, |L1x| = (2/3)·tan-ish small; the up
     * component (index 1) half of the full one. */
    TU_CHECK_REL(out[1 * 3], 0.5 * full[1 * 3], 1e-9);
    TU_CHECK(out[3 * 3] < 0.0);
    /* Tilted edge (30° in the plane): still exactly half. */
    const double c1[3] = {-50 * 0.5, 1, -50 * 0.8660254037844386}, f1[3] = {100 * 0.5, 0, 100 * 0.8660254037844386},
                 f2[3] = {50 * 0.8660254037844386, 0, -50 * 0.5};
    double v2[12];
    uint32_t idx2[6];
    quad_mesh(v2, idx2, c1, f1, f2);
    pb_mesh_desc m2 = {"tilted", v2, 4, idx2, 2};
    pb_direct_scene *scene2 = NULL;
    TU_REQUIRE(pb_direct_scene_create(&m2, 1, &scene2, &err) == PB_SUCCESS);
    project(&l, 1, scene2, probe, 256, out);
    TU_CHECK_REL(out[0], 0.5 * full[0], 1e-12);
    pb_direct_scene_destroy(scene2);

    /* Point lamp (radius 0.3) at (0, 3, 0) behind the y = 1 wall: wall covers x in [0, 50] only, so
     * place the lamp at x = 5 where the wall is; the whole cap is hidden: exactly zero. */
    const double pos[3] = {5, 3, 0};
    pb_light pl = point(100.0, 0.3, pos, true);
    project(&pl, 1, scene, probe, 256, out);
    for (int i = 0; i < 27; i++) TU_CHECK(out[i] == 0.0);
    /* The same lamp at x = −5 is in the open: equal to the unoccluded value. */
    pl.position[0] = -5.0;
    project(&pl, 1, scene, probe, 256, out);
    project(&pl, 1, NULL, probe, 256, full);
    for (int i = 0; i < 27; i++) TU_CHECK(out[i] == full[i]);
    pb_direct_scene_destroy(scene);
}

/* Extremes: a sun of 1e5 W/m² stays exact; colour channels independent. */
static void test_extremes(void)
{
    const double dir[3] = {0, -1, 0}, probe[3] = {0, 0, 0};
    pb_light l = sun(1e5, 0.0093, dir);
    l.color[1] = 0.0;
    l.color[2] = 1e-3;
    double out[27];
    project(&l, 1, NULL, probe, 0, out);
    TU_CHECK_REL(out[0], 1e5 * K00, 1e-12);
    TU_CHECK(out[1] == 0.0);
    TU_CHECK_REL(out[2], 1e-3 * K00, 1e-12);
    const double a = 0.5 * 0.0093, t2 = tan(a) * tan(a);
    TU_CHECK_REL(out[1 * 3], 2.0 * 1e5 / t2 * K1 * (1.0 / cos(a) - 1.0), 1e-6); /* z1 of the disc */
}

static void test_invalid(void)
{
    const double dir[3] = {0, -1, 0}, probe[3] = {0, 0, 0};
    pb_light l = sun(1.0, 0.0, dir);
    double out[27] = {0};
    pb_direct_desc d = {0};
    d.max_band = 5;
    pb_error err = {0};
    TU_CHECK(pb_direct_project(&d, &l, 1, probe, out, &err) == PB_ERROR_INVALID_ARGUMENT);
    d.max_band = 2;
    l.color[0] = -1.0;
    pb_error e2 = {0};
    TU_CHECK(pb_direct_project(&d, &l, 1, probe, out, &e2) == PB_ERROR_NEGATIVE);
    l.color[0] = NAN;
    pb_error e3 = {0};
    TU_CHECK(pb_direct_project(&d, &l, 1, probe, out, &e3) == PB_ERROR_NON_FINITE);
    l.color[0] = 1.0;
    l.type = (pb_light_type)17;
    pb_error e4 = {0};
    TU_CHECK(pb_direct_project(&d, &l, 1, probe, out, &e4) == PB_ERROR_INVALID_ARGUMENT);
    for (int i = 0; i < 27; i++) TU_CHECK(out[i] == 0.0); /* nothing added on error */
    pb_direct_scene *s = NULL;
    pb_error e5 = {0};
    TU_CHECK(pb_direct_scene_create(NULL, 0, &s, &e5) == PB_SUCCESS); /* empty: nothing occludes */
    pb_direct_scene_destroy(s);
    const double v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t bad[3] = {0, 1, 3};
    pb_mesh_desc m = {"bad", v, 3, bad, 1};
    pb_error e6 = {0};
    TU_CHECK(pb_direct_scene_create(&m, 1, &s, &e6) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(s == NULL);
}

/* Sky table: summing every cell gives the world's projection (pb_sh_project_equirect) for a world
 * at 8× the panorama's resolution, including one whose whole energy sits in a single texel of
 * radiance 1e30; with a visibility of 1 everywhere pb_direct_add_sky reproduces it, with the lower
 * half of the panorama hidden exactly the table rows of the upper half. */
static void test_sky(void)
{
    enum { WW = 256, WH = 128, PW = 32, PH = 16, N = 9 };
    float *world = calloc((size_t)WW * WH * 4, sizeof(float));
    double *table = malloc(sizeof(double) * PW * PH * N * 3);
    float *vis = malloc(sizeof(float) * PW * PH);
    TU_REQUIRE(world && table && vis);
    for (int pass = 0; pass < 2; pass++) {
        unsigned s = 12345;
        for (size_t i = 0; i < (size_t)WW * WH; i++)
            for (int c = 0; c < 4; c++) {
                s = s * 1103515245u + 12345u;
                world[i * 4 + c] = pass == 0 ? (float)((s >> 8) & 0xFFFF) / 65536.0f * (c == 3 ? 1.0f : 2.0f) : 0.0f;
            }
        if (pass == 1) world[((size_t)37 * WW + 201) * 4 + 1] = 1e30f;
        pb_sh_project_desc pd = {0};
        pd.pixels = world;
        pd.width = WW;
        pd.height = WH;
        pd.max_band = 2;
        double ref[27] = {0};
        pb_error err = {0};
        TU_REQUIRE(pb_sh_project_equirect(&pd, ref, &err) == PB_SUCCESS);
        TU_REQUIRE(pb_direct_sky_table(world, WW, WH, 4, PW, PH, 2, NULL, table, &err) == PB_SUCCESS);
        for (int i = 0; i < PW * PH; i++) vis[i] = 1.0f;
        double got[27] = {0};
        pb_direct_add_sky(table, PW, PH, 2, vis, 1, got);
        double scale = 0.0;
        for (int i = 0; i < 27; i++) scale = fmax(scale, fabs(ref[i]));
        for (int i = 0; i < 27; i++) TU_CHECK_NEAR(got[i], ref[i], 1e-11 * scale);
        for (int i = 0; i < 27; i++) TU_CHECK(isfinite(got[i]));
        /* Lower half hidden. */
        for (int r = PH / 2; r < PH; r++)
            for (int c = 0; c < PW; c++) vis[r * PW + c] = 0.0f;
        double half[27] = {0}, want[27] = {0};
        pb_direct_add_sky(table, PW, PH, 2, vis, 1, half);
        for (int k = 0; k < PW * PH / 2; k++)
            for (int i = 0; i < 27; i++) want[i] += table[(size_t)k * 27 + i];
        for (int i = 0; i < 27; i++) TU_CHECK_NEAR(half[i], want[i], 1e-12 * scale);
    }
    pb_error err = {0};
    world[0] = -1.0f;
    TU_CHECK(pb_direct_sky_table(world, WW, WH, 4, PW, PH, 2, NULL, table, &err) == PB_ERROR_NEGATIVE);
    free(world);
    free(table);
    free(vis);
}

int main(void)
{
    TU_RUN(test_delta_sun);
    TU_RUN(test_sun_disc);
    TU_RUN(test_point);
    TU_RUN(test_spot);
    TU_RUN(test_area);
    TU_RUN(test_occlusion);
    TU_RUN(test_extremes);
    TU_RUN(test_invalid);
    TU_RUN(test_sky);
    return TU_EXIT();
}
