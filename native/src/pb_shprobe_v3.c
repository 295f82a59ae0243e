/* `.shprobe` versions 3 and 4 (docs/shprobe-format.md, "Version 3", "Version 4"): the file image of
 * probe positions with a sparse structure (corner octree, tetrahedra; version 4: the kd corner tree of
 * boxes with per-axis levels and its split tree), and the validation of that structure, which the
 * shared checks (pb_shprobe.c) call for the reader and the writer alike.
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_shprobe.h"

#include "schnee/pb_sh.h"

#include "pb_morton.h"
#include "pb_shprobe_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Hanging rules (octree and kd tree): sources earlier, weights finite in [0, 1] summing to 1. */
static pb_result check_hanging(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    for (uint32_t j = 0; j < p->hanging_count; j++) {
        uint64_t off = lay->hanging_offset + (uint64_t)V3_HANGING_SIZE * j;
        double sum = 0.0;
        for (int k = 0; k < 4; k++) {
            uint32_t src = p->hanging_sources[4u * j + (uint32_t)k];
            float w = p->hanging_weights[4u * j + (uint32_t)k];
            if (src >= (uint64_t)p->probe_count + j)
                return pb_error_set(err, code,
                                    "hanging node %u source %d (offset %llu) is %u; it must be a probe or an "
                                    "earlier hanging node, below %llu",
                                    j, k, (unsigned long long)(off + 4u * (uint32_t)k), src,
                                    (unsigned long long)p->probe_count + j);
            if (!isfinite(w))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "hanging node %u weight %d is %g (offset %llu)", j, k,
                                    (double)w, (unsigned long long)(off + 16u + 4u * (uint32_t)k));
            if (w < 0.0f || w > 1.0f)
                return pb_error_set(err, code, "hanging node %u weight %d is %g (offset %llu); it must be in [0, 1]", j,
                                    k, (double)w, (unsigned long long)(off + 16u + 4u * (uint32_t)k));
            sum += w;
        }
        if (fabs(sum - 1.0) > HANGING_SUM_TOL)
            return pb_error_set(err, code, "hanging node %u weights sum to %.9g (offset %llu); they must sum to 1", j,
                                sum, (unsigned long long)(off + 16u));
    }
    return PB_SUCCESS;
}

/* Kd corner tree leaves (version 4): the levels word (each level at most R, top byte 0), aligned per
 * axis, inside the lattice, min corners in strictly increasing Morton order (pb_cotree_leaves() order),
 * corner references below P + H. */
static pb_result check_kd_leaves(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    uint64_t nodes = (uint64_t)p->probe_count + p->hanging_count, prev = 0;
    for (uint32_t i = 0; i < p->element_count; i++) {
        const uint32_t *l = p->leaves + 4u * i;
        unsigned long long off = lay->grid_offset + (uint64_t)V3_LEAF_SIZE * i;
        uint32_t lv[3] = {l[3] & 0xffu, l[3] >> 8 & 0xffu, l[3] >> 16 & 0xffu};
        if (l[3] >> 24)
            return pb_error_set(err, code,
                                "leaf %u levels word 0x%08X (offset %llu) has a nonzero top byte; it holds "
                                "lx | ly << 8 | lz << 16",
                                i, l[3], off + 12u);
        for (int k = 0; k < 3; k++)
            if (lv[k] > p->root_level)
                return pb_error_set(err, code,
                                    "leaf %u level %c is %u (offset %llu); it must be at most the root level %u", i,
                                    "xyz"[k], lv[k], off + 12u, p->root_level);
        for (int k = 0; k < 3; k++)
            if (l[k] % (1u << lv[k]) != 0 || (uint64_t)l[k] + (1u << lv[k]) > p->grid_dims[k])
                return pb_error_set(err, code,
                                    "leaf %u at (%u, %u, %u) levels (%u, %u, %u) (offset %llu) is not aligned to its "
                                    "size or reaches past the lattice extent %u x %u x %u",
                                    i, l[0], l[1], l[2], lv[0], lv[1], lv[2], off, p->grid_dims[0], p->grid_dims[1],
                                    p->grid_dims[2]);
        uint64_t m = pb_morton3_(l[0], l[1], l[2]);
        if (i > 0 && m <= prev)
            return pb_error_set(err, code,
                                "leaf %u at (%u, %u, %u) (offset %llu) is not after the leaf before it in Morton order "
                                "of min corners",
                                i, l[0], l[1], l[2], off);
        prev = m;
        for (int c = 0; c < 8; c++) {
            int32_t v = p->leaf_corners[8u * i + (uint32_t)c];
            if (v < 0 || (uint64_t)v >= nodes)
                return pb_error_set(err, code,
                                    "leaf %u corner %d (offset %llu) is %d; it must be a node index below %llu", i, c,
                                    off + 16u + 4u * (uint32_t)c, (int)v, (unsigned long long)nodes);
        }
    }
    return PB_SUCCESS;
}

