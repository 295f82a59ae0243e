/* The deferred per-pixel probe pass (docs/engine.md "The per-pixel probe pass"). Per pixel, the scene
 * pass (mesh.frag built with SV_DEFERRED_PROBES) writes the colour without the terms the probes decide,
 * and a G-buffer of four targets: the surface point, its normal, the diffuse factor, the baked lights'
 * direct light, the sky's specular before its ratio. A compute dispatch (shaders/probe_pass.comp) then
 * evaluates E once per pixel, with the same functions as the forward path, and adds those terms into the
 * HDR target. A GPU runs it on its compute units; the forward path shades every fragment drawn, overdraw
 * included, on its graphics part alone (bench/results/engine_gpu.md: the H100/H200 run fragment shaders on
 * a small share of their chip). */
#ifndef SV_PROBE_PASS_H
#define SV_PROBE_PASS_H

#include <stdbool.h>

#include "sv_renderer.h"

/* The G-buffer targets' formats, SV_GBUF_POINT first (the scene pass's pipelines, sv_pipelines.c). */
const VkFormat *sv_probe_pass_formats(void);
/* The pipeline, its set and layout (sv_renderer_create, after the scene set layout exists). Prints a
 * clear message and returns false on failure; false with nothing made when the device cannot run it
 * (fewer than 1 + SV_GBUF_COUNT colour attachments, or no independentBlend or maintenance4): r->probe_pass stays false, the forward path. */
bool sv_probe_pass_create(sv_renderer *r);
/* The G-buffer targets at the renderer's size and the set's images (sv_renderer_resize). */
bool sv_probe_pass_resize(sv_renderer *r);
/* Whether this frame's scene pass takes the deferred path: the pass is on, the view is shaded (no debug
 * view) and some fragment can ask for per-pixel probes. */
bool sv_probe_pass_active(const sv_renderer *r, const sv_view *view);
/* Whether no fragment of this frame can ask for per-pixel probes and it is shaded (no debug view): the scene
 * pass may take the shader without the grid lookup (SV_PIPELINE_MESH_LEAN). */
bool sv_probe_pass_lean(const sv_renderer *r, const sv_view *view);
/* The G-buffer targets to attachments (cleared where read: the point target's meta is 0 elsewhere). */
void sv_probe_pass_begin(const sv_renderer *r, VkCommandBuffer cmd, VkRenderingAttachmentInfo att[SV_GBUF_COUNT]);
/* After the scene pass: the dispatch over the HDR target, which ends in VK_IMAGE_LAYOUT_GENERAL. */
void sv_probe_pass_record(const sv_renderer *r, VkCommandBuffer cmd);
void sv_probe_pass_destroy(sv_renderer *r);

#endif
