/* The brick view (docs/engine.md "Probe view"; schnee-view --probe-path bricks --probe-view, --brick-view
 * cells|texels|validity): what the probe bricks hold, drawn over the scene.
 *   cells     one box per brick, its region [r, r + 4 * 2^L) in its level's colour, + the probe spheres
 *             (the leaf outlines of bricked grids are left out; other grids' outlines stay);
 *   texels    the boxes + each brick's 125 texels as small spheres shaded with the texel's N / D from the
 *             pool (E(n) / pi; D = 0 "no probe" magenta, 0 < D < 1 tinted red);
 *   validity  the boxes + the texels coloured by D alone.
 * sv_bricks.c hands over every grid's pb_bricks before it frees them (sv_brick_view_capture): the view
 * keeps each brick's grid, index, region and level; the texel values are read on the GPU from the pool
 * the per-pixel path samples. One draw per brick and pass, the brick in the push constants
 * (shaders/sv_gpu_brick_view.h). */
#ifndef SV_BRICK_VIEW_ENGINE_H
#define SV_BRICK_VIEW_ENGINE_H

#include "schnee/pb_bricks.h"
#include "sv_gpu_brick_view.h"
#include "sv_renderer.h"

/* Keeps the regions of bricks[0 .. grid_count) (NULL where a grid is not bricked) in r->brick_view. False
 * only when out of memory (message printed). */
bool sv_brick_view_capture(sv_renderer *r, pb_bricks *const *bricks, uint32_t grid_count);
/* Bricks kept (0 without --probe-path bricks or without tree grids). */
uint32_t sv_brick_view_count(const sv_renderer *r);
/* Records the brick view's draws in `mode` (SV_BRICK_VIEW_*) into the scene pass (scene set bound, the
 * vertex and index buffers of the scene bound: the texel spheres are the probe view's UV sphere). */
void sv_brick_view_draw(const sv_renderer *r, VkCommandBuffer cmd, uint32_t mode);
void sv_brick_view_destroy(sv_renderer *r);

#endif