/* A box of the split tree on the way down: its node, min corner and per-axis levels. */
typedef struct kd_box {
    uint32_t node, min[3], lv[3];
} kd_box;

/* One split-tree node reached from its parent: a leaf (its record must be the node's box) or a split
 * (its axis must have level > 0; its children, after it and not reached before, are pushed). */
static pb_result kd_visit(const pb_shprobe *p, const layout *lay, uint32_t G, const kd_box *b, uint8_t *seen,
                          kd_box *stack, uint32_t *depth, uint32_t *reached, pb_result code, pb_error *err)
{
    uint32_t v = p->split_nodes[b->node], axis = v & 3u, arg = v >> 2, K = p->split_node_count;
    unsigned long long off = lay->split_offset + (uint64_t)V4_NODE_SIZE * b->node;
    if (axis == 0) {
        if (arg == PB_SHPROBE_SPLIT_EMPTY) return PB_SUCCESS;
        if (arg >= p->element_count)
            return pb_error_set(err, code,
                                "split-tree node %u (offset %llu) names leaf %u; leaves are below %u (or %u = none)",
                                b->node, off, arg, p->element_count, PB_SHPROBE_SPLIT_EMPTY);
        const uint32_t *l = p->leaves + 4u * arg;
        if (l[0] != b->min[0] || l[1] != b->min[1] || l[2] != b->min[2] ||
            l[3] != (b->lv[0] | b->lv[1] << 8 | b->lv[2] << 16))
            return pb_error_set(err, code,
                                "split-tree node %u (offset %llu) reaches leaf %u at (%u, %u, %u) levels word 0x%X, "
                                "but the node's box is at (%u, %u, %u) levels (%u, %u, %u)",
                                b->node, off, arg, l[0], l[1], l[2], l[3], b->min[0], b->min[1], b->min[2], b->lv[0],
                                b->lv[1], b->lv[2]);
        (*reached)++;
        return PB_SUCCESS;
    }
    uint32_t a = axis - 1u;
    if (b->lv[a] == 0)
        return pb_error_set(err, code,
                            "split-tree node %u (offset %llu) splits along %c a box of level 0 on that axis, at (%u, "
                            "%u, %u) levels (%u, %u, %u)",
                            b->node, off, "xyz"[a], b -> min[0], b -> min[1], b -> min[2], b -> lv[0], b -> lv[1],
                            b -> lv[2]);
    if (arg <= b->node || arg < G || arg >= K - 1u)
        return pb_error_set(err, code,
                            "split-tree node %u (offset %llu) names children %u and %u; they must come after it and "
                            "after the %u root cells, below the node count %u",
                            b->node, off, arg, arg + 1u, G, K);
    for (uint32_t c = arg; c <= arg + 1u; c++) {
        if (seen[c >> 3] & (1u << (c & 7u)))
            return pb_error_set(err, code,
                                "split-tree node %u (offset %llu) is the child of two splits (the second: node %u)", c,
                                (unsigned long long)(lay->split_offset + (uint64_t)V4_NODE_SIZE * c), b->node);
        seen[c >> 3] |= (uint8_t)(1u << (c & 7u));
    }
    /* Each split lowers the level sum (at most 3R) by one: the stack holds at most 3R + 1 boxes. */
    kd_box lo = *b, hi = *b;
    lo.node = arg;
    hi.node = arg + 1u;
    lo.lv[a] = hi.lv[a] = b->lv[a] - 1u;
    hi.min[a] += 1u << hi.lv[a];
    stack[(*depth)++] = hi;
    stack[(*depth)++] = lo;
    return PB_SUCCESS;
}

