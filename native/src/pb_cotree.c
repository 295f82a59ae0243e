/* The corner octree (pb_cotree.h; docs/placement.md, "Interpolation"): leaves, their split and drop,
 * the numbering of the probes and the hanging rules (finalize), and the visibility field's table of
 * corner pairs. Point location and weights: pb_interp.c.
 *
 * Corner octree, the rule that makes it continuous: a corner node p that lies on a leaf D's boundary
 * without being one of D's corners hangs on the largest such D, and its value is D's trilinear field
 * at p (bilinear on a face, linear on an edge). A leaf's field restricted to one of its faces is
 * bilinear in that face's corners; a finer leaf sharing part of the face takes its face corners from
 * the same bilinear function, and a bilinear function restricted to an axis-aligned sub-rectangle is
 * again bilinear in the sub-rectangle's corners: both sides agree on the whole face (C0). D's own
 * corners can hang only on leaves larger than D (a corner of D has coordinates that are multiples of
 * D's size, so it cannot lie inside a face of a leaf of D's size or smaller), so resolving hanging
 * nodes from the largest host down needs each source only once, and the recursion ends.
 *
 * Boxes with per-axis levels (docs/aniso-refinement.md): the same argument needs the nesting rule (two
 * leaves sharing part of a face: one's face contains the other's; finalize forces splits until it
 * holds, pb_cotree_boxes.c), the host becomes the leaf whose face holds the corner in its interior,
 * else the one with the longest edge holding it, and the order of resolution the potential (a source's
 * is strictly larger). A tree of cubes keeps the octree's host and order above, bit for bit.
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_cotree.h"

#include "pb_interp_internal.h"
#include "pb_morton.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void cotree_clear_nodes(pb_cotree *t)
{
    free(t->probe_lattice);
    free(t->hang_lattice);
    free(t->hang_src);
    free(t->hang_w);
    free(t->exp_start);
    free(t->exp_probe);
    free(t->exp_w);
    free(t->corners);
    hmap_free(&t->node_map);
    t->probe_lattice = t->hang_lattice = t->hang_src = t->exp_start = t->exp_probe = NULL;
    t->hang_w = NULL;
    t->exp_w = NULL;
    t->corners = NULL;
    t->probe_count = t->hanging_count = 0;
    t->finalized = false;
}

void pb_cotree_destroy(pb_cotree *tree)
{
    if (!tree) return;
    cotree_clear_nodes(tree);
    hmap_free(&tree->leaf_map);
    hmap_free(&tree->root_map);
    free(tree->split_nodes);
    free(tree->leaves);
    free(tree->levels);
    free(tree);
}

typedef struct leaf_rec {
    uint64_t morton;
    uint32_t l[4], lv[3];
} leaf_rec;

static int cmp_leaf_morton(const void *pa, const void *pb)
{
    const leaf_rec *a = pa, *b = pb;
    if (a->morton != b->morton) return a->morton < b->morton ? -1 : 1;
    return a->l[3] < b->l[3] ? 1 : (a->l[3] > b->l[3] ? -1 : 0); /* larger first: an overlap shows as nesting */
}

/* "level 3" for a cube, "levels (3, 1, 3)" for a box: the leaf's levels in a message. */
static const char *levels_text(const uint32_t lv[3], char buf[48])
{
    if (lv[0] == lv[1] && lv[1] == lv[2])
        snprintf(buf, 48, "level %u", lv[0]);
    else
        snprintf(buf, 48, "levels (%u, %u, %u)", lv[0], lv[1], lv[2]);
    return buf;
}

/* Sorts the leaves (Morton order of min corners; per-axis levels along), checks levels, alignment,
 * bounds and non-overlap, and rebuilds the corner map and the split tree (point location). */
