/* The brick view (schnee-view --probe-path bricks --probe-view, --brick-view; docs/engine.md "Probe view"):
 * the modes and the per-brick push constants, read by the C engine (engine/src/sv_brick_view.c) and the
 * shaders probe_bricks_outline.* / probe_bricks_texels.* (C and GLSL, like sv_gpu.h).
 *
 * One draw per brick (24 line vertices for its region's outline; 125 instances of the probe view's UV
 * sphere for its texels), with sv_gpu_draw as push constants, its fields used as:
 *   model[0].xyz  the region's min corner r in lattice coordinates (min cells of the grid; exact floats)
 *   model[0].w    the brick's level L (region edge 4 * 2^L min cells, texel spacing 2^L)
 *   material_index  the grid (index into grids[]), probe_index  the brick's index b in the grid's pool,
 *   object_index    the mode (SV_BRICK_VIEW_*), flags  0,
 *   normal_matrix[0].xy  the target's width and height in pixels (the texels' pixel-centre rays).
 * A texel sphere (brick-local texel t = i + 5j + 25k = gl_InstanceIndex) sits at lattice point
 * r + 2^L (i, j, k), radius SV_BRICK_TEXEL_RADIUS * 2^L min cells. */
#ifndef SV_GPU_BRICK_VIEW_H
#define SV_GPU_BRICK_VIEW_H

#define SV_BRICK_VIEW_CELLS    0u /* the bricks' region outlines (colour by level) + the probe spheres */
#define SV_BRICK_VIEW_TEXELS   1u /* outlines + each texel as a sphere shaded with its N / D (E(n) / pi) */
#define SV_BRICK_VIEW_VALIDITY 2u /* outlines + each texel as a flat sphere coloured by its D */
#define SV_BRICK_VIEW_COUNT    3u

#define SV_BRICK_TEXEL_RADIUS  0.08 /* texel sphere radius, in texel spacings (2^L min cells) */
#define SV_BRICK_LEVEL_COLOURS 6u   /* outline colours, level min(L, 5) (probe_bricks_outline.frag) */

#endif
