/* Schnee probes — the interpolation structures in `.shprobe` version 3 files (docs/shprobe-format.md,
 * "Version 3"): a file image from a corner octree or tetrahedra, the structure back from a file, and
 * the resampling to the seed's dense grid for engines that read version 1 only.
 * Part of pb_interp.h (include either); source native/src/pb_interp_v3.c.
 */
#ifndef SCHNEE_PB_INTERP_V3_H
#define SCHNEE_PB_INTERP_V3_H

#include "schnee/pb_common.h"
#include "schnee/pb_cotree.h"
#include "schnee/pb_shprobe.h"
#include "schnee/pb_tetra.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- files (.shprobe version 3) --------------------------------------------------------------------- */

/* An octree file image of a finalized tree: positions, leaves (Morton order), corners and hanging rules
 * filled, lattice frame in grid_origin/grid_spacing/grid_dims; the caller fills the probe records
 * (coeffs: pb_shprobe_colour_count colours per probe) and writes it. A tree whose leaves are all cubes
 * gives version 3 structure 1 (byte for byte as before boxes); one with a box that is not a cube gives
 * version 4 structure 3 (packed levels in the leaves' 4th word, root_level, the canonical split tree). */
pb_result pb_shprobe_from_cotree(const pb_cotree *tree, uint32_t representation, uint32_t max_band, pb_shprobe **out,
                                 pb_error *err);
/* A version 3 tetrahedra file image (positions, tetrahedra, neighbours); records left to the caller. */
pb_result pb_shprobe_from_tetra(const pb_tetra *tetra, const double *positions, uint32_t representation,
                                uint32_t max_band, pb_shprobe **out, pb_error *err);
/* The interpolation structure a file holds, with the file's own probe numbering: *tree for an
 * octree (built from its leaves, corners and hanging rules; a version 4 kd corner tree from its boxes
 * with pb_cotree_create_boxes), *tetra for tetrahedra; the other is NULL. Octree frames must have identity axes (a rotated frame is refused with a message). */
pb_result pb_interp_from_shprobe(const pb_shprobe *file, pb_cotree **tree, pb_tetra **tetra, pb_error *err);
/* Resamples a version 3 file's field onto a dense grid (the seed's version 1 layout, DESIGN.md §4):
 * every grid cell whose centre the structure covers becomes a probe holding the interpolated record
 * (coefficients, scale, ambient; validity-weighted as the query), others −1. spacing 0 = the octree's
 * min cell (required > 0 for tetrahedra); the grid covers the lattice (octree) or the probes' bounds.
 * SH only (version 1 cannot hold cubes); write the result with version 1 (L ≤ 2) or 0. */
pb_result pb_interp_resample_dense(const pb_shprobe *file, double spacing, pb_shprobe **out, pb_error *err);
/* The writer's option for engines that only read the seed's format: resamples `file` (version 3,
 * SH) as pb_interp_resample_dense and writes the dense grid atomically as `version` (1, or 0 = the
 * smallest that holds it: 1 for L <= 2, else 2). */
pb_result pb_shprobe_write_resampled(const char *path, const pb_shprobe *file, double spacing, uint32_t version,
                                     pb_error *err);

#ifdef __cplusplus
}
#endif
#endif
