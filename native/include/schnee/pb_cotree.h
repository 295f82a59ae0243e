/* Schnee probes — the corner octree (issue 12, docs/placement.md "Interpolation"): probes at the
 * corners of octree leaves, shared by neighbours, trilinear inside each leaf. A leaf corner that lies
 * on the face or edge of a larger neighbour is a *hanging node*, not a probe: its value is that
 * neighbour's field there (bilinear on the face, linear on the edge), so the field is C0-continuous
 * across leaves of different sizes and hanging nodes need no bake.
 *
 * How to use it: pb_cotree_create() (a uniform layer of leaves of 2^level min cells over a box),
 * optionally pb_cotree_split() pass by pass (pb_refine.h decides which leaves), then
 * pb_cotree_finalize() numbers the probes (corner nodes that are not hanging) and the hanging rules;
 * read probe positions with pb_cotree_probe_positions(); query with pb_interp_query_cotree()
 * (pb_interp.h); pb_cotree_destroy(). Coordinates: engine space, metres, double; lattice coordinates
 * are integers in units of the min cell size, relative to the origin.
 * Boxes (docs/aniso-refinement.md): pb_cotree_split_axes() halves leaves along some axes only, or
 * pb_cotree_create_boxes() takes boxes with per-axis levels; finalize then also applies the nesting
 * rule (forced splits); pb_cotree_leaf_levels() gives the levels, pb_cotree_split_tree() the canonical
 * split tree that locates points. A tree of cubes behaves exactly as the octree always did.
 * Part of pb_interp.h (include either); sources native/src/pb_cotree.c, pb_cotree_boxes.c.
 */
#ifndef SCHNEE_PB_COTREE_H
#define SCHNEE_PB_COTREE_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PB_COTREE_MAX_LEVEL  20u                 /* leaves are at most 2^20 min cells wide */
#define PB_COTREE_MAX_AXIS   (UINT32_C(1) << 20) /* lattice extent per axis, in min cells */
#define PB_COTREE_MAX_LEAVES (UINT32_C(1) << 26)

/* ---- the visibility field of a corner octree (docs/placement.md "Visibility field") ---------------
 * Which corner probes of a leaf light a point p, decided continuously in p. For each ordered pair of a
 * leaf's corners (k, c) the bake-free static geometry gives t = the fraction of the way from corner c
 * towards corner k at which that segment first meets a surface (1: clear). Along the edge k -> c the
 * linear function f(x) = V + (1 - V) x with V = 1 - 1/(2t) equals 1/2 exactly at that surface, the one
 * nearest c. In 3D, c's visibility at p is the trilinear blend v_c(p) = sum_k w_k(p) V(k, c) (V(c, c) = 1)
 * and its weight is w_c(p) * smoothstep(1/2, 1/2 + PB_VIS_RAMP, v_c(p)): 0 on the far side of a wall,
 * 1 away from walls. On a face shared by two leaves only the face's corners carry weight in both, with
 * the same segments, so the field is continuous across leaf borders (conforming faces; at a T-junction
 * the hanging corner's own segments are used, continuous up to that difference). When no corner keeps
 * weight the plain weights are used. t is stored as round(255 t) in [1, 255], 255 = clear. The engine's
 * per-pixel shader mirrors this (shaders/shading.glsl octree_irradiance); on the static surfaces of the
 * bake it also weighs the corners by the back-face weight, in the blend of v_c too. */
#define PB_VIS_RAMP  0.25
#define PB_VIS_SHIFT 1e-3 /* min cells: segments on leaf edges/faces are traced this far to each side */
#define PB_VIS_CLEAR 255u
/* First meeting of the segment a -> b with the occluders, as a fraction of its length in [0, 1];
 * >= 1 = clear. Called once per ordered corner pair. */
typedef double (*pb_segment_fn)(void *user, const double a[3], const double b[3]);
/* V(k, c) from a stored byte (exact mirror of the GLSL's pair_vis()). */
static inline double pb_vis_pair_value(uint8_t q)
{
    return q >= PB_VIS_CLEAR ? 1.0 : 1.0 - 127.5 / (double)(q ? q : 1u);
}

/* ---- corner octree ------------------------------------------------------------------------------ */

typedef struct pb_cotree pb_cotree;

