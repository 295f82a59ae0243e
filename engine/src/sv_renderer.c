/* The renderer's driver and frame recorder (see sv_renderer.h): creation over the rooms (sv_upload,
 * sv_shadows, sv_pipelines), the render targets, and one frame as a few passes. */
#include "sv_renderer.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sv_brick_view.h"
#include "sv_bricks.h"
#include "sv_math.h"
#include "sv_pipelines.h"
#include "sv_probe_pass.h"
#include "sv_shadows.h"
#include "sv_upload.h"

static VkFormat pick_depth_format(sv_context *ctx)
{
    VkFormat candidates[] = {VK_FORMAT_D32_SFLOAT, VK_FORMAT_X8_D24_UNORM_PACK32, VK_FORMAT_D16_UNORM};
    for (int i = 0; i < 3; ++i) {
        VkFormatProperties p;
        vkGetPhysicalDeviceFormatProperties(ctx->physical, candidates[i], &p);
        if (p.optimalTilingFeatures & VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT) return candidates[i];
    }
    return VK_FORMAT_D16_UNORM;
}

/* The timestamp query pool where the queue family writes timestamps (lavapipe and GPUs do). */
static bool create_timestamps(sv_renderer *r)
{
    sv_context *ctx = r->ctx;
    uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(ctx->physical, &n, NULL);
    VkQueueFamilyProperties *q = calloc(n ? n : 1, sizeof *q);
    if (!q) return false;
    vkGetPhysicalDeviceQueueFamilyProperties(ctx->physical, &n, q);
    uint32_t bits = ctx->queue_family < n ? q[ctx->queue_family].timestampValidBits : 0;
    free(q);
    if (!bits || ctx->properties.limits.timestampPeriod <= 0.0f) return true; /* no timestamps: none reported */
    r->timestamp_mask = bits >= 64 ? ~UINT64_C(0) : (UINT64_C(1) << bits) - 1;
    VkQueryPoolCreateInfo qi = {.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO,
                                .queryType = VK_QUERY_TYPE_TIMESTAMP,
                                .queryCount = SV_TIMESTAMPS};
    VK_CHECK(vkCreateQueryPool(ctx->device, &qi, NULL, &r->timestamps));
    return true;
fail:
    return false;
}

bool sv_renderer_create(sv_renderer *r, sv_context *ctx, const sv_scene *scene, const sv_probes *probes,
                        VkFormat output_format, const sv_renderer_desc *desc)
{
    memset(r, 0, sizeof(*r));
    r->ctx = ctx;
    r->hdr_format = VK_FORMAT_R32G32B32A32_SFLOAT; /* exact linear values for .exr output */
    r->depth_format = pick_depth_format(ctx);
    r->output_format = output_format;
    r->encode_srgb = output_format != VK_FORMAT_B8G8R8A8_SRGB && output_format != VK_FORMAT_R8G8B8A8_SRGB;
    r->shadow_cascades = desc->shadow_cascades ? desc->shadow_cascades : SV_SHADOW_DEFAULT_CASCADES;
    if (r->shadow_cascades > SV_MAX_SHADOW_CASCADES) r->shadow_cascades = SV_MAX_SHADOW_CASCADES;
    r->unrolled_groups = sv_shader_loops_unrolled(desc->shader_loops, ctx->properties.deviceType);
    const sv_gltf *g = scene->gltf;
    if (!sv_upload_geometry(r, g) || !sv_upload_materials(r, g, &scene->ext) || !sv_upload_textures(r, g) ||
        !sv_upload_lights(r, g, &scene->ext, desc->shadow_res) || !sv_shadows_create(r, desc->shadow_res) ||
        !sv_upload_probes(r, scene, probes, desc) || !sv_upload_sky(r, desc->sky))
        return false;
    if (!sv_buffer_create(ctx, sizeof(sv_gpu_frame), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true, &r->frame)) return false;
    r->material_count = g->material_count + 1;
    /* The probe pass where per-pixel probes can be asked for: a grid to sample (docs/engine.md "The per-pixel
     * probe pass"); --probe-mode material takes it when a material or node asks for per pixel. */
    r->probe_pass = desc->probe_pass != SV_PROBE_PASS_FRAGMENT && r->grid_count > 0;
    /* The G-buffer's meta word holds an object's probe-buffer entry in its top 24 bits. */
    if (r->probe_pass && r->probe_count >> (32u - SV_GBUF_META_ENTRY_SHIFT)) {
        fprintf(stderr,
                "schnee-view: warning: %u probe-buffer entries exceed the probe pass's %u: per-pixel probes are "
                "shaded in the scene pass\n",
                r->probe_count, 1u << (32u - SV_GBUF_META_ENTRY_SHIFT));
        r->probe_pass = false;
    }
    r->lean_scene = desc->probe_pass != SV_PROBE_PASS_FRAGMENT;
    for (uint32_t m = 0; m < g->material_count; ++m)
        r->pixel_modes |= scene->ext.materials[m].probe_mode == SV_PROBE_MODE_PIXEL;
    for (uint32_t o = 0; o < scene->object_count; ++o)
        r->pixel_modes |= scene->objects[o].probe_mode == SV_PROBE_MODE_PIXEL;
    return sv_pipelines_create_descriptors(r, g) && (!r->probe_pass || sv_probe_pass_create(r)) &&
           sv_pipelines_create(r) && create_timestamps(r);
}

