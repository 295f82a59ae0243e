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
    free(tree->leaves);
    free(tree);
}

static int cmp_leaf_morton(const void *pa, const void *pb)
{
    const uint32_t *a = pa, *b = pb;
    uint64_t ma = pb_morton3_(a[0], a[1], a[2]), mb = pb_morton3_(b[0], b[1], b[2]);
    if (ma != mb) return ma < mb ? -1 : 1;
    return a[3] < b[3] ? 1 : (a[3] > b[3] ? -1 : 0); /* larger first: an overlap shows as nesting */
}

/* Sorts the leaves, rebuilds the corner map and checks alignment, bounds and non-overlap. */
static pb_result cotree_index_leaves(pb_cotree *t, pb_error *err)
{
    qsort(t->leaves, t->leaf_count, 4 * sizeof(uint32_t), cmp_leaf_morton);
    hmap_free(&t->leaf_map);
    if (!hmap_init(&t->leaf_map, t->leaf_count))
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u leaves", t->leaf_count);
    t->max_level = 0;
    uint64_t prev_end = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        const uint32_t *l = t->leaves + 4u * i;
        if (l[3] > PB_COTREE_MAX_LEVEL)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "leaf %u has level %u, above the limit %u", i, l[3],
                                PB_COTREE_MAX_LEVEL);
        uint32_t s = 1u << l[3];
        for (int k = 0; k < 3; k++) {
            if (l[k] % s != 0)
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "leaf %u at (%u, %u, %u) level %u is not aligned to its size %u", i, l[0], l[1],
                                    l[2], l[3], s);
            if ((uint64_t)l[k] + s > t->dims[k])
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "leaf %u at (%u, %u, %u) level %u reaches past the lattice extent %u on axis %c", i,
                                    l[0], l[1], l[2], l[3], t->dims[k], "XYZ"[k]);
        }
        uint64_t start = pb_morton3_(l[0], l[1], l[2]);
        if (i > 0 && start < prev_end)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "leaf %u at (%u, %u, %u) level %u overlaps another leaf", i, l[0], l[1], l[2], l[3]);
        prev_end = start + ((uint64_t)1 << (3u * l[3]));
        bool inserted;
        *hmap_put(&t->leaf_map, pack3(l[0], l[1], l[2]), &inserted) = i;
        if (l[3] > t->max_level) t->max_level = l[3];
    }
    return PB_SUCCESS;
}

