/* The renderer's upload room: everything that goes from the scene and the probes into GPU buffers
 * and images. sv_renderer_create calls, in this order:
 *   sv_upload_geometry   one vertex and one index buffer for every primitive, plus the probe view's sphere
 *   sv_upload_materials  sv_gpu_material per glTF material, the glTF default material last
 *   sv_upload_textures   each glTF texture as RGBA8 sRGB (a file, or embedded bytes decoded from memory;
 *                        white with a warning when unreadable)
 *   sv_upload_lights     sv_gpu_light per light instance, assigning shadow layers (sv_shadows_assign)
 *   sv_upload_probes     the probe, ambient-cube, cell, grid and cell-index buffers (float or half)
 *   sv_upload_sky        the sky's mips and the BRDF LUT (1x1 stand-ins without a sky)
 * and every frame, before the passes (sv_renderer_record):
 *   sv_upload_probe_slots    the per-object probe slots that moved objects rewrote
 *   sv_upload_retrace_masks  the visibility masks again after an object's first move
 * Each start-up function prints a clear message and returns false on failure (the caller destroys
 * the renderer, which frees what was made). */
#ifndef SV_UPLOAD_H
#define SV_UPLOAD_H

#include "sv_renderer.h"

/* The vertex layout of every vertex buffer: position xyz, normal xyz, uv (floats). */
#define SV_VERTEX_FLOATS 8

bool sv_upload_geometry(sv_renderer *r, const sv_gltf *g);
bool sv_upload_materials(sv_renderer *r, const sv_gltf *g, const sv_ext *ext);
bool sv_upload_textures(sv_renderer *r, const sv_gltf *g);
bool sv_upload_lights(sv_renderer *r, const sv_gltf *g, const sv_ext *ext, uint32_t shadow_res);
bool sv_upload_probes(sv_renderer *r, const sv_scene *scene, const sv_probes *probes, const sv_renderer_desc *desc);
bool sv_upload_sky(sv_renderer *r, const sv_sky *sky);

/* Copies `regions` of a filled staging buffer into `out` (UNDEFINED -> transfer -> shader read), blocking,
 * then frees the staging buffer. */
bool sv_upload_staging_to_image(sv_renderer *r, sv_buffer *staging, sv_image *out, const VkBufferImageCopy *regions,
                                uint32_t count);

/* The glTF texture a material's texture reference samples, or -1 (none, or a texture without an image). */
int32_t sv_texture_slot(const sv_gltf *g, const sv_gltf_texture_ref *ref);

/* Per frame, recorded before the passes: the per-object probe slots when they changed since the last
 * upload, then a barrier to the shaders. */
void sv_upload_probe_slots(sv_renderer *r, VkCommandBuffer cmd);
/* Per frame: the visibility masks traced again when objects left the static scene since the last trace. */
void sv_upload_retrace_masks(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene);

#endif