bool sv_renderer_gpu_times(sv_renderer *r, double ms[4])
{
    uint64_t t[SV_TIMESTAMPS];
    if (!r->timestamps || vkGetQueryPoolResults(r->ctx->device, r->timestamps, 0, SV_TIMESTAMPS, sizeof t, t,
                                                sizeof t[0], VK_QUERY_RESULT_64_BIT) != VK_SUCCESS)
        return false;
    double period_ms = r->ctx->properties.limits.timestampPeriod * 1e-6;
    for (int k = 0; k < 3; ++k) ms[k] = (double)((t[k + 1] - t[k]) & r->timestamp_mask) * period_ms;
    ms[3] = (double)((t[2] - t[4]) & r->timestamp_mask) * period_ms;
    return true;
}

bool sv_renderer_resize(sv_renderer *r, uint32_t width, uint32_t height)
{
    sv_context *ctx = r->ctx;
    vkDeviceWaitIdle(ctx->device);
    sv_image_destroy(ctx, &r->hdr);
    sv_image_destroy(ctx, &r->depth);
    if (!sv_image_create(ctx, width, height, r->hdr_format,
                         VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
                             VK_IMAGE_USAGE_TRANSFER_SRC_BIT | (r->probe_pass ? VK_IMAGE_USAGE_STORAGE_BIT : 0u),
                         VK_IMAGE_ASPECT_COLOR_BIT, &r->hdr) ||
        !sv_image_create(ctx, width, height, r->depth_format, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                         VK_IMAGE_ASPECT_DEPTH_BIT, &r->depth))
        return false;
    r->width = width;
    r->height = height;
    if (!sv_probe_pass_resize(r)) return false;
    VkDescriptorImageInfo img = {r->hdr_sampler, r->hdr.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    VkWriteDescriptorSet w = {
        .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
        .dstSet = r->tonemap_set,
        .dstBinding = SV_BINDING_HDR,
        .descriptorCount = 1,
        .descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
        .pImageInfo = &img,
    };
    vkUpdateDescriptorSets(ctx->device, 1, &w, 0, NULL);
    return true;
}

void sv_view_projection(const sv_view *v, float aspect, float m[16])
{
    memset(m, 0, 16 * sizeof(float));
    if (v->yfov > 0.0f) {
        float f = 1.0f / tanf(0.5f * v->yfov);
        m[0] = f / aspect;
        m[5] = -f; /* Vulkan clip space: y down */
        m[11] = -1.0f;
        if (v->zfar > 0.0f) {
            m[10] = v->zfar / (v->znear - v->zfar);
            m[14] = v->znear * v->zfar / (v->znear - v->zfar);
        } else {
            m[10] = -1.0f;
            m[14] = -v->znear;
        }
    } else {
        float ymag = v->ymag > 0 ? v->ymag : 1.0f;
        float xmag = ymag * aspect; /* keep pixels square in the viewport */
        float zfar = v->zfar > v->znear ? v->zfar : v->znear + 1000.0f;
        m[0] = 1.0f / xmag;
        m[5] = -1.0f / ymag;
        m[10] = -1.0f / (zfar - v->znear);
        m[14] = -v->znear / (zfar - v->znear);
        m[15] = 1.0f;
    }
}

/* Inverse-transpose of the upper 3x3 as three vec4 columns. */
static void normal_matrix(const float m[16], float out[3][4])
{
    float a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[2], h = m[6], i = m[10];
    float A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
    float D = -(b * i - c * h), E = a * i - c * g, F = -(a * h - b * g);
    float G = b * f - c * e, H = -(a * f - c * d), I = a * e - b * d;
    float det = a * A + b * B + c * C;
    float s = fabsf(det) > 1e-20f ? 1.0f / det : 0.0f;
    /* inverse-transpose = cofactor matrix / det; column k of it. */
    float cols[3][3] = {{A, B, C}, {D, E, F}, {G, H, I}};
    for (int k = 0; k < 3; ++k) {
        for (int r = 0; r < 3; ++r) out[k][r] = cols[k][r] * s;
        out[k][3] = 0.0f;
    }
}

/* One viewport and scissor over the whole target (every pipeline takes them as dynamic state). */
static void set_viewport(const sv_renderer *r, VkCommandBuffer cmd)
{
    VkViewport viewport = {0, 0, (float)r->width, (float)r->height, 0.0f, 1.0f};
    VkRect2D scissor = {{0, 0}, {r->width, r->height}};
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
}

/* The frame uniform: camera, modes and counts, and the shadow layers' fit when `shadows` (recomputed
 * every frame: the scene's bounds change as objects move, a sun's cascades follow the view). */
static void fill_frame(const sv_renderer *r, const sv_scene *scene, const sv_view *view, bool shadows,
                       sv_gpu_frame *frame)
{
    float proj[16];
    sv_view_projection(view, (float)r->width / (float)r->height, proj);
    sv_mat4_mul(proj, view->view, frame->view_proj);
    if (!sv_mat4_invert(frame->view_proj, frame->inv_view_proj)) sv_mat4_identity(frame->inv_view_proj);
    memcpy(frame->camera_pos, view->camera_pos, 3 * sizeof(float));
    frame->camera_pos[3] = r->has_sky ? (float)r->sky.mip_levels : 0.0f;
    frame->light_count = r->light_count;
    frame->debug_mode = view->debug_mode;
    frame->flags = view->flags | (r->has_sky ? SV_FRAME_SKY : 0u) | (r->bricks ? SV_FRAME_BRICKS : 0u);
    frame->probe_rebase = r->probe_rebase;
    frame->grid_count = r->grid_count;
    frame->probe_mode = view->probe_mode;
    /* Without a cube buffer (no material and no --probe-representation asked for cubes) an
     * ambient-cube override would read zeros: it falls back to SH. */
    frame->probe_representation = view->probe_representation == SV_PROBE_REP_AMBIENT_CUBE && !r->has_cubes
                                      ? SV_PROBE_REP_SH
                                      : view->probe_representation;
    frame->normal_bias = view->normal_bias;
    if (shadows) sv_shadows_fit(r, scene, view, frame);
}

/* Rendering begun over `count` colour attachments and the depth, the viewport set. */
static void begin_rendering(const sv_renderer *r, VkCommandBuffer cmd, const VkRenderingAttachmentInfo *color,
                            uint32_t count, const VkRenderingAttachmentInfo *depth)
{
    VkRenderingInfo ri = {
        .sType = VK_STRUCTURE_TYPE_RENDERING_INFO,
        .renderArea = {{0, 0}, {r->width, r->height}},
        .layerCount = 1,
        .colorAttachmentCount = count,
        .pColorAttachments = color,
        .pDepthAttachment = depth,
    };
    vkCmdBeginRendering(cmd, &ri);
    set_viewport(r, cmd);
}

/* The HDR target and depth to attachments, cleared (black, alpha 0; depth 1), rendering begun; with
 * `deferred` the probe pass's G-buffer too (sv_probe_pass_begin); `keep_depth`: the depth is stored for a
 * later rendering (the probe view after the probe pass). */
static void begin_scene_pass(const sv_renderer *r, VkCommandBuffer cmd, bool deferred, bool keep_depth)
{
    sv_image_barrier(cmd, r->hdr.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                     VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                     VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
    sv_image_barrier(cmd, r->depth.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    /* The background is black, alpha 0 (the zero clear value). */
    VkRenderingAttachmentInfo color[1 + SV_GBUF_COUNT] = {
        sv_attachment(r->hdr.view, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_ATTACHMENT_LOAD_OP_CLEAR,
                      VK_ATTACHMENT_STORE_OP_STORE)};
    if (deferred) sv_probe_pass_begin(r, cmd, color + 1);
    VkRenderingAttachmentInfo depth =
        sv_attachment(r->depth.view, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, VK_ATTACHMENT_LOAD_OP_CLEAR,
                      keep_depth ? VK_ATTACHMENT_STORE_OP_STORE : VK_ATTACHMENT_STORE_OP_DONT_CARE);
    depth.clearValue.depthStencil = (VkClearDepthStencilValue){1.0f, 0};
    begin_rendering(r, cmd, color, deferred ? 1 + SV_GBUF_COUNT : 1, &depth);
}

/* After the probe pass: the HDR target and depth as they are, for the probe view drawn over them. */
static void resume_scene_pass(const sv_renderer *r, VkCommandBuffer cmd)
{
    sv_image_barrier(cmd, r->hdr.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_GENERAL,
                     VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                     VK_ACCESS_SHADER_WRITE_BIT, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                     VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
    /* The objects' depth, stored by the first rendering, is tested against here. */
    sv_image_barrier(cmd, r->depth.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                     VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    VkRenderingAttachmentInfo color = sv_attachment(r->hdr.view, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                                                    VK_ATTACHMENT_LOAD_OP_LOAD, VK_ATTACHMENT_STORE_OP_STORE);
    VkRenderingAttachmentInfo depth = sv_attachment(r->depth.view, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                                                    VK_ATTACHMENT_LOAD_OP_LOAD, VK_ATTACHMENT_STORE_OP_DONT_CARE);
    begin_rendering(r, cmd, &color, 1, &depth);
}

/* Every primitive of every object with `pipeline` (one of the scene shader's builds) and its material's set 1
 * (rebound only when it changes from `bound_material`), transform, normal matrix, probe and flags. */
static void draw_objects(const sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, uint32_t bound_material,
                         sv_pipeline_id pipeline)
{
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipelines[pipeline]);
    VkDeviceSize zero = 0;
    vkCmdBindVertexBuffers(cmd, 0, 1, &r->vertices.buffer, &zero);
    vkCmdBindIndexBuffer(cmd, r->indices.buffer, 0, VK_INDEX_TYPE_UINT32);
    const sv_gltf *g = scene->gltf;
    for (uint32_t o = 0; o < scene->object_count; ++o) {
        const sv_object *obj = &scene->objects[o];
        sv_gpu_draw draw = {0};
        memcpy(draw.model, obj->world, sizeof(draw.model));
        normal_matrix(obj->world, draw.normal_matrix);
        draw.probe_index = obj->probe;
        draw.object_index = o;
        const float *w = obj->world; /* column-major: det of the upper 3x3 */
        float det = w[0] * (w[5] * w[10] - w[9] * w[6]) - w[4] * (w[1] * w[10] - w[9] * w[2]) +
                    w[8] * (w[1] * w[6] - w[5] * w[2]);
        draw.flags = (det < 0.0f ? SV_DRAW_MIRRORED : 0u) | (obj->movable ? SV_DRAW_MOVABLE : 0u) | obj->probe_flags;
        /* The object's own probe mode / representation (VULKAN_SCHNEE_node), + 1; 0 = its materials'. */
        if (obj->probe_mode < SV_PROBE_MODE_MATERIAL) draw.flags |= (obj->probe_mode + 1u) << SV_DRAW_NODE_MODE_SHIFT;
        if (obj->probe_representation < SV_PROBE_REP_MATERIAL)
            draw.flags |= (obj->probe_representation + 1u) << SV_DRAW_NODE_REP_SHIFT;
        const sv_gltf_mesh *mesh = &g->meshes[obj->mesh];
        for (uint32_t p = 0; p < mesh->primitive_count; ++p) {
            uint32_t pi = r->mesh_prim_base[obj->mesh] + p;
            if (!r->prim_index_count[pi]) continue;
            draw.material_index = r->prim_material[pi];
            if (draw.material_index != bound_material) {
                bound_material = draw.material_index;
                vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->scene_layout, SV_SET_MATERIAL, 1,
                                        &r->material_sets[bound_material], 0, NULL);
            }
            vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                               sizeof(draw), &draw);
            vkCmdDrawIndexed(cmd, r->prim_index_count[pi], 1, r->prim_first_index[pi], r->prim_vertex_offset[pi], 0);
        }
    }
}

/* The probe view: a sphere per probe, then the grid cells' outlines (they follow the spheres in the
 * instance buffer). With probe bricks, the brick view (sv_brick_view.h): the spheres only in its cells
 * mode, the bricks' boxes (and texels) instead of the bricked grids' leaf outlines (draw.flags 1). */
static void draw_probe_view(const sv_renderer *r, VkCommandBuffer cmd, const sv_view *view)
{
    bool bricks = sv_brick_view_count(r) > 0;
    sv_gpu_draw draw = {0};
    sv_mat4_identity(draw.model);
    draw.flags = bricks ? 1u : 0u;
    vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(draw),
                       &draw);
    if (r->sphere_count && (!bricks || view->brick_view == SV_BRICK_VIEW_CELLS)) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipelines[SV_PIPELINE_CELLS]);
        vkCmdDrawIndexed(cmd, r->sphere_index_count, r->sphere_count, r->sphere_first_index, r->sphere_vertex_offset,
                         0);
    }
    if (bricks) {
        sv_brick_view_draw(r, cmd, view->brick_view);
        vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                           sizeof(draw), &draw);
    }
    if (r->outline_count) {
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipelines[SV_PIPELINE_OUTLINE]);
        vkCmdDraw(cmd, 24, r->outline_count, 0, r->sphere_count);
    }
}

