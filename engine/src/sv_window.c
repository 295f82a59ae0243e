/* Window front end: GLFW window, swapchain, frame loop, frame time in the title, the screenshot of
 * --frames/--screenshot. Keyboard and mouse are sv_input.c's; scene, probes and every draw go through
 * the same sv_renderer as the headless path. */
#define _DEFAULT_SOURCE /* clock_gettime, mkstemps, strcasecmp under -std=c11 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define GLFW_INCLUDE_VULKAN
#include <GLFW/glfw3.h>

#include "schnee/pb_image.h"
#include "sv_app.h"
#include "sv_clock.h"
#include "sv_input.h"

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

/* The window's state across frames. */
typedef struct sv_window {
    GLFWwindow *win;
    sv_app_gpu gpu;
    sv_swapchain sc;
    sv_buffer shot; /* host-visible copy of the last frame (--screenshot) */
    VkSemaphore acquired;
    VkColorSpaceKHR space;
    sv_input input;
    sv_view view;
    uint32_t frame;                           /* frames presented */
    double last, title_time, ms_avg, gpu_avg; /* gpu_avg: timestamps, 0 = none */
} sv_window;

/* The window, the Vulkan context on its surface, the swapchain and the renderer. False with a message. */
static bool open_window(sv_window *w, const sv_options *opt, const sv_scene *scene, const sv_probes *probes,
                        const sv_sky *sky)
{
    sv_context *ctx = &w->gpu.ctx;
    if (!glfwVulkanSupported()) {
        fprintf(stderr, "schnee-view: error: GLFW found no Vulkan loader\n");
        return false;
    }
    glfwWindowHint(GLFW_CLIENT_API, GLFW_NO_API);
    w->win = glfwCreateWindow((int)opt->width, (int)opt->height, "schnee-view", NULL, NULL);
    if (!w->win) {
        fprintf(stderr, "schnee-view: error: cannot create a window\n");
        return false;
    }
    uint32_t ext_count = 0;
    const char **exts = glfwGetRequiredInstanceExtensions(&ext_count);
    if (!exts || !sv_app_gpu_init(&w->gpu, opt, exts, ext_count, make_surface, w->win, true)) return false;
    w->sc.format = pick_surface_format(ctx, &w->space);
    if (w->sc.format == VK_FORMAT_UNDEFINED) {
        fprintf(stderr, "schnee-view: error: the window surface reports no formats\n");
        return false;
    }
    if (!create_swapchain(ctx, w->win, w->space, &w->sc) ||
        !sv_app_gpu_renderer(&w->gpu, opt, scene, probes, sky, w->sc.format, w->sc.extent.width, w->sc.extent.height))
        return false;
    VkSemaphoreCreateInfo si = {.sType = VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VK_CHECK(vkCreateSemaphore(ctx->device, &si, NULL, &w->acquired));
    return true;
fail:
    return false;
}

/* Frame time, GPU time, shading and probe modes and the selected object in the title, 4 times a second. */
static void update_title(sv_window *w, const sv_scene *scene, double now)
{
    if (now - w->title_time <= 250.0 || !scene->object_count) return;
    char title[256];
    const sv_object *o = &scene->objects[w->input.selected];
    const char *mode = sv_probe_mode_name(w->view.probe_mode);
    char gpu_ms[32] = "";
    if (w->gpu_avg > 0.0) snprintf(gpu_ms, sizeof gpu_ms, ", GPU %.2f ms", w->gpu_avg);
    snprintf(title, sizeof(title), "schnee-view - %.2f ms (%.0f fps%s) - %s%s, probe mode %s - object '%s' probe %u",
             w->ms_avg, 1000.0 / w->ms_avg, gpu_ms,
             w->view.debug_mode == SV_DEBUG_PROBE_COLOR ? "probe colours" : "shaded",
             w->view.show_cells ? " + probe view" : "", mode ? mode : "?", o->name, o->probe);
    glfwSetWindowTitle(w->win, title);
    w->title_time = now;
}

/* After a resize: the swapchain again and the renderer's targets at its size; false when minimised. */
static bool recreate_swapchain(sv_window *w)
{
    sv_context *ctx = &w->gpu.ctx;
    vkDeviceWaitIdle(ctx->device);
    destroy_swapchain(ctx, &w->sc);
    return create_swapchain(ctx, w->win, w->space, &w->sc) &&
           sv_renderer_resize(&w->gpu.renderer, w->sc.extent.width, w->sc.extent.height);
}

/* Records the frame into swapchain image `image`, and its copy into w->shot when `take_shot`. */
static bool record_frame(sv_window *w, sv_scene *scene, uint32_t image, bool take_shot)
{
    VkCommandBuffer cmd = w->gpu.cmd;
    sv_swapchain *sc = &w->sc;
    VkCommandBufferBeginInfo begin = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                      .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
    VK_CHECK(vkResetCommandBuffer(cmd, 0));
    VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
    sv_renderer_record(&w->gpu.renderer, cmd, scene, &w->view, sc->images[image], sc->views[image],
                       take_shot ? VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL : VK_IMAGE_LAYOUT_PRESENT_SRC_KHR);
    if (take_shot) {
        VkBufferImageCopy region = {.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
                                    .imageExtent = {sc->extent.width, sc->extent.height, 1}};
        vkCmdCopyImageToBuffer(cmd, sc->images[image], VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, w->shot.buffer, 1,
                               &region);
        sv_image_barrier(cmd, sc->images[image], VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         VK_IMAGE_LAYOUT_PRESENT_SRC_KHR, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT,
                         VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0);
        VkBufferMemoryBarrier hb = {
            .sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER,
            .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
            .dstAccessMask = VK_ACCESS_HOST_READ_BIT,
            .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
            .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
            .buffer = w->shot.buffer,
            .size = VK_WHOLE_SIZE,
        };
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 0, NULL, 1, &hb, 0,
                             NULL);
    }
    VK_CHECK(vkEndCommandBuffer(cmd));
    return true;
fail:
    return false;
}

