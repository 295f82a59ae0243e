/* Probe visibility through the static scene (docs/engine.md "Static scene", "Per-pixel probes"):
 * the objects' triangles at their current transforms, as occluders of the bake core
 * (schnee/pb_occluder.h; the engine never calls Embree itself).
 *
 *   - Per object: sv_static_vis_create() once (every object's triangles), then sv_probe_visible()
 *     as the pb_visible_fn of pb_interp_query_cotree / _tetra with an sv_vis_query: the segment
 *     probe -> point must cross no triangle of an object that never moved, the queried one aside.
 *   - Per pixel: sv_probe_visibility_masks() traces the neighbour masks of the dense grids and the
 *     per-leaf visibility field of the octree grids through the objects never moved.
 */
#ifndef SV_PROBE_VIS_H
#define SV_PROBE_VIS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "schnee/pb_occluder.h"
#include "sv_probes.h"

/* Every object's triangles at their current transforms; NULL (with a warning) on failure, then
 * every probe is visible. */
sv_static_vis *sv_static_vis_create(const sv_scene *scene);
void sv_static_vis_destroy(sv_static_vis *vis);

/* The user data of sv_probe_visible. */
typedef struct sv_vis_query {
    const sv_static_vis *vis; /* NULL: everything visible */
    const sv_scene *scene;
    uint32_t self;          /* the queried object: never blocks its own probes */
    const float *positions; /* the grid's probe positions (world space) */
} sv_vis_query;

/* pb_visible_fn: the segment probe -> point (its ends left out by 1e-4 of its length) crosses no
 * triangle (either side) of an object that has not moved, other than q->self. */
bool sv_probe_visible(void *user, uint32_t probe, const double point[3]);

/* Neighbour visibility masks, one uint32 per cell in the layout of the concatenated dense cell grids
 * (n cells): bit (dx+1) + 3(dy+1) + 9(dz+1) (d in {-1,0,1}^3; bit 13 = the cell itself, always set) is
 * set when the segment between the centres of the cell and of its neighbour at offset d crosses no
 * triangle of the static scene (both sides). Empty cells, and cells whose neighbour is empty or
 * outside the grid, keep the bit set (no information, no change to the weights). Then, in `leaf_vis`
 * (leaf_count × 64 bytes, octree grids in order), each octree leaf's table of the continuous
 * visibility field (pb_cotree_pair_visibility, pb_interp.h): 56 segments between its corners.
 * Returns the masks (caller frees), NULL when out of memory. */
uint32_t *sv_probe_visibility_masks(const sv_probes *probes, const sv_scene *scene, size_t n, uint8_t *leaf_vis,
                                    size_t leaf_count);

/* The static scene's occluder as sv_probe_visibility_masks traces it (the objects never moved, both
 * sides of every triangle), for other tracers such as the probe bricks' build (sv_bricks_vis.c); NULL
 * when the scene has no object or no triangle (no message) or the occluder fails (a warning). Free with
 * pb_occluder_destroy. */
pb_occluder *sv_static_occluder(const sv_scene *scene);
/* pb_segment_fn over such an occluder (user): the first surface on a -> b as a fraction of its length,
 * 1 when clear; the leaf tables' segment function. */
double sv_segment_first_hit(void *user, const double a[3], const double b[3]);

#endif