static pb_result cotree_index_leaves(pb_cotree *t, pb_error *err)
{
    uint32_t n = t->leaf_count;
    leaf_rec *rec = malloc(((size_t)n + 1) * sizeof *rec);
    if (!rec) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u leaves", n);
    for (uint32_t i = 0; i < n; i++) {
        memcpy(rec[i].l, t->leaves + 4u * i, 3 * sizeof(uint32_t));
        memcpy(rec[i].lv, t->levels + 3u * i, 3 * sizeof(uint32_t));
        uint32_t m = rec[i].lv[0] > rec[i].lv[1] ? rec[i].lv[0] : rec[i].lv[1];
        rec[i].l[3] = m > rec[i].lv[2] ? m : rec[i].lv[2];
        rec[i].morton = pb_morton3_(rec[i].l[0], rec[i].l[1], rec[i].l[2]);
    }
    qsort(rec, n, sizeof *rec, cmp_leaf_morton);
    for (uint32_t i = 0; i < n; i++) {
        memcpy(t->leaves + 4u * i, rec[i].l, 4 * sizeof(uint32_t));
        memcpy(t->levels + 3u * i, rec[i].lv, 3 * sizeof(uint32_t));
    }
    free(rec);
    hmap_free(&t->leaf_map);
    hmap_free(&t->root_map);
    free(t->split_nodes);
    t->split_nodes = NULL;
    t->split_count = 0;
    t->max_level = 0;
    t->cubes = true;
    for (uint32_t i = 0; i < n && t->cubes; i++) {
        const uint32_t *lv = t->levels + 3u * i;
        t->cubes = lv[0] == lv[1] && lv[1] == lv[2];
    }
    char lt[48];
    uint64_t prev_end = 0;
    for (uint32_t i = 0; i < n; i++) {
        const uint32_t *l = t->leaves + 4u * i, *lv = t->levels + 3u * i;
        if (l[3] > PB_COTREE_MAX_LEVEL)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "leaf %u has level %u, above the limit %u", i, l[3],
                                PB_COTREE_MAX_LEVEL);
        if (l[3] > t->root_level)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "leaf %u has level %u, above the root level %u", i,
                                l[3], t->root_level);
        for (int k = 0; k < 3; k++) {
            uint32_t s = 1u << lv[k];
            if (l[k] % s != 0 && t->cubes)
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "leaf %u at (%u, %u, %u) level %u is not aligned to its size %u", i, l[0], l[1],
                                    l[2], l[3], s);
            if (l[k] % s != 0)
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "leaf %u at (%u, %u, %u) %s is not aligned to its size %u on axis %c", i, l[0],
                                    l[1], l[2], levels_text(lv, lt), s, "XYZ"[k]);
            if ((uint64_t)l[k] + s > t->dims[k])
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "leaf %u at (%u, %u, %u) %s reaches past the lattice extent %u on axis %c", i, l[0],
                                    l[1], l[2], levels_text(lv, lt), t->dims[k], "XYZ"[k]);
        }
        if (l[3] > t->max_level) t->max_level = l[3];
        if (!t->cubes) continue; /* cubes: the octree's Morton check; boxes: the split tree proves it */
        uint64_t start = pb_morton3_(l[0], l[1], l[2]);
        if (i > 0 && start < prev_end)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "leaf %u at (%u, %u, %u) level %u overlaps another leaf", i, l[0], l[1], l[2], l[3]);
        prev_end = start + ((uint64_t)1 << (3u * l[3]));
    }
    pb_result r = _pb_cotree_index_split_tree(t, err);
    if (r != PB_SUCCESS) return r;
    if (!hmap_init(&t->leaf_map, n)) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u leaves", n);
    for (uint32_t i = 0; i < n; i++) {
        bool inserted;
        *hmap_put(&t->leaf_map, pack3(t->leaves[4u * i], t->leaves[4u * i + 1], t->leaves[4u * i + 2]), &inserted) = i;
    }
    return PB_SUCCESS;
}

