/* pb_placement_classify (pb_octree.h): the inside/solid/box classification the corner octree uses,
 * with the rules of pb_placement_build. Closed forms: a 10 m × 4 m × 10 m room volume with a solid
 * 2 m block at its centre (outward normals); points inside the block see only back faces (ratio 1),
 * points in the room's air see only front faces (ratio 0); boxes inside / across / outside the room. */
#include "schnee/pb_octree.h"

#include "testutil.h"

#include <stdlib.h>

static double pos[2][24];
static uint32_t idx[36];

/* Closed box, counter-clockwise seen from outside. */
static void box(double *p, const double lo[3], const double hi[3])
{
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi[0] : lo[0];
        p[3 * i + 1] = (i & 2) ? hi[1] : lo[1];
        p[3 * i + 2] = (i & 4) ? hi[2] : lo[2];
    }
    static const int faces[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    for (int f = 0; f < 6; f++) {
        const int t[6] = {faces[f][0], faces[f][1], faces[f][2], faces[f][0], faces[f][2], faces[f][3]};
        for (int k = 0; k < 6; k++) idx[6 * f + k] = (uint32_t)t[k];
    }
}

static void test_points_and_boxes(void)
{
    box(pos[0], (const double[3]){0, 0, 0}, (const double[3]){10, 4, 10});
    box(pos[1], (const double[3]){4, 0, 4}, (const double[3]){6, 2, 6});
    pb_mesh_desc vol = {"room", pos[0], 8, idx, 12}, geo = {"block", pos[1], 8, idx, 12};
    pb_placement_desc d = {
        .volumes = &vol, .volume_count = 1, .geometry = &geo, .geometry_count = 1, .thread_count = 2};
    const double points[5 * 3] = {1, 1, 1, 5, 1, 5, 11, 1, 1, 5.5, 1.5, 4.5, 9.9, 3.9, 0.1};
    const double boxes[4 * 4] = {5, 2, 5, 1, 10, 2, 5, 1, 20, 2, 20, 1, 2, 2, 2, 0.5};
    uint8_t inside[5], cls[4];
    float ratio[5];
    pb_classify_query q = {points, 5, inside, ratio, boxes, 4, cls};
    pb_error err = {0};
    TU_REQUIRE(pb_placement_classify(&d, &q, &err) == PB_SUCCESS);
    const uint8_t want_inside[5] = {1, 1, 0, 1, 1};
    for (int i = 0; i < 5; i++) TU_CHECK(inside[i] == want_inside[i]);
    TU_CHECK_NEAR(ratio[0], 0.0, 0); /* air: only the block's front faces */
    TU_CHECK_NEAR(ratio[1], 1.0, 0); /* inside the block: every hit a back face */
    TU_CHECK_NEAR(ratio[3], 1.0, 0);
    TU_CHECK_NEAR(ratio[4], 0.0, 0);
    const uint8_t want_cls[4] = {1, 2, 0, 1};
    for (int i = 0; i < 4; i++) TU_CHECK(cls[i] == want_cls[i]);
    /* Only some outputs. */
    uint8_t in2[5];
    pb_classify_query q2 = {points, 5, in2, NULL, NULL, 0, NULL};
    TU_REQUIRE(pb_placement_classify(&d, &q2, &err) == PB_SUCCESS);
    TU_CHECK(memcmp(in2, inside, 5) == 0);
    /* Errors as the placement's. */
    const double bad[3] = {NAN, 0, 0};
    pb_classify_query q3 = {bad, 1, in2, NULL, NULL, 0, NULL};
    pb_error e3 = {0};
    TU_CHECK(pb_placement_classify(&d, &q3, &e3) == PB_ERROR_NON_FINITE);
    TU_CHECK(strstr(e3.message, "point 0 coordinate 0 is nan") != NULL);
    uint32_t open_idx[33];
    memcpy(open_idx, idx, sizeof open_idx);
    pb_mesh_desc open = {"open room", pos[0], 8, open_idx, 11};
    pb_placement_desc d4 = d;
    d4.volumes = &open;
    pb_error e4 = {0};
    TU_CHECK(pb_placement_classify(&d4, &q, &e4) == PB_ERROR_OPEN_MESH);
    TU_CHECK(strstr(e4.message, "open room") != NULL);
}

int main(void)
{
    TU_RUN(test_points_and_boxes);
    return TU_EXIT();
}
