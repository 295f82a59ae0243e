/* Boxes with per-axis levels (pb_cotree.h; docs/aniso-refinement.md): the canonical split tree, which
 * locates points (split_descend in pb_interp_internal.h) and proves that given boxes tile their root
 * cells without overlap, and the nesting rule's forced splits. The rest of the corner tree (leaves,
 * splits, probes, hanging rules): pb_cotree.c.
 *
 * Canonical split tree: at every box the split is along the lowest axis whose middle plane no leaf of
 * the box crosses. A leaf inside a box crosses its middle plane on axis a exactly when its level on a
 * equals the box's (dyadic intervals nest), so the test is a comparison of levels, and since a box is
 * only split along an axis no leaf of it reaches, every leaf stays inside its box on the way down: a
 * leaf node is a box that holds exactly one leaf equal to it, and a box that holds leaves but has no
 * free plane holds a leaf equal to it beside others (an overlap) or leaves that no sequence of 2:1
 * splits makes (refused).
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_cotree.h"

#include "pb_interp_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SPLIT_MAX_NODES (UINT32_C(1) << 30) /* node indices live in 30 bits */

typedef struct split_build {
    const pb_cotree *t;
    uint32_t *idx, *tmp; /* leaf indices, partitioned in place per box */
    uint32_t *nodes;
    size_t count, cap;
    pb_error *err;
} split_build;

