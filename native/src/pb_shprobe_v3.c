/* `.shprobe` version 3 (docs/shprobe-format.md, "Version 3"): the file image of probe positions with
 * a sparse structure (corner octree or tetrahedra), and the validation of that structure, which the
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
                    return pb_error_set(err, code,
                                        "hanging node %u weight %d is %g (offset %llu); it must be in [0, 1]", j, k,
                                        (double)w, (unsigned long long)(off + 16u + 4u * (uint32_t)k));
                sum += w;
            }
            if (fabs(sum - 1.0) > HANGING_SUM_TOL)
                return pb_error_set(err, code, "hanging node %u weights sum to %.9g (offset %llu); they must sum to 1",
                                    j, sum, (unsigned long long)(off + 16u));
        }
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

pb_result pb_shprobe_create_v3(uint32_t probe_count, uint32_t representation, uint32_t max_band, uint32_t structure,
                               const uint32_t grid_dims[3], uint32_t element_count, uint32_t hanging_count,
                               pb_shprobe **out, pb_error *err)
{
    if (!out || !grid_dims) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_create_v3: NULL argument");
    *out = NULL;
    if (max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "max band %u is out of range 0..%d", max_band,
                            PB_SH_MAX_BAND);
    pb_shprobe h;
    memset(&h, 0, sizeof h);
    h.probe_count = probe_count;
    h.max_band = max_band;
    h.representation = representation;
    h.structure = structure;
    h.element_count = element_count;
    h.hanging_count = hanging_count;
    if (structure != PB_SHPROBE_TETRA) memcpy(h.grid_dims, grid_dims, sizeof h.grid_dims);
    pb_result r = pb_shprobe_check_v3_kind_(&h, true, PB_ERROR_INVALID_ARGUMENT, err);
    if (r != PB_SUCCESS) return r;
    layout lay;
    r = pb_shprobe_layout_compute_(3, &h, true, PB_ERROR_TOO_LARGE, &lay, err);
    if (r != PB_SUCCESS) return r;
    pb_shprobe *p = calloc(1, sizeof *p);
    if (!p) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for .shprobe header");
    *p = h;
    p->version = 3;
    memcpy(p->grid_axes, pb_shprobe_identity_axes_, sizeof p->grid_axes);
    p->default_sh_scale = 1.0f;
    p->default_ambient = 0.1f;
    size_t P = probe_count, N = element_count, H = hanging_count;
    p->coeffs = calloc(P * lay.disk_coeffs * 3u + 1u, sizeof(float));
    p->probe_scale = malloc((P + 1u) * sizeof(float));
    p->probe_ambient = malloc((P + 1u) * sizeof(float));
    p->validity = malloc((P + 1u) * sizeof(float));
    p->positions = calloc(P * 3u + 1u, sizeof(float));
    bool ok = p->coeffs && p->probe_scale && p->probe_ambient && p->validity && p->positions;
    if (structure == PB_SHPROBE_GRID) {
        p->grid = malloc((size_t)lay.grid_cells * sizeof(int32_t) + sizeof(int32_t));
        ok = ok && p->grid;
        for (uint64_t j = 0; ok && j < lay.grid_cells; j++) p->grid[j] = -1;
    } else if (structure == PB_SHPROBE_OCTREE) {
        p->leaves = calloc(N * 4u + 1u, sizeof(uint32_t));
        p->leaf_corners = calloc(N * 8u + 1u, sizeof(int32_t));
        p->hanging_sources = calloc(H * 4u + 1u, sizeof(uint32_t));
        p->hanging_weights = calloc(H * 4u + 1u, sizeof(float));
        ok = ok && p->leaves && p->leaf_corners && p->hanging_sources && p->hanging_weights;
    } else {
        p->tets = calloc(N * 4u + 1u, sizeof(uint32_t));
        p->tet_neighbours = calloc(N * 4u + 1u, sizeof(int32_t));
        ok = ok && p->tets && p->tet_neighbours;
    }
    if (!ok) {
        pb_shprobe_destroy(p);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes and the %s structure",
                            probe_count, pb_shprobe_structure_name_(structure));
    }
    for (size_t i = 0; i < P; i++) {
        p->probe_scale[i] = 1.0f;
        p->probe_ambient[i] = p->default_ambient;
        p->validity[i] = 1.0f;
    }
    *out = p;
    return PB_SUCCESS;
}
