/* Schnee probes — the solid test: is a point inside solid geometry? (docs/placement.md)
 *
 * A point inside a closed solid sees (nearly) only the back faces of its surface, one in the open
 * sees front faces. How to use it:
 *   1. pb_solid_ray_dirs(): the fixed fan of `count` unit directions (default 64).
 *   2. Cast them from the point against the scene geometry: pb_occluder_backface_count()
 *      (pb_occluder.h) gives the rays that hit and those whose first hit is a back face.
 *   3. pb_solid_is_inside(hits, back, ratio) decides; pb_solid_ratio() is the stored figure.
 * The placement (pb_octree.h) prunes leaf centres this way and pb_placement_classify reports the
 * ratio for the corner octree.
 */
#ifndef SCHNEE_PB_SOLID_H
#define SCHNEE_PB_SOLID_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* 64 rays: a probe inside a closed solid sees ~100 % back faces, one in the open 0 %; 64
 * directions resolve the ratio in steps of 1.6 % and cost ~64 ray casts, negligible next to the
 * panorama render of the same probe. */
#define PB_SOLID_DEFAULT_RAYS 64u
/* 0.25: single-sided planes facing away and small open meshes can show a probe some back faces
 * while it is in free space; a probe inside a closed solid sees (nearly) only back faces. A quarter
 * of the hitting rays tolerates such stray back faces yet prunes anything enclosed by geometry. */
#define PB_SOLID_DEFAULT_BACKFACE_RATIO 0.25
#define PB_SOLID_MAX_RAYS               65536u

/* dirs[k], k < count: spherical Fibonacci directions, z_k = 1 − (2k + 1)/count, azimuth
 * 0.1 + k·π(3 − √5) rad (so that none lies in an axis plane); unit length up to float rounding. */
void pb_solid_ray_dirs(uint32_t count, float (*dirs)[3]);

/* back / hits as stored in pb_placement.backface_ratio; 0 when no ray hits. */
float pb_solid_ratio(uint32_t hits, uint32_t back);

/* Inside solid geometry: more than max_ratio of the rays that hit saw a back face first
 * (back > max_ratio · hits, in double). */
bool pb_solid_is_inside(uint32_t hits, uint32_t back, double max_ratio);

#ifdef __cplusplus
}
#endif
#endif