/* A tree with room for n leaves (leaves and levels uninitialised, leaf_count n). */
static pb_result cotree_alloc(const double origin[3], double min_cell, const uint32_t dims[3], uint64_t n,
                              pb_cotree **out, pb_error *err)
{
    if (!origin || !dims || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "corner octree: NULL argument");
    *out = NULL;
    if (!(min_cell > 0.0) || !isfinite(min_cell))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "min cell size %g must be finite and > 0", min_cell);
    for (int k = 0; k < 3; k++) {
        if (!isfinite(origin[k])) return pb_error_set(err, PB_ERROR_NON_FINITE, "origin[%d] is %g", k, origin[k]);
        if (dims[k] == 0 || dims[k] > PB_COTREE_MAX_AXIS)
            return pb_error_set(err, dims[k] ? PB_ERROR_TOO_LARGE : PB_ERROR_INVALID_ARGUMENT,
                                "lattice extent %u on axis %c is outside 1..%u min cells", dims[k], "XYZ"[k],
                                PB_COTREE_MAX_AXIS);
    }
    pb_cotree *t = calloc(1, sizeof *t);
    if (t) {
        t->leaves = malloc(((size_t)n + 1) * 4 * sizeof(uint32_t));
        t->levels = malloc(((size_t)n + 1) * 3 * sizeof(uint32_t));
    }
    if (!t || !t->leaves || !t->levels) {
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu leaves", (unsigned long long)n);
    }
    memcpy(t->origin, origin, sizeof t->origin);
    t->h = min_cell;
    memcpy(t->dims, dims, sizeof t->dims);
    t->leaf_count = (uint32_t)n;
    *out = t;
    return PB_SUCCESS;
}

/* Indexes a freshly filled tree; destroys it on failure. */
static pb_result cotree_publish(pb_cotree *t, pb_cotree **out, pb_error *err)
{
    pb_result r = cotree_index_leaves(t, err);
    if (r != PB_SUCCESS) {
        pb_cotree_destroy(t);
        *out = NULL;
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_cotree_create(const double origin[3], double min_cell, uint32_t root_level, const uint32_t root_dims[3],
                           pb_cotree **out, pb_error *err)
{
    if (!root_dims) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "corner octree: NULL root dims");
    if (root_level > PB_COTREE_MAX_LEVEL)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "root level %u is above the limit %u", root_level,
                            PB_COTREE_MAX_LEVEL);
    uint32_t dims[3];
    uint64_t n = 1;
    for (int k = 0; k < 3; k++) {
        uint64_t d = (uint64_t)root_dims[k] << root_level;
        if (root_dims[k] == 0 || d > PB_COTREE_MAX_AXIS)
            return pb_error_set(
                err, root_dims[k] ? PB_ERROR_TOO_LARGE : PB_ERROR_INVALID_ARGUMENT,
                "%u root cells of 2^%u min cells on axis %c: the lattice extent must be 1..%u min cells", root_dims[k],
                root_level, "XYZ"[k], PB_COTREE_MAX_AXIS);
        dims[k] = (uint32_t)d;
        n *= root_dims[k];
    }
    if (n > PB_COTREE_MAX_LEAVES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%llu root leaves are above the limit of %u leaves",
                            (unsigned long long)n, PB_COTREE_MAX_LEAVES);
    pb_cotree *t;
    pb_result r = cotree_alloc(origin, min_cell, dims, n, &t, err);
    if (r != PB_SUCCESS) return r;
    t->root_level = root_level;
    uint32_t s = 1u << root_level, i = 0;
    for (uint32_t z = 0; z < root_dims[2]; z++)
        for (uint32_t y = 0; y < root_dims[1]; y++)
            for (uint32_t x = 0; x < root_dims[0]; x++, i++) {
                uint32_t *l = t->leaves + 4u * i, *lv = t->levels + 3u * i;
                l[0] = x * s, l[1] = y * s, l[2] = z * s, l[3] = root_level;
                lv[0] = lv[1] = lv[2] = root_level;
            }
    return cotree_publish(t, out, err);
}

static pb_result check_leaf_count(const uint32_t *leaves, uint32_t leaf_count, pb_error *err)
{
    if (leaf_count > 0 && !leaves) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "corner octree: NULL leaves");
    if (leaf_count > PB_COTREE_MAX_LEAVES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%u leaves are above the limit of %u leaves", leaf_count,
                            PB_COTREE_MAX_LEAVES);
    return PB_SUCCESS;
}

pb_result pb_cotree_create_leaves(const double origin[3], double min_cell, const uint32_t dims[3],
                                  const uint32_t *leaves, uint32_t leaf_count, pb_cotree **out, pb_error *err)
{
    pb_result r = check_leaf_count(leaves, leaf_count, err);
    pb_cotree *t = NULL;
    if (r == PB_SUCCESS) r = cotree_alloc(origin, min_cell, dims, leaf_count, &t, err);
    if (r != PB_SUCCESS) return r;
    for (uint32_t i = 0; i < leaf_count; i++) {
        memcpy(t->leaves + 4u * i, leaves + 4u * i, 4 * sizeof(uint32_t));
        uint32_t lv = leaves[4u * i + 3];
        for (int k = 0; k < 3; k++) t->levels[3u * i + (uint32_t)k] = lv;
        if (lv > t->root_level) t->root_level = lv > PB_COTREE_MAX_LEVEL ? PB_COTREE_MAX_LEVEL : lv;
    }
    return cotree_publish(t, out, err);
}

