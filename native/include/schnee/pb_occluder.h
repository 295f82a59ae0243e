/* Schnee probes — occluders: a triangle scene for rays and box queries (the one place that talks to
 * Embree; its headers stay private to native/src).
 *
 * How to use it:
 *   1. Describe the triangles as pb_occluder_mesh records (double positions relative to
 *      desc.origin, or float positions already in the occluder's frame) and call
 *      pb_occluder_create(). Meshes without triangles are skipped; a scene with no triangle at all
 *      is valid (nothing is ever hit).
 *   2. Query it from any number of threads (queries only read the handle):
 *      - pb_occluder_occluded():      is anything on the segment [tnear, tfar] of a ray?
 *      - pb_occluder_first_hit():     the nearest hit on it, optionally skipping some meshes;
 *      - pb_occluder_backface_count(): how many rays of a fan hit something, and how many of those
 *                                     hit a back face first (the solid test, pb_solid.h);
 *      - pb_occluder_crossings():     every triangle a ray crosses (parity inside tests);
 *      - pb_occluder_box_overlaps():  does an axis-aligned cube touch any triangle (exact SAT)?
 *   3. pb_occluder_error() turns an Embree error met while querying into a pb_error;
 *      pb_occluder_destroy() frees everything.
 * pb_point_index is the same for points: the nearest of a set of points (ties: smaller index).
 *
 * Frame: all coordinates passed to queries are in the occluder's frame, i.e. relative to
 * desc.origin (float rays are cast exactly as given: callers that need bit-identical rays round
 * their doubles to float themselves). Mesh indices in results are indices into desc.meshes.
 * Back faces: the front of a triangle is the side its counter-clockwise normal (v1−v0)×(v2−v0)
 * points to (glTF's and Blender's convention).
 */
#ifndef SCHNEE_PB_OCCLUDER_H
#define SCHNEE_PB_OCCLUDER_H

#include "schnee/pb_common.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct pb_occluder pb_occluder;

typedef struct pb_occluder_mesh {
    const double *positions;  /* vertex_count × 3, metres; desc.origin is subtracted (then rounded to
                                  float). Box and back-face queries read them: borrowed, they must
                                  outlive the occluder. NULL: positions_f is used. */
    const float *positions_f; /* vertex_count × 3 in the occluder's frame, copied (no box or back-face
                                  queries in double; those use these floats) */
    const uint32_t *indices;  /* triangle_count × 3, each < vertex_count; borrowed like positions */
    uint32_t vertex_count;
    uint32_t triangle_count;
} pb_occluder_mesh;

/* Flags of pb_occluder_desc. */
enum {
    PB_OCCLUDER_ROBUST = 1u,       /* Embree's robust traversal (no hit lost on shared edges) */
    PB_OCCLUDER_FILTERABLE = 2u,   /* needed by pb_occluder_crossings and by first_hit with a skip function */
    PB_OCCLUDER_BUILD_MEDIUM = 4u, /* medium BVH build quality (default: Embree's default) */
};

typedef struct pb_occluder_desc {
    const pb_occluder_mesh *meshes;
    uint32_t mesh_count;
    double origin[3];      /* subtracted from double positions */
    uint32_t thread_count; /* threads the BVH build may use; 0 = 1 */
    uint32_t flags;        /* PB_OCCLUDER_* ; 0 = none */
    const char *what;      /* for messages, e.g. "scene geometry"; NULL = "occluder" */
} pb_occluder_desc;

/* One ray segment in the occluder's frame: the points org + t·dir for t in [tnear, tfar]. */
typedef struct pb_occluder_ray {
    float org[3];
    float dir[3];
    float tnear, tfar; /* tfar may be INFINITY */
} pb_occluder_ray;

/* Refuses NULL arrays, indices out of range and non-finite positions (PB_ERROR_INVALID_ARGUMENT /
 * PB_ERROR_NON_FINITE naming the mesh, triangle or vertex), and reports Embree failures
 * (PB_ERROR_EMBREE). *out is NULL on failure. */
pb_result pb_occluder_create(const pb_occluder_desc *desc, pb_occluder **out, pb_error *err);