/* Submits the recorded frame (after the image is acquired) and presents it; an out-of-date or
 * suboptimal swapchain is made again. */
static bool submit_and_present(sv_window *w, uint32_t image)
{
    sv_context *ctx = &w->gpu.ctx;
    VkPipelineStageFlags wait_stage = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
    VkSubmitInfo submit = {
        .sType = VK_STRUCTURE_TYPE_SUBMIT_INFO,
        .waitSemaphoreCount = 1,
        .pWaitSemaphores = &w->acquired,
        .pWaitDstStageMask = &wait_stage,
        .commandBufferCount = 1,
        .pCommandBuffers = &w->gpu.cmd,
        .signalSemaphoreCount = 1,
        .pSignalSemaphores = &w->sc.render_done[image],
    };
    VK_CHECK(vkQueueSubmit(ctx->queue, 1, &submit, w->gpu.fence));
    VkPresentInfoKHR present = {
        .sType = VK_STRUCTURE_TYPE_PRESENT_INFO_KHR,
        .waitSemaphoreCount = 1,
        .pWaitSemaphores = &w->sc.render_done[image],
        .swapchainCount = 1,
        .pSwapchains = &w->sc.handle,
        .pImageIndices = &image,
    };
    VkResult pres = vkQueuePresentKHR(ctx->queue, &present);
    if (pres == VK_ERROR_OUT_OF_DATE_KHR || pres == VK_SUBOPTIMAL_KHR) {
        if (!recreate_swapchain(w)) glfwWaitEvents();
    } else {
        VK_CHECK(pres);
    }
    return true;
fail:
    return false;
}

/* After the last frame of --frames: its screenshot written (waiting for the frame first). */
static bool finish_screenshot(sv_window *w, const sv_options *opt, bool take_shot)
{
    if (take_shot) {
        VK_CHECK(vkWaitForFences(w->gpu.ctx.device, 1, &w->gpu.fence, VK_TRUE, UINT64_MAX));
        return write_screenshot(opt->screenshot, w->shot.mapped,
                                w->sc.format == VK_FORMAT_B8G8R8A8_SRGB || w->sc.format == VK_FORMAT_B8G8R8A8_UNORM,
                                w->sc.extent.width, w->sc.extent.height);
    }
    fprintf(stderr, "schnee-view: error: the swapchain cannot be copied (no TRANSFER_SRC usage); no screenshot\n");
fail:
    return false;
}