static pb_result cotree_alloc(const double origin[3], double min_cell, const uint32_t dims[3], pb_cotree **out,
                              pb_error *err)
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
    if (!t) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    memcpy(t->origin, origin, sizeof t->origin);
    t->h = min_cell;
    memcpy(t->dims, dims, sizeof t->dims);
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
    pb_result r = cotree_alloc(origin, min_cell, dims, &t, err);
    if (r != PB_SUCCESS) return r;
    t->leaves = malloc((size_t)n * 4 * sizeof(uint32_t));
    if (!t->leaves) {
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu leaves", (unsigned long long)n);
    }
    uint32_t s = 1u << root_level, i = 0;
    for (uint32_t z = 0; z < root_dims[2]; z++)
        for (uint32_t y = 0; y < root_dims[1]; y++)
            for (uint32_t x = 0; x < root_dims[0]; x++, i++) {
                uint32_t *l = t->leaves + 4u * i;
                l[0] = x * s, l[1] = y * s, l[2] = z * s, l[3] = root_level;
            }
    t->leaf_count = (uint32_t)n;
    r = cotree_index_leaves(t, err);
    if (r != PB_SUCCESS) {
        pb_cotree_destroy(t);
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_cotree_create_leaves(const double origin[3], double min_cell, const uint32_t dims[3],
                                  const uint32_t *leaves, uint32_t leaf_count, pb_cotree **out, pb_error *err)
{
    if (leaf_count > 0 && !leaves) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "corner octree: NULL leaves");
    if (leaf_count > PB_COTREE_MAX_LEAVES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%u leaves are above the limit of %u leaves", leaf_count,
                            PB_COTREE_MAX_LEAVES);
    pb_cotree *t;
    pb_result r = cotree_alloc(origin, min_cell, dims, &t, err);
    if (r != PB_SUCCESS) return r;
    t->leaves = malloc(((size_t)leaf_count + 1u) * 4 * sizeof(uint32_t));
    if (!t->leaves) {
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u leaves", leaf_count);
    }
    if (leaf_count) memcpy(t->leaves, leaves, (size_t)leaf_count * 4 * sizeof(uint32_t));
    t->leaf_count = leaf_count;
    r = cotree_index_leaves(t, err);
    if (r != PB_SUCCESS) {
        pb_cotree_destroy(t);
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_cotree_drop(pb_cotree *t, const uint8_t *drop, pb_error *err)
{
    if (!t || !drop) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_drop: NULL argument");
    uint32_t n = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++)
        if (!drop[i]) memmove(t->leaves + 4u * n++, t->leaves + 4u * i, 4 * sizeof(uint32_t));
    t->leaf_count = n;
    cotree_clear_nodes(t);
    return cotree_index_leaves(t, err);
}

pb_result pb_cotree_split(pb_cotree *t, const uint8_t *split, uint32_t *split_count, pb_error *err)
{
    if (!t || !split) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_split: NULL argument");
    uint64_t n = 0, splits = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        bool s = split[i] && t->leaves[4u * i + 3] > 0;
        n += s ? 8u : 1u;
        splits += s;
    }
    if (n > PB_COTREE_MAX_LEAVES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "splitting %llu leaves gives %llu leaves, above the limit of %u",
                            (unsigned long long)splits, (unsigned long long)n, PB_COTREE_MAX_LEAVES);
    uint32_t *nl = malloc((size_t)(n + 1) * 4 * sizeof(uint32_t));
    if (!nl) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu leaves", (unsigned long long)n);
    uint32_t k = 0;
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        const uint32_t *l = t->leaves + 4u * i;
        if (split[i] && l[3] > 0) {
            uint32_t s = 1u << (l[3] - 1);
            for (uint32_t c = 0; c < 8; c++, k++) {
                uint32_t *o = nl + 4u * k;
                o[0] = l[0] + (c & 1 ? s : 0), o[1] = l[1] + (c & 2 ? s : 0), o[2] = l[2] + (c & 4 ? s : 0);
                o[3] = l[3] - 1;
            }
        } else {
            memcpy(nl + 4u * k++, l, 4 * sizeof(uint32_t));
        }
    }
    free(t->leaves);
    t->leaves = nl;
    t->leaf_count = k;
    cotree_clear_nodes(t);
    if (split_count) *split_count = (uint32_t)splits;
    return cotree_index_leaves(t, err);
}

typedef struct node_tmp {
    uint32_t p[3];
    int32_t host;   /* leaf it hangs on, −1 = probe */
    uint32_t level; /* host level */
    uint64_t morton;
} node_tmp;

static int cmp_node(const void *pa, const void *pb)
{
    const node_tmp *a = pa, *b = pb;
    bool ha = a->host >= 0, hb = b->host >= 0;
    if (ha != hb) return ha ? 1 : -1;                                    /* probes first */
    if (ha && a->level != b->level) return a->level > b->level ? -1 : 1; /* largest host first */
    return a->morton < b->morton ? -1 : (a->morton > b->morton ? 1 : 0);
}