pb_result pb_cotree_create_boxes(const double origin[3], double min_cell, uint32_t root_level, const uint32_t dims[3],
                                 const uint32_t *leaves, uint32_t leaf_count, pb_cotree **out, pb_error *err)
{
    pb_result r = check_leaf_count(leaves, leaf_count, err);
    if (r != PB_SUCCESS) return r;
    if (root_level > PB_COTREE_MAX_LEVEL)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "root level %u is above the limit %u", root_level,
                            PB_COTREE_MAX_LEVEL);
    for (uint32_t i = 0; i < leaf_count; i++)
        if (leaves[4u * i + 3] >> 24)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "leaf %u: the levels word 0x%08x is not PB_LEVELS_PACK(lx, ly, lz) (top byte not 0)", i,
                                leaves[4u * i + 3]);
    pb_cotree *t;
    r = cotree_alloc(origin, min_cell, dims, leaf_count, &t, err);
    if (r != PB_SUCCESS) return r;
    t->root_level = root_level;
    for (uint32_t i = 0; i < leaf_count; i++) {
        const uint32_t *l = leaves + 4u * i;
        memcpy(t->leaves + 4u * i, l, 3 * sizeof(uint32_t));
        uint32_t *lv = t->levels + 3u * i;
        lv[0] = PB_LEVEL_X(l[3]), lv[1] = PB_LEVEL_Y(l[3]), lv[2] = PB_LEVEL_Z(l[3]);
    }
    return cotree_publish(t, out, err);
}

pb_result pb_cotree_drop(pb_cotree *t, const uint8_t *drop, pb_error *err)
{
    if (!t || !drop) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_drop: NULL argument");
    uint32_t n = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++)
        if (!drop[i]) {
            memmove(t->leaves + 4u * n, t->leaves + 4u * i, 4 * sizeof(uint32_t));
            memmove(t->levels + 3u * n++, t->levels + 3u * i, 3 * sizeof(uint32_t));
        }
    t->leaf_count = n;
    cotree_clear_nodes(t);
    return cotree_index_leaves(t, err);
}

/* The axes of mask m (bits 0-2) on which leaf i can halve (level > 0). */
static uint32_t split_mask(const pb_cotree *t, uint32_t i, uint32_t m)
{
    const uint32_t *lv = t->levels + 3u * i;
    return m & 7u & ((lv[0] > 0) | (lv[1] > 0) << 1 | (lv[2] > 0) << 2);
}

pb_result pb_cotree_split_axes(pb_cotree *t, const uint8_t *axes, uint32_t *split_count, pb_error *err)
{
    if (!t || !axes) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_split_axes: NULL argument");
    uint64_t n = 0, splits = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        uint32_t m = split_mask(t, i, axes[i]);
        n += 1u << ((m & 1u) + (m >> 1 & 1u) + (m >> 2 & 1u));
        splits += m != 0;
    }
    if (n > PB_COTREE_MAX_LEAVES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "splitting %llu leaves gives %llu leaves, above the limit of %u",
                            (unsigned long long)splits, (unsigned long long)n, PB_COTREE_MAX_LEAVES);
    uint32_t *nl = malloc((size_t)(n + 1) * 4 * sizeof(uint32_t)), *nv = malloc((size_t)(n + 1) * 3 * sizeof(uint32_t));
    if (!nl || !nv) {
        free(nl);
        free(nv);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu leaves", (unsigned long long)n);
    }
    uint32_t k = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        const uint32_t *l = t->leaves + 4u * i, *lv = t->levels + 3u * i;
        uint32_t m = split_mask(t, i, axes[i]), kids = 1u << ((m & 1u) + (m >> 1 & 1u) + (m >> 2 & 1u));
        for (uint32_t c = 0; c < kids; c++, k++) {
            uint32_t *o = nl + 4u * k, *ov = nv + 3u * k, bit = 0;
            memcpy(o, l, 4 * sizeof(uint32_t));
            memcpy(ov, lv, 3 * sizeof(uint32_t));
            for (int a = 0; a < 3; a++) {
                if (!((m >> a) & 1u)) continue;
                ov[a]--;
                if ((c >> bit++) & 1u) o[a] += 1u << ov[a];
            }
        }
    }
    free(t->leaves);
    free(t->levels);
    t->leaves = nl;
    t->levels = nv;
    t->leaf_count = k;
    cotree_clear_nodes(t);
    if (split_count) *split_count = (uint32_t)splits;
    return cotree_index_leaves(t, err);
}

