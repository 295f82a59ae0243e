/* Occluders (pb_occluder.h) against closed forms: a segment through a known triangle hits it at the
 * parameter where it crosses the plane, a segment beside it misses, the solid test's back-face ratio
 * is 1 inside a closed outward-facing cube and 0 outside it, a cube's crossings have the parity of
 * inside/outside, box overlap follows the separating-axis test, the nearest point breaks ties by
 * index, and broken input is refused with a pb_error naming the problem. */
#include "schnee/pb_occluder.h"
#include "testutil.h"

#include <stdlib.h>

/* The triangle (0,0,0) (1,0,0) (0,1,0) in the plane z = 0, normal +z, far from the origin (origin
 * subtracted: the occluder works in floats relative to it). */
static const double far_off[3] = {1e6, -2e6, 3e5};
static double tri_pos[9];
static const uint32_t tri_idx[3] = {0, 1, 2};

static pb_occluder *make_triangle(uint32_t flags)
{
    const double local[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    for (int i = 0; i < 9; i++) tri_pos[i] = local[i] + far_off[i % 3];
    pb_occluder_mesh m = {tri_pos, NULL, tri_idx, 3, 1};
    pb_occluder_desc d = {0};
    d.meshes = &m;
    d.mesh_count = 1;
    for (int a = 0; a < 3; a++) d.origin[a] = far_off[a];
    d.flags = flags;
    pb_occluder *o = NULL;
    pb_error err = {0};
    if (pb_occluder_create(&d, &o, &err) != PB_SUCCESS) fprintf(stderr, "create: %s\n", err.message);
    return o;
}

/* Segment (0.25, 0.25, 1) → (0.25, 0.25, −1): crosses the plane at t = 1/2 of a direction of length 2,
 * i.e. at ray parameter 0.5 (exact in float). A parallel one at x = y = 0.8 (x + y > 1) misses. */
static void test_segment_through_a_triangle(void)
{
    pb_occluder *o = make_triangle(PB_OCCLUDER_FILTERABLE);
    TU_REQUIRE(o != NULL);
    TU_CHECK(pb_occluder_triangle_count(o) == 1);
    pb_occluder_ray hit = {{0.25f, 0.25f, 1.0f}, {0.0f, 0.0f, -2.0f}, 0.0f, 1.0f};
    pb_occluder_ray miss = {{0.8f, 0.8f, 1.0f}, {0.0f, 0.0f, -2.0f}, 0.0f, 1.0f};
    pb_occluder_ray short_ = {{0.25f, 0.25f, 1.0f}, {0.0f, 0.0f, -2.0f}, 0.0f, 0.49f}; /* stops above */
    TU_CHECK(pb_occluder_occluded(o, &hit));
    TU_CHECK(!pb_occluder_occluded(o, &miss));
    TU_CHECK(!pb_occluder_occluded(o, &short_));
    float t = -1.0f;
    uint32_t mesh = 99;
    TU_CHECK(pb_occluder_first_hit(o, &hit, NULL, NULL, &t, &mesh));
    TU_CHECK_NEAR(t, 0.5, 1e-6);
    TU_CHECK(mesh == 0);
    TU_CHECK(!pb_occluder_first_hit(o, &miss, NULL, NULL, &t, NULL));
    /* From below (the back side) it blocks all the same: occluders are two-sided. */
    pb_occluder_ray up = {{0.25f, 0.25f, -1.0f}, {0.0f, 0.0f, 1.0f}, 0.0f, INFINITY};
    TU_CHECK(pb_occluder_first_hit(o, &up, NULL, NULL, &t, NULL));
    TU_CHECK_NEAR(t, 1.0, 1e-6);
    pb_error err = {0};
    TU_CHECK(pb_occluder_error(o, &err, "testing") == PB_SUCCESS);
    pb_occluder_destroy(o);
}

static bool skip_all(void *user, uint32_t mesh)
{
    (void)user;
    return mesh == 0;
}

static void test_skipped_mesh_does_not_block(void)
{
    pb_occluder *o = make_triangle(PB_OCCLUDER_FILTERABLE);
    TU_REQUIRE(o != NULL);
    pb_occluder_ray hit = {{0.25f, 0.25f, 1.0f}, {0.0f, 0.0f, -2.0f}, 0.0f, 1.0f};
    TU_CHECK(!pb_occluder_first_hit(o, &hit, skip_all, NULL, NULL, NULL));
    pb_occluder_destroy(o);
}

/* The unit cube [0, 1]^3 with outward (counter-clockwise from outside) faces. */
static const double cube_pos[24] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 1};
static const uint32_t cube_idx[36] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                                      2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};

