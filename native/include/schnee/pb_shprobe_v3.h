/* Schnee probes — `.shprobe` version 3 and 4 file images: probe positions with a sparse structure
 * (docs/shprobe-format.md, "Version 3", "Version 4"). Fill the arrays, then write with pb_shprobe_write().
 * Part of pb_shprobe.h (the struct and the limits live there; include either).
 */
#ifndef SCHNEE_PB_SHPROBE_V3_H
#define SCHNEE_PB_SHPROBE_V3_H

#include "schnee/pb_shprobe.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A version 3 file image with positions, structure arrays sized by element/hanging counts (zeroed),
 * scales 1, ambients 0.1, validity 1, identity axes. grid_dims: the grid (structure GRID, grid
 * filled with −1), the lattice extent (OCTREE), ignored (TETRA, stored as 0). */
pb_result pb_shprobe_create_v3(uint32_t probe_count, uint32_t representation, uint32_t max_band, uint32_t structure,
                               const uint32_t grid_dims[3], uint32_t element_count, uint32_t hanging_count,
                               pb_shprobe **out, pb_error *err);
/* A version 4 file image (structure KDTREE, positions): leaves, corners, hanging rules and the
 * split_node_count split-tree nodes zeroed, root_level set; scales 1, ambients 0.1, validity 1. */
pb_result pb_shprobe_create_v4(uint32_t probe_count, uint32_t representation, uint32_t max_band,
                               const uint32_t lattice_dims[3], uint32_t leaf_count, uint32_t hanging_count,
                               uint32_t root_level, uint32_t split_node_count, pb_shprobe **out, pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