/* The scene pass into the HDR target: the sky (shaded view only), the objects, with the probe pass the
 * dispatch that adds the per-pixel probe terms (sv_probe_pass.h), the probe view; the target ends
 * shader-readable for the tone map. Timestamp 4 after the objects, 2 at the end. */
static void record_scene_pass(const sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, const sv_view *view)
{
    bool deferred = sv_probe_pass_active(r, view);
    bool cells = view->show_cells && r->sphere_count + r->outline_count + sv_brick_view_count(r);
    begin_scene_pass(r, cmd, deferred, deferred && cells);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->scene_layout, SV_SET_SCENE, 1, &r->scene_set, 0,
                            NULL);
    /* Set 1 must be bound for every pipeline of this layout: the default material's set. */
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->scene_layout, SV_SET_MATERIAL, 1,
                            &r->material_sets[r->material_count - 1], 0, NULL);
    if (r->has_sky && view->debug_mode == SV_DEBUG_NONE) {
        sv_gpu_draw none = {0};
        vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                           sizeof(none), &none);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS,
                          r->pipelines[deferred ? SV_PIPELINE_SKY_DEFERRED : SV_PIPELINE_SKY]);
        vkCmdDraw(cmd, 3, 1, 0, 0);
    }
    /* The scene shader: with the G-buffer; without the grid lookup where no fragment asks for it; else the
     * whole forward shader (debug views, --probe-pass fragment, per pixel without the pass). */
    sv_pipeline_id mesh = deferred                                       ? SV_PIPELINE_MESH_DEFERRED
                          : r->lean_scene && sv_probe_pass_lean(r, view) ? SV_PIPELINE_MESH_LEAN
                                                                         : SV_PIPELINE_MESH;
    draw_objects(r, cmd, scene, r->material_count - 1, mesh);
    if (cells && !deferred) draw_probe_view(r, cmd, view);
    vkCmdEndRendering(cmd);
    if (r->timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r->timestamps, 4);
    VkImageLayout layout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    VkPipelineStageFlags stage = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
    VkAccessFlags access = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    if (deferred) {
        sv_probe_pass_record(r, cmd);
        layout = VK_IMAGE_LAYOUT_GENERAL;
        stage = VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT;
        access = VK_ACCESS_SHADER_WRITE_BIT;
        if (cells) {
            resume_scene_pass(r, cmd);
            draw_probe_view(r, cmd, view);
            vkCmdEndRendering(cmd);
            layout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
            stage = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
            access = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
        }
    }
    if (r->timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r->timestamps, 2);
    sv_image_barrier(cmd, r->hdr.image, VK_IMAGE_ASPECT_COLOR_BIT, layout, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                     stage, access, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
}

