/* The shadow maps' fitting math (docs/engine.md "Shadows"): pure functions, no Vulkan, so that
 * tests/engine/shadows/test_shadow_math.c checks them on the CPU.
 *
 * Every frame, for each layer of the shadow map array (sv_shadow_layer: a cascade of a sun, a spot
 * light, a face of a point light's cube), the renderer asks for a world -> light-clip matrix
 * (column-major, x, y in [-1, 1] and z in [0, 1] after the divide by w: Vulkan) and the layer's
 * sv_gpu_frame.shadow_params:
 *   1. sv_shadow_fit_layers() does it for all layers at once: it fits the camera's view slices
 *      (sv_cascade_view_fit, sv_cascade_split) when a sun has several cascades, then calls
 *   2. sv_shadow_fit_ortho (a sun over the whole scene bounds), sv_shadow_fit_cascade (a sun's
 *      cascade: a texel-snapped square around a view slice) or sv_shadow_fit_perspective (a spot's
 *      cone, a cube face) for each layer.
 * The scene bounds [lo, hi] are world-space metres (sv_scene.aabb_min / aabb_max). */
#ifndef SV_SHADOW_MATH_H
#define SV_SHADOW_MATH_H

#include <stdbool.h>
#include <stdint.h>

#include "sv_gpu.h"

/* One layer of the shadow map array: what the frame's projection of it is fitted to. */
typedef struct sv_shadow_layer {
    uint32_t kind;  /* SV_SHADOW_ORTHO, _SPOT or _CUBE */
    float pos[3];   /* world position of the light (spot, cube) */
    float dir[3];   /* world direction of the layer's axis: where the light (sun, spot) or the cube face points */
    float tan_half; /* spot, cube: tan(half field of view) before the filter's margin */
    uint32_t cascade, cascades; /* ortho: this layer's cascade (0 = nearest) of the light's `cascades` */
} sv_shadow_layer;

/* The camera the cascades follow: the fields of sv_view they read (sv_renderer.h). */
typedef struct sv_shadow_camera {
    float view[16];      /* world -> camera, column-major (camera looks along -Z) */
    float camera_pos[3]; /* world position */
    float yfov;          /* radians (perspective); 0 = orthographic with ymag */
    float ymag;          /* orthographic half height (0: 1) */
    float znear, zfar;   /* zfar 0 = infinite (perspective) */
} sv_shadow_camera;

/* The camera seen by the cascades: its basis (from the view matrix's rows), the half extents of its
 * cross-section (per metre of depth for a perspective camera, metres for an orthographic one) and
 * its depth range [near, far] along the view direction clamped to the scene bounds. */
typedef struct sv_cascade_view {
    float eye[3], right[3], up[3], fwd[3];
    float hx, hy;
    bool perspective;
    float near, far;
} sv_cascade_view;

/* An orthonormal light basis: f = unit dir (straight down when degenerate), x = normalize(f x up),
 * y = x x f, with up = +Y, or +X when |f.y| > 0.99. */
void sv_shadow_basis(const float dir[3], float x[3], float y[3], float f[3]);

/* A sun's single layer: an orthographic box along `dir` around the 8 corners of [lo, hi] (padded by
 * 1 % plus 1 mm), `res` texels per side; writes the matrix m and params[0..3]. */
void sv_shadow_fit_ortho(const float dir[3], const float lo[3], const float hi[3], uint32_t res, float m[16],
                         float params[4]);

/* The camera's basis, cross-section and depth range clipped to [lo, hi] (aspect = width / height);
 * false when the scene lies wholly outside the camera's depth range. */
bool sv_cascade_view_fit(const sv_shadow_camera *camera, float aspect, const float lo[3], const float hi[3],
                         sv_cascade_view *cv);

/* Depth of split i of `count` (0 = cv->near, count = cv->far): the practical split scheme. */
float sv_cascade_split(const sv_cascade_view *cv, uint32_t i, uint32_t count);

/* Cascade `cascade` of `count` of a sun along `dir`: a texel-snapped square around the view slice's
 * bounding sphere, depth over the whole scene [lo, hi]. */
void sv_shadow_fit_cascade(const float dir[3], const float lo[3], const float hi[3], const sv_cascade_view *cv,
                           uint32_t cascade, uint32_t count, uint32_t res, float m[16], float params[4]);

/* A spot light's layer or a point light's cube face: a perspective frustum from layer->pos along
 * layer->dir reaching the farthest corner of [lo, hi]. */
void sv_shadow_fit_perspective(const sv_shadow_layer *layer, const float lo[3], const float hi[3], uint32_t res,
                               float m[16], float params[4]);

/* Every layer's matrix m[k] and params[k] for this frame: cascades (when `cascades` > 1 and the view
 * sees the scene) follow `camera` at `aspect`, the rest fit the scene bounds [lo, hi]. */
void sv_shadow_fit_layers(const sv_shadow_layer *layers, uint32_t count, uint32_t cascades,
                          const sv_shadow_camera *camera, float aspect, const float lo[3], const float hi[3],
                          uint32_t res, float m[][16], float params[][4]);

#endif