/* The same from the bake's mesh records (pb_octree.h's pb_mesh_desc: double positions and indices,
 * borrowed) — the placement's and the direct light's occluders. */
struct pb_mesh_desc;
pb_result pb_occluder_create_from_meshes(const struct pb_mesh_desc *meshes, uint32_t count, const double origin[3],
                                         uint32_t thread_count, uint32_t flags, const char *what, pb_occluder **out,
                                         pb_error *err);
void pb_occluder_destroy(pb_occluder *occluder);

/* Triangles in the scene (meshes that were skipped count 0). */
uint64_t pb_occluder_triangle_count(const pb_occluder *occluder);

/* Whether any triangle (either side) lies on the segment. */
bool pb_occluder_occluded(const pb_occluder *occluder, const pb_occluder_ray *ray);

/* Called for each candidate hit of pb_occluder_first_hit: true skips that mesh's triangle. */
typedef bool (*pb_occluder_skip_fn)(void *user, uint32_t mesh);

/* The nearest hit on the segment (either side): true with *t its ray parameter (and *mesh its mesh
 * when not NULL); false when the segment is clear. skip (optional; needs PB_OCCLUDER_FILTERABLE)
 * ignores the triangles of the meshes it accepts. */
bool pb_occluder_first_hit(const pb_occluder *occluder, const pb_occluder_ray *ray, pb_occluder_skip_fn skip,
                           void *skip_user, float *t, uint32_t *mesh);

/* The solid test's fan: `count` rays from `origin` (rounded to float) along dirs[k], unbounded.
 * *hits = rays that hit a triangle, *back = those whose first hit is a back face (judged in double
 * from the mesh positions). Cast 16 at a time. */
void pb_occluder_backface_count(const pb_occluder *occluder, const double origin[3], const float (*dirs)[3],
                                uint32_t count, uint32_t *hits, uint32_t *back);

/* back / hits of pb_occluder_backface_count, 0 when no ray hits. */
float pb_occluder_backface_ratio(const pb_occluder *occluder, const double origin[3], const float (*dirs)[3],
                                 uint32_t count);

/* Every triangle the ray from org (rounded to float) along dir, t in [0, ∞), crosses, each once,
 * as (mesh, triangle) pairs in no particular order; needs PB_OCCLUDER_FILTERABLE. Returns false when
 * more than `capacity` were met (then the arrays hold the first `capacity`). */
bool pb_occluder_crossings(const pb_occluder *occluder, const double org[3], const double dir[3], uint32_t capacity,
                           uint32_t *mesh, uint32_t *triangle, uint32_t *count);

/* Whether the closed cube (centre, half edge h > 0) overlaps any triangle (exact separating-axis
 * test in double; candidates from a sphere query of radius h·√3 plus slack and `pad` metres). */
bool pb_occluder_box_overlaps(const pb_occluder *occluder, const double centre[3], double h, double pad);

/* PB_SUCCESS, or PB_ERROR_EMBREE "<Embree's message> while <what>" for the first Embree error met
 * by this occluder since its creation. */
pb_result pb_occluder_error(const pb_occluder *occluder, pb_error *err, const char *what);

/* ---- the nearest of a set of points ---------------------------------------------------------- */

typedef struct pb_point_index pb_point_index;

/* points: count × 3 (borrowed: must outlive the index), in any frame; pad: metres each point's box
 * is widened by (plus 1e-6 of its largest coordinate). */
pb_result pb_point_index_create(const double *points, uint32_t count, double pad, uint32_t thread_count,
                                pb_point_index **out, pb_error *err);
void pb_point_index_destroy(pb_point_index *index);

/* Index of the point nearest to p (squared distance in double; ties: the smaller index), −1 when
 * the set is empty. slack: metres of margin kept while searching, so equally near points are still
 * visited. */
int32_t pb_point_index_nearest(const pb_point_index *index, const double p[3], double slack);

/* As pb_occluder_error. */
pb_result pb_point_index_error(const pb_point_index *index, pb_error *err, const char *what);

#ifdef __cplusplus
}
#endif
#endif
