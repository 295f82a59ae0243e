/* The application layer shared by both front ends (sv_app.h): the initial view, the renderer
 * description, the GPU setup and teardown, assignments and the validation verdict. It calls
 * neither main.c nor a front end. */
#define _DEFAULT_SOURCE /* clock_gettime under -std=c11 */
#include "sv_app.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "sv_clock.h"
#include "sv_math.h"

bool sv_app_initial_view(const sv_options *opt, const sv_scene *scene, sv_view *v)
{
    memset(v, 0, sizeof(*v));
    v->exposure = opt->exposure;
    v->tonemap = opt->tonemap;
    v->debug_mode = opt->debug_mode;
    v->flags = opt->no_direct ? SV_FRAME_NO_DIRECT : 0;
    v->show_cells = opt->show_cells;
    v->brick_view = opt->brick_view;
    v->probe_mode = opt->probe_mode;
    v->probe_representation = opt->probe_representation;
    v->normal_bias = opt->normal_bias;
    if (opt->no_specular) v->flags |= SV_FRAME_NO_SPECULAR;
    if (opt->no_renorm) v->flags |= SV_FRAME_NO_RENORM;
    const sv_gltf *g = scene->gltf;
    if (opt->look) {
        float up[3] = {0, 1, 0};
        memcpy(v->camera_pos, opt->look_from, sizeof(v->camera_pos));
        sv_mat4_look_at(v->camera_pos, opt->look_at, up, v->view);
        v->yfov = 0.8f;
        v->znear = 0.05f;
        v->zfar = 0.0f; /* infinite */
        return true;
    }
    int32_t cam = -1;
    if (opt->camera) {
        cam = sv_gltf_find_camera(g, opt->camera);
        if (cam < 0) {
            fprintf(stderr, "schnee-view: error: no camera named '%s' in %s (%u camera(s))\n", opt->camera,
                    opt->scene_path, g->camera_instance_count);
            for (uint32_t i = 0; i < g->camera_instance_count; ++i)
                fprintf(stderr, "  node '%s'\n", g->nodes[g->camera_instances[i].node].name);
            return false;
        }
    } else if (g->camera_instance_count) {
        cam = 0;
    }
    if (cam >= 0) {
        const sv_gltf_camera_instance *ci = &g->camera_instances[cam];
        const sv_gltf_camera *c = &g->cameras[ci->camera];
        if (!sv_mat4_invert(ci->world, v->view)) {
            fprintf(stderr, "schnee-view: error: camera '%s' has a singular transform\n", g->nodes[ci->node].name);
            return false;
        }
        memcpy(v->camera_pos, ci->world + 12, 3 * sizeof(float));
        v->yfov = c->type == SV_GLTF_CAMERA_PERSPECTIVE ? c->yfov : 0.0f;
        v->xmag = c->xmag;
        v->ymag = c->ymag;
        v->znear = c->znear > 0 ? c->znear : 0.01f;
        v->zfar = c->zfar;
        return true;
    }
    /* Frame the bounds: look at the centre from +Z and somewhat above, far enough that the
     * bounding sphere fits the vertical field of view. */
    float center[3] = {0, 0, 0}, radius = 1.0f;
    if (scene->aabb_min[0] <= scene->aabb_max[0]) {
        float d2 = 0;
        for (int k = 0; k < 3; ++k) {
            center[k] = 0.5f * (scene->aabb_min[k] + scene->aabb_max[k]);
            float e = 0.5f * (scene->aabb_max[k] - scene->aabb_min[k]);
            d2 += e * e;
        }
        radius = fmaxf(sqrtf(d2), 1e-3f);
    }
    v->yfov = 0.8f;
    float dist = radius / sinf(0.5f * v->yfov);
    float dir[3] = {0.0f, 0.35f, 1.0f};
    float dl = sqrtf(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    for (int k = 0; k < 3; ++k) v->camera_pos[k] = center[k] + dir[k] / dl * dist;
    float up[3] = {0, 1, 0};
    sv_mat4_look_at(v->camera_pos, center, up, v->view);
    v->znear = dist * 0.01f;
    v->zfar = dist * 10.0f;
    return true;
}

void sv_app_print_assignments(const sv_scene *scene, const sv_probes *probes)
{
    for (uint32_t i = 0; i < scene->object_count; ++i) {
        const sv_object *o = &scene->objects[i];
        printf("object %u '%s' probe %u center (%g, %g, %g)\n", i, o->name, o->probe,
               0.5 * (o->aabb_min[0] + o->aabb_max[0]), 0.5 * (o->aabb_min[1] + o->aabb_max[1]),
               0.5 * (o->aabb_min[2] + o->aabb_max[2]));
        if (o->probe_mode < SV_PROBE_MODE_MATERIAL || o->probe_representation < SV_PROBE_REP_MATERIAL)
            printf("  own probe mode %s representation %s (VULKAN_SCHNEE_node)\n",
                   o->probe_mode < SV_PROBE_MODE_MATERIAL ? sv_probe_mode_name(o->probe_mode) : "material",
                   o->probe_representation < SV_PROBE_REP_MATERIAL
                       ? sv_probe_representation_name(o->probe_representation)
                       : "material");
        if (i >= probes->slot_count || o->probe != probes->total + i) continue;
        const sv_object_weights *w = &probes->slot_weights[i];
        printf("  grid %u weights %u:", w->grid, w->count);
        for (uint32_t k = 0; k < w->count; ++k) printf(" %u:%.9g", w->probe[k], w->weight[k]);
        printf("\n");
    }
    fflush(stdout);
}

bool sv_app_validation_clean(const sv_context *ctx)
{
    if (!ctx->validation) return true;
    if (ctx->validation_errors || ctx->validation_warnings) {
        fprintf(stderr, "schnee-view: error: validation reported %u error(s) and %u warning(s)\n",
                ctx->validation_errors, ctx->validation_warnings);
        return false;
    }
    return true;
}

sv_renderer_desc sv_app_renderer_desc(const sv_options *opt, const sv_sky *sky)
{
    sv_renderer_desc d = SV_RENDERER_DESC_DEFAULT;
    d.fallback_radiance = opt->fallback_radiance;
    d.half_probes = opt->half_probes;
    d.bricks = opt->bricks;
    d.bricks_required = opt->bricks && opt->bricks_given;
    d.shader_loops = opt->shader_loops;
    d.probe_pass = opt->probe_pass;
    d.shadow_res = opt->shadow_res;
    d.shadow_cascades = opt->shadow_cascades;
    d.cube_probes = opt->probe_representation == SV_PROBE_REP_AMBIENT_CUBE;
    d.sky = sky && sky->present && !opt->no_sky ? sky : NULL;
    d.probe_view = opt->show_cells || !opt->headless; /* the window's C and B keys turn the probe view on */
    return d;
}

bool sv_app_gpu_init(sv_app_gpu *gpu, const sv_options *opt, const char *const *extensions, uint32_t extension_count,
                     bool (*make_surface)(sv_context *ctx, void *user), void *user, bool fence_signaled)
{
    memset(gpu, 0, sizeof(*gpu));
    double t0 = sv_now_ms();
    sv_context *ctx = &gpu->ctx;
    if (!sv_create_instance(ctx, opt->validation, extensions, extension_count)) return false;
    if (make_surface && !make_surface(ctx, user)) return false;
    if (!sv_pick_device(ctx) || !sv_create_device(ctx) || !sv_create_command_pool(ctx)) return false;
    VkFenceCreateInfo fi = {.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO,
                            .flags = fence_signaled ? VK_FENCE_CREATE_SIGNALED_BIT : 0};
    VK_CHECK(vkCreateFence(ctx->device, &fi, NULL, &gpu->fence));
    VkCommandBufferAllocateInfo ai = {
        .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
        .commandPool = ctx->command_pool,
        .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
        .commandBufferCount = 1,
    };
    VK_CHECK(vkAllocateCommandBuffers(ctx->device, &ai, &gpu->cmd));
    gpu->setup_ms = sv_now_ms() - t0;
    return true;
fail:
    return false;
}

bool sv_app_gpu_renderer(sv_app_gpu *gpu, const sv_options *opt, const sv_scene *scene, const sv_probes *probes,
                         const sv_sky *sky, VkFormat format, uint32_t width, uint32_t height)
{
    double t0 = sv_now_ms();
    sv_renderer_desc desc = sv_app_renderer_desc(opt, sky);
    if (!sv_renderer_create(&gpu->renderer, &gpu->ctx, scene, probes, format, &desc) ||
        !sv_renderer_resize(&gpu->renderer, width, height) || !sv_app_initial_view(opt, scene, &gpu->view))
        return false;
    gpu->upload_ms = sv_now_ms() - t0;
    return true;
}

int sv_app_gpu_destroy(sv_app_gpu *gpu, int rc)
{
    if (gpu->ctx.device) {
        vkDeviceWaitIdle(gpu->ctx.device);
        if (gpu->fence) vkDestroyFence(gpu->ctx.device, gpu->fence, NULL);
        sv_renderer_destroy(&gpu->renderer);
    }
    sv_context_destroy(&gpu->ctx);
    if (!sv_app_validation_clean(&gpu->ctx) && rc == 0) rc = 3;
    return rc;
}
