/* The shadow maps' GPU side (see sv_shadows.h; the fitting math is sv_shadow_math.c). */
#include "sv_shadows.h"

#include <math.h>
#include <string.h>

#include "sv_math.h"

/* Which lights get shadow map layers (docs/engine.md "Shadows"): lights whose mode is mixed or
 * realtime (or no extension), in light-instance order, while SV_MAX_SHADOW_LAYERS lasts: a directional
 * light r->shadow_cascades layers (its cascades; as many as are left when fewer are, with a warning),
 * a spot light one (six, as a cube, when its outer cone is wider than SV_SPOT_SHADOW_MAX_ANGLE), a point
 * light six. A light that does not fit (a sun: no layer left) is unshadowed with a warning naming it.
 * None when shadow_res is 0. Returns the light's first layer or -1; *cascades = the layers a sun got. */
int sv_shadows_assign(sv_renderer *r, const sv_gltf_light_instance *li, const sv_gltf_light *s, uint32_t *cascades)
{
    const char *name = s->name ? s->name : "";
    bool sun = s->type == SV_GLTF_LIGHT_DIRECTIONAL;
    bool cube = s->type == SV_GLTF_LIGHT_POINT ||
                (s->type == SV_GLTF_LIGHT_SPOT && s->outer_cone_angle > SV_SPOT_SHADOW_MAX_ANGLE);
    uint32_t need = sun ? r->shadow_cascades : cube ? 6u : 1u;
    uint32_t left = SV_MAX_SHADOW_LAYERS - r->shadow_count;
    if (need > left && !(sun && left > 0)) {
        fprintf(stderr,
                "schnee-view: warning: light '%s' needs %u shadow map layer%s but only %u of %d are left; it is "
                "unshadowed\n",
                name, need, need == 1 ? "" : "s", left, SV_MAX_SHADOW_LAYERS);
        return -1;
    }
    if (need > left) { /* a sun: fewer, wider cascades rather than none */
        fprintf(stderr,
                "schnee-view: warning: light '%s' needs %u shadow map layers (cascades) but only %u of %d are left; "
                "it gets %u cascade%s\n",
                name, need, left, SV_MAX_SHADOW_LAYERS, left, left == 1 ? "" : "s");
        need = left;
    }
    int first = (int)r->shadow_count;
    static const float faces[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (uint32_t f = 0; f < need; ++f) {
        sv_shadow_layer *layer = &r->shadow_layers[r->shadow_count++];
        memcpy(layer->pos, li->position, sizeof(layer->pos));
        memcpy(layer->dir, cube ? faces[f] : li->direction, sizeof(layer->dir));
        layer->kind = sun ? SV_SHADOW_ORTHO : cube ? SV_SHADOW_CUBE : SV_SHADOW_SPOT;
        layer->tan_half = cube ? 1.0f : tanf(fmaxf(s->outer_cone_angle, 1e-3f));
        layer->cascade = sun ? f : 0;
        layer->cascades = sun ? need : 1;
    }
    *cascades = sun ? need : 0;
    return first;
}

/* A depth format the device can render to and sample (D32 float preferred), and whether it filters
 * linearly (the hardware 2x2 bilinear comparison; nearest otherwise). */
static VkFormat pick_shadow_format(sv_context *ctx, bool *linear)
{
    VkFormat candidates[] = {VK_FORMAT_D32_SFLOAT, VK_FORMAT_D16_UNORM};
    const VkFormatFeatureFlags need =
        VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT;
    for (int i = 0; i < 2; ++i) {
        VkFormatProperties p;
        vkGetPhysicalDeviceFormatProperties(ctx->physical, candidates[i], &p);
        if ((p.optimalTilingFeatures & need) == need) {
            *linear = (p.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT) != 0;
            return candidates[i];
        }
    }
    *linear = false;
    return VK_FORMAT_D16_UNORM; /* required by the spec for depth attachments and sampling */
}

/* The shadow map array (shadow_count layers of shadow_res^2, or one 1x1 layer when no light is
 * shadowed: the binding needs an image), its per-layer views and the comparison sampler. The image is
 * left in SHADER_READ_ONLY_OPTIMAL, the layout every frame's shadow pass returns it to. */
bool sv_shadows_create(sv_renderer *r, uint32_t shadow_res)
{
    sv_context *ctx = r->ctx;
    bool linear = false;
    r->shadow_format = pick_shadow_format(ctx, &linear);
    uint32_t max_dim = ctx->properties.limits.maxImageDimension2D;
    if (r->shadow_count && shadow_res > max_dim) {
        fprintf(stderr, "schnee-view: warning: --shadow-res %u exceeds the device's limit %u; using %u\n", shadow_res,
                max_dim, max_dim);
        shadow_res = max_dim;
    }
    r->shadow_res = r->shadow_count ? shadow_res : 1;
    uint32_t layers = r->shadow_count ? r->shadow_count : 1;
    if (!sv_image_create_layers(ctx, r->shadow_res, r->shadow_res, 1, layers, r->shadow_format,
                                VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT,
                                VK_IMAGE_ASPECT_DEPTH_BIT, &r->shadow))
        return false;
    for (uint32_t k = 0; k < r->shadow_count; ++k) {
        VkImageViewCreateInfo vi = {
            .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
            .image = r->shadow.image,
            .viewType = VK_IMAGE_VIEW_TYPE_2D,
            .format = r->shadow_format,
            .subresourceRange = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 1, k, 1},
        };
        VK_CHECK(vkCreateImageView(ctx->device, &vi, NULL, &r->shadow_layer_views[k]));
    }
    VkSamplerCreateInfo si =
        sv_sampler_info(linear ? VK_FILTER_LINEAR : VK_FILTER_NEAREST, VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_BORDER);
    si.compareEnable = VK_TRUE;
    si.compareOp = VK_COMPARE_OP_LESS_OR_EQUAL;
    si.borderColor = VK_BORDER_COLOR_FLOAT_OPAQUE_WHITE;
    VK_CHECK(vkCreateSampler(ctx->device, &si, NULL, &r->shadow_sampler));
    VkCommandBuffer cmd = sv_begin_one_shot(ctx);
    if (!cmd) return false;
    sv_image_barrier(cmd, r->shadow.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                     VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
    return sv_end_one_shot(ctx, cmd);
fail:
    return false;
}

/* The shadow pass (docs/engine.md "Shadows"): every layer cleared to depth 1, then every opaque or
 * masked primitive of every object drawn depth-only from its light; the array ends in
 * SHADER_READ_ONLY_OPTIMAL for the scene pass. */
void sv_shadows_record(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, const sv_gpu_frame *frame)
{
    const sv_gltf *g = scene->gltf;
    sv_image_barrier(cmd, r->shadow.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    VkViewport viewport = {0, 0, (float)r->shadow_res, (float)r->shadow_res, 0.0f, 1.0f};
    VkRect2D scissor = {{0, 0}, {r->shadow_res, r->shadow_res}};
    VkDeviceSize zero = 0;
    for (uint32_t k = 0; k < r->shadow_count; ++k) {
        VkRenderingAttachmentInfo depth =
            sv_attachment(r->shadow_layer_views[k], VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                          VK_ATTACHMENT_LOAD_OP_CLEAR, VK_ATTACHMENT_STORE_OP_STORE);
        depth.clearValue.depthStencil = (VkClearDepthStencilValue){1.0f, 0};
        VkRenderingInfo ri = {
            .sType = VK_STRUCTURE_TYPE_RENDERING_INFO,
            .renderArea = scissor,
            .layerCount = 1,
            .pDepthAttachment = &depth,
        };
        vkCmdBeginRendering(cmd, &ri);
        vkCmdSetViewport(cmd, 0, 1, &viewport);
        vkCmdSetScissor(cmd, 0, 1, &scissor);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->pipelines[SV_PIPELINE_SHADOW]);
        vkCmdBindVertexBuffers(cmd, 0, 1, &r->vertices.buffer, &zero);
        vkCmdBindIndexBuffer(cmd, r->indices.buffer, 0, VK_INDEX_TYPE_UINT32);
        for (uint32_t o = 0; o < scene->object_count; ++o) {
            const sv_object *obj = &scene->objects[o];
            sv_gpu_shadow_draw draw;
            sv_mat4_mul(frame->shadow_view_proj[k], obj->world, draw.light_mvp);
            vkCmdPushConstants(cmd, r->shadow_layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(draw), &draw);
            const sv_gltf_mesh *mesh = &g->meshes[obj->mesh];
            for (uint32_t p = 0; p < mesh->primitive_count; ++p) {
                uint32_t pi = r->mesh_prim_base[obj->mesh] + p;
                uint32_t mat = r->prim_material[pi];
                if (!r->prim_index_count[pi] ||
                    (mat < g->material_count && g->materials[mat].alpha_mode == SV_GLTF_ALPHA_BLEND))
                    continue;
                vkCmdDrawIndexed(cmd, r->prim_index_count[pi], 1, r->prim_first_index[pi], r->prim_vertex_offset[pi],
                                 0);
            }
        }
        vkCmdEndRendering(cmd);
    }
    sv_image_barrier(cmd, r->shadow.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                     VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                     VK_ACCESS_SHADER_READ_BIT);
}

void sv_shadows_fit(const sv_renderer *r, const sv_scene *scene, const sv_view *view, sv_gpu_frame *frame)
{
    sv_shadow_camera camera = {.yfov = view->yfov, .ymag = view->ymag, .znear = view->znear, .zfar = view->zfar};
    memcpy(camera.view, view->view, sizeof(camera.view));
    memcpy(camera.camera_pos, view->camera_pos, sizeof(camera.camera_pos));
    sv_shadow_fit_layers(r->shadow_layers, r->shadow_count, r->shadow_cascades, &camera,
                         (float)r->width / (float)r->height, scene->aabb_min, scene->aabb_max, r->shadow_res,
                         frame->shadow_view_proj, frame->shadow_params);
}

void sv_shadows_destroy(sv_renderer *r)
{
    sv_context *ctx = r->ctx;
    if (r->shadow_sampler) vkDestroySampler(ctx->device, r->shadow_sampler, NULL);
    for (uint32_t k = 0; k < SV_MAX_SHADOW_LAYERS; ++k)
        if (r->shadow_layer_views[k]) vkDestroyImageView(ctx->device, r->shadow_layer_views[k], NULL);
    sv_image_destroy(ctx, &r->shadow);
}