/* The node of the box (lo, lv) holding the leaves idx[b..e). Depth ≤ 3R. */
static pb_result split_box(split_build *sb, uint32_t node, uint32_t b, uint32_t e, const uint32_t lo[3],
                           const uint32_t lv[3])
{
    const pb_cotree *t = sb->t;
    if (b == e) {
        sb->nodes[node] = PB_SPLIT_TREE_EMPTY << 2;
        return PB_SUCCESS;
    }
    const uint32_t first = sb->idx[b], *fl = t->leaves + 4u * first, *fv = t->levels + 3u * first;
    if (e - b == 1 && !memcmp(fl, lo, 3 * sizeof(uint32_t)) && !memcmp(fv, lv, 3 * sizeof(uint32_t))) {
        sb->nodes[node] = first << 2;
        return PB_SUCCESS;
    }
    int axis = -1;
    for (int a = 0; a < 3 && axis < 0; a++) {
        bool crossed = !lv[a];
        for (uint32_t j = b; j < e && !crossed; j++) crossed = t->levels[3u * sb->idx[j] + (uint32_t)a] >= lv[a];
        if (!crossed) axis = a;
    }
    if (axis < 0) { /* name two overlapping leaves (among the box's first 1024: a failure path) */
        uint32_t n = e - b < 1024u ? e - b : 1024u;
        for (uint32_t j = b; j < b + n; j++)
            for (uint32_t k = j + 1; k < b + n; k++) {
                const uint32_t i1 = sb->idx[j], i2 = sb->idx[k];
                const uint32_t *l1 = t->leaves + 4u * i1, *v1 = t->levels + 3u * i1, *l2 = t->leaves + 4u * i2,
                               *v2 = t->levels + 3u * i2;
                bool meet = true;
                for (int a = 0; a < 3; a++)
                    meet = meet && l1[a] < l2[a] + (1u << v2[a]) && l2[a] < l1[a] + (1u << v1[a]);
                if (meet)
                    return pb_error_set(sb->err, PB_ERROR_INVALID_ARGUMENT,
                                        "leaf %u at (%u, %u, %u) levels (%u, %u, %u) overlaps leaf %u at (%u, %u, %u) "
                                        "levels (%u, %u, %u)",
                                        i1, l1[0], l1[1], l1[2], v1[0], v1[1], v1[2], i2, l2[0], l2[1], l2[2], v2[0],
                                        v2[1], v2[2]);
            }
        return pb_error_set(sb->err, PB_ERROR_INVALID_ARGUMENT,
                            "the %u leaves in the box at (%u, %u, %u) levels (%u, %u, %u) are not 2:1 splits of it (a "
                            "leaf crosses every middle plane; leaf %u is one) or overlap",
                            e - b, lo[0], lo[1], lo[2], lv[0], lv[1], lv[2], first);
    }
    uint32_t a = (uint32_t)axis, mid = lo[a] + (1u << (lv[a] - 1u)), m = b, nu = 0;
    for (uint32_t j = b; j < e; j++) {
        uint32_t i = sb->idx[j];
        if (t->leaves[4u * i + a] < mid)
            sb->idx[m++] = i;
        else
            sb->tmp[nu++] = i;
    }
    memcpy(sb->idx + m, sb->tmp, nu * sizeof(uint32_t));
    if (sb->count + 2 > SPLIT_MAX_NODES)
        return pb_error_set(sb->err, PB_ERROR_TOO_LARGE, "the split tree needs more than %u nodes", SPLIT_MAX_NODES);
    if (sb->count + 2 > sb->cap) {
        size_t cap = sb->cap * 2 + 16;
        uint32_t *nn = realloc(sb->nodes, cap * sizeof(uint32_t));
        if (!nn) return pb_error_set(sb->err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %zu split tree nodes", cap);
        sb->nodes = nn;
        sb->cap = cap;
    }
    uint32_t child = (uint32_t)sb->count;
    sb->count += 2;
    sb->nodes[node] = child << 2 | (a + 1u);
    uint32_t clv[3] = {lv[0], lv[1], lv[2]}, clo[3] = {lo[0], lo[1], lo[2]};
    clv[a]--;
    pb_result r = split_box(sb, child, b, m, clo, clv);
    clo[a] = mid;
    return r != PB_SUCCESS ? r : split_box(sb, child + 1u, m, e, clo, clv);
}

/* The split tree of t's leaves (Morton order: a root cell's leaves are consecutive). full: every root
 * cell of the grid G = ceil(dims / 2^R) as nodes 0..G-1, x fastest (the file's tree); else only the
 * non-empty root cells, in Morton order, and root_map gets pack(root cell) → node. Nodes depth first:
 * a split's two children are appended, then the lower child's subtree is built, then the upper's. */
static pb_result split_make(const pb_cotree *t, bool full, uint32_t **out_nodes, uint32_t *out_count, hmap *root_map,
                            pb_error *err)
{
    uint32_t N = t->leaf_count, R = t->root_level, grid[3];
    uint64_t G = 1;
    for (int k = 0; k < 3; k++) {
        grid[k] = (uint32_t)(((uint64_t)t->dims[k] + (1u << R) - 1u) >> R);
        G *= grid[k];
    }
    if (full && G >= SPLIT_MAX_NODES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "the root grid %u x %u x %u (root level %u) has too many cells",
                            grid[0], grid[1], grid[2], R);
    split_build sb = {.t = t, .err = err};
    uint32_t *gstart = malloc(((size_t)N + 2) * sizeof(uint32_t)), groups = 0;
    sb.idx = malloc(((size_t)N + 1) * sizeof(uint32_t));
    sb.tmp = malloc(((size_t)N + 1) * sizeof(uint32_t));
    hmap gmap = {0};
    bool ok = gstart && sb.idx && sb.tmp && hmap_init(&gmap, N);
    pb_result r = ok ? PB_SUCCESS : pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the split tree");
    uint64_t prev = UINT64_MAX;
    for (uint32_t i = 0; ok && i < N; i++) {
        const uint32_t *l = t->leaves + 4u * i;
        uint64_t key = pack3(l[0] >> R, l[1] >> R, l[2] >> R);
        sb.idx[i] = i;
        if (key == prev) continue;
        bool inserted;
        *hmap_put(&gmap, key, &inserted) = groups;
        gstart[groups++] = i;
        prev = key;
    }
    if (ok) gstart[groups] = N;
    size_t roots = full ? (size_t)G : groups;
    sb.cap = roots + 2u * (size_t)N + 16u;
    sb.nodes = ok ? malloc(sb.cap * sizeof(uint32_t)) : NULL;
    if (ok && !sb.nodes) r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the split tree");
    if (r == PB_SUCCESS && !full && !hmap_init(root_map, groups))
        r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the split tree");
    sb.count = roots;
    for (size_t n = 0; r == PB_SUCCESS && n < roots; n++) {
        uint32_t g = (uint32_t)n, lo[3], lv[3] = {R, R, R};
        if (full) {
            uint32_t cell[3] = {(uint32_t)(n % grid[0]), (uint32_t)(n / grid[0] % grid[1]),
                                (uint32_t)(n / grid[0] / grid[1])};
            if (!hmap_get(&gmap, pack3(cell[0], cell[1], cell[2]), &g)) {
                sb.nodes[n] = PB_SPLIT_TREE_EMPTY << 2;
                continue;
            }
        }
        const uint32_t *l = t->leaves + 4u * gstart[g];
        for (int k = 0; k < 3; k++) lo[k] = l[k] >> R << R;
        if (!full) {
            bool inserted;
            *hmap_put(root_map, pack3(lo[0] >> R, lo[1] >> R, lo[2] >> R), &inserted) = g;
        }
        r = split_box(&sb, (uint32_t)n, gstart[g], gstart[g + 1], lo, lv);
    }
    free(gstart);
    free(sb.idx);
    free(sb.tmp);
    hmap_free(&gmap);
    if (r != PB_SUCCESS) {
        free(sb.nodes);
        if (!full) hmap_free(root_map);
        return r;
    }
    *out_nodes = sb.nodes;
    *out_count = (uint32_t)sb.count;
    return PB_SUCCESS;
}

pb_result _pb_cotree_index_split_tree(pb_cotree *t, pb_error *err)
{
    return split_make(t, false, &t->split_nodes, &t->split_count, &t->root_map, err);
}

pb_result pb_cotree_split_tree(const pb_cotree *t, uint32_t *nodes, uint32_t capacity, uint32_t *count, pb_error *err)
{
    if (!t || !count) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_split_tree: NULL argument");
    uint32_t *tree = NULL, k = 0;
    pb_result r = split_make(t, true, &tree, &k, NULL, err);
    if (r != PB_SUCCESS) return r;
    *count = k;
    if (nodes && capacity < k)
        r = pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the split tree has %u nodes, room for %u given", k, capacity);
    else if (nodes)
        memcpy(nodes, tree, (size_t)k * sizeof(uint32_t));
    free(tree);
    return r;
}

int32_t pb_cotree_split_tree_find(const uint32_t *nodes, const uint32_t root_grid[3], uint32_t root_level,
                                  const uint32_t q[3])
{
    if (!nodes || !root_grid || !q || root_level > PB_COTREE_MAX_LEVEL) return -1;
    uint32_t lo[3], lv[3], cell[3];
    for (int k = 0; k < 3; k++) {
        cell[k] = q[k] >> root_level;
        if (cell[k] >= root_grid[k]) return -1;
        lo[k] = cell[k] << root_level, lv[k] = root_level;
    }
    uint64_t root = cell[0] + (uint64_t)root_grid[0] * (cell[1] + (uint64_t)root_grid[1] * cell[2]);
    if (root >= SPLIT_MAX_NODES) return -1;
    return split_descend(nodes, (uint32_t)root, lo, lv, q);
}

/* ---- the nesting rule ------------------------------------------------------------------------------ */

/* Leaf i below the face on axis a, leaf j above it, sharing part of it; b < c the face's axes. A cross
 * (i finer on one, coarser on the other): the leaf coarser on the axis of the smaller level difference
 * splits along it; a tie: i, the leaf on the lower side. */
static void cross_check(const pb_cotree *t, uint32_t i, uint32_t j, uint32_t b, uint32_t c, uint8_t *axes)
{
    const uint32_t *vi = t->levels + 3u * i, *vj = t->levels + 3u * j;
    int db = (int)vj[b] - (int)vi[b], dc = (int)vi[c] - (int)vj[c];
    if (db > 0 && dc > 0) { /* i finer on b, coarser on c */
        if (dc <= db)
            axes[i] |= (uint8_t)(1u << c);
        else
            axes[j] |= (uint8_t)(1u << b);
    } else if (db < 0 && dc < 0) { /* i coarser on b, finer on c */
        if (-db <= -dc)
            axes[i] |= (uint8_t)(1u << b);
        else
            axes[j] |= (uint8_t)(1u << c);
    }
}

/* The leaves above the rectangle [b0, b0 + 2^lb) x [c0, c0 + 2^lc) of leaf i's upper face on axis a
 * (plane u_a = hi): the box over the rectangle's min corner either covers it or the rectangle is halved
 * where the box is smaller (depth ≤ lb + lc). */
static void face_walk(const pb_cotree *t, uint32_t i, uint32_t a, uint32_t hi, uint32_t b0, uint32_t lb, uint32_t c0,
                      uint32_t lc, uint8_t *axes)
{
    uint32_t b = a == 0 ? 1u : 0u, c = a == 2 ? 1u : 2u, q[3], lo[3], lv[3];
    q[a] = hi, q[b] = b0, q[c] = c0;
    int32_t j = locate_box(t, q, lo, lv);
    if (lv[b] >= lb && lv[c] >= lc) {
        if (j >= 0) cross_check(t, i, (uint32_t)j, b, c, axes);
    } else if (lv[b] < lb) {
        face_walk(t, i, a, hi, b0, lb - 1u, c0, lc, axes);
        face_walk(t, i, a, hi, b0 + (1u << (lb - 1u)), lb - 1u, c0, lc, axes);
    } else {
        face_walk(t, i, a, hi, b0, lb, c0, lc - 1u, axes);
        face_walk(t, i, a, hi, b0, lb, c0 + (1u << (lc - 1u)), lc - 1u, axes);
    }
}

pb_result _pb_cotree_apply_nesting(pb_cotree *t, pb_error *err)
{
    for (;;) {
        uint8_t *axes = calloc((size_t)t->leaf_count + 1u, 1);
        if (!axes) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u split masks", t->leaf_count);
        for (uint32_t i = 0; i < t->leaf_count; i++) {
            const uint32_t *l = t->leaves + 4u * i, *v = t->levels + 3u * i;
            for (uint32_t a = 0; a < 3; a++) {
                uint32_t hi = l[a] + (1u << v[a]), b = a == 0 ? 1u : 0u, c = a == 2 ? 1u : 2u;
                if (hi < t->dims[a]) face_walk(t, i, a, hi, l[b], v[b], l[c], v[c], axes);
            }
        }
        uint32_t n = 0;
        for (uint32_t i = 0; i < t->leaf_count; i++) n += axes[i] != 0;
        pb_result r = n ? pb_cotree_split_axes(t, axes, NULL, err) : PB_SUCCESS;
        free(axes);
        if (r != PB_SUCCESS || !n) return r;
        t->forced += n;
    }
}
