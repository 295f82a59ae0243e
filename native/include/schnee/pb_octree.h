/* Schnee probes — probe placement: sparse adaptive octree over probe volumes (DESIGN.md §6).
 *
 * How to use it:
 *   1. Describe the probe-volume meshes (closed) and the scene geometry as pb_mesh_desc arrays, in
 *      engine space, metres, double precision (scenes far from the origin stay exact: the core
 *      works relative to the volumes' centre).
 *   2. Fill a pb_placement_desc (zero = defaults) and call pb_placement_build().
 *   3. Read the result's fields; pb_placement_destroy() frees it.
 * All geometry queries go through Embree (one device per call, thread count bounded by the desc).
 *
 * Rules: a leaf cell yields a probe at its centre when that point is inside the union of the volumes
 * and not inside solid geometry. Cells whose box overlaps a scene triangle subdivide down to
 * min_cell_size; others stay as large as max_cell_size allows. The occupancy grid has spacing
 * min_cell_size; every grid cell whose centre is inside the volumes maps to a probe (its own leaf's,
 * or the nearest valid probe when that one was pruned).
 */
#ifndef SCHNEE_PB_OCTREE_H
#define SCHNEE_PB_OCTREE_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct pb_mesh_desc {
    const char *name;        /* for messages (e.g. which volume is open); may be NULL */
    const double *positions; /* vertex_count * 3, engine space, metres */
    uint32_t vertex_count;
    const uint32_t *indices; /* triangle_count * 3 */
    uint32_t triangle_count;
} pb_mesh_desc;

typedef struct pb_placement_desc {
    const pb_mesh_desc *volumes; /* closed meshes; probes fill their union; >= 1 required */
    uint32_t volume_count;
    const pb_mesh_desc *geometry; /* scene geometry; may be empty */
    uint32_t geometry_count;
    double min_cell_size;        /* 0 = 0.5 m */
    double max_cell_size;        /* 0 = 16 m; rounded down to min_cell_size·2^k */
    uint32_t solid_ray_count;    /* 0 = default (documented in the source), rays per probe for the solid test */
    double solid_backface_ratio; /* 0 = default; a probe is inside solid geometry when more than
                                       this fraction of its rays first hit a back face */
    uint64_t max_grid_cells;     /* 0 = default limit (documented); larger dense grids are refused
                                       with PB_ERROR_TOO_LARGE naming the size */
    uint32_t thread_count;       /* 0 = all cores; 1 = the calling thread only */
    pb_progress_fn progress;     /* optional; returning false cancels */
    void *progress_user;
} pb_placement_desc;

typedef struct pb_placement {
    uint32_t probe_count;
    double *positions;     /* probe_count * 3, engine space */
    double *cell_sizes;    /* probe_count: edge length of the leaf cell each probe sits in */
    float *backface_ratio; /* probe_count: fraction of solid-test rays that hit a back face */
    uint32_t grid_dims[3]; /* X, Y, Z */
    double grid_origin[3]; /* min corner of grid cell (0,0,0), engine space */
    double grid_spacing;   /* = min_cell_size */
    int32_t *grid;         /* X*Y*Z, flat x + y*X + z*X*Y: probe index or −1 (outside the volumes) */
    uint64_t leaf_count;   /* octree leaves visited */
    uint64_t pruned_count; /* leaf centres inside the volumes rejected as inside solid geometry */
} pb_placement;

pb_result pb_placement_build(const pb_placement_desc *desc, pb_placement **out, pb_error *err);
void pb_placement_destroy(pb_placement *placement);

/* Classification against the volumes and geometry of `desc` with the rules of pb_placement_build,
 * for the corner octree (pb_interp.h, pb_refine.h), whose probes sit at leaf corners:
 * - points (engine space): point_inside[i] = 1 when inside the union of the volumes (majority of
 *   three parity rays); backface_ratio[i] = the solid test's back-face ratio (0 without geometry);
 *   a point is inside solid geometry when the ratio > desc->solid_backface_ratio (default 0.25);
 * - boxes (centre x, y, z, half edge; engine space): box_class[i] = 0 entirely outside the volumes,
 *   1 entirely inside, 2 crossed by a volume surface (a leaf to keep, and to split if its part
 *   inside needs probes of its own).
 * Outputs may be NULL (that work is skipped). Same checks, errors, threads and progress stages as
 * pb_placement_build ("checking meshes", "building BVH", "classifying", "done"). */
typedef struct pb_classify_query {
    const double *points; /* point_count × 3 */
    uint32_t point_count;
    uint8_t *point_inside;
    float *backface_ratio;
    const double *boxes; /* box_count × 4 */
    uint32_t box_count;
    uint8_t *box_class;
} pb_classify_query;

pb_result pb_placement_classify(const pb_placement_desc *desc, const pb_classify_query *query, pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
