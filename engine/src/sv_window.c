/* Window front end: GLFW window, swapchain, free-flying camera, debug toggles, frame time in the
 * title. Scene, probes and every draw go through the same sv_renderer as the headless path. */
#define _DEFAULT_SOURCE /* clock_gettime, mkstemps, strcasecmp under -std=c11 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include "schnee/pb_image.h"
#include "sv_app.h"
#include "sv_clock.h"
#include "sv_math.h"

#define SV_MAX_SWAPCHAIN_IMAGES 8

typedef struct sv_swapchain {
    VkSwapchainKHR handle;
    VkFormat format;
    VkExtent2D extent;
    uint32_t count;
    VkImage images[SV_MAX_SWAPCHAIN_IMAGES];
    VkImageView views[SV_MAX_SWAPCHAIN_IMAGES];
    VkSemaphore render_done[SV_MAX_SWAPCHAIN_IMAGES];
    bool can_copy; /* TRANSFER_SRC usage supported: screenshots possible */
} sv_swapchain;

static VkFormat pick_surface_format(sv_context *ctx, VkColorSpaceKHR *space)
{
    uint32_t n = 0;
    VkFormat chosen = VK_FORMAT_UNDEFINED;
    if (vkGetPhysicalDeviceSurfaceFormatsKHR(ctx->physical, ctx->surface, &n, NULL) != VK_SUCCESS || n == 0)
        return chosen;
    VkSurfaceFormatKHR *f = calloc(n, sizeof(*f));
    if (!f) return chosen;
    if (vkGetPhysicalDeviceSurfaceFormatsKHR(ctx->physical, ctx->surface, &n, f) == VK_SUCCESS) {
        chosen = f[0].format;
        *space = f[0].colorSpace;
        for (uint32_t i = 0; i < n; ++i)
            if (f[i].format == VK_FORMAT_B8G8R8A8_SRGB || f[i].format == VK_FORMAT_R8G8B8A8_SRGB) {
                chosen = f[i].format;
                *space = f[i].colorSpace;
                break;
            }
    }
    free(f);
    return chosen;
}

static void destroy_swapchain(sv_context *ctx, sv_swapchain *sc)
{
    for (uint32_t i = 0; i < sc->count; ++i) {
        if (sc->views[i]) vkDestroyImageView(ctx->device, sc->views[i], NULL);
        if (sc->render_done[i]) vkDestroySemaphore(ctx->device, sc->render_done[i], NULL);
    }
    if (sc->handle) vkDestroySwapchainKHR(ctx->device, sc->handle, NULL);
    VkFormat f = sc->format;
    memset(sc, 0, sizeof(*sc));
    sc->format = f;
}

static bool create_swapchain(sv_context *ctx, GLFWwindow *win, VkColorSpaceKHR space, sv_swapchain *sc)
{
    VkSurfaceCapabilitiesKHR caps;
    VK_CHECK(vkGetPhysicalDeviceSurfaceCapabilitiesKHR(ctx->physical, ctx->surface, &caps));
    int fw = 0, fh = 0;
    glfwGetFramebufferSize(win, &fw, &fh);
    VkExtent2D extent = caps.currentExtent;
    if (extent.width == UINT32_MAX) {
        extent.width = (uint32_t)fw;
        extent.height = (uint32_t)fh;
    }
    if (extent.width < caps.minImageExtent.width) extent.width = caps.minImageExtent.width;
    if (extent.height < caps.minImageExtent.height) extent.height = caps.minImageExtent.height;
    if (extent.width > caps.maxImageExtent.width) extent.width = caps.maxImageExtent.width;
    if (extent.height > caps.maxImageExtent.height) extent.height = caps.maxImageExtent.height;
    if (extent.width == 0 || extent.height == 0) return false; /* minimised */
    uint32_t count = caps.minImageCount + 1;
    if (caps.maxImageCount && count > caps.maxImageCount) count = caps.maxImageCount;
    sc->can_copy = (caps.supportedUsageFlags & VK_IMAGE_USAGE_TRANSFER_SRC_BIT) != 0;
    VkSwapchainCreateInfoKHR info = {
        .sType = VK_STRUCTURE_TYPE_SWAPCHAIN_CREATE_INFO_KHR,
        .surface = ctx->surface,
        .minImageCount = count,
        .imageFormat = sc->format,
        .imageColorSpace = space,
        .imageExtent = extent,
        .imageArrayLayers = 1,
        .imageUsage = VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | (sc->can_copy ? VK_IMAGE_USAGE_TRANSFER_SRC_BIT : 0),
        .imageSharingMode = VK_SHARING_MODE_EXCLUSIVE,
        .preTransform = caps.currentTransform,
        .compositeAlpha = VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR,
        .presentMode = VK_PRESENT_MODE_FIFO_KHR, /* always available */
        .clipped = VK_TRUE,
    };
    if (!(caps.supportedCompositeAlpha & VK_COMPOSITE_ALPHA_OPAQUE_BIT_KHR))
        info.compositeAlpha = VK_COMPOSITE_ALPHA_INHERIT_BIT_KHR;
    VK_CHECK(vkCreateSwapchainKHR(ctx->device, &info, NULL, &sc->handle));
    sc->extent = extent;
    VK_CHECK(vkGetSwapchainImagesKHR(ctx->device, sc->handle, &sc->count, NULL));
    if (sc->count > SV_MAX_SWAPCHAIN_IMAGES) sc->count = SV_MAX_SWAPCHAIN_IMAGES;
    VkResult res = vkGetSwapchainImagesKHR(ctx->device, sc->handle, &sc->count, sc->images);
    if (res != VK_SUCCESS && res != VK_INCOMPLETE) VK_CHECK(res);
    for (uint32_t i = 0; i < sc->count; ++i) {
        VkImageViewCreateInfo vi = {
            .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
            .image = sc->images[i],
            .viewType = VK_IMAGE_VIEW_TYPE_2D,
            .format = sc->format,
            .subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1},
        };
        VK_CHECK(vkCreateImageView(ctx->device, &vi, NULL, &sc->views[i]));
        VkSemaphoreCreateInfo si = {.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
        VK_CHECK(vkCreateSemaphore(ctx->device, &si, NULL, &sc->render_done[i]));
    }
    return true;
fail:
    return false;
}

