/* The renderer's pipelines room: samplers, descriptor sets and every graphics pipeline.
 *   sv_pipelines_create_descriptors  samplers; set 0 (the scene's buffers and images), set 1 per
 *                                    material (its two textures), the tone map's set (the HDR target,
 *                                    written by sv_renderer_resize)
 *   sv_pipelines_create              the pipeline layouts, then one pipeline per entry of a table of
 *                                    descriptions (shader pair, vertex layout, targets, depth, blend,
 *                                    cull) in sv_pipelines.c, into r->pipelines[SV_PIPELINE_*]
 *   sv_pipelines_destroy             all of the above
 * To add a pipeline: its SPIR-V include, an SV_PIPELINE_* id (sv_renderer.h), a table row. */
#ifndef SV_PIPELINES_H
#define SV_PIPELINES_H

#include "sv_renderer.h"

/* Needs the uploads (buffers, textures, sky, shadow maps) made and r->material_count set. */
bool sv_pipelines_create_descriptors(sv_renderer *r, const sv_gltf *g);
/* Needs the descriptor set layouts and, for the shadow pipeline, r->shadow_count and r->shadow_format. */
bool sv_pipelines_create(sv_renderer *r);
void sv_pipelines_destroy(sv_renderer *r);

#endif
