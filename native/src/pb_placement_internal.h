/* Probe placement, private to its files (not installed): the context of one pb_placement_build /
 * pb_placement_classify call and the functions the files share.
 *
 *   pb_placement_ctx.c  settings and validation, progress and cancelling, the parallel for, the
 *                       occluders of the volumes and of the geometry (pb_occluder.h) and the queries
 *                       on them (box overlap, inside the volumes).
 *   pb_octree.c         the placement: octree, occupancy grid, nearest probe, pb_placement_build.
 *   pb_solid.c          the solid test (pb_solid.h): its ray fan and the pruning of leaves.
 *   pb_classify.c       pb_placement_classify (points and boxes for the corner octree).
 */
#ifndef SCHNEE_PB_PLACEMENT_INTERNAL_H
#define SCHNEE_PB_PLACEMENT_INTERNAL_H

#include "schnee/pb_occluder.h"
#include "schnee/pb_octree.h"
#include "schnee/pb_solid.h"

#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>

/* Defaults of pb_placement_desc (a zero field selects them; documented in docs/placement.md). */
#define PB_DEFAULT_MIN_CELL 0.5
#define PB_DEFAULT_MAX_CELL 16.0
/* 2^26 cells = 256 MiB of int32 grid (and of .shprobe file): a 100 m × 100 m × 25 m level at the
 * default 0.5 m cell size needs 2·10^6 cells; 2^26 is ~32× that. */
#define PB_DEFAULT_MAX_GRID_CELLS (UINT64_C(1) << 26)
#define PB_MAX_THREADS            256u
/* Octree depth is bounded so that every integer coordinate (grid units) fits in uint32. */
#define PB_MAX_LEVELS     30u
#define PB_MAX_AXIS_CELLS (UINT32_C(1) << 30)

/* Geometric tolerance, in units of min_cell_size: boxes are padded by it for the scene-geometry
 * test (a triangle touching a cell face counts as overlapping, also after rounding) and shrunk by
 * it for the volume-surface test (a volume face on a cell face does not make the cell straddle). */
#define PB_BOX_EPS 1e-6

/* Cell flags. */
#define CELL_FULL      1u /* box entirely inside the volumes (no volume triangle crosses it) */
#define CELL_CENTRE_IN 2u /* centre inside the volumes (known) */
#define CELL_PRUNED    4u /* centre inside solid geometry */

/* Classification results of one octree cell. */
enum { CLS_DROP = 0, CLS_LEAF = 1, CLS_SPLIT = 2 };

/* Grid marker while filling: inside the volumes, probe still to be chosen (nearest). */
#define GRID_NEAREST (-2)

typedef struct oct_cell {
    uint32_t x, y, z; /* min corner, grid units */
    uint8_t lg;       /* edge = 2^lg grid units */
    uint8_t flags;
} oct_cell;

typedef struct oct_ctx {
    const pb_placement_desc *desc;
    pb_error *err;

    /* Settings after defaults. */
    double min_cell, solid_ratio;
    uint32_t solid_rays, threads;
    uint64_t max_cells;

    /* Frame and grid. */
    double centre[3];     /* absolute centre of the volumes' bounding box */
    double bbmin[3];      /* absolute min corner = grid origin */
    double origin_rel[3]; /* grid origin relative to centre */
    uint32_t dims[3];
    uint32_t root_lg; /* root cell edge = 2^root_lg grid units */
    double eps;       /* PB_BOX_EPS · min_cell, metres */

    /* Occluders (pb_occluder.h): the volumes, the scene geometry (NULL without triangles) and,
     * for the last stage, the probe points. */
    pb_occluder *vol, *geo;
    pb_point_index *probe_index;

    float (*ray_dirs)[3];

    /* Progress. */
    atomic_bool cancel;
    double last_report; /* monotonic seconds */
} oct_ctx;

/* ---------------------------------------------------------------------------------------------- */
/* The context (pb_placement_ctx.c)                                                                */

void pb_oct_ctx_init(oct_ctx *c, const pb_placement_desc *desc, pb_error *err);
void pb_oct_ctx_free(oct_ctx *c);

/* Stage 1: settings after defaults, input checks, the frame and the grid. */
pb_result pb_oct_setup(oct_ctx *c);
/* Stage 2: the occluders of the volumes and of the geometry. */
pb_result pb_oct_build_scenes(oct_ctx *c);

/* Reports progress from the calling thread; returns false (and raises the cancel flag) when the
 * callback asks to cancel. `force` reports regardless of the 50 ms throttle. */
bool pb_oct_report(oct_ctx *c, double fraction, const char *stage, bool force);
pb_result pb_oct_cancelled(oct_ctx *c, const char *stage);
/* The first Embree error any occluder of the call met, as a pb_error. */
pb_result pb_oct_occluder_check(oct_ctx *c, const char *what);

/* Parallel for: the calling thread and up to threads−1 workers take chunks of [0, count) from an
 * atomic counter; only the calling thread reports progress (p0 → p1 of `stage`). Returns false
 * when cancelled. */
typedef void (*range_fn)(oct_ctx *c, void *user, uint64_t begin, uint64_t end);
bool pb_oct_parallel_for(oct_ctx *c, uint64_t count, uint64_t chunk, range_fn fn, void *user, double p0, double p1,
                         const char *stage);

/* Queries in relative coordinates: does the cube (centre, half edge h) touch a scene triangle
 * (padded by eps) / cross the volumes' surface (shrunk by eps); is the point inside the volumes. */
bool pb_oct_box_touches_geometry(const oct_ctx *c, const double centre[3], double h);
bool pb_oct_box_straddles_volumes(const oct_ctx *c, const double centre[3], double h);
bool pb_oct_point_inside(const oct_ctx *c, const double p[3]);

/* Relative coordinates of a cell: centre and half edge. */
static inline void cell_geometry(const oct_ctx *c, uint64_t x, uint64_t y, uint64_t z, uint32_t lg, double centre[3],
                                 double *h)
{
    double edge = c->min_cell * (double)(UINT64_C(1) << lg);
    *h = 0.5 * edge;
    centre[0] = c->origin_rel[0] + (double)x * c->min_cell + *h;
    centre[1] = c->origin_rel[1] + (double)y * c->min_cell + *h;
    centre[2] = c->origin_rel[2] + (double)z * c->min_cell + *h;
}

/* ---------------------------------------------------------------------------------------------- */
/* The solid test (pb_solid.c)                                                                     */

/* c->ray_dirs: the fan of c->solid_rays directions (pb_solid_ray_dirs). */
pb_result pb_oct_make_ray_dirs(oct_ctx *c);
/* Hits and back-face hits of the fan from `ctr` (relative coordinates) against the geometry. */
void pb_oct_solid_count(oct_ctx *c, const double ctr[3], uint32_t *hits_out, uint32_t *back_out);

typedef struct solid_job {
    oct_cell *leaves;
    float *ratio;
} solid_job;
/* range_fn of stage 4 over a solid_job: each leaf's ratio, CELL_PRUNED when inside solid geometry. */
void pb_oct_solid_range(oct_ctx *c, void *user, uint64_t begin, uint64_t end);

#endif