/* A uniform layer of leaves of 2^root_level min cells, root_dims leaves per axis, min corner at
 * `origin`. Lattice extent = root_dims · 2^root_level min cells per axis (≤ 2^20). */
pb_result pb_cotree_create(const double origin[3], double min_cell, uint32_t root_level, const uint32_t root_dims[3],
                           pb_cotree **out, pb_error *err);
/* A tree from explicit leaves (4 uint32 each: x, y, z lattice min corner, level), e.g. a file's.
 * Leaves must be aligned (x, y, z multiples of 2^level), inside `dims`, and not overlap. Root level:
 * the largest leaf level. */
pb_result pb_cotree_create_leaves(const double origin[3], double min_cell, const uint32_t dims[3],
                                  const uint32_t *leaves, uint32_t leaf_count, pb_cotree **out, pb_error *err);
/* ---- boxes with per-axis levels (issue 29 item 3, docs/aniso-refinement.md) --------------------------
 * A leaf may be a box: level lx, ly, lz per axis (it spans 2^l_a min cells on axis a from a min corner
 * that is a multiple of 2^l_a). pb_cotree_leaves()' fourth word stays the leaf's largest level (its
 * level as before for a cube); pb_cotree_leaf_levels() gives the three. A tree of cubes behaves exactly
 * as before. */
#define PB_LEVELS_PACK(lx, ly, lz) ((uint32_t)(lx) | (uint32_t)(ly) << 8 | (uint32_t)(lz) << 16)
#define PB_LEVEL_X(p)              ((p)&0xffu)
#define PB_LEVEL_Y(p)              ((p) >> 8 & 0xffu)
#define PB_LEVEL_Z(p)              ((p) >> 16 & 0xffu)
/* A tree from explicit boxes (4 uint32 each: x, y, z lattice min corner, packed levels
 * PB_LEVELS_PACK), e.g. a version-4 file's. root_level R: Max Cell Size = 2^R min cells (every level
 * ≤ R; the split tree's root grid is ceil(dims / 2^R)). Boxes must be aligned, inside `dims`, not
 * overlap, and be what 2:1 splits of the root cells make (a split tree exists); the nesting rule is not
 * checked here: finalize enforces it by forced splits. Leaves are then in Morton order of min corners. */
pb_result pb_cotree_create_boxes(const double origin[3], double min_cell, uint32_t root_level, const uint32_t dims[3],
                                 const uint32_t *leaves, uint32_t leaf_count, pb_cotree **out, pb_error *err);
/* leaf_count × 3 levels (lx, ly, lz), leaves in pb_cotree_leaves() order. */
void pb_cotree_leaf_levels(const pb_cotree *tree, uint32_t *out);
/* The root level R (create: root_level; create_leaves: the largest leaf level). */
uint32_t pb_cotree_root_level(const pb_cotree *tree);
/* Whether every leaf is a cube (lx = ly = lz): the octree (a version-3 file's structure 1). */
bool pb_cotree_all_cubes(const pb_cotree *tree);
/* Halves every leaf along the axes of its mask (bit 0 = x, 1 = y, 2 = z; axes at level 0 are ignored):
 * 2^|axes| children. pb_cotree_split(flags) is split_axes with mask 7 where a flag is set. The tree must
 * be finalized again afterwards; finalize first applies the nesting rule (docs/aniso-refinement.md:
 * forced splits remove every cross), *forced (pb_cotree_forced_splits) counts them. */
pb_result pb_cotree_split_axes(pb_cotree *tree, const uint8_t *axes, uint32_t *split_count, pb_error *err);
uint32_t pb_cotree_forced_splits(const pb_cotree *tree); /* by the last finalize */
/* The canonical split tree (docs/aniso-refinement.md "Point location", "Canonical split tree"): *count
 * nodes, nodes 0..G-1 the root cells (x fastest, G = prod ceil(dims / 2^R)); bits 0-1: 0 leaf, 1/2/3 split
 * along x/y/z; bits 2-31: a leaf's index in pb_cotree_leaves() order (2^30 - 1 = empty) or a split's
 * lower child (upper = lower + 1). At every box the split is along the lowest axis whose middle plane no
 * leaf crosses, so the tree depends on the leaves alone. Nodes depth first: a split's two children are
 * appended, then the lower child's subtree, then the upper's; roots in order. nodes NULL: only *count
 * (capacity below *count: invalid argument). Of the current leaves: after finalize, the final ones. */