pb_result pb_cotree_split(pb_cotree *t, const uint8_t *split, uint32_t *split_count, pb_error *err)
{
    if (!t || !split) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_split: NULL argument");
    uint8_t *axes = malloc((size_t)t->leaf_count + 1u);
    if (!axes) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u split flags", t->leaf_count);
    for (uint32_t i = 0; i < t->leaf_count; i++) axes[i] = split[i] ? 7u : 0u;
    pb_result r = pb_cotree_split_axes(t, axes, split_count, err);
    free(axes);
    return r;
}

typedef struct node_tmp {
    uint32_t p[3];
    int32_t host;   /* leaf it hangs on, −1 = probe */
    uint32_t level; /* sort key of a hanging node: cubes its host's level, boxes its potential */
    uint64_t morton;
} node_tmp;

/* A lattice point's potential (docs/aniso-refinement.md, "Resolution order"): the sum over the axes of
 * its trailing zero bits, each capped at R + 1 (0 counts R + 1). A hanging node's sources have a
 * strictly larger one, so resolving by decreasing potential finds every source resolved. */
static uint32_t potential(const uint32_t p[3], uint32_t R)
{
    uint32_t sum = 0;
    for (int k = 0; k < 3; k++) {
        uint32_t z = 0;
        while (z <= R && !((p[k] >> z) & 1u)) z++;
        sum += z;
    }
    return sum;
}

/* Host key of leaf li for corner node p, 0 when p is one of its corners. Cubes (the octree's rule):
 * 1 + the leaf's level, the largest leaf wins. Boxes: a face that holds p in its interior before any
 * edge (100 per axis on which p is inside the leaf's extent), then the larger face / longer edge (the
 * levels of those axes). Ties: the lower leaf index. */
static uint32_t host_key(const pb_cotree *t, uint32_t li, const uint32_t p[3])
{
    const uint32_t *l = t->leaves + 4u * li, *lv = t->levels + 3u * li;
    uint32_t inside = 0, sum = 0;
    for (int k = 0; k < 3; k++)
        if (p[k] != l[k] && p[k] != l[k] + (1u << lv[k])) inside++, sum += lv[k];
    if (!inside) return 0;
    return t->cubes ? 1u + l[3] : 100u * inside + sum;
}

static int cmp_node(const void *pa, const void *pb)
{
    const node_tmp *a = pa, *b = pb;
    bool ha = a->host >= 0, hb = b->host >= 0;
    if (ha != hb) return ha ? 1 : -1;                                    /* probes first */
    if (ha && a->level != b->level) return a->level > b->level ? -1 : 1; /* largest host first */
    return a->morton < b->morton ? -1 : (a->morton > b->morton ? 1 : 0);
}

/* Hanging test: among the leaves around each corner node p that have p on their boundary but not as a
 * corner, the host by host_key(); a hanging node's sort key. */
static void cotree_find_hosts(const pb_cotree *t, node_tmp *nodes, size_t n)
{
    for (size_t j = 0; j < n; j++) {
        node_tmp *nd = nodes + j;
        for (uint32_t o = 0; o < 8; o++) {
            uint32_t q[3];
            bool inside = true;
            for (int k = 0; k < 3; k++) {
                bool neg = !((o >> k) & 1);
                if (neg && nd->p[k] == 0) inside = false;
                if (!neg && nd->p[k] >= t->dims[k]) inside = false;
                q[k] = neg ? nd->p[k] - 1 : nd->p[k];
            }
            if (!inside) continue;
            int32_t li = locate_cell(t, q);
            if (li < 0) continue;
            uint32_t key = host_key(t, (uint32_t)li, nd->p);
            if (key && (nd->host < 0 || key > nd->level || (key == nd->level && li < nd->host))) {
                nd->host = li;
                nd->level = key;
            }
        }
        if (nd->host >= 0 && !t->cubes) nd->level = potential(nd->p, t->root_level);
    }
}

