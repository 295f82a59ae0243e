/* The solid test (pb_solid.h): a fixed fan of rays from a point; more than a given fraction of
 * back faces among the first hits means the point is inside solid geometry. Stage 4 of the
 * placement (pb_octree.c) and the classification (pb_classify.c) run it through pb_occluder.h. */
#include "pb_placement_internal.h"

#include <math.h>
#include <stdlib.h>

/* Spherical Fibonacci directions (offset by 0.1 rad so that none lies in an axis plane). */
void pb_solid_ray_dirs(uint32_t count, float (*dirs)[3])
{
    const double golden = 3.14159265358979323846 * (3.0 - sqrt(5.0));
    for (uint32_t k = 0; k < count; k++) {
        double zc = 1.0 - (2.0 * k + 1.0) / count, rr = sqrt(fmax(0.0, 1.0 - zc * zc));
        double phi = 0.1 + golden * k;
        dirs[k][0] = (float)(rr * cos(phi));
        dirs[k][1] = (float)(rr * sin(phi));
        dirs[k][2] = (float)zc;
    }
}

float pb_solid_ratio(uint32_t hits, uint32_t back) { return hits ? (float)back / (float)hits : 0.0f; }

bool pb_solid_is_inside(uint32_t hits, uint32_t back, double max_ratio)
{
    return (double)back > max_ratio * (double)hits;
}

/* The fan of the solid test (pb_solid_ray_dirs). */
pb_result pb_oct_make_ray_dirs(oct_ctx *c)
{
    c->ray_dirs = malloc(sizeof *c->ray_dirs * c->solid_rays);
    if (!c->ray_dirs) return pb_error_set(c->err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    pb_solid_ray_dirs(c->solid_rays, c->ray_dirs);
    return PB_SUCCESS;
}

/* ---------------------------------------------------------------------------------------------- */
/* Stage 4: solid test                                                                              */

/* Back-face hits and hits of the solid test's rays from `ctr` (relative coordinates). */
void pb_oct_solid_count(oct_ctx *c, const double ctr[3], uint32_t *hits_out, uint32_t *back_out)
{
    pb_occluder_backface_count(c->geo, ctr, (const float(*)[3])c->ray_dirs, c->solid_rays, hits_out, back_out);
}

void pb_oct_solid_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end)
{
    solid_job *j = (solid_job *)user;
    for (uint64_t i = begin; i < end; i++) {
        oct_cell *leaf = &j->leaves[i];
        j->ratio[i] = 0.0f;
        if (!(leaf->flags & CELL_CENTRE_IN) || !c->geo) continue;
        double ctr[3], h;
        cell_geometry(c, leaf->x, leaf->y, leaf->z, leaf->lg, ctr, &h);
        uint32_t hits = 0, back = 0;
        pb_oct_solid_count(c, ctr, &hits, &back);
        j->ratio[i] = pb_solid_ratio(hits, back);
        if (pb_solid_is_inside(hits, back, c->solid_ratio)) leaf->flags |= CELL_PRUNED;
    }
}
