/* The solid test (pb_solid.h) against closed forms: the fan is spherical Fibonacci (z_k =
 * 1 − (2k + 1)/n exactly in float, unit directions, mean ~0), the decision is back > ratio · hits,
 * and with an occluder (pb_occluder.h) a point inside a closed outward-facing box is inside solid
 * geometry (ratio 1) while one outside it, or inside an inward-facing room, is not (ratio 0). */
#include "schnee/pb_occluder.h"
#include "schnee/pb_solid.h"
#include "testutil.h"

#include <stdlib.h>

static void test_fan_is_spherical_fibonacci(void)
{
    float dirs[PB_SOLID_DEFAULT_RAYS][3];
    pb_solid_ray_dirs(PB_SOLID_DEFAULT_RAYS, dirs);
    double mean[3] = {0, 0, 0};
    for (uint32_t k = 0; k < PB_SOLID_DEFAULT_RAYS; k++) {
        double n =
            sqrt((double)dirs[k][0] * dirs[k][0] + (double)dirs[k][1] * dirs[k][1] + (double)dirs[k][2] * dirs[k][2]);
        TU_CHECK_NEAR(n, 1.0, 1e-6);                                                    /* float rounding */
        TU_CHECK(dirs[k][2] == (float)(1.0 - (2.0 * k + 1.0) / PB_SOLID_DEFAULT_RAYS)); /* the closed form */
        TU_CHECK(dirs[k][0] != 0.0f && dirs[k][1] != 0.0f);                             /* none in an axis plane */
        for (int a = 0; a < 3; a++) mean[a] += dirs[k][a] / PB_SOLID_DEFAULT_RAYS;
    }
    /* Equal-area bands: the z mean is 0 exactly up to rounding; x and y are small for 64 points. */
    TU_CHECK_NEAR(mean[2], 0.0, 1e-7);
    TU_CHECK_NEAR(mean[0], 0.0, 0.05);
    TU_CHECK_NEAR(mean[1], 0.0, 0.05);
}

static void test_decision_rule(void)
{
    TU_CHECK(pb_solid_ratio(0, 0) == 0.0f);
    TU_CHECK(pb_solid_ratio(64, 16) == 0.25f);
    TU_CHECK(!pb_solid_is_inside(64, 16, PB_SOLID_DEFAULT_BACKFACE_RATIO)); /* exactly a quarter: kept */
    TU_CHECK(pb_solid_is_inside(64, 17, PB_SOLID_DEFAULT_BACKFACE_RATIO));
    TU_CHECK(!pb_solid_is_inside(0, 0, PB_SOLID_DEFAULT_BACKFACE_RATIO));
    TU_CHECK(!pb_solid_is_inside(10, 10, 1.0)); /* ratio 1 disables pruning */
}

/* Box [0, 2] x [0, 1] x [0, 3]; `inward` flips every triangle (a room seen from inside). */
static float solid_ratio_at(const double p[3], bool inward)
{
    static const uint32_t f[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                   2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    double pos[24];
    uint32_t idx[36];
    for (int v = 0; v < 8; v++) {
        pos[3 * v + 0] = (v & 1) ? 2.0 : 0.0;
        pos[3 * v + 1] = (v & 2) ? 1.0 : 0.0;
        pos[3 * v + 2] = (v & 4) ? 3.0 : 0.0;
    }
    for (int t = 0; t < 12; t++)
        for (int k = 0; k < 3; k++) idx[3 * t + k] = f[3 * t + (inward ? 2 - k : k)];
    pb_occluder_mesh m = {pos, NULL, idx, 8, 12};
    pb_occluder_desc d = {0};
    d.meshes = &m;
    d.mesh_count = 1;
    pb_occluder *o = NULL;
    pb_error err = {0};
    if (pb_occluder_create(&d, &o, &err) != PB_SUCCESS) return -1.0f;
    float dirs[PB_SOLID_DEFAULT_RAYS][3];
    pb_solid_ray_dirs(PB_SOLID_DEFAULT_RAYS, dirs);
    float r = pb_occluder_backface_ratio(o, p, (const float(*)[3])dirs, PB_SOLID_DEFAULT_RAYS);
    pb_occluder_destroy(o);
    return r;
}

static void test_inside_a_closed_box_is_solid(void)
{
    const double in[3] = {1.3, 0.4, 2.1}, out[3] = {-0.5, 0.5, 1.5};
    TU_CHECK(solid_ratio_at(in, false) == 1.0f);
    TU_CHECK(solid_ratio_at(out, false) == 0.0f);
    TU_CHECK(solid_ratio_at(in, true) == 0.0f); /* a room: its walls face the probe */
}

int main(void)
{
    TU_RUN(test_fan_is_spherical_fibonacci);
    TU_RUN(test_decision_rule);
    TU_RUN(test_inside_a_closed_box_is_solid);
    return TU_EXIT();
}