/* Free-flying camera: position, yaw (about +Y, 0 = looking along -Z), pitch. */
typedef struct fly_camera {
    float pos[3];
    float yaw, pitch;
} fly_camera;

static void fly_forward(const fly_camera *c, float f[3])
{
    f[0] = sinf(c->yaw) * cosf(c->pitch);
    f[1] = sinf(c->pitch);
    f[2] = -cosf(c->yaw) * cosf(c->pitch);
}

static void fly_to_view(const fly_camera *c, sv_view *v)
{
    float f[3], target[3], up[3] = {0, 1, 0};
    fly_forward(c, f);
    for (int k = 0; k < 3; ++k) target[k] = c->pos[k] + f[k];
    sv_mat4_look_at(c->pos, target, up, v->view);
    memcpy(v->camera_pos, c->pos, sizeof(c->pos));
}

static bool write_screenshot(const char *path, const uint8_t *bgra_or_rgba, bool bgra, uint32_t w, uint32_t h)
{
    float *px = malloc((size_t)w * h * 3 * sizeof(float));
    if (!px) return false;
    for (size_t i = 0; i < (size_t)w * h; ++i)
        for (int c = 0; c < 3; ++c) px[i * 3 + c] = bgra_or_rgba[i * 4 + (bgra ? 2 - c : c)] / 255.0f;
    pb_error err = {0};
    bool ok = pb_image_write(path, w, h, 3, px, &err) == PB_SUCCESS;
    if (!ok)
        fprintf(stderr, "schnee-view: error: cannot write %s: %s\n", path, err.message);
    else
        fprintf(stderr, "schnee-view: wrote %s\n", path);
    free(px);
    return ok;
}

static bool make_surface(sv_context *ctx, void *win)
{
    VK_CHECK(glfwCreateWindowSurface(ctx->instance, (GLFWwindow *)win, NULL, &ctx->surface));
    return true;
fail:
    return false;
}

