/* Schnee probes — interpolation between probes at their real positions (issue 12, docs/placement.md).
 *
 * Two structures, one query:
 *   (a) a corner octree (pb_cotree): probes at the corners of octree leaves, shared by neighbours,
 *       trilinear inside each leaf. A leaf corner that lies on the face or edge of a larger neighbour
 *       is a *hanging node*, not a probe: its value is that neighbour's field there (bilinear on the
 *       face, linear on the edge), so the field is C0-continuous across leaves of different sizes and
 *       hanging nodes need no bake.
 *   (b) a Delaunay tetrahedralisation of probe positions (qhull), barycentric inside each
 *       tetrahedron; point location through a uniform grid of tetrahedron bounds.
 *
 * How to use it:
 *   1. Corner octree: pb_cotree_create() (a uniform layer of leaves of 2^level min cells over a box),
 *      optionally pb_cotree_split() pass by pass (pb_refine.h decides which leaves), then
 *      pb_cotree_finalize() numbers the probes (corner nodes that are not hanging) and the hanging
 *      rules. Read probe positions with pb_cotree_probe_positions().
 *      Tetrahedra: pb_tetra_create() from probe positions.
 *   2. pb_interp_query_*() gives weights over probe indices for a point; multiply them with any
 *      per-probe data (SH coefficients, ambient cubes, noise) — the field is linear in the probes.
 *   3. *_destroy().
 * Coordinates: engine space, metres, double. Lattice coordinates are integers in units of the min
 * cell size, relative to the origin. Nothing here allocates per query; queries are thread-safe.
 *
 * Layout: this header holds the query (point location and weights, native/src/pb_interp.c) and
 * includes the structures and the files: pb_cotree.h (pb_cotree.c), pb_tetra.h (pb_tetra.c),
 * pb_interp_v3.h (pb_interp_v3.c). Private to native/src: pb_interp_internal.h.
 */
#ifndef SCHNEE_PB_INTERP_H
#define SCHNEE_PB_INTERP_H

#include "schnee/pb_common.h"
#include "schnee/pb_cotree.h"
#include "schnee/pb_shprobe.h"
#include "schnee/pb_tetra.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Most probes one query can weight: 8 corners, hanging ones expanded and merged. */
#define PB_INTERP_MAX_WEIGHTS 64u

/* Result of a query: `count` probes with weights > 0 summing to 1; count 0 = no probe covers the
 * point (outside the structure, or every probe dropped by visibility/validity). */
typedef struct pb_interp_weights {
    uint32_t count;
    uint32_t probe[PB_INTERP_MAX_WEIGHTS];
    double weight[PB_INTERP_MAX_WEIGHTS];
} pb_interp_weights;

/* Optional visibility judge: return false when `probe` cannot see `point` (e.g. a wall between
 * them); the probe is dropped and the remaining weights renormalised. Called once per probe with a
 * nonzero weight. */
typedef bool (*pb_visible_fn)(void *user, uint32_t probe, const double point[3]);

typedef struct pb_interp_options {
    pb_visible_fn visible; /* NULL = every probe visible */
    void *visible_user;
    /* NULL = all valid; else per probe, a probe with validity <= 0 is dropped (inside solid geometry) */
    const float *validity;
    /* Corner octrees only. NULL = none; else leaf_count × 64 from pb_cotree_pair_visibility(): the
     * continuous visibility field (pb_cotree.h). */
    const uint8_t *pair_visibility;
} pb_interp_options;

/* ---- point location and weights ------------------------------------------------------------------ */

/* Leaf holding the point (closed on the lattice's max faces), or −1. */
int32_t pb_cotree_locate(const pb_cotree *tree, const double point[3]);
/* Weights of leaf `leaf`'s own field at `point` (clamped into the leaf): for a point on a face shared
 * by two leaves the field is the same from both sides (C0), this picks one. Requires finalize. */
pb_result pb_interp_query_cotree_leaf(const pb_cotree *tree, uint32_t leaf, const double point[3],
                                      const pb_interp_options *opt, pb_interp_weights *out);
/* Weights of the probes at `point` (engine space); requires finalize. */
pb_result pb_interp_query_cotree(const pb_cotree *tree, const double point[3], const pb_interp_options *opt,
                                 pb_interp_weights *out);
/* Tetrahedron holding the point, or −1 (outside the convex hull). */
int32_t pb_tetra_locate(const pb_tetra *tetra, const double point[3]);
pb_result pb_interp_query_tetra(const pb_tetra *tetra, const double point[3], const pb_interp_options *opt,
                                pb_interp_weights *out);

#ifdef __cplusplus
}
#endif

#include "schnee/pb_interp_v3.h" /* pb_shprobe_from_cotree, _from_tetra, pb_interp_from_shprobe, ... */
#endif
