/* Interpolation between probes at their real positions: corner octree with hanging nodes, and
 * Delaunay tetrahedra (qhull). See pb_interp.h and docs/placement.md, "Interpolation".
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
#include "schnee/pb_interp.h"

#include "schnee/pb_sh.h"

#include "pb_morton.h"

#include <libqhull_r/qhull_ra.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define HANG_MAX_EXPANDED 32u /* probes one hanging node may depend on (after merging) */

/* ---- small hash map uint64 → uint32 (open addressing, linear probing) ------------------------------- */

typedef struct hmap {
    uint64_t *keys; /* UINT64_MAX = empty */
    uint32_t *vals;
    size_t cap; /* power of two */
    size_t count;
} hmap;

static void hmap_free(hmap *m)
{
    free(m->keys);
    free(m->vals);
    memset(m, 0, sizeof *m);
}

static inline size_t hmap_hash(uint64_t k)
{
    k ^= k >> 33;
    k *= UINT64_C(0xff51afd7ed558ccd);
    k ^= k >> 33;
    k *= UINT64_C(0xc4ceb9fe1a85ec53);
    k ^= k >> 33;
    return (size_t)k;
}

static bool hmap_init(hmap *m, size_t expected)
{
    memset(m, 0, sizeof *m);
    size_t cap = 16;
    while (cap < expected * 2 + 16) cap <<= 1;
    m->keys = malloc(cap * sizeof *m->keys);
    m->vals = malloc(cap * sizeof *m->vals);
    if (!m->keys || !m->vals) {
        hmap_free(m);
        return false;
    }
    memset(m->keys, 0xff, cap * sizeof *m->keys);
    m->cap = cap;
    return true;
}

/* Inserts (or finds) key; returns the slot's value pointer, *inserted tells which. No growth: the
 * callers size the map for the keys they insert. */
static uint32_t *hmap_put(hmap *m, uint64_t key, bool *inserted)
{
    size_t mask = m->cap - 1, i = hmap_hash(key) & mask;
    while (m->keys[i] != UINT64_MAX && m->keys[i] != key) i = (i + 1) & mask;
    *inserted = m->keys[i] == UINT64_MAX;
    if (*inserted) {
        m->keys[i] = key;
        m->vals[i] = 0;
        m->count++;
    }
    return &m->vals[i];
}

static bool hmap_get(const hmap *m, uint64_t key, uint32_t *val)
{
    if (!m->cap) return false;
    size_t mask = m->cap - 1, i = hmap_hash(key) & mask;
    while (m->keys[i] != UINT64_MAX) {
        if (m->keys[i] == key) {
            *val = m->vals[i];
            return true;
        }
        i = (i + 1) & mask;
    }
    return false;
}

/* ---- lattice keys and Morton order ------------------------------------------------------------------ */

static inline uint64_t pack3(uint32_t x, uint32_t y, uint32_t z)
{
    return (uint64_t)x | (uint64_t)y << 21 | (uint64_t)z << 42;
}

/* ---- corner octree ------------------------------------------------------------------------------------ */

struct pb_cotree {
    double origin[3];
    double h;
    uint32_t dims[3];
    uint32_t *leaves; /* leaf_count × (x, y, z, level) */
    uint32_t leaf_count;
    uint32_t max_level;
    hmap leaf_map; /* pack(min corner) → leaf */
    bool finalized;
    uint32_t probe_count;
    uint32_t *probe_lattice; /* probe_count × 3 */
    uint32_t hanging_count;
    uint32_t *hang_lattice; /* hanging_count × 3 */
    uint32_t *hang_src;     /* hanging_count × 4 node indices */
    float *hang_w;          /* hanging_count × 4 */
    uint32_t *exp_start;    /* hanging_count + 1: CSR of the expanded probe weights */
    uint32_t *exp_probe;
    double *exp_w;
    hmap node_map;    /* pack(lattice) → node index (probes first, then hanging) */
    int32_t *corners; /* leaf_count × 8 node indices */
};

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