int sv_run_window(const sv_options *opt, sv_scene *scene, sv_probes *probes, const sv_sky *sky)
{
    int rc = 1;
    sv_app_gpu gpu = {0};
    sv_context *ctx = &gpu.ctx;
    sv_swapchain sc = {0};
    sv_buffer shot = {0};
    GLFWwindow *win = NULL;
    VkSemaphore acquired = VK_NULL_HANDLE;
    VkColorSpaceKHR space = VK_COLOR_SPACE_SRGB_NONLINEAR_KHR;

    if (!glfwInit()) {
        fprintf(stderr, "schnee-view: error: cannot open a window (no display?); use --headless --output PATH\n");
        return 1;
    }
    if (!glfwVulkanSupported()) {
        fprintf(stderr, "schnee-view: error: GLFW found no Vulkan loader\n");
        goto done;
    }
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    win = glfwCreateWindow((int)opt->width, (int)opt->height, "schnee-view", NULL, NULL);
    if (!win) {
        fprintf(stderr, "schnee-view: error: cannot create a window\n");
        goto done;
    }
    uint32_t ext_count = 0;
    const char **exts = glfwGetRequiredInstanceExtensions(&ext_count);
    if (!exts || !sv_app_gpu_init(&gpu, opt, exts, ext_count, make_surface, win, true)) goto done;
    sc.format = pick_surface_format(ctx, &space);
    if (sc.format == VK_FORMAT_UNDEFINED) {
        fprintf(stderr, "schnee-view: error: the window surface reports no formats\n");
        goto done;
    }
    if (!create_swapchain(ctx, win, space, &sc) ||
        !sv_app_gpu_renderer(&gpu, opt, scene, probes, sky, sc.format, sc.extent.width, sc.extent.height))
        goto done;
    VkSemaphoreCreateInfo si = {.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VK_CHECK(vkCreateSemaphore(ctx->device, &si, NULL, &acquired));
    sv_renderer *r = &gpu.renderer;
    VkCommandBuffer cmd = gpu.cmd;
    VkFence fence = gpu.fence;
    sv_view view = gpu.view;
    fly_camera cam;
    memcpy(cam.pos, view.camera_pos, sizeof(cam.pos));
    /* view rows: row 2 = -forward */
    float fwd[3] = {-view.view[2], -view.view[6], -view.view[10]};
    cam.pitch = asinf(fmaxf(-1.0f, fminf(1.0f, fwd[1])));
    cam.yaw = atan2f(fwd[0], -fwd[2]);
    float speed = 1.0f;
    if (scene->aabb_min[0] <= scene->aabb_max[0])
        speed = fmaxf(0.5f,
                      0.25f * fmaxf(scene->aabb_max[0] - scene->aabb_min[0], scene->aabb_max[2] - scene->aabb_min[2]));

    uint32_t selected = 0, frame = 0;
    double last = sv_now_ms(), title_time = last, ms_avg = 0.0, gpu_avg = 0.0; /* gpu_avg: timestamps, 0 = none */
    double mouse_x = 0, mouse_y = 0;
    bool dragging = false, prev_p = false, prev_c = false, prev_n = false, prev_m = false;
    while (!glfwWindowShouldClose(win)) {
        glfwPollEvents();
        double now = sv_now_ms();
        float dt = (float)((now - last) * 1e-3);
        last = now;
        ms_avg = ms_avg == 0.0 ? dt * 1e3 : 0.9 * ms_avg + 0.1 * dt * 1e3;
        if (glfwGetKey(win, GLFW_KEY_ESCAPE) == GLFW_PRESS) glfwSetWindowShouldClose(win, 1);

        /* Toggles on key press edges. */
        bool p = glfwGetKey(win, GLFW_KEY_P) == GLFW_PRESS, c = glfwGetKey(win, GLFW_KEY_C) == GLFW_PRESS;
        bool n = glfwGetKey(win, GLFW_KEY_N) == GLFW_PRESS, m = glfwGetKey(win, GLFW_KEY_M) == GLFW_PRESS;
        /* M cycles the probe mode: per material -> object -> pixel -> (any later mode) -> off -> per
         * material, through the values of sv_gpu.h (MATERIAL is the last, OFF the first). */
        if (m && !prev_m)
            view.probe_mode = view.probe_mode == SV_PROBE_MODE_MATERIAL        ? SV_PROBE_MODE_OFF + 1u
                              : view.probe_mode == SV_PROBE_MODE_OFF           ? SV_PROBE_MODE_MATERIAL
                              : view.probe_mode + 1u == SV_PROBE_MODE_MATERIAL ? SV_PROBE_MODE_OFF
                                                                               : view.probe_mode + 1u;
        prev_m = m;
        if (p && !prev_p)
            view.debug_mode = view.debug_mode == SV_DEBUG_PROBE_COLOR ? SV_DEBUG_NONE : SV_DEBUG_PROBE_COLOR;
        if (c && !prev_c) view.show_cells = !view.show_cells;
        if (n && !prev_n && scene->object_count) selected = (selected + 1) % scene->object_count;
        prev_p = p;
        prev_c = c;
        prev_n = n;

        /* Free-fly camera: right mouse drag looks, WASD/QE moves. */
        double mx, my;
        glfwGetCursorPos(win, &mx, &my);
        bool rmb = glfwGetMouseButton(win, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
        bool moved = false;
        if (rmb && dragging) {
            cam.yaw += (float)(mx - mouse_x) * 0.004f;
            cam.pitch = fmaxf(-1.55f, fminf(1.55f, cam.pitch - (float)(my - mouse_y) * 0.004f));
            moved = mx != mouse_x || my != mouse_y;
        }
        dragging = rmb;
        mouse_x = mx;
        mouse_y = my;
        float f[3], right[3];
        fly_forward(&cam, f);
        right[0] = cosf(cam.yaw);
        right[1] = 0.0f;
        right[2] = sinf(cam.yaw);
        float step = speed * dt * (glfwGetKey(win, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ? 4.0f : 1.0f);
        struct {
            int key;
            const float *dir;
            float sign;
        } keys[] = {
            {GLFW_KEY_W, f, 1},
            {GLFW_KEY_S, f, -1},
            {GLFW_KEY_D, right, 1},
            {GLFW_KEY_A, right, -1},
        };
        for (size_t k = 0; k < sizeof(keys) / sizeof(keys[0]); ++k)
            if (glfwGetKey(win, keys[k].key) == GLFW_PRESS) {
                for (int j = 0; j < 3; ++j) cam.pos[j] += keys[k].sign * step * keys[k].dir[j];
                moved = true;
            }
        if (glfwGetKey(win, GLFW_KEY_E) == GLFW_PRESS) cam.pos[1] += step, moved = true;
        if (glfwGetKey(win, GLFW_KEY_Q) == GLFW_PRESS) cam.pos[1] -= step, moved = true;
        if (moved) fly_to_view(&cam, &view);

        /* Move the selected object; its probe is re-queried by sv_probes_assign. */
        if (scene->object_count) {
            int move_keys[6] = {GLFW_KEY_J, GLFW_KEY_L, GLFW_KEY_K, GLFW_KEY_I, GLFW_KEY_U, GLFW_KEY_O};
            float delta[3] = {0, 0, 0};
            for (int k = 0; k < 6; ++k)
                if (glfwGetKey(win, move_keys[k]) == GLFW_PRESS)
                    delta[k / 2 == 0 ? 0 : k / 2 == 1 ? 2 : 1] += (k % 2 ? 1.0f : -1.0f) * step;
            if (delta[0] != 0 || delta[1] != 0 || delta[2] != 0) {
                uint32_t node = scene->objects[selected].node;
                float t[3];
                const float *local = scene->node_local + 16 * node;
                for (int k = 0; k < 3; ++k) t[k] = local[12 + k] + delta[k];
                sv_scene_set_translation(scene, node, t);
            }
            sv_probes_assign(probes, scene);
        }

        if (now - title_time > 250.0 && scene->object_count) {
            char title[256];
            const sv_object *o = &scene->objects[selected];
            const char *mode = sv_probe_mode_name(view.probe_mode);
            char gpu_ms[32] = "";
            if (gpu_avg > 0.0) snprintf(gpu_ms, sizeof gpu_ms, ", GPU %.2f ms", gpu_avg);
            snprintf(title, sizeof(title),
                     "schnee-view - %.2f ms (%.0f fps%s) - %s%s, probe mode %s - object '%s' probe %u", ms_avg,
                     1000.0 / ms_avg, gpu_ms, view.debug_mode == SV_DEBUG_PROBE_COLOR ? "probe colours" : "shaded",
                     view.show_cells ? " + probe view" : "", mode ? mode : "?", o->name, o->probe);
            glfwSetWindowTitle(win, title);
            title_time = now;
        }

        VK_CHECK(vkWaitForFences(ctx->device, 1, &fence, VK_TRUE, UINT64_MAX));
        double stage[3]; /* the previous frame is done: its GPU time, smoothed like the frame time */
        if (frame > 0 && sv_renderer_gpu_times(r, stage)) {
            double g = stage[0] + stage[1] + stage[2];
            gpu_avg = gpu_avg > 0.0 ? 0.9 * gpu_avg + 0.1 * g : g;
        }
        uint32_t image = 0;
        VkResult acq = vkAcquireNextImageKHR(ctx->device, sc.handle, UINT64_MAX, acquired, VK_NULL_HANDLE, &image);
        if (acq == VK_ERROR_OUT_OF_DATE_KHR) {
            vkDeviceWaitIdle(ctx->device);
            destroy_swapchain(ctx, &sc);
            if (create_swapchain(ctx, win, space, &sc) && sv_renderer_resize(r, sc.extent.width, sc.extent.height))
                continue;
            glfwWaitEvents(); /* minimised: wait for a usable size */
            continue;
        }
        if (acq != VK_SUBOPTIMAL_KHR) VK_CHECK(acq);
        VK_CHECK(vkResetFences(ctx->device, 1, &fence));

        bool last_frame = opt->frames && frame + 1 >= opt->frames;
        bool take_shot = last_frame && opt->screenshot && sc.can_copy;
        if (take_shot && !shot.buffer &&
            !sv_buffer_create(ctx, (VkDeviceSize)sc.extent.width * sc.extent.height * 4,
                              VK_BUFFER_USAGE_TRANSFER_DST_BIT, true, &shot))
            goto done;
        VkCommandBufferBeginInfo begin = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                          .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
        VK_CHECK(vkResetCommandBuffer(cmd, 0));
        VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
        sv_renderer_record(r, cmd, scene, &view, sc.images[image], sc.views[image],
                           take_shot ? VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL : VK_IMAGE_LAYOUT_PRESENT_SRC_KHR);
        if (take_shot) {
            VkBufferImageCopy region = {.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                                        .imageExtent = {sc.extent.width, sc.extent.height, 1}};
            vkCmdCopyImageToBuffer(cmd, sc.images[image], VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, shot.buffer, 1,
                                   &region);
            sv_image_barrier(cmd, sc.images[image], VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                             VK_IMAGE_LAYOUT_PRESENT_SRC_KHR, VK_PIPELINE_STAGE_TRANSFER_BIT,
                             VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0);
            VkBufferMemoryBarrier hb = {
                .sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER,
                .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                .dstAccessMask = VK_ACCESS_HOST_READ_BIT,
                .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
                .buffer = shot.buffer,
                .size = VK_WHOLE_SIZE,
            };
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 0, NULL, 1, &hb, 0,
                                 NULL);
        }
        VK_CHECK(vkEndCommandBuffer(cmd));
        VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
        VkSubmitInfo submit = {
            .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
            .waitSemaphoreCount = 1,
            .pWaitSemaphores = &acquired,
            .pWaitDstStageMask = &wait_stage,
            .commandBufferCount = 1,
            .pCommandBuffers = &cmd,
            .signalSemaphoreCount = 1,
            .pSignalSemaphores = &sc.render_done[image],
        };
        VK_CHECK(vkQueueSubmit(ctx->queue, 1, &submit, fence));
        VkPresentInfoKHR present = {
            .sType = VK_STRUCTURE_TYPE_PRESENT_INFO_KHR,
            .waitSemaphoreCount = 1,
            .pWaitSemaphores = &sc.render_done[image],
            .swapchainCount = 1,
            .pSwapchains = &sc.handle,
            .pImageIndices = &image,
        };
        VkResult pres = vkQueuePresentKHR(ctx->queue, &present);
        if (pres == VK_ERROR_OUT_OF_DATE_KHR || pres == VK_SUBOPTIMAL_KHR) {
            vkDeviceWaitIdle(ctx->device);
            destroy_swapchain(ctx, &sc);
            if (!create_swapchain(ctx, win, space, &sc) || !sv_renderer_resize(r, sc.extent.width, sc.extent.height))
                glfwWaitEvents();
        } else {
            VK_CHECK(pres);
        }
        frame++;
        if (take_shot) {
            VK_CHECK(vkWaitForFences(ctx->device, 1, &fence, VK_TRUE, UINT64_MAX));
            if (!write_screenshot(opt->screenshot, shot.mapped,
                                  sc.format == VK_FORMAT_B8G8R8A8_SRGB || sc.format == VK_FORMAT_B8G8R8A8_UNORM,
                                  sc.extent.width, sc.extent.height))
                goto done;
        } else if (last_frame && opt->screenshot) {
            fprintf(stderr,
                    "schnee-view: error: the swapchain cannot be copied (no TRANSFER_SRC usage); no screenshot\n");
            goto done;
        }
        if (last_frame) break;
    }
    fprintf(stderr, "schnee-view: %u frame(s) presented, last mean frame time %.2f ms\n", frame, ms_avg);
    rc = 0;
done:
fail:
    if (ctx->device) {
        vkDeviceWaitIdle(ctx->device);
        if (acquired) vkDestroySemaphore(ctx->device, acquired, NULL);
        sv_buffer_destroy(ctx, &shot);
        destroy_swapchain(ctx, &sc);
    }
    rc = sv_app_gpu_destroy(&gpu, rc);
    if (win) glfwDestroyWindow(win);
    glfwTerminate();
    return rc;
}