pb_result pb_cotree_finalize(pb_cotree *t, pb_error *err)
{
    if (!t) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_finalize: NULL tree");
    cotree_clear_nodes(t);
    t->forced = 0;
    if (!t->cubes) { /* cubes never cross */
        pb_result r = _pb_cotree_apply_nesting(t, err);
        if (r != PB_SUCCESS) return r;
    }
    size_t maxn = (size_t)t->leaf_count * 8u;
    node_tmp *nodes = malloc((maxn + 1) * sizeof *nodes);
    bool ok = nodes && hmap_init(&t->node_map, maxn);
    if (!ok) {
        free(nodes);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu corner nodes", maxn);
    }
    /* Unique corner points. */
    size_t n = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        const uint32_t *l = t->leaves + 4u * i, *lv = t->levels + 3u * i;
        for (uint32_t c = 0; c < 8; c++) {
            uint32_t p[3];
            for (int k = 0; k < 3; k++) p[k] = l[k] + ((c >> k) & 1u ? 1u << lv[k] : 0u);
            bool inserted;
            uint32_t *v = hmap_put(&t->node_map, pack3(p[0], p[1], p[2]), &inserted);
            if (!inserted) continue;
            *v = (uint32_t)n;
            node_tmp *nd = nodes + n++;
            memcpy(nd->p, p, sizeof nd->p);
            nd->host = -1;
            nd->level = 0;
            nd->morton = pb_morton3_(p[0], p[1], p[2]);
        }
    }
    cotree_find_hosts(t, nodes, n);
    qsort(nodes, n, sizeof *nodes, cmp_node);
    uint32_t P = 0;
    while (P < n && nodes[P].host < 0) P++;
    uint32_t H = (uint32_t)(n - P);
    t->probe_count = P;
    t->hanging_count = H;
    t->probe_lattice = malloc(((size_t)P + 1) * 3 * sizeof(uint32_t));
    t->hang_lattice = malloc(((size_t)H + 1) * 3 * sizeof(uint32_t));
    t->hang_src = calloc(((size_t)H + 1) * 4, sizeof(uint32_t));
    t->hang_w = calloc(((size_t)H + 1) * 4, sizeof(float));
    t->exp_start = calloc((size_t)H + 2, sizeof(uint32_t));
    t->exp_probe = malloc(((size_t)H * HANG_MAX_EXPANDED + 1) * sizeof(uint32_t));
    t->exp_w = malloc(((size_t)H * HANG_MAX_EXPANDED + 1) * sizeof(double));
    t->corners = malloc(((size_t)t->leaf_count * 8 + 1) * sizeof(int32_t));
    if (!t->probe_lattice || !t->hang_lattice || !t->hang_src || !t->hang_w || !t->exp_start || !t->exp_probe ||
        !t->exp_w || !t->corners) {
        free(nodes);
        cotree_clear_nodes(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes and %u hanging nodes", P, H);
    }
    for (uint32_t j = 0; j < (uint32_t)n; j++) {
        bool inserted;
        *hmap_put(&t->node_map, pack3(nodes[j].p[0], nodes[j].p[1], nodes[j].p[2]), &inserted) = j;
        uint32_t *dst = j < P ? t->probe_lattice + 3u * j : t->hang_lattice + 3u * (j - P);
        memcpy(dst, nodes[j].p, 3 * sizeof(uint32_t));
    }
    /* Hanging rules, largest host first: sources are probes or earlier hanging nodes. */
    uint32_t e = 0;
    for (uint32_t hI = 0; hI < H; hI++) {
        const node_tmp *nd = nodes + P + hI;
        const uint32_t *l = t->leaves + 4u * (uint32_t)nd->host, *lv = t->levels + 3u * (uint32_t)nd->host;
        double tt[3], w8[8];
        for (int k = 0; k < 3; k++) tt[k] = ((double)nd->p[k] - l[k]) / (double)(1u << lv[k]);
        trilinear8(tt, w8);
        uint32_t ns = 0, cnt = 0;
        t->exp_start[hI] = e;
        for (uint32_t c = 0; c < 8; c++) {
            if (w8[c] <= 0.0) continue;
            uint32_t cp[3];
            for (int k = 0; k < 3; k++) cp[k] = l[k] + ((c >> k) & 1u ? 1u << lv[k] : 0u);
            uint32_t src;
            if (!hmap_get(&t->node_map, pack3(cp[0], cp[1], cp[2]), &src) || src >= P + hI || ns >= 4) {
                uint32_t at[3] = {nd->p[0], nd->p[1], nd->p[2]};
                free(nodes);
                cotree_clear_nodes(t);
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "internal: hanging node (%u, %u, %u) has an unresolved source", at[0], at[1],
                                    at[2]);
            }
            t->hang_src[4u * hI + ns] = src;
            t->hang_w[4u * hI + ns] = (float)w8[c];
            ns++;
            bool fits = true;
            if (src < P) {
                fits = merge_add(t->exp_probe + e, t->exp_w + e, &cnt, HANG_MAX_EXPANDED, src, w8[c]);
            } else {
                uint32_t sh = src - P;
                for (uint32_t q = t->exp_start[sh]; q < t->exp_start[sh + 1] && fits; q++)
                    fits = merge_add(t->exp_probe + e, t->exp_w + e, &cnt, HANG_MAX_EXPANDED, t->exp_probe[q],
                                     w8[c] * t->exp_w[q]);
            }
            if (!fits) {
                uint32_t at[3] = {nd->p[0], nd->p[1], nd->p[2]};
                free(nodes);
                cotree_clear_nodes(t);
                return pb_error_set(err, PB_ERROR_TOO_LARGE,
                                    "hanging node (%u, %u, %u) depends on more than %u probes; the octree is too "
                                    "unbalanced",
                                    at[0], at[1], at[2], HANG_MAX_EXPANDED);
            }
        }
        e += cnt;
        t->exp_start[hI + 1] = e;
    }
    free(nodes);
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        const uint32_t *l = t->leaves + 4u * i, *lv = t->levels + 3u * i;
        for (uint32_t c = 0; c < 8; c++) {
            uint32_t v = 0, p[3];
            for (int k = 0; k < 3; k++) p[k] = l[k] + ((c >> k) & 1u ? 1u << lv[k] : 0u);
            (void)hmap_get(&t->node_map, pack3(p[0], p[1], p[2]), &v);
            t->corners[8u * i + c] = (int32_t)v;
        }
    }
    t->finalized = true;
    return PB_SUCCESS;
}