/* Leaf holding the unit lattice cell with min corner q, or −1. */
static int32_t locate_cell(const pb_cotree *t, const uint32_t q[3])
{
    for (uint32_t lv = 0; lv <= t->max_level; lv++) {
        uint32_t mask = ~((1u << lv) - 1u), i;
        if (hmap_get(&t->leaf_map, pack3(q[0] & mask, q[1] & mask, q[2] & mask), &i) && t->leaves[4u * i + 3] == lv)
            return (int32_t)i;
    }
    return -1;
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

/* Adds w·(node's expansion) into a small merged list. */
static bool merge_add(uint32_t *probe, double *weight, uint32_t *count, uint32_t cap, uint32_t p, double w)
{
    for (uint32_t i = 0; i < *count; i++)
        if (probe[i] == p) {
            weight[i] += w;
            return true;
        }
    if (*count >= cap) return false;
    probe[*count] = p;
    weight[*count] = w;
    (*count)++;
    return true;
}

static void trilinear8(const double t[3], double w[8])
{
    for (int c = 0; c < 8; c++)
        w[c] = (c & 1 ? t[0] : 1 - t[0]) * (c & 2 ? t[1] : 1 - t[1]) * (c & 4 ? t[2] : 1 - t[2]);
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

/* Lattice coordinates u of a point and the unit cell holding it (max faces closed). */
static bool point_cell(const pb_cotree *t, const double point[3], double u[3], uint32_t q[3])
{
    for (int k = 0; k < 3; k++) {
        u[k] = (point[k] - t->origin[k]) / t->h;
        if (!(u[k] >= 0.0) || !(u[k] <= (double)t->dims[k])) return false;
        double f = floor(u[k]);
        q[k] = f >= (double)t->dims[k] ? t->dims[k] - 1 : (uint32_t)f;
    }
    return true;
}

/* The leaf holding lattice point u in unit cell q. A point on a face between a leaf and a lattice
 * cell no leaf covers (the sparse tree's outer faces, e.g. a wall's surface on a volume's max face)
 * belongs to the leaf: within PB_COTREE_FACE_EPS units of a cell's lower face the cells below are
 * tried too (x first, then y, then z and their combinations, in the order of the bit mask), so such a
 * surface does not flicker between the leaf and nothing with its coordinates' rounding. Mirrored by
 * octree_locate_point() in shaders/shading.glsl. */
#define PB_COTREE_FACE_EPS 0.01
static int32_t locate_point_cell(const pb_cotree *t, const double u[3], const uint32_t q[3])
{
    int32_t li = locate_cell(t, q);
    for (uint32_t m = 1; li < 0 && m < 8; m++) {
        uint32_t r[3];
        bool ok = true;
        for (int k = 0; k < 3; k++) {
            bool down = (m >> k) & 1u;
            if (down && !(q[k] > 0 && u[k] - (double)q[k] < PB_COTREE_FACE_EPS)) ok = false;
            r[k] = down ? q[k] - 1 : q[k];
        }
        if (ok) li = locate_cell(t, r);
    }
    return li;
}

int32_t pb_cotree_locate(const pb_cotree *t, const double point[3])
{
    if (!t || !point) return -1;
    double u[3];
    uint32_t q[3];
    if (!point_cell(t, point, u, q)) return -1;
    return locate_point_cell(t, u, q);
}

/* Drops invisible / invalid probes and zero weights, renormalises. */
static void finish_weights(pb_interp_weights *w, const double point[3], const pb_interp_options *opt)
{
    uint32_t n = 0;
    double sum = 0.0;
    for (uint32_t i = 0; i < w->count; i++) {
        uint32_t p = w->probe[i];
        double wi = w->weight[i];
        if (!(wi > 0.0)) continue;
        if (opt && opt->validity && !(opt->validity[p] > 0.0f)) continue;
        if (opt && opt->visible && !opt->visible(opt->visible_user, p, point)) continue;
        w->probe[n] = p;
        w->weight[n] = wi;
        sum += wi;
        n++;
    }
    if (!(sum > 0.0)) n = 0;
    for (uint32_t i = 0; i < n; i++) w->weight[i] /= sum;
    w->count = n;
}

static void leaf_weights(const pb_cotree *t, int32_t li, const double u[3], const double point[3],
                         const pb_interp_options *opt, pb_interp_weights *out);

pb_result pb_interp_query_cotree(const pb_cotree *t, const double point[3], const pb_interp_options *opt,
                                 pb_interp_weights *out)
{
    if (!t || !point || !out) return pb_error_set(NULL, PB_ERROR_INVALID_ARGUMENT, "NULL argument");
    out->count = 0;
    if (!t->finalized) return PB_ERROR_INVALID_ARGUMENT;
    double u[3];
    uint32_t q[3];
    if (!point_cell(t, point, u, q)) return PB_SUCCESS;
    int32_t li = locate_point_cell(t, u, q);
    if (li < 0) return PB_SUCCESS;
    leaf_weights(t, li, u, point, opt, out);
    return PB_SUCCESS;
}

pb_result pb_interp_query_cotree_leaf(const pb_cotree *t, uint32_t leaf, const double point[3],
                                      const pb_interp_options *opt, pb_interp_weights *out)
{
    if (!t || !point || !out) return PB_ERROR_INVALID_ARGUMENT;
    out->count = 0;
    if (!t->finalized || leaf >= t->leaf_count) return PB_ERROR_INVALID_ARGUMENT;
    double u[3];
    for (int k = 0; k < 3; k++) u[k] = (point[k] - t->origin[k]) / t->h;
    leaf_weights(t, (int32_t)leaf, u, point, opt, out);
    return PB_SUCCESS;
}

/* smoothstep(1/2, 1/2 + PB_VIS_RAMP, v): GLSL's smoothstep, as shading.glsl's octree_irradiance. */
static double vis_ramp(double v)
{
    double x = (v - 0.5) / PB_VIS_RAMP;
    x = x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
    return x * x * (3.0 - 2.0 * x);
}

/* The corner weights w8 of leaf li expanded over the probes (hanging corners through their rules),
 * then validity / visibility dropped and renormalised (finish_weights). */
static void expand_weights(const pb_cotree *t, int32_t li, const double w8[8], const double point[3],
                           const pb_interp_options *opt, pb_interp_weights *out)
{
    out->count = 0;
    for (uint32_t c = 0; c < 8; c++) {
        if (w8[c] <= 0.0) continue;
        uint32_t node = (uint32_t)t->corners[8u * (uint32_t)li + c];
        if (node < t->probe_count) {
            (void)merge_add(out->probe, out->weight, &out->count, PB_INTERP_MAX_WEIGHTS, node, w8[c]);
        } else {
            uint32_t hI = node - t->probe_count;
            for (uint32_t e = t->exp_start[hI]; e < t->exp_start[hI + 1]; e++)
                (void)merge_add(out->probe, out->weight, &out->count, PB_INTERP_MAX_WEIGHTS, t->exp_probe[e],
                                w8[c] * t->exp_w[e]);
        }
    }
    finish_weights(out, point, opt);
}

static void leaf_weights(const pb_cotree *t, int32_t li, const double u[3], const double point[3],
                         const pb_interp_options *opt, pb_interp_weights *out)
{
    const uint32_t *l = t->leaves + 4u * (uint32_t)li;
    double s = (double)(1u << l[3]), tt[3], w8[8];
    for (int k = 0; k < 3; k++) {
        tt[k] = (u[k] - l[k]) / s;
        tt[k] = tt[k] < 0.0 ? 0.0 : (tt[k] > 1.0 ? 1.0 : tt[k]);
    }
    trilinear8(tt, w8);
    if (opt && opt->pair_visibility) {
        /* The visibility field (pb_interp.h): each corner's weight times the ramp of its blended
         * visibility; when that leaves nothing, the plain weights below. */
        const uint8_t *pv = opt->pair_visibility + 64u * (uint32_t)li;
        double wv[8];
        for (uint32_t c = 0; c < 8; c++) {
            double v = 0.0;
            for (uint32_t k = 0; k < 8; k++) v += w8[k] * pb_vis_pair_value(pv[8u * k + c]);
            wv[c] = w8[c] > 0.0 ? w8[c] * vis_ramp(v) : 0.0;
        }
        expand_weights(t, li, wv, point, opt, out);
        if (out->count) return;
    }
    expand_weights(t, li, w8, point, opt, out);
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

/* ---- tetrahedra -------------------------------------------------------------------------------------- */

struct pb_tetra {
    uint32_t point_count;
    double *points; /* point_count × 3 */
    uint32_t tet_count;
    uint32_t *tets;     /* × 4 */
    int32_t *nbr;       /* × 4 */
    double *inv;        /* × 12: rows of the inverse of [v1−v0, v2−v0, v3−v0]ᵀ, then v0; NaN = degenerate */
    double lo[3], cell; /* acceleration grid */
    uint32_t gdims[3];
    uint32_t *gstart; /* cells + 1 */
    uint32_t *gtets;
};

void pb_tetra_destroy(pb_tetra *t)
{
    if (!t) return;
    free(t->points);
    free(t->tets);
    free(t->nbr);
    free(t->inv);
    free(t->gstart);
    free(t->gtets);
    free(t);
}

uint32_t pb_tetra_count(const pb_tetra *t) { return t ? t->tet_count : 0; }
uint32_t pb_tetra_point_count(const pb_tetra *t) { return t ? t->point_count : 0; }
const uint32_t *pb_tetra_tets(const pb_tetra *t) { return t ? t->tets : NULL; }
const int32_t *pb_tetra_neighbours(const pb_tetra *t) { return t ? t->nbr : NULL; }

typedef struct face_ref {
    uint32_t v[3];
    uint32_t tet;
    uint32_t i;
} face_ref;

static int cmp_face(const void *pa, const void *pb)
{
    const face_ref *a = pa, *b = pb;
    for (int k = 0; k < 3; k++)
        if (a->v[k] != b->v[k]) return a->v[k] < b->v[k] ? -1 : 1;
    return a->tet < b->tet ? -1 : (a->tet > b->tet ? 1 : 0);
}

static void sort3(uint32_t v[3])
{
    uint32_t tmp;
    if (v[0] > v[1]) tmp = v[0], v[0] = v[1], v[1] = tmp;
    if (v[1] > v[2]) tmp = v[1], v[1] = v[2], v[2] = tmp;
    if (v[0] > v[1]) tmp = v[0], v[0] = v[1], v[1] = tmp;
}

/* Neighbours, inverse matrices and the acceleration grid, from points + tets. */
static pb_result tetra_index(pb_tetra *t, pb_error *err)
{
    uint32_t T = t->tet_count;
    t->nbr = malloc(((size_t)T * 4 + 1) * sizeof(int32_t));
    t->inv = malloc(((size_t)T * 12 + 1) * sizeof(double));
    face_ref *f = malloc(((size_t)T * 4 + 1) * sizeof *f);
    if (!t->nbr || !t->inv || !f) {
        free(f);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u tetrahedra", T);
    }
    for (uint32_t i = 0; i < T; i++)
        for (uint32_t k = 0; k < 4; k++) {
            face_ref *r = f + 4u * i + k;
            for (uint32_t m = 0, n = 0; m < 4; m++)
                if (m != k) r->v[n++] = t->tets[4u * i + m];
            sort3(r->v);
            r->tet = i;
            r->i = k;
            t->nbr[4u * i + k] = -1;
        }
    qsort(f, (size_t)T * 4, sizeof *f, cmp_face);
    for (size_t j = 0; j + 1 < (size_t)T * 4; j++)
        if (memcmp(f[j].v, f[j + 1].v, sizeof f[j].v) == 0) {
            t->nbr[4u * f[j].tet + f[j].i] = (int32_t)f[j + 1].tet;
            t->nbr[4u * f[j + 1].tet + f[j + 1].i] = (int32_t)f[j].tet;
            j++;
        }
    free(f);

    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < t->point_count; i++)
        for (int k = 0; k < 3; k++) {
            double v = t->points[3u * i + (uint32_t)k];
            lo[k] = v < lo[k] ? v : lo[k];
            hi[k] = v > hi[k] ? v : hi[k];
        }
    for (uint32_t i = 0; i < T; i++) {
        const double *v0 = t->points + 3u * t->tets[4u * i];
        double m[3][3], maxe = 0.0;
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) {
                m[r][k] = t->points[3u * t->tets[4u * i + (uint32_t)r + 1] + (uint32_t)k] - v0[k];
                maxe = fmax(maxe, fabs(m[r][k]));
            }
        /* m rows are edges e_r; barycentrics λ_r = (M⁻ᵀ (p − v0))_r with M = [e0 e1 e2] as columns. */
        double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                     m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        double *o = t->inv + 12u * i;
        if (!(fabs(det) > 1e-12 * maxe * maxe * maxe)) {
            for (int k = 0; k < 12; k++) o[k] = NAN;
            continue;
        }
        /* Inverse of the matrix whose columns are e0, e1, e2 = transpose of m: inv(mᵀ) = inv(m)ᵀ. */
        double c[3][3];
        c[0][0] = m[1][1] * m[2][2] - m[1][2] * m[2][1];
        c[0][1] = m[1][2] * m[2][0] - m[1][0] * m[2][2];
        c[0][2] = m[1][0] * m[2][1] - m[1][1] * m[2][0];
        c[1][0] = m[0][2] * m[2][1] - m[0][1] * m[2][2];
        c[1][1] = m[0][0] * m[2][2] - m[0][2] * m[2][0];
        c[1][2] = m[0][1] * m[2][0] - m[0][0] * m[2][1];
        c[2][0] = m[0][1] * m[1][2] - m[0][2] * m[1][1];
        c[2][1] = m[0][2] * m[1][0] - m[0][0] * m[1][2];
        c[2][2] = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        /* c is the cofactor matrix of m: inv(m) = cᵀ/det, so inv(mᵀ) = c/det; row r gives λ_{r+1}. */
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) o[3 * r + k] = c[r][k] / det;
        for (int k = 0; k < 3; k++) o[9 + k] = v0[k];
    }

    /* Uniform grid, about 2 tetrahedra per cell, at most 128 cells per axis. */
    double ext = fmax(fmax(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
    double vol = fmax(hi[0] - lo[0], ext * 1e-3) * fmax(hi[1] - lo[1], ext * 1e-3) * fmax(hi[2] - lo[2], ext * 1e-3);
    double cell = cbrt(vol / fmax((double)T / 2.0, 1.0));
    if (!(cell > 0.0)) cell = 1.0;
    uint64_t cells = 1;
    for (int k = 0; k < 3; k++) {
        double d = ceil((hi[k] - lo[k]) / cell);
        if (d < 1) d = 1;
        if (d > 128) d = 128;
        t->gdims[k] = (uint32_t)d;
        cells *= t->gdims[k];
    }
    for (int k = 0; k < 3; k++) {
        /* One cell size for all axes would overflow 128 on flat sets: per-axis via the max. */
        double c = (hi[k] - lo[k]) / t->gdims[k];
        if (c > cell) cell = c;
    }
    memcpy(t->lo, lo, sizeof lo);
    t->cell = cell;
    t->gstart = calloc((size_t)cells + 1, sizeof(uint32_t));
    if (!t->gstart) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the tetrahedron grid");
    uint64_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            uint32_t run = 0;
            for (uint64_t c = 0; c < cells; c++) {
                uint32_t k = t->gstart[c];
                t->gstart[c] = run;
                run += k;
            }
            t->gstart[cells] = run;
            total = run;
            t->gtets = malloc(((size_t)total + 1) * sizeof(uint32_t));
            if (!t->gtets) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the tetrahedron grid");
        }
        uint32_t *fill = NULL;
        if (pass == 1) {
            fill = malloc(((size_t)cells + 1) * sizeof(uint32_t));
            if (!fill) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the tetrahedron grid");
            memcpy(fill, t->gstart, (size_t)cells * sizeof(uint32_t));
        }
        for (uint32_t i = 0; i < T; i++) {
            if (isnan(t->inv[12u * i])) continue;
            uint32_t a[3], b[3];
            for (int k = 0; k < 3; k++) {
                double mn = INFINITY, mx = -INFINITY;
                for (int v = 0; v < 4; v++) {
                    double x = t->points[3u * t->tets[4u * i + (uint32_t)v] + (uint32_t)k];
                    mn = fmin(mn, x), mx = fmax(mx, x);
                }
                double ga = floor((mn - lo[k]) / cell - 1e-9), gb = floor((mx - lo[k]) / cell + 1e-9);
                a[k] = ga < 0 ? 0 : (ga >= t->gdims[k] ? t->gdims[k] - 1 : (uint32_t)ga);
                b[k] = gb < 0 ? 0 : (gb >= t->gdims[k] ? t->gdims[k] - 1 : (uint32_t)gb);
            }
            for (uint32_t z = a[2]; z <= b[2]; z++)
                for (uint32_t y = a[1]; y <= b[1]; y++)
                    for (uint32_t x = a[0]; x <= b[0]; x++) {
                        uint64_t c = x + (uint64_t)t->gdims[0] * (y + (uint64_t)t->gdims[1] * z);
                        if (pass == 0)
                            t->gstart[c]++;
                        else
                            t->gtets[fill[c]++] = i;
                    }
        }
        free(fill);
    }
    return PB_SUCCESS;
}