static pb_occluder *make_cube(uint32_t flags)
{
    pb_occluder_mesh m = {cube_pos, NULL, cube_idx, 8, 12};
    pb_occluder_desc d = {0};
    d.meshes = &m;
    d.mesh_count = 1;
    d.flags = flags;
    d.thread_count = 2;
    pb_occluder *o = NULL;
    pb_error err = {0};
    if (pb_occluder_create(&d, &o, &err) != PB_SUCCESS) fprintf(stderr, "create: %s\n", err.message);
    return o;
}

/* 64 spherical-Fibonacci directions, none in an axis plane. */
static void fan(float dirs[64][3])
{
    const double golden = 3.14159265358979323846 * (3.0 - sqrt(5.0));
    for (int k = 0; k < 64; k++) {
        double z = 1.0 - (2.0 * k + 1.0) / 64.0, r = sqrt(1.0 - z * z), phi = 0.1 + golden * k;
        dirs[k][0] = (float)(r * cos(phi));
        dirs[k][1] = (float)(r * sin(phi));
        dirs[k][2] = (float)z;
    }
}

/* Inside a closed outward-facing cube every ray leaves through a back face: ratio 1. Outside, every
 * ray that hits enters through a front face: ratio 0 (and some rays hit: the cube is near). */
static void test_backface_ratio_of_a_closed_cube(void)
{
    pb_occluder *o = make_cube(0);
    TU_REQUIRE(o != NULL);
    float dirs[64][3];
    fan(dirs);
    const double inside[3] = {0.3, 0.6, 0.45}, outside[3] = {1.5, 0.5, 0.5};
    uint32_t hits = 0, back = 0;
    pb_occluder_backface_count(o, inside, (const float(*)[3])dirs, 64, &hits, &back);
    TU_CHECK(hits == 64 && back == 64);
    TU_CHECK_NEAR(pb_occluder_backface_ratio(o, inside, (const float(*)[3])dirs, 64), 1.0, 0.0);
    pb_occluder_backface_count(o, outside, (const float(*)[3])dirs, 64, &hits, &back);
    TU_CHECK(hits > 0 && back == 0);
    TU_CHECK_NEAR(pb_occluder_backface_ratio(o, outside, (const float(*)[3])dirs, 64), 0.0, 0.0);
    /* 17 rays: one full packet of 16 and one ray in the next. */
    pb_occluder_backface_count(o, inside, (const float(*)[3])dirs, 17, &hits, &back);
    TU_CHECK(hits == 17 && back == 17);
    pb_occluder_destroy(o);
}

/* A ray from inside crosses the cube once, one from outside towards it twice, one away from it never. */
static void test_crossings_parity(void)
{
    pb_occluder *o = make_cube(PB_OCCLUDER_FILTERABLE | PB_OCCLUDER_ROBUST);
    TU_REQUIRE(o != NULL);
    const double d[3] = {0.26726124191242440, 0.53452248382484879, 0.80178372573727319};
    const double back_d[3] = {-d[0], -d[1], -d[2]};
    const double inside[3] = {0.4, 0.3, 0.2}, before[3] = {0.1 - 2 * d[0], 0.2 - 2 * d[1], 0.1 - 2 * d[2]};
    uint32_t mesh[8], tri[8], n = 99;
    TU_CHECK(pb_occluder_crossings(o, inside, d, 8, mesh, tri, &n));
    TU_CHECK(n == 1 && mesh[0] == 0 && tri[0] < 12);
    TU_CHECK(pb_occluder_crossings(o, before, d, 8, mesh, tri, &n));
    TU_CHECK(n == 2);
    TU_CHECK(pb_occluder_crossings(o, before, back_d, 8, mesh, tri, &n));
    TU_CHECK(n == 0);
    /* Capacity 1 with two crossings: reported as an overflow. */
    TU_CHECK(!pb_occluder_crossings(o, before, d, 1, mesh, tri, &n));
    TU_CHECK(n == 1);
    pb_occluder_destroy(o);
}

/* Boxes around the cube's surface overlap it; boxes strictly inside or outside do not (only the
 * surface is geometry). */
static void test_box_overlaps(void)
{
    pb_occluder *o = make_cube(0);
    TU_REQUIRE(o != NULL);
    const double on_face[3] = {1.0, 0.5, 0.5}, in_middle[3] = {0.5, 0.5, 0.5}, away[3] = {2.0, 0.5, 0.5};
    const double touching[3] = {1.25, 0.5, 0.5};
    TU_CHECK(pb_occluder_box_overlaps(o, on_face, 0.1, 0.0));
    TU_CHECK(!pb_occluder_box_overlaps(o, in_middle, 0.4, 0.0));
    TU_CHECK(pb_occluder_box_overlaps(o, in_middle, 0.5, 0.0)); /* closed: faces touch */
    TU_CHECK(!pb_occluder_box_overlaps(o, away, 0.5, 0.0));
    TU_CHECK(pb_occluder_box_overlaps(o, touching, 0.25, 0.0));
    TU_CHECK(!pb_occluder_box_overlaps(o, touching, 0.2, 0.0));
    pb_occluder_destroy(o);
}

