/* Probe bricks in the engine (docs/probe-bricks.md, docs/engine.md "Probe bricks"; --probe-path bricks):
 * every corner octree / kd corner tree grid of SH probes is resampled at load by the core's pb_bricks
 * (the file's coefficients at its band, validity and probe scale: N = sum W m s c, D = sum W m, the
 * field octree_irradiance shades for a movable object) and uploaded as two 3D textures:
 *   pool         RGBA16F (RGBA32F when a texel exceeds the half range), linear filtering, clamp to edge:
 *                one slab of z per channel group (group g of every grid at z + g * slab), the grids'
 *                pools side by side along z within a slab;
 *   indirection  RGBA32UI, nearest (read with texelFetch): the grids' indirection grids along z.
 * With a static scene (scene's objects never moved) the bricks are built with its tracer and their
 * brick tables and visibility records go into a storage buffer (sv_bricks_vis.h, step 5).
 * Each bricked grid's record gets SV_GRID_BRICKS and its offsets (sv_gpu_grid.bricks). Grids of other
 * structures (dense, tetrahedra) or holding ambient cubes keep the storage-buffer path. */
#ifndef SV_BRICKS_H
#define SV_BRICKS_H

#include "sv_renderer.h"

/* With `enabled`, builds and uploads the bricks of `probes` and fills `grids` (one per probe grid);
 * otherwise uploads 1x1x1 stand-ins (the bindings must hold images). Creates the two samplers either
 * way. When a grid cannot be bricked (the core's refusal, e.g. its memory cap), the pool or the
 * indirection exceeds the device's maxImageDimension3D, or the device cannot filter the pool's format
 * linearly: with `required` (--probe-path bricks given) false with a clear error; else (the default) the
 * same message as a warning, the stand-ins stay bound, r->bricks false and every grid takes the storage
 * buffers. Keeps the bricks' figures for sv_bricks_report. */
bool sv_bricks_upload(sv_renderer *r, const sv_scene *scene, const sv_probes *probes, sv_gpu_grid *grids, bool enabled,
                      bool required);
/* The `probe bricks:` line (when the bricks are uploaded): the bricks' figures kept by sv_bricks_upload, what
 * the same grids take on the buffers path, and gpu_bytes (every probe texture and buffer this run allocated,
 * sv_upload_probes) per file probe. */
void sv_bricks_report(const sv_renderer *r, uint64_t gpu_bytes, uint64_t file_probes);
void sv_bricks_destroy(sv_renderer *r);

#endif