/* The tone-map pass: the HDR target through exposure, operator and sRGB into the output image,
 * which ends in `out_final` (a transfer source for a read-back, else present). */
static void record_tonemap_pass(const sv_renderer *r, VkCommandBuffer cmd, const sv_view *view, VkImage out_image,
                                VkImageView out_view, VkImageLayout out_final)
{
    sv_image_barrier(cmd, out_image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, 0,
                     VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
    VkRenderingAttachmentInfo out = sv_attachment(out_view, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                                                  VK_ATTACHMENT_LOAD_OP_DONT_CARE, VK_ATTACHMENT_STORE_OP_STORE);
    begin_rendering(r, cmd, &out, 1, NULL);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipelines[SV_PIPELINE_TONEMAP]);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->tonemap_layout, 0, 1, &r->tonemap_set, 0, NULL);
    sv_gpu_tonemap tm = {view->exposure, view->tonemap, r->encode_srgb ? 1u : 0u, 0};
    vkCmdPushConstants(cmd, r->tonemap_layout, VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(tm), &tm);
    vkCmdDraw(cmd, 3, 1, 0, 0);
    vkCmdEndRendering(cmd);
    if (r->timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r->timestamps, 3);
    VkPipelineStageFlags dst_stage = out_final == VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL
                                         ? VK_PIPELINE_STAGE_TRANSFER_BIT
                                         : VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT;
    VkAccessFlags dst_access = out_final == VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL ? VK_ACCESS_TRANSFER_READ_BIT : 0;
    sv_image_barrier(cmd, out_image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, out_final,
                     VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, dst_stage,
                     dst_access);
}