enum { FRAME_ERROR, FRAME_NEXT, FRAME_LAST };

/* One turn of the loop: input, title, the previous frame's GPU time, acquire, record, present. */
static int draw_frame(sv_window *w, const sv_options *opt, sv_scene *scene, sv_probes *probes)
{
    sv_context *ctx = &w->gpu.ctx;
    glfwPollEvents();
    double now = sv_now_ms();
    float dt = (float)((now - w->last) * 1e-3);
    w->last = now;
    w->ms_avg = w->ms_avg == 0.0 ? dt * 1e3 : 0.9 * w->ms_avg + 0.1 * dt * 1e3;
    sv_input_update(&w->input, dt, &w->view, scene, probes);
    update_title(w, scene, now);
    VK_CHECK(vkWaitForFences(ctx->device, 1, &w->gpu.fence, VK_TRUE, UINT64_MAX));
    double stage[4]; /* the previous frame is done: its GPU time, smoothed like the frame time */
    if (w->frame > 0 && sv_renderer_gpu_times(&w->gpu.renderer, stage)) {
        double g = stage[0] + stage[1] + stage[2];
        w->gpu_avg = w->gpu_avg > 0.0 ? 0.9 * w->gpu_avg + 0.1 * g : g;
    }
    uint32_t image = 0;
    VkResult acq = vkAcquireNextImageKHR(ctx->device, w->sc.handle, UINT64_MAX, w->acquired, VK_NULL_HANDLE, &image);
    if (acq == VK_ERROR_OUT_OF_DATE_KHR) {
        if (!recreate_swapchain(w)) glfwWaitEvents(); /* minimised: wait for a usable size */
        return FRAME_NEXT;
    }
    if (acq != VK_SUBOPTIMAL_KHR) VK_CHECK(acq);
    VK_CHECK(vkResetFences(ctx->device, 1, &w->gpu.fence));
    bool last_frame = opt->frames && w->frame + 1 >= opt->frames;
    bool take_shot = last_frame && opt->screenshot && w->sc.can_copy;
    if (take_shot && !w->shot.buffer &&
        !sv_buffer_create(ctx, (VkDeviceSize)w->sc.extent.width * w->sc.extent.height * 4,
                          VK_BUFFER_USAGE_TRANSFER_DST_BIT, true, &w->shot))
        return FRAME_ERROR;
    if (!record_frame(w, scene, image, take_shot) || !submit_and_present(w, image)) return FRAME_ERROR;
    w->frame++;
    if (last_frame && opt->screenshot && !finish_screenshot(w, opt, take_shot)) return FRAME_ERROR;
    return last_frame ? FRAME_LAST : FRAME_NEXT;
fail:
    return FRAME_ERROR;
}

int sv_run_window(const sv_options *opt, sv_scene *scene, sv_probes *probes, const sv_sky *sky)
{
    int rc = 1;
    sv_window w = {.space = VK_COLOR_SPACE_SRGB_NONLINEAR_KHR};
    sv_context *ctx = &w.gpu.ctx;
    if (!glfwInit()) {
        fprintf(stderr, "schnee-view: error: cannot open a window (no display?); use --headless --output PATH\n");
        return 1;
    }
    if (open_window(&w, opt, scene, probes, sky)) {
        w.view = w.gpu.view;
        sv_input_init(&w.input, w.win, &w.view, scene);
        w.last = w.title_time = sv_now_ms();
        int step = FRAME_NEXT;
        while (step == FRAME_NEXT && !glfwWindowShouldClose(w.win)) step = draw_frame(&w, opt, scene, probes);
        if (step != FRAME_ERROR) {
            fprintf(stderr, "schnee-view: %u frame(s) presented, last mean frame time %.2f ms\n", w.frame, w.ms_avg);
            rc = 0;
        }
    }
    if (ctx->device) {
        vkDeviceWaitIdle(ctx->device);
        if (w.acquired) vkDestroySemaphore(ctx->device, w.acquired, NULL);
        sv_buffer_destroy(ctx, &w.shot);
        destroy_swapchain(ctx, &w.sc);
    }
    rc = sv_app_gpu_destroy(&w.gpu, rc);
    if (w.win) glfwDestroyWindow(w.win);
    glfwTerminate();
    return rc;
}