pb_result pb_cotree_split_tree(const pb_cotree *tree, uint32_t *nodes, uint32_t capacity, uint32_t *count,
                               pb_error *err);
#define PB_SPLIT_TREE_EMPTY ((UINT32_C(1) << 30) - 1u)
/* The descent (docs/aniso-refinement.md "Point location"): the leaf index a split tree holds for the
 * unit lattice cell with min corner q, or −1 (outside the root grid, an empty node, or a split of an axis
 * already at level 0). At most 3·root_level steps. `nodes` must be a split tree whose child indices are
 * in range (pb_cotree_split_tree's, or a file's after the reader's checks). */
int32_t pb_cotree_split_tree_find(const uint32_t *nodes, const uint32_t root_grid[3], uint32_t root_level,
                                  const uint32_t q[3]);

/* Drops leaves whose flag is nonzero (e.g. outside the probe volumes); not finalized afterwards. */
pb_result pb_cotree_drop(pb_cotree *tree, const uint8_t *drop, pb_error *err);
/* Replaces every leaf whose flag is nonzero and whose level is > 0 by its 8 children (flags of
 * level-0 leaves are ignored: Min Cell Size is the limit; a box halves along its axes above level 0). Leaf order: Morton order of min corners.
 * The tree must be finalized again afterwards. *split_count (optional) = leaves split. */
pb_result pb_cotree_split(pb_cotree *tree, const uint8_t *split, uint32_t *split_count, pb_error *err);
/* Numbers the probes (non-hanging corner nodes, in Morton order of their lattice point) and builds
 * the hanging rules. Fails (PB_ERROR_TOO_LARGE) if a hanging node would depend on more than 32 probes
 * (only in pathologically unbalanced trees). With boxes (docs/aniso-refinement.md) it first applies the
 * nesting rule (forced splits: leaf indices change), a hanging corner's host is the leaf whose face
 * holds it in its interior, else the one with the longest edge holding it, and the rules are in
 * decreasing potential (ties: Morton order). A tree of cubes: the octree's rules and order, unchanged. */
pb_result pb_cotree_finalize(pb_cotree *tree, pb_error *err);
void pb_cotree_destroy(pb_cotree *tree);

uint32_t pb_cotree_leaf_count(const pb_cotree *tree);
const uint32_t *pb_cotree_leaves(const pb_cotree *tree); /* leaf_count × (x, y, z, level) */
void pb_cotree_frame(const pb_cotree *tree, double origin[3], double *min_cell, uint32_t dims[3]);
/* After finalize: */
uint32_t pb_cotree_probe_count(const pb_cotree *tree);
const uint32_t *pb_cotree_probe_lattice(const pb_cotree *tree);     /* probe_count × (x, y, z) */
void pb_cotree_probe_positions(const pb_cotree *tree, double *out); /* probe_count × 3, engine space */
/* Node numbering for a file: nodes [0, P) are probes, [P, P+H) hanging nodes. leaf_corners gets
 * leaf_count × 8 node indices (corner bit 0 = +x, bit 1 = +y, bit 2 = +z). */
uint32_t pb_cotree_hanging_count(const pb_cotree *tree);
void pb_cotree_leaf_corners(const pb_cotree *tree, int32_t *leaf_corners);
/* hanging_count × 4 sources (node indices: probes or earlier hanging nodes) and weights (0 unused). */
void pb_cotree_hanging_rules(const pb_cotree *tree, uint32_t *sources, float *weights);
/* Probe index of a lattice point, or −1 if it is not a probe. */
int32_t pb_cotree_find_probe(const pb_cotree *tree, const uint32_t lattice[3]);
/* The visibility field's table (above): out[64 i + 8 k + c] for leaf i (leaves in pb_cotree_leaves()
 * order), corner k looking at corner c (bit 0 = +x, 1 = +y, 2 = +z), from segment(c, k); the diagonal is
 * PB_VIS_CLEAR. A segment on a leaf edge (face) is traced 4 (2) times, moved by ±PB_VIS_SHIFT min cells
 * across the axes on which its ends agree, and its first hit kept: 152 calls of `segment` per leaf.
 * Needs no finalize. */
pb_result pb_cotree_pair_visibility(const pb_cotree *tree, pb_segment_fn segment, void *user, uint8_t *out,
                                    pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
