/* Classification of arbitrary points and boxes against the placement's volumes and geometry
 * (pb_placement_classify, pb_octree.h): the corner octree's inside and solid tests. */
#include "pb_placement_internal.h"

#include <math.h>
#include <stdlib.h>

/* ---------------------------------------------------------------------------------------------- */
/* Classification of arbitrary points and boxes (corner octree)                                    */

typedef struct classify_points_job {
    const pb_classify_query *q;
} classify_points_job;

static void classify_points_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    const pb_classify_query *q = ((classify_points_job *)user)->q;
    for (uint64_t i = begin; i < end; i++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = q->points[3 * i + (uint64_t)k] - c->centre[k];
        if (q->point_inside) q->point_inside[i] = pb_oct_point_inside(c, p) ? 1 : 0;
        if (q->backface_ratio) {
            uint32_t hits = 0, back = 0;
            if (c->geo) pb_oct_solid_count(c, p, &hits, &back);
            q->backface_ratio[i] = pb_solid_ratio(hits, back);
        }
    }
}

static void classify_boxes_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    const pb_classify_query *q = ((classify_points_job *)user)->q;
    for (uint64_t i = begin; i < end; i++) {
        const double *b = q->boxes + 4 * i;
        double ctr[3] = {b[0] - c->centre[0], b[1] - c->centre[1], b[2] - c->centre[2]};
        if (pb_oct_box_straddles_volumes(c, ctr, b[3]))
            q->box_class[i] = 2;
        else
            q->box_class[i] = pb_oct_point_inside(c, ctr) ? 1 : 0;
    }
}

static pb_result classify(oct_ctx *c, const pb_classify_query *q)
{
    if (!pb_oct_report(c, 0.0, "checking meshes", true)) return pb_oct_cancelled(c, "checking meshes");
    pb_result r = pb_oct_setup(c);
    if (r) return r;
    for (uint64_t i = 0; q->points && i < 3 * (uint64_t)q->point_count; i++)
        if (!isfinite(q->points[i]))
            return pb_error_set(c->err, PB_ERROR_NON_FINITE, "point %llu coordinate %llu is %g",
                                (unsigned long long)(i / 3), (unsigned long long)(i % 3), q->points[i]);
    for (uint64_t i = 0; q->boxes && i < 4 * (uint64_t)q->box_count; i++)
        if (!isfinite(q->boxes[i]) || (i % 4 == 3 && !(q->boxes[i] > 0)))
            return pb_error_set(c->err, isfinite(q->boxes[i]) ? PB_ERROR_INVALID_ARGUMENT : PB_ERROR_NON_FINITE,
                                "box %llu value %llu is %g (centre finite, half edge > 0)", (unsigned long long)(i / 4),
                                (unsigned long long)(i % 4), q->boxes[i]);
    r = pb_oct_build_scenes(c);
    if (r) return r;
    r = pb_oct_make_ray_dirs(c);
    if (r) return r;
    classify_points_job j = {q};
    if (q->points && (q->point_inside || q->backface_ratio) &&
        !pb_oct_parallel_for(c, q->point_count, 64, classify_points_range, &j, 0.10, 0.80, "classifying"))
        return pb_oct_cancelled(c, "classifying");
    if (q->boxes && q->box_class &&
        !pb_oct_parallel_for(c, q->box_count, 64, classify_boxes_range, &j, 0.80, 1.0, "classifying"))
        return pb_oct_cancelled(c, "classifying");
    r = pb_oct_occluder_check(c, "classifying");
    if (r) return r;
    pb_oct_report(c, 1.0, "done", true);
    return PB_SUCCESS;
}

pb_result pb_placement_classify(const pb_placement_desc *desc, const pb_classify_query *query, pb_error *err)
{
    if (!desc || !query)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_placement_classify: desc and query must not be NULL");
    if ((query->point_count && !query->points) || (query->box_count && !query->boxes))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_placement_classify: NULL points or boxes");
    oct_ctx *c = calloc(1, sizeof *c);
    if (!c) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    pb_oct_ctx_init(c, desc, err);
    pb_result r = classify(c, query);
    pb_oct_ctx_free(c);
    return r;
}