/* The split tree (version 4), depth first from each root cell: every non-root node the child of exactly
 * one earlier split, a split's axis of level > 0 in its box, every leaf reached once with its record equal
 * to its node's box. With the leaves' own checks this proves that they tile the non-empty roots without
 * overlap (the role of the octree's Morton check). Scratch: one bit per node. */
static pb_result check_split_tree(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    uint32_t K = p->split_node_count, R = p->root_level, root[3];
    for (int k = 0; k < 3; k++) root[k] = (uint32_t)(((uint64_t)p->grid_dims[k] + (1u << R) - 1u) >> R);
    uint32_t G = root[0] * root[1] * root[2]; /* <= K (header check) */
    uint8_t *seen = calloc((size_t)K / 8u + 1u, 1);
    if (!seen) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u split-tree nodes", K);
    kd_box stack[3u * V3_MAX_LEVEL + 2u];
    uint32_t reached = 0;
    pb_result r = PB_SUCCESS;
    for (uint32_t g = 0; g < G && r == PB_SUCCESS; g++) {
        seen[g >> 3] |= (uint8_t)(1u << (g & 7u));
        uint32_t depth = 1;
        stack[0] = (kd_box){g, {g % root[0] << R, g / root[0] % root[1] << R, g / (root[0] * root[1]) << R}, {R, R, R}};
        while (depth > 0 && r == PB_SUCCESS) {
            kd_box b = stack[--depth];
            r = kd_visit(p, lay, G, &b, seen, stack, &depth, &reached, code, err);
        }
    }
    for (uint32_t i = G; i < K && r == PB_SUCCESS; i++)
        if (!(seen[i >> 3] & (1u << (i & 7u))))
            r = pb_error_set(err, code,
                             "split-tree node %u (offset %llu) is not the child of any split reached from the root "
                             "cells",
                             i, (unsigned long long)(lay->split_offset + (uint64_t)V4_NODE_SIZE * i));
    if (r == PB_SUCCESS && reached != p->element_count)
        r = pb_error_set(err, code, "the split tree (offset %llu) reaches %u of the %u leaves",
                         (unsigned long long)lay->split_offset, reached, p->element_count);
    free(seen);
    return r;
}
/* Octree leaves, corner references and hanging rules; tetrahedra and neighbours. Leaves must be in
 * Morton order of their min corners (z most significant): aligned cubes in that order do not overlap
 * exactly when each one's Morton range ends before the next one starts, so one pass proves it. */