static void test_nearest_point(void)
{
    const double pts[12] = {0, 0, 0, 2, 0, 0, 1, 0, 0, 1, 0, 0}; /* points 2 and 3 coincide */
    pb_point_index *ix = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_point_index_create(pts, 4, 1e-6, 1, &ix, &err) == PB_SUCCESS);
    const double a[3] = {0.1, 0.3, 0}, b[3] = {1.2, 0, 0}, c[3] = {1.9, -0.1, 0.1}, mid[3] = {0.5, 0, 0};
    TU_CHECK(pb_point_index_nearest(ix, a, 1e-6) == 0);
    TU_CHECK(pb_point_index_nearest(ix, b, 1e-6) == 2); /* ties: the smaller index */
    TU_CHECK(pb_point_index_nearest(ix, c, 1e-6) == 1);
    TU_CHECK(pb_point_index_nearest(ix, mid, 1e-6) == 0); /* 0 and 2 at 0.5: index 0 */
    TU_CHECK(pb_point_index_error(ix, &err, "testing") == PB_SUCCESS);
    pb_point_index_destroy(ix);
    TU_REQUIRE(pb_point_index_create(NULL, 0, 0, 1, &ix, &err) == PB_SUCCESS);
    TU_CHECK(pb_point_index_nearest(ix, a, 0) == -1);
    pb_point_index_destroy(ix);
}

/* Broken input is refused with a code and a message naming the mesh and the problem. */
static void test_degenerate_input_is_refused(void)
{
    pb_occluder *o = (pb_occluder *)1;
    pb_error err = {0};
    const uint32_t bad_idx[3] = {0, 1, 3};
    pb_occluder_mesh m = {cube_pos, NULL, bad_idx, 3, 1};
    pb_occluder_desc d = {0};
    d.meshes = &m;
    d.mesh_count = 1;
    TU_CHECK(pb_occluder_create(&d, &o, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(o == NULL);
    TU_CHECK(strstr(err.message, "vertex index 3") != NULL);

    double nan_pos[9] = {0, 0, 0, 1, 0, 0, 0, NAN, 0};
    pb_occluder_mesh n = {nan_pos, NULL, tri_idx, 3, 1};
    d.meshes = &n;
    memset(&err, 0, sizeof err); /* pb_error keeps the first error */
    TU_CHECK(pb_occluder_create(&d, &o, &err) == PB_ERROR_NON_FINITE);
    TU_CHECK(strstr(err.message, "non-finite y") != NULL);

    pb_occluder_mesh none = {NULL, NULL, tri_idx, 3, 1};
    d.meshes = &none;
    memset(&err, 0, sizeof err); /* pb_error keeps the first error */
    TU_CHECK(pb_occluder_create(&d, &o, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(strstr(err.message, "no position array") != NULL);

    d.meshes = NULL;
    TU_CHECK(pb_occluder_create(&d, &o, &err) == PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(pb_occluder_create(NULL, &o, &err) == PB_ERROR_INVALID_ARGUMENT);

    /* No triangle at all is valid: nothing is ever hit. */
    d.mesh_count = 0;
    TU_REQUIRE(pb_occluder_create(&d, &o, &err) == PB_SUCCESS);
    pb_occluder_ray r = {{0, 0, 1}, {0, 0, -1}, 0, INFINITY};
    TU_CHECK(!pb_occluder_occluded(o, &r));
    TU_CHECK(pb_occluder_triangle_count(o) == 0);
    const double p[3] = {0, 0, 0};
    float dirs[64][3];
    fan(dirs);
    TU_CHECK(pb_occluder_backface_ratio(o, p, (const float(*)[3])dirs, 64) == 0.0f);
    pb_occluder_destroy(o);
}

int main(void)
{
    TU_RUN(test_segment_through_a_triangle);
    TU_RUN(test_skipped_mesh_does_not_block);
    TU_RUN(test_backface_ratio_of_a_closed_cube);
    TU_RUN(test_crossings_parity);
    TU_RUN(test_box_overlaps);
    TU_RUN(test_nearest_point);
    TU_RUN(test_degenerate_input_is_refused);
    return TU_EXIT();
}