pb_result pb_cotree_finalize(pb_cotree *t, pb_error *err)
{
    if (!t) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_finalize: NULL tree");
    cotree_clear_nodes(t);
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
        const uint32_t *l = t->leaves + 4u * i;
        uint32_t s = 1u << l[3];
        for (uint32_t c = 0; c < 8; c++) {
            uint32_t p[3] = {l[0] + (c & 1 ? s : 0), l[1] + (c & 2 ? s : 0), l[2] + (c & 4 ? s : 0)};
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
    /* Hanging test: the largest leaf around p that has p on its boundary but not as a corner. */
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
            const uint32_t *l = t->leaves + 4u * (uint32_t)li;
            uint32_t s = 1u << l[3];
            bool corner = true;
            for (int k = 0; k < 3; k++)
                if (nd->p[k] != l[k] && nd->p[k] != l[k] + s) corner = false;
            if (corner) continue;
            if (nd->host < 0 || l[3] > nd->level || (l[3] == nd->level && li < nd->host)) {
                nd->host = li;
                nd->level = l[3];
            }
        }
    }
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
        const uint32_t *l = t->leaves + 4u * (uint32_t)nd->host;
        double s = (double)(1u << l[3]), tt[3], w8[8];
        for (int k = 0; k < 3; k++) tt[k] = ((double)nd->p[k] - l[k]) / s;
        trilinear8(tt, w8);
        uint32_t ns = 0, cnt = 0;
        t->exp_start[hI] = e;
        for (uint32_t c = 0; c < 8; c++) {
            if (w8[c] <= 0.0) continue;
            uint32_t cs = 1u << l[3];
            uint32_t cp[3] = {l[0] + (c & 1 ? cs : 0), l[1] + (c & 2 ? cs : 0), l[2] + (c & 4 ? cs : 0)};
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
        const uint32_t *l = t->leaves + 4u * i;
        uint32_t s = 1u << l[3];
        for (uint32_t c = 0; c < 8; c++) {
            uint32_t v = 0;
            (void)hmap_get(&t->node_map, pack3(l[0] + (c & 1 ? s : 0), l[1] + (c & 2 ? s : 0), l[2] + (c & 4 ? s : 0)),
                           &v);
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
    if (!t || !out) return;
    for (uint32_t i = 0; i < t->leaf_count; i++)
        for (int k = 0; k < 3; k++) out[3u * i + (uint32_t)k] = t->leaves[4u * i + 3u];
}
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

pb_result pb_cotree_pair_visibility(const pb_cotree *t, pb_segment_fn segment, void *user, uint8_t *out, pb_error *err)
{
    if (!t || !segment || (!out && t->leaf_count))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_cotree_pair_visibility: NULL argument");
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        const uint32_t *l = t->leaves + 4u * i;
        double s = (double)(1u << l[3]), p[8][3];
        for (uint32_t c = 0; c < 8; c++)
            for (int k = 0; k < 3; k++) p[c][k] = t->origin[k] + ((double)l[k] + ((c >> k) & 1u ? s : 0.0)) * t->h;
        uint8_t *o = out + 64u * i;
        for (uint32_t k = 0; k < 8; k++)
            for (uint32_t c = 0; c < 8; c++) {
                double f = 1.0;
                /* A segment along a leaf edge or face lies in the faces of the leaves around it, where
                 * walls and ceilings modelled on the lattice planes lie too (hit or missed by rounding):
                 * it is traced once moved by PB_VIS_SHIFT min cells to each side across every axis on
                 * which its ends agree, and the first hit of any counts. The same rays from every leaf
                 * sharing the segment: the table, and so the field, stays continuous across leaves. */
                uint32_t flat = 7u & ~(k ^ c); /* axes on which the two corners agree */
                uint32_t combos = 1u << ((flat & 1u) + ((flat >> 1) & 1u) + ((flat >> 2) & 1u));
                for (uint32_t m = 0; k != c && m < combos; m++) {
                    double a[3], b[3];
                    uint32_t bit = 0;
                    for (int ax = 0; ax < 3; ax++) {
                        double d = 0.0;
                        if ((flat >> ax) & 1u) d = ((m >> bit++) & 1u ? PB_VIS_SHIFT : -PB_VIS_SHIFT) * t->h;
                        a[ax] = p[c][ax] + d;
                        b[ax] = p[k][ax] + d;
                    }
                    double fm = segment(user, a, b);
                    if (fm < f) f = fm;
                }
                /* NaN or beyond the ends: clear; a hit at the very start still leaves 1/255. */
                long q = !(f < 1.0) ? (long)PB_VIS_CLEAR : lround(255.0 * (f > 0.0 ? f : 0.0));
                o[8u * k + c] = (uint8_t)(q < 1 ? 1 : (q > (long)PB_VIS_CLEAR ? (long)PB_VIS_CLEAR : q));
            }
    }
    return PB_SUCCESS;
}
