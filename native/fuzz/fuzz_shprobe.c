/* libFuzzer target for the .shprobe reader: any byte string must either parse into a file whose
 * every value the reader promises is valid, or fail with an error code and a message — never
 * crash, leak or read out of bounds (built with ASan/UBSan by tests/fuzz/run_shprobe_fuzz.sh). */
#include "schnee/pb_interp.h"
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pb_shprobe *p = NULL;
    pb_error err;
    memset(&err, 0, sizeof err);
    pb_result r = pb_shprobe_read_memory(data, size, &p, &err);
    if (r != PB_SUCCESS) {
        /* A rejection must carry a code and a non-empty message, and return no file. */
        if (p != NULL || err.code != r || err.message[0] == '\0') abort();
        return 0;
    }
    /* Accepted: re-check the reader's promises (touching every array also lets ASan see overruns). */
    if (p->version < 1 || p->version > 4 || p->max_band > PB_SH_MAX_BAND) abort();
    if ((p->version == 4) != (p->structure == PB_SHPROBE_KDTREE)) abort();
    if (p->structure != PB_SHPROBE_TETRA && (!(p->grid_spacing > 0.0f) || !isfinite(p->grid_spacing))) abort();
    size_t coeffs = (size_t)p->probe_count * pb_shprobe_colour_count(p) * 3u;
    for (size_t i = 0; i < coeffs; i++)
        if (!isfinite(p->coeffs[i])) abort();
    if (p->structure != PB_SHPROBE_GRID) {
        /* Version 3 and 4 structures: every reference in range, and the interpolation built from the
         * file answers queries with weights over valid probes only (pb_interp.c on hostile structure). */
        uint64_t nodes = (uint64_t)p->probe_count + p->hanging_count;
        if (p->structure == PB_SHPROBE_OCTREE || p->structure == PB_SHPROBE_KDTREE) {
            for (size_t i = 0; i < (size_t)p->element_count * 8u; i++)
                if (p->leaf_corners[i] < 0 || (uint64_t)p->leaf_corners[i] >= nodes) abort();
            /* kd tree: leaf nodes name leaves (or none), splits name children inside the tree */
            for (uint32_t i = 0; p->structure == PB_SHPROBE_KDTREE && i < p->split_node_count; i++) {
                uint32_t v = p->split_nodes[i], arg = v >> 2;
                if ((v & 3u) == 0 ? arg != PB_SHPROBE_SPLIT_EMPTY && arg >= p->element_count
                                  : arg <= i || arg + 1u >= p->split_node_count)
                    abort();
            }
        } else {
            for (size_t i = 0; i < (size_t)p->element_count * 4u; i++)
                if (p->tets[i] >= p->probe_count) abort();
        }
        pb_cotree *tree = NULL;
        pb_tetra *tetra = NULL;
        pb_error e2;
        memset(&e2, 0, sizeof e2);
        if (pb_interp_from_shprobe(p, &tree, &tetra, &e2) == PB_SUCCESS) {
            for (int s = 0; s < 8; s++) {
                double q[3];
                for (int k = 0; k < 3; k++) q[k] = p->positions[3u * (s % p->probe_count) + (uint32_t)k] + 0.01 * s;
                pb_interp_weights w;
                if (tree)
                    pb_interp_query_cotree(tree, q, NULL, &w);
                else
                    pb_interp_query_tetra(tetra, q, NULL, &w);
                for (uint32_t i = 0; i < w.count; i++)
                    if (w.probe[i] >= p->probe_count || !(w.weight[i] > 0.0)) abort();
            }
        } else if (e2.message[0] == '\0') {
            abort();
        }
        pb_cotree_destroy(tree);
        pb_tetra_destroy(tetra);
        pb_shprobe_destroy(p);
        return 0;
    }
    size_t cells = (size_t)p->grid_dims[0] * p->grid_dims[1] * p->grid_dims[2];
    for (size_t j = 0; j < cells; j++)
        if (p->grid[j] < -1 || (p->grid[j] >= 0 && (uint32_t)p->grid[j] >= p->probe_count)) abort();
    float centre[3];
    for (int k = 0; k < 3; k++) centre[k] = p->grid_origin[k] + 0.5f * p->grid_spacing * (float)p->grid_dims[k];
    int32_t idx = pb_shprobe_lookup(p, centre);
    if (idx < -1 || (idx >= 0 && (uint32_t)idx >= p->probe_count)) abort();
    pb_shprobe_destroy(p);
    return 0;
}
