/* Internal (not installed): what the interpolation sources share: the corner octree's and the
 * tetrahedra's structs, the lattice hash map and the small weight helpers (pb_cotree.c builds the
 * octree, pb_tetra.c the tetrahedra, pb_interp.c locates points and weighs probes, pb_interp_v3.c
 * converts to and from version 3 files). */
#ifndef SCHNEE_PB_INTERP_INTERNAL_H
#define SCHNEE_PB_INTERP_INTERNAL_H

#include "schnee/pb_interp.h"

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

static inline void hmap_free(hmap *m)
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

static inline bool hmap_init(hmap *m, size_t expected)
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
static inline uint32_t *hmap_put(hmap *m, uint64_t key, bool *inserted)
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

static inline bool hmap_get(const hmap *m, uint64_t key, uint32_t *val)
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
    uint32_t *leaves; /* leaf_count × (x, y, z, level): level = the largest of the leaf's three */
    uint32_t *levels; /* leaf_count × (lx, ly, lz): per-axis levels (docs/aniso-refinement.md) */
    uint32_t leaf_count;
    uint32_t max_level;
    uint32_t root_level; /* R: Max Cell Size = 2^R min cells; every level ≤ R */
    bool cubes;          /* every leaf has lx = ly = lz: the corner octree's rules, bit for bit */
    uint32_t forced;     /* leaves split by the nesting rule in the last finalize */
    hmap leaf_map;       /* pack(min corner) → leaf */
    /* Point location: the canonical split tree of the non-empty root cells (pb_cotree_boxes.c),
     * root_map: pack(root cell) → its node; nodes in the file's format (pb_cotree.h). */
    hmap root_map;
    uint32_t *split_nodes;
    uint32_t split_count;
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

/* ---- helpers of several parts ------------------------------------------------------------------------ */

/* Descent of a split tree (pb_cotree.h) from `node`, the box (lo, lv) on entry, to the leaf holding
 * lattice cell q: its index, or −1 where the tree has no leaf (an empty node, or a malformed node
 * splitting an axis at level 0). lo, lv end as the box reached (a leaf's, or the empty box's). At most
 * lv_x + lv_y + lv_z steps. */
static inline int32_t split_descend(const uint32_t *nodes, uint32_t node, uint32_t lo[3], uint32_t lv[3],
                                    const uint32_t q[3])
{
    for (;;) {
        uint32_t nd = nodes[node], ax = nd & 3u;
        if (!ax) return (nd >> 2) == ((UINT32_C(1) << 30) - 1u) ? -1 : (int32_t)(nd >> 2);
        uint32_t a = ax - 1u;
        if (!lv[a]) return -1;
        lv[a]--;
        uint32_t upper = q[a] >= lo[a] + (1u << lv[a]);
        if (upper) lo[a] += 1u << lv[a];
        node = (nd >> 2) + upper;
    }
}

/* The box (lo, lv) holding lattice cell q (q < dims): a leaf's (its index returned) or an empty one
 * (−1; the whole root cell where the root has no leaf). */
static inline int32_t locate_box(const pb_cotree *t, const uint32_t q[3], uint32_t lo[3], uint32_t lv[3])
{
    uint32_t R = t->root_level, node;
    for (int k = 0; k < 3; k++) lo[k] = q[k] >> R << R, lv[k] = R;
    if (!hmap_get(&t->root_map, pack3(q[0] >> R, q[1] >> R, q[2] >> R), &node)) return -1;
    return split_descend(t->split_nodes, node, lo, lv, q);
}

/* Leaf holding the unit lattice cell with min corner q, or −1. */
static inline int32_t locate_cell(const pb_cotree *t, const uint32_t q[3])
{
    uint32_t lo[3], lv[3];
    return locate_box(t, q, lo, lv);
}

/* Internal parts of pb_cotree_boxes.c used by pb_cotree.c. */
/* Builds the split tree of t's (sorted) leaves into t->split_nodes / root_map; fails (invalid
 * argument) where the leaves overlap or are not 2:1 splits of the root cells. */
pb_result _pb_cotree_index_split_tree(pb_cotree *t, pb_error *err);
/* The nesting rule (docs/aniso-refinement.md): sweeps of forced splits until no two face neighbours
 * cross; t->forced counts the leaves split. */
pb_result _pb_cotree_apply_nesting(pb_cotree *t, pb_error *err);

/* Adds w·(node's expansion) into a small merged list. */
static inline bool merge_add(uint32_t *probe, double *weight, uint32_t *count, uint32_t cap, uint32_t p, double w)
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

static inline void trilinear8(const double t[3], double w[8])
{
    for (int c = 0; c < 8; c++)
        w[c] = (c & 1 ? t[0] : 1 - t[0]) * (c & 2 ? t[1] : 1 - t[1]) * (c & 4 ? t[2] : 1 - t[2]);
}

/* The pair table of a box (pb_cotree_pair_visibility's rule, docs: the leaf visibility field): corners at
 * origin + (lo + bits · 2^lv) h, each of the 56 ordered pairs traced through `segment` (shifted by
 * PB_VIS_SHIFT across the axes its ends share), round(255 t) into o[8k + c], PB_VIS_CLEAR on the diagonal.
 * Returns whether some pair is blocked. Used for leaves (pb_cotree.c) and brick cells (pb_bricks.c). */
bool pb_vis_trace_box(const double origin[3], double h, const uint32_t lo[3], const uint32_t lv[3],
                      pb_segment_fn segment, void *user, uint8_t o[64]);

#endif