pb_result pb_shprobe_check_structure_(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    uint64_t nodes = (uint64_t)p->probe_count + p->hanging_count;
    if (lay->structure == PB_SHPROBE_OCTREE) {
        uint64_t prev_end = 0;
        for (uint32_t i = 0; i < p->element_count; i++) {
            const uint32_t *l = p->leaves + 4u * i;
            uint64_t off = lay->grid_offset + (uint64_t)V3_LEAF_SIZE * i;
            if (l[3] > V3_MAX_LEVEL)
                return pb_error_set(err, code, "leaf %u level %u (offset %llu) is above %u", i, l[3],
                                    (unsigned long long)(off + 12u), V3_MAX_LEVEL);
            uint32_t size = 1u << l[3];
            for (int k = 0; k < 3; k++)
                if (l[k] % size != 0 || (uint64_t)l[k] + size > p->grid_dims[k])
                    return pb_error_set(err, code,
                                        "leaf %u at (%u, %u, %u) level %u (offset %llu) is not aligned to its size or "
                                        "reaches past the lattice extent %u x %u x %u",
                                        i, l[0], l[1], l[2], l[3], (unsigned long long)off, p->grid_dims[0],
                                        p->grid_dims[1], p->grid_dims[2]);
            uint64_t start = pb_morton3_(l[0], l[1], l[2]);
            if (i > 0 && start < prev_end)
                return pb_error_set(err, code,
                                    "leaf %u at (%u, %u, %u) (offset %llu) overlaps the leaf before it or is out of "
                                    "Morton order",
                                    i, l[0], l[1], l[2], (unsigned long long)off);
            prev_end = start + ((uint64_t)1 << (3u * l[3]));
            for (int c = 0; c < 8; c++) {
                int32_t v = p->leaf_corners[8u * i + (uint32_t)c];
                if (v < 0 || (uint64_t)v >= nodes)
                    return pb_error_set(
                        err, code, "leaf %u corner %d (offset %llu) is %d; it must be a node index below %llu", i, c,
                        (unsigned long long)(off + 16u + 4u * (uint32_t)c), (int)v, (unsigned long long)nodes);
            }
        }
        pb_result r = check_hanging(p, lay, code, err);
        if (r != PB_SUCCESS) return r;
    } else if (lay->structure == PB_SHPROBE_KDTREE) {
        pb_result r = check_kd_leaves(p, lay, code, err);
        if (r == PB_SUCCESS) r = check_hanging(p, lay, code, err);
        if (r == PB_SUCCESS) r = check_split_tree(p, lay, code, err);
        return r;
    } else if (lay->structure == PB_SHPROBE_TETRA) {
        for (uint32_t i = 0; i < p->element_count; i++) {
            uint64_t off = lay->grid_offset + (uint64_t)V3_TET_SIZE * i;
            const uint32_t *t = p->tets + 4u * i;
            for (int k = 0; k < 4; k++) {
                if (t[k] >= p->probe_count)
                    return pb_error_set(err, code,
                                        "tetrahedron %u vertex %d (offset %llu) is %u; it must be a probe index below "
                                        "%u",
                                        i, k, (unsigned long long)(off + 4u * (uint32_t)k), t[k], p->probe_count);
                for (int m = 0; m < k; m++)
                    if (t[m] == t[k])
                        return pb_error_set(err, code, "tetrahedron %u (offset %llu) repeats vertex %u", i,
                                            (unsigned long long)off, t[k]);
                int32_t nb = p->tet_neighbours[4u * i + (uint32_t)k];
                if (nb < -1 || (nb >= 0 && (uint32_t)nb >= p->element_count))
                    return pb_error_set(
                        err, code, "tetrahedron %u neighbour %d (offset %llu) is %d; it must be -1 or below %u", i, k,
                        (unsigned long long)(off + 16u + 4u * (uint32_t)k), (int)nb, p->element_count);
            }
        }
    }
    return PB_SUCCESS;
}