static pb_result tetra_alloc(const double *positions, uint32_t count, pb_tetra **out, pb_error *err)
{
    if (!positions || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "tetrahedra: NULL argument");
    *out = NULL;
    if (count < 4)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "%u probes cannot be tetrahedralised; at least 4 needed",
                            count);
    for (uint64_t i = 0; i < (uint64_t)count * 3; i++)
        if (!isfinite(positions[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %llu position[%llu] is %g",
                                (unsigned long long)(i / 3), (unsigned long long)(i % 3), positions[i]);
    pb_tetra *t = calloc(1, sizeof *t);
    if (!t) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    t->point_count = count;
    t->points = malloc((size_t)count * 3 * sizeof(double));
    if (!t->points) {
        free(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes", count);
    }
    memcpy(t->points, positions, (size_t)count * 3 * sizeof(double));
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_tetra_create(const double *positions, uint32_t count, pb_tetra **out, pb_error *err)
{
    pb_tetra *t;
    pb_result r = tetra_alloc(positions, count, &t, err);
    if (r != PB_SUCCESS) return r;
    char *errbuf = NULL;
    size_t errlen = 0;
    FILE *errfile = open_memstream(&errbuf, &errlen);
    qhT qh_qh;
    qhT *qh = &qh_qh;
    qh_zero(qh, errfile);
    char flags[] = "qhull d Qbb Qc Qz Q12 Qt";
    int exitcode = qh_new_qhull(qh, 3, (int)count, t->points, False, flags, NULL, errfile);
    if (exitcode == 0) {
        facetT *facet;
        vertexT *vertex, **vertexp;
        uint32_t T = 0;
        FORALLfacets
        {
            if (!facet->upperdelaunay) T++;
        }
        t->tets = malloc(((size_t)T + 1) * 4 * sizeof(uint32_t));
        if (!t->tets) {
            r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u tetrahedra", T);
        } else {
            uint32_t i = 0;
            FORALLfacets
            {
                if (facet->upperdelaunay) continue;
                uint32_t k = 0;
                FOREACHvertex_(facet->vertices)
                {
                    if (k < 4) t->tets[4u * i + k] = (uint32_t)qh_pointid(qh, vertex->point);
                    k++;
                }
                if (k == 4) i++; /* Qt makes every facet a simplex; anything else is skipped */
            }
            t->tet_count = i;
        }
    }
    qh_freeqhull(qh, !qh_ALL);
    int curlong, totlong;
    qh_memfreeshort(qh, &curlong, &totlong);
    if (errfile) fclose(errfile);
    if (exitcode != 0) {
        /* qhull's own text (its first line) says why: coplanar input, too few points, ... */
        char first[200] = "";
        if (errbuf) {
            size_t n = strcspn(errbuf, "\n");
            if (n >= sizeof first) n = sizeof first - 1;
            memcpy(first, errbuf, n);
            first[n] = 0;
        }
        r = pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                         "the %u probe positions cannot be tetrahedralised (qhull error %d: %s); are they coplanar?",
                         count, exitcode, first);
    }
    free(errbuf);
    if (r == PB_SUCCESS && t->tet_count == 0)
        r = pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the %u probe positions give no tetrahedron", count);
    if (r == PB_SUCCESS) r = tetra_index(t, err);
    if (r != PB_SUCCESS) {
        pb_tetra_destroy(t);
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_tetra_create_from(const double *positions, uint32_t count, const uint32_t *tets, uint32_t tet_count,
                               pb_tetra **out, pb_error *err)
{
    if (!tets && tet_count) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "tetrahedra: NULL tets");
    pb_tetra *t;
    pb_result r = tetra_alloc(positions, count, &t, err);
    if (r != PB_SUCCESS) return r;
    t->tets = malloc(((size_t)tet_count + 1) * 4 * sizeof(uint32_t));
    if (!t->tets) {
        pb_tetra_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u tetrahedra", tet_count);
    }
    for (uint64_t i = 0; i < (uint64_t)tet_count * 4; i++)
        if (tets[i] >= count) {
            pb_tetra_destroy(t);
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "tetrahedron %llu vertex %llu is %u, not below %u",
                                (unsigned long long)(i / 4), (unsigned long long)(i % 4), tets[i], count);
        }
    if (tet_count) memcpy(t->tets, tets, (size_t)tet_count * 4 * sizeof(uint32_t));
    t->tet_count = tet_count;
    r = tetra_index(t, err);
    if (r != PB_SUCCESS) {
        pb_tetra_destroy(t);
        return r;
    }
    *out = t;
    return PB_SUCCESS;
}

static void tet_bary(const pb_tetra *t, uint32_t i, const double p[3], double l[4])
{
    const double *o = t->inv + 12u * i;
    double d[3] = {p[0] - o[9], p[1] - o[10], p[2] - o[11]};
    l[1] = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
    l[2] = o[3] * d[0] + o[4] * d[1] + o[5] * d[2];
    l[3] = o[6] * d[0] + o[7] * d[1] + o[8] * d[2];
    l[0] = 1.0 - l[1] - l[2] - l[3];
}

/* Best tetrahedron for p (largest smallest barycentric, accepted ≥ −1e-9) and its barycentrics. */
static int32_t tetra_find(const pb_tetra *t, const double p[3], double best_l[4])
{
    if (!t || !p || !t->gstart) return -1;
    uint32_t g[3];
    for (int k = 0; k < 3; k++) {
        double u = (p[k] - t->lo[k]) / t->cell;
        if (!(u >= -1e-9) || !(u <= (double)t->gdims[k] + 1e-9)) return -1;
        double f = floor(u);
        g[k] = f < 0 ? 0 : (f >= t->gdims[k] ? t->gdims[k] - 1 : (uint32_t)f);
    }
    uint64_t c = g[0] + (uint64_t)t->gdims[0] * (g[1] + (uint64_t)t->gdims[1] * g[2]);
    int32_t best = -1;
    double best_min = -1e-9;
    for (uint32_t j = t->gstart[c]; j < t->gstart[c + 1]; j++) {
        uint32_t i = t->gtets[j];
        double l[4];
        tet_bary(t, i, p, l);
        double mn = fmin(fmin(l[0], l[1]), fmin(l[2], l[3]));
        if (mn >= best_min) {
            best_min = mn;
            best = (int32_t)i;
            memcpy(best_l, l, sizeof l);
            if (mn >= 0.0) break; /* inside: any containing tetrahedron gives the same field */
        }
    }
    return best;
}

int32_t pb_tetra_locate(const pb_tetra *t, const double point[3])
{
    double l[4];
    return tetra_find(t, point, l);
}

pb_result pb_interp_query_tetra(const pb_tetra *t, const double point[3], const pb_interp_options *opt,
                                pb_interp_weights *out)
{
    if (!t || !point || !out) return PB_ERROR_INVALID_ARGUMENT;
    out->count = 0;
    double l[4];
    int32_t i = tetra_find(t, point, l);
    if (i < 0) return PB_SUCCESS;
    for (uint32_t k = 0; k < 4; k++) {
        double w = l[k] < 0.0 ? 0.0 : l[k];
        (void)merge_add(out->probe, out->weight, &out->count, PB_INTERP_MAX_WEIGHTS, t->tets[4u * (uint32_t)i + k], w);
    }
    finish_weights(out, point, opt);
    return PB_SUCCESS;
}

/* ---- files --------------------------------------------------------------------------------------------- */

pb_result pb_shprobe_from_cotree(const pb_cotree *t, uint32_t representation, uint32_t max_band, pb_shprobe **out,
                                 pb_error *err)
{
    if (!t || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_from_cotree: NULL argument");
    *out = NULL;
    if (!t->finalized) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the corner octree is not finalized");
    pb_shprobe *p;
    pb_result r = pb_shprobe_create_v3(t->probe_count, representation, max_band, PB_SHPROBE_OCTREE, t->dims,
                                       t->leaf_count, t->hanging_count, &p, err);
    if (r != PB_SUCCESS) return r;
    for (int k = 0; k < 3; k++) p->grid_origin[k] = (float)t->origin[k];
    p->grid_spacing = (float)t->h;
    for (uint32_t i = 0; i < t->probe_count; i++)
        for (int k = 0; k < 3; k++)
            p->positions[3u * i + (uint32_t)k] = (float)(t->origin[k] + t->h * t->probe_lattice[3u * i + (uint32_t)k]);
    memcpy(p->leaves, t->leaves, (size_t)t->leaf_count * 4 * sizeof(uint32_t));
    memcpy(p->leaf_corners, t->corners, (size_t)t->leaf_count * 8 * sizeof(int32_t));
    memcpy(p->hanging_sources, t->hang_src, (size_t)t->hanging_count * 4 * sizeof(uint32_t));
    memcpy(p->hanging_weights, t->hang_w, (size_t)t->hanging_count * 4 * sizeof(float));
    *out = p;
    return PB_SUCCESS;
}

pb_result pb_shprobe_from_tetra(const pb_tetra *t, const double *positions, uint32_t representation, uint32_t max_band,
                                pb_shprobe **out, pb_error *err)
{
    if (!t || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_from_tetra: NULL argument");
    *out = NULL;
    const uint32_t zero[3] = {0, 0, 0};
    pb_shprobe *p;
    pb_result r = pb_shprobe_create_v3(t->point_count, representation, max_band, PB_SHPROBE_TETRA, zero, t->tet_count,
                                       0, &p, err);
    if (r != PB_SUCCESS) return r;
    const double *pos = positions ? positions : t->points;
    for (size_t i = 0; i < (size_t)t->point_count * 3; i++) p->positions[i] = (float)pos[i];
    p->grid_spacing = 1.0f; /* unused by tetrahedra */
    memcpy(p->tets, t->tets, (size_t)t->tet_count * 4 * sizeof(uint32_t));
    memcpy(p->tet_neighbours, t->nbr, (size_t)t->tet_count * 4 * sizeof(int32_t));
    *out = p;
    return PB_SUCCESS;
}

/* A tree with a file's numbering: leaves as stored (Morton order, so the indices survive the sort),
 * corners and hanging rules as stored, expansions recomputed. */
static pb_result cotree_from_file(const pb_shprobe *f, pb_cotree **out, pb_error *err)
{
    static const float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    bool zero = true;
    for (int i = 0; i < 9; i++) zero &= f->grid_axes[i] == 0.0f;
    if (!zero && memcmp(f->grid_axes, identity, sizeof identity) != 0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "octree files with rotated axes are not interpolated by this version (identity only)");
    double origin[3] = {f->grid_origin[0], f->grid_origin[1], f->grid_origin[2]};
    pb_cotree *t;
    pb_result r = pb_cotree_create_leaves(origin, f->grid_spacing, f->grid_dims, f->leaves, f->element_count, &t, err);
    if (r != PB_SUCCESS) return r;
    if (memcmp(t->leaves, f->leaves, (size_t)f->element_count * 4 * sizeof(uint32_t)) != 0) {
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the file's leaves are not in Morton order");
    }
    uint32_t P = f->probe_count, H = f->hanging_count, N = f->element_count;
    t->probe_count = P;
    t->hanging_count = H;
    t->probe_lattice = calloc((size_t)P * 3 + 1, sizeof(uint32_t));
    t->hang_lattice = calloc((size_t)H * 3 + 1, sizeof(uint32_t));
    t->hang_src = malloc(((size_t)H * 4 + 1) * sizeof(uint32_t));
    t->hang_w = malloc(((size_t)H * 4 + 1) * sizeof(float));
    t->exp_start = calloc((size_t)H + 2, sizeof(uint32_t));
    t->exp_probe = malloc(((size_t)H * HANG_MAX_EXPANDED + 1) * sizeof(uint32_t));
    t->exp_w = malloc(((size_t)H * HANG_MAX_EXPANDED + 1) * sizeof(double));
    t->corners = malloc(((size_t)N * 8 + 1) * sizeof(int32_t));
    bool ok = t->probe_lattice && t->hang_lattice && t->hang_src && t->hang_w && t->exp_start && t->exp_probe &&
              t->exp_w && t->corners && hmap_init(&t->node_map, (size_t)N * 8);
    if (!ok) {
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the file's octree");
    }
    memcpy(t->hang_src, f->hanging_sources, (size_t)H * 4 * sizeof(uint32_t));
    memcpy(t->hang_w, f->hanging_weights, (size_t)H * 4 * sizeof(float));
    memcpy(t->corners, f->leaf_corners, (size_t)N * 8 * sizeof(int32_t));
    for (uint32_t i = 0; i < N; i++) {
        const uint32_t *l = t->leaves + 4u * i;
        uint32_t s = 1u << l[3];
        for (uint32_t c = 0; c < 8; c++) {
            uint32_t pnt[3] = {l[0] + (c & 1 ? s : 0), l[1] + (c & 2 ? s : 0), l[2] + (c & 4 ? s : 0)};
            uint32_t node = (uint32_t)t->corners[8u * i + c];
            if (node >= P + H) {
                pb_cotree_destroy(t);
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "leaf %u corner %u is not a node", i, c);
            }
            bool inserted;
            *hmap_put(&t->node_map, pack3(pnt[0], pnt[1], pnt[2]), &inserted) = node;
            memcpy(node < P ? t->probe_lattice + 3u * node : t->hang_lattice + 3u * (node - P), pnt, sizeof pnt);
        }
    }
    uint32_t e = 0;
    for (uint32_t hI = 0; hI < H; hI++) {
        uint32_t cnt = 0;
        t->exp_start[hI] = e;
        bool fits = true;
        for (uint32_t k = 0; k < 4 && fits; k++) {
            uint32_t src = t->hang_src[4u * hI + k];
            double w = t->hang_w[4u * hI + k];
            if (!(w > 0.0)) continue;
            if (src >= P + hI) {
                fits = false;
                break;
            }
            if (src < P) {
                fits = merge_add(t->exp_probe + e, t->exp_w + e, &cnt, HANG_MAX_EXPANDED, src, w);
            } else {
                for (uint32_t q = t->exp_start[src - P]; q < t->exp_start[src - P + 1] && fits; q++)
                    fits = merge_add(t->exp_probe + e, t->exp_w + e, &cnt, HANG_MAX_EXPANDED, t->exp_probe[q],
                                     w * t->exp_w[q]);
            }
        }
        if (!fits) {
            pb_cotree_destroy(t);
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "hanging node %u has a source that is not earlier or depends on more than %u probes",
                                hI, HANG_MAX_EXPANDED);
        }
        e += cnt;
        t->exp_start[hI + 1] = e;
    }
    t->finalized = true;
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_interp_from_shprobe(const pb_shprobe *f, pb_cotree **tree, pb_tetra **tetra, pb_error *err)
{
    if (!f || !tree || !tetra) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_interp_from_shprobe: NULL");
    *tree = NULL;
    *tetra = NULL;
    if (f->structure == PB_SHPROBE_OCTREE) return cotree_from_file(f, tree, err);
    if (f->structure != PB_SHPROBE_TETRA)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "the file holds a dense grid, not probe positions with an interpolation structure");
    double *pos = malloc(((size_t)f->probe_count * 3 + 1) * sizeof(double));
    if (!pos) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    for (size_t i = 0; i < (size_t)f->probe_count * 3; i++) pos[i] = f->positions[i];
    pb_result r = pb_tetra_create_from(pos, f->probe_count, f->tets, f->element_count, tetra, err);
    free(pos);
    return r;
}

/* The interpolation weights at the centre of cell j of a dense grid (min corner lo, cell size
 * spacing, dims cells per axis; j in the version 1/2 grid order, x fastest, then y, then z). */
static void dense_cell_weights(const pb_cotree *tree, const pb_tetra *tetra, const pb_interp_options *opt,
                               const double lo[3], double spacing, const uint32_t dims[3], uint64_t j,
                               pb_interp_weights *w)
{
    const uint64_t cell[3] = {j % dims[0], (j / dims[0]) % dims[1], j / ((uint64_t)dims[0] * dims[1])};
    double p[3];
    for (int k = 0; k < 3; k++) p[k] = lo[k] + spacing * ((double)cell[k] + 0.5);
    if (tree)
        pb_interp_query_cotree(tree, p, opt, w);
    else
        pb_interp_query_tetra(tetra, p, opt, w);
}

pb_result pb_interp_resample_dense(const pb_shprobe *f, double spacing, pb_shprobe **out, pb_error *err)
{
    if (!f || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_interp_resample_dense: NULL argument");
    *out = NULL;
    if (f->representation != PB_SHPROBE_SH)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "a dense version 1/2 grid holds SH only; this file holds ambient cubes");
    pb_cotree *tree;
    pb_tetra *tetra;
    pb_result r = pb_interp_from_shprobe(f, &tree, &tetra, err);
    if (r != PB_SUCCESS) return r;
    double lo[3], hi[3];
    if (tree) {
        if (!(spacing > 0.0)) spacing = tree->h;
        for (int k = 0; k < 3; k++) lo[k] = tree->origin[k], hi[k] = tree->origin[k] + tree->h * tree->dims[k];
    } else {
        if (!(spacing > 0.0) || !isfinite(spacing)) {
            pb_tetra_destroy(tetra);
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "resampling tetrahedra needs a grid spacing > 0");
        }
        for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
        for (uint32_t i = 0; i < tetra->point_count; i++)
            for (int k = 0; k < 3; k++) {
                lo[k] = fmin(lo[k], tetra->points[3u * i + (uint32_t)k]);
                hi[k] = fmax(hi[k], tetra->points[3u * i + (uint32_t)k]);
            }
    }
    uint32_t dims[3];
    uint64_t cells = 1;
    for (int k = 0; k < 3; k++) {
        double d = ceil((hi[k] - lo[k]) / spacing - 1e-6);
        if (d < 1) d = 1;
        if (d > (double)PB_SHPROBE_MAX_GRID_CELLS) d = (double)PB_SHPROBE_MAX_GRID_CELLS + 1;
        dims[k] = (uint32_t)d;
        cells *= dims[k];
    }
    uint32_t C = pb_sh_count(f->max_band);
    int32_t *map = NULL;
    pb_shprobe *g = NULL;
    if (cells > PB_SHPROBE_MAX_GRID_CELLS) {
        r = pb_error_set(err, PB_ERROR_TOO_LARGE,
                         "the dense grid would have %u x %u x %u cells, above the limit of %llu; use a larger spacing",
                         dims[0], dims[1], dims[2], (unsigned long long)PB_SHPROBE_MAX_GRID_CELLS);
        goto done;
    }
    map = malloc((size_t)cells * sizeof(int32_t));
    if (!map) {
        r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu cells", (unsigned long long)cells);
        goto done;
    }
    pb_interp_options opt = {.validity = f->validity};
    uint32_t n = 0;
    for (uint64_t j = 0; j < cells; j++) {
        pb_interp_weights w;
        dense_cell_weights(tree, tetra, &opt, lo, spacing, dims, j, &w);
        map[j] = w.count ? (int32_t)n++ : -1;
    }
    if (n > PB_SHPROBE_MAX_PROBES) {
        r = pb_error_set(err, PB_ERROR_TOO_LARGE, "the dense grid would hold %u probes, above the limit of %u", n,
                         PB_SHPROBE_MAX_PROBES);
        goto done;
    }
    r = pb_shprobe_create(n, f->max_band, dims, false, &g, err);
    if (r != PB_SUCCESS) goto done;
    for (int k = 0; k < 3; k++) g->grid_origin[k] = (float)lo[k];
    g->grid_spacing = (float)spacing;
    g->default_sh_scale = f->default_sh_scale;
    g->default_ambient = f->default_ambient;
    for (uint64_t j = 0; j < cells; j++) {
        g->grid[j] = map[j];
        if (map[j] < 0) continue;
        pb_interp_weights w;
        dense_cell_weights(tree, tetra, &opt, lo, spacing, dims, j, &w);
        float *dst = g->coeffs + (size_t)map[j] * C * 3u;
        double acc[PB_SH_MAX_COEFFS * 3] = {0}, sc = 0.0, am = 0.0;
        for (uint32_t i = 0; i < w.count; i++) {
            const float *src = f->coeffs + (size_t)w.probe[i] * C * 3u;
            for (uint32_t k = 0; k < C * 3u; k++) acc[k] += w.weight[i] * src[k];
            sc += w.weight[i] * (f->probe_scale ? f->probe_scale[w.probe[i]] : 1.0f);
            am += w.weight[i] * (f->probe_ambient ? f->probe_ambient[w.probe[i]] : f->default_ambient);
        }
        for (uint32_t k = 0; k < C * 3u; k++) dst[k] = (float)acc[k];
        g->probe_scale[map[j]] = (float)sc;
        g->probe_ambient[map[j]] = (float)am;
    }
    *out = g;
    g = NULL;
done:
    free(map);
    pb_shprobe_destroy(g);
    pb_cotree_destroy(tree);
    pb_tetra_destroy(tetra);
    return r;
}

pb_result pb_shprobe_write_resampled(const char *path, const pb_shprobe *file, double spacing, uint32_t version,
                                     pb_error *err)
{
    if (version != 0 && version != 1 && version != 2)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "a dense grid is written as version 1, 2 or 0 (auto), not %u", version);
    pb_shprobe *dense = NULL;
    pb_result r = pb_interp_resample_dense(file, spacing, &dense, err);
    if (r != PB_SUCCESS) return r;
    dense->version = version;
    r = pb_shprobe_write(path, dense, err);
    pb_shprobe_destroy(dense);
    return r;
}