void sv_renderer_record(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, const sv_view *view,
                        VkImage out_image, VkImageView out_view, VkImageLayout out_final)
{
    bool shadows = r->shadow_count && scene->aabb_min[0] <= scene->aabb_max[0];
    sv_gpu_frame frame = {0};
    fill_frame(r, scene, view, shadows, &frame);
    memcpy(r->frame.mapped, &frame, sizeof(frame));
    if (r->timestamps) {
        vkCmdResetQueryPool(cmd, r->timestamps, 0, SV_TIMESTAMPS);
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, r->timestamps, 0);
    }
    sv_upload_probe_slots(r, cmd);
    sv_upload_retrace_masks(r, cmd, scene);
    if (shadows) sv_shadows_record(r, cmd, scene, &frame);
    if (r->timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r->timestamps, 1);
    record_scene_pass(r, cmd, scene, view);
    record_tonemap_pass(r, cmd, view, out_image, out_view, out_final);
}

void sv_renderer_destroy(sv_renderer *r)
{
    sv_context *ctx = r->ctx;
    if (!ctx || !ctx->device) return;
    VkDevice dev = ctx->device;
    vkDeviceWaitIdle(dev);
    if (r->timestamps) vkDestroyQueryPool(dev, r->timestamps, NULL);
    sv_probe_pass_destroy(r);
    sv_pipelines_destroy(r);
    sv_shadows_destroy(r);
    sv_bricks_destroy(r);
    sv_brick_view_destroy(r);
    sv_image_destroy(ctx, &r->sky);
    sv_image_destroy(ctx, &r->brdf_lut);
    for (uint32_t i = 0; i < r->texture_count; ++i) sv_image_destroy(ctx, &r->textures[i]);
    free(r->textures);
    sv_image_destroy(ctx, &r->white);
    sv_image_destroy(ctx, &r->hdr);
    sv_image_destroy(ctx, &r->depth);
    sv_buffer *bufs[] = {&r->vertices, &r->indices,    &r->frame,  &r->materials, &r->probes, &r->probes_half,
                         &r->cubes,    &r->cubes_half, &r->lights, &r->cells,     &r->grids,  &r->cell_index};
    for (size_t i = 0; i < sizeof(bufs) / sizeof(bufs[0]); ++i) sv_buffer_destroy(ctx, bufs[i]);
    free(r->prim_first_index);
    free(r->prim_index_count);
    free(r->prim_vertex_offset);
    free(r->prim_material);
    free(r->mesh_prim_base);
    memset(r, 0, sizeof(*r));
}