uint32_t pb_cotree_leaf_count(const pb_cotree *t) { return t ? t->leaf_count : 0; }
const uint32_t *pb_cotree_leaves(const pb_cotree *t) { return t ? t->leaves : NULL; }
void pb_cotree_leaf_levels(const pb_cotree *t, uint32_t *out)
{
    if (t && out) memcpy(out, t->levels, (size_t)t->leaf_count * 3 * sizeof(uint32_t));
}
uint32_t pb_cotree_root_level(const pb_cotree *t) { return t ? t->root_level : 0; }
bool pb_cotree_all_cubes(const pb_cotree *t) { return !t || t->cubes; }
uint32_t pb_cotree_forced_splits(const pb_cotree *t) { return t ? t->forced : 0; }
uint32_t pb_cotree_probe_count(const pb_cotree *t) { return t && t->finalized ? t->probe_count : 0; }
uint32_t pb_cotree_hanging_count(const pb_cotree *t) { return t && t->finalized ? t->hanging_count : 0; }
const uint32_t *pb_cotree_probe_lattice(const pb_cotree *t) { return t && t->finalized ? t->probe_lattice : NULL; }

void pb_cotree_frame(const pb_cotree *t, double origin[3], double *min_cell, uint32_t dims[3])
{
    if (origin) memcpy(origin, t->origin, sizeof t->origin);
    if (min_cell) *min_cell = t->h;
    if (dims) memcpy(dims, t->dims, sizeof t->dims);
}

