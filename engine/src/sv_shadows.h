/* The renderer's shadow room (docs/engine.md "Shadows"), the GPU side: which lights get layers of the
 * shadow map array, the array itself, each frame's fit (the pure math of sv_shadow_math.h, fed from
 * the view) and the depth-only pass that renders every layer. In a frame:
 *   sv_shadows_fit     fills sv_gpu_frame.shadow_view_proj / shadow_params for every layer
 *   sv_shadows_record  clears and renders every layer, leaving the array shader-readable
 * The shadow pipeline and its layout belong to the pipelines room (sv_pipelines.h). */
#ifndef SV_SHADOWS_H
#define SV_SHADOWS_H

#include "sv_renderer.h"

/* Lights whose mode is mixed or realtime get layers in light-instance order while
 * SV_MAX_SHADOW_LAYERS lasts (a sun r->shadow_cascades, a spot 1 or 6, a point light 6); a light that
 * does not fit is unshadowed with a warning. Returns the light's first layer or -1; *cascades = the
 * layers a sun got. */
int sv_shadows_assign(sv_renderer *r, const sv_gltf_light_instance *li, const sv_gltf_light *s, uint32_t *cascades);
/* The shadow map array (r->shadow_count layers of shadow_res^2, or one 1x1 layer), its per-layer views
 * and its comparison sampler; left SHADER_READ_ONLY_OPTIMAL. */
bool sv_shadows_create(sv_renderer *r, uint32_t shadow_res);
/* This frame's light-space matrices and shadow_params of every layer, fitted to the scene's current
 * bounds and, for a sun's cascades, to `view`. */
void sv_shadows_fit(const sv_renderer *r, const sv_scene *scene, const sv_view *view, sv_gpu_frame *frame);
/* The shadow pass: every layer cleared to depth 1, then every opaque or masked primitive drawn
 * depth-only with frame->shadow_view_proj. */
void sv_shadows_record(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, const sv_gpu_frame *frame);
void sv_shadows_destroy(sv_renderer *r);

#endif