/* A version 3 or 4 file image with positions and the structure's arrays (zeroed). */
static pb_result create_image(uint32_t version, const pb_shprobe *h, pb_shprobe **out, pb_error *err)
{
    if (h->max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "max band %u is out of range 0..%d", h->max_band,
                            PB_SH_MAX_BAND);
    pb_result r = pb_shprobe_check_v3_kind_(version, h, true, PB_ERROR_INVALID_ARGUMENT, err);
    if (r != PB_SUCCESS) return r;
    layout lay;
    r = pb_shprobe_layout_compute_(version, h, true, PB_ERROR_TOO_LARGE, &lay, err);
    if (r != PB_SUCCESS) return r;
    pb_shprobe *p = calloc(1, sizeof *p);
    if (!p) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for .shprobe header");
    *p = *h;
    p->version = version;
    memcpy(p->grid_axes, pb_shprobe_identity_axes_, sizeof p->grid_axes);
    p->default_sh_scale = 1.0f;
    p->default_ambient = 0.1f;
    size_t P = h->probe_count, N = h->element_count, H = h->hanging_count;
    p->coeffs = calloc(P * lay.disk_coeffs * 3u + 1u, sizeof(float));
    p->probe_scale = malloc((P + 1u) * sizeof(float));
    p->probe_ambient = malloc((P + 1u) * sizeof(float));
    p->validity = malloc((P + 1u) * sizeof(float));
    p->positions = calloc(P * 3u + 1u, sizeof(float));
    bool ok = p->coeffs && p->probe_scale && p->probe_ambient && p->validity && p->positions;
    if (h->structure == PB_SHPROBE_GRID) {
        p->grid = malloc((size_t)lay.grid_cells * sizeof(int32_t) + sizeof(int32_t));
        ok = ok && p->grid;
        for (uint64_t j = 0; ok && j < lay.grid_cells; j++) p->grid[j] = -1;
    } else if (h->structure == PB_SHPROBE_OCTREE || h->structure == PB_SHPROBE_KDTREE) {
        p->leaves = calloc(N * 4u + 1u, sizeof(uint32_t));
        p->leaf_corners = calloc(N * 8u + 1u, sizeof(int32_t));
        p->hanging_sources = calloc(H * 4u + 1u, sizeof(uint32_t));
        p->hanging_weights = calloc(H * 4u + 1u, sizeof(float));
        ok = ok && p->leaves && p->leaf_corners && p->hanging_sources && p->hanging_weights;
        if (h->structure == PB_SHPROBE_KDTREE) {
            p->split_nodes = calloc((size_t)h->split_node_count + 1u, sizeof(uint32_t));
            ok = ok && p->split_nodes;
        }
    } else {
        p->tets = calloc(N * 4u + 1u, sizeof(uint32_t));
        p->tet_neighbours = calloc(N * 4u + 1u, sizeof(int32_t));
        ok = ok && p->tets && p->tet_neighbours;
    }
    if (!ok) {
        pb_shprobe_destroy(p);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes and the %s structure",
                            h->probe_count, pb_shprobe_structure_name_(h->structure));
    }
    for (size_t i = 0; i < P; i++) {
        p->probe_scale[i] = 1.0f;
        p->probe_ambient[i] = p->default_ambient;
        p->validity[i] = 1.0f;
    }
    *out = p;
    return PB_SUCCESS;
}

pb_result pb_shprobe_create_v3(uint32_t probe_count, uint32_t representation, uint32_t max_band, uint32_t structure,
                               const uint32_t grid_dims[3], uint32_t element_count, uint32_t hanging_count,
                               pb_shprobe **out, pb_error *err)
{
    if (!out || !grid_dims) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_create_v3: NULL argument");
    *out = NULL;
    pb_shprobe h;
    memset(&h, 0, sizeof h);
    h.probe_count = probe_count;
    h.max_band = max_band;
    h.representation = representation;
    h.structure = structure;
    h.element_count = element_count;
    h.hanging_count = hanging_count;
    if (structure != PB_SHPROBE_TETRA) memcpy(h.grid_dims, grid_dims, sizeof h.grid_dims);
    return create_image(3, &h, out, err);
}

pb_result pb_shprobe_create_v4(uint32_t probe_count, uint32_t representation, uint32_t max_band,
                               const uint32_t lattice_dims[3], uint32_t leaf_count, uint32_t hanging_count,
                               uint32_t root_level, uint32_t split_node_count, pb_shprobe **out, pb_error *err)
{
    if (!out || !lattice_dims)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_create_v4: NULL argument");
    *out = NULL;
    pb_shprobe h;
    memset(&h, 0, sizeof h);
    h.probe_count = probe_count;
    h.max_band = max_band;
    h.representation = representation;
    h.structure = PB_SHPROBE_KDTREE;
    h.element_count = leaf_count;
    h.hanging_count = hanging_count;
    h.root_level = root_level;
    h.split_node_count = split_node_count;
    memcpy(h.grid_dims, lattice_dims, sizeof h.grid_dims);
    return create_image(4, &h, out, err);
}