void pb_cotree_probe_positions(const pb_cotree *t, double *out)
{
    if (!t || !t->finalized || !out) return;
    for (uint32_t i = 0; i < t->probe_count; i++)
        for (int k = 0; k < 3; k++)
            out[3u * i + (uint32_t)k] = t->origin[k] + t->h * t->probe_lattice[3u * i + (uint32_t)k];
}

void pb_cotree_leaf_corners(const pb_cotree *t, int32_t *leaf_corners)
{
    if (!t || !t->finalized || !leaf_corners) return;
    memcpy(leaf_corners, t->corners, (size_t)t->leaf_count * 8 * sizeof(int32_t));
}

void pb_cotree_hanging_rules(const pb_cotree *t, uint32_t *sources, float *weights)
{
    if (!t || !t->finalized) return;
    if (sources) memcpy(sources, t->hang_src, (size_t)t->hanging_count * 4 * sizeof(uint32_t));
    if (weights) memcpy(weights, t->hang_w, (size_t)t->hanging_count * 4 * sizeof(float));
}

int32_t pb_cotree_find_probe(const pb_cotree *t, const uint32_t lattice[3])
{
    if (!t || !t->finalized || !lattice) return -1;
    for (int k = 0; k < 3; k++)
        if (lattice[k] > t->dims[k]) return -1;
    uint32_t v;
    if (!hmap_get(&t->node_map, pack3(lattice[0], lattice[1], lattice[2]), &v) || v >= t->probe_count) return -1;
    return (int32_t)v;
}

bool pb_vis_trace_box(const double origin[3], double h, const uint32_t lo[3], const uint32_t lv[3],
                      pb_segment_fn segment, void *user, uint8_t o[64])
{
    double p[8][3];
    for (uint32_t c = 0; c < 8; c++)
        for (int k = 0; k < 3; k++)
            p[c][k] = origin[k] + ((double)lo[k] + ((c >> k) & 1u ? (double)(1u << lv[k]) : 0.0)) * h;
    bool blocked = false;
    for (uint32_t k = 0; k < 8; k++)
        for (uint32_t c = 0; c < 8; c++) {
            double f = 1.0;
            /* A segment along a box edge or face lies in the faces of the boxes around it, where walls and
             * ceilings modelled on the lattice planes lie too (hit or missed by rounding): it is traced once
             * moved by PB_VIS_SHIFT min cells to each side across every axis on which its ends agree, and
             * the first hit of any counts. The same rays from every box sharing the segment: the table,
             * and so the field, stays continuous across boxes. */
            uint32_t flat = 7u & ~(k ^ c); /* axes on which the two corners agree */
            uint32_t combos = 1u << ((flat & 1u) + ((flat >> 1) & 1u) + ((flat >> 2) & 1u));
            for (uint32_t m = 0; k != c && m < combos; m++) {
                double a[3], b[3];
                uint32_t bit = 0;
                for (int ax = 0; ax < 3; ax++) {
                    double d = 0.0;
                    if ((flat >> ax) & 1u) d = ((m >> bit++) & 1u ? PB_VIS_SHIFT : -PB_VIS_SHIFT) * h;
                    a[ax] = p[c][ax] + d;
                    b[ax] = p[k][ax] + d;
                }
                double fm = segment(user, a, b);
                if (fm < f) f = fm;
            }
            /* NaN or beyond the ends: clear; a hit at the very start still leaves 1/255. */
            long q = !(f < 1.0) ? (long)PB_VIS_CLEAR : lround(255.0 * (f > 0.0 ? f : 0.0));
            o[8u * k + c] = (uint8_t)(q < 1 ? 1 : (q > (long)PB_VIS_CLEAR ? (long)PB_VIS_CLEAR : q));
            blocked = blocked || o[8u * k + c] != PB_VIS_CLEAR;
        }
    return blocked;
}

pb_result pb_cotree_pair_visibility(const pb_cotree *t, pb_segment_fn segment, void *user, uint8_t *out, pb_error *err)
{
    if (!t || !segment || (!out && t->leaf_count))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_pair_visibility: NULL argument");
    for (uint32_t i = 0; i < t->leaf_count; i++)
        (void)pb_vis_trace_box(t->origin, t->h, t->leaves + 4u * i, t->levels + 3u * i, segment, user, out + 64u * i);
    return PB_SUCCESS;
}
