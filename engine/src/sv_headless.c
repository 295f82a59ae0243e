/* Headless front end: render offscreen, copy to a host-visible buffer, write with OpenImageIO. */
#define _DEFAULT_SOURCE /* clock_gettime, mkstemps, strcasecmp under -std=c11 */
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "schnee/pb_image.h"
#include "sv_app.h"
#include "sv_clock.h"

/* .exr and .pfm hold the linear HDR values (float readback); other formats the tone-mapped sRGB bytes. */
static bool float_output(const char *path)
{
    size_t n = strlen(path);
    return n >= 4 && (strcasecmp(path + n - 4, ".exr") == 0 || strcasecmp(path + n - 4, ".pfm") == 0);
}

/* Records a copy of `image` (in `layout`) into `buffer`, then returns the image to `layout`. */
static void record_readback(VkCommandBuffer cmd, VkImage image, VkImageLayout layout, uint32_t w, uint32_t h,
                            VkBuffer buffer)
{
    if (layout != VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL)
        sv_image_barrier(cmd, image, VK_IMAGE_ASPECT_COLOR_BIT, layout, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                         VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_READ_BIT);
    VkBufferImageCopy region = {.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1}, .imageExtent = {w, h, 1}};
    vkCmdCopyImageToBuffer(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, buffer, 1, &region);
    VkBufferMemoryBarrier b = {
        .sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER,
        .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
        .dstAccessMask = VK_ACCESS_HOST_READ_BIT,
        .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
        .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
        .buffer = buffer,
        .size = VK_WHOLE_SIZE,
    };
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 0, NULL, 1, &b, 0, NULL);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static bool submit_and_wait(sv_context *ctx, VkCommandBuffer cmd, VkFence fence)
{
    VkSubmitInfo submit = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1, .pCommandBuffers = &cmd};
    VK_CHECK(vkResetFences(ctx->device, 1, &fence));
    VK_CHECK(vkQueueSubmit(ctx->queue, 1, &submit, fence));
    VK_CHECK(vkWaitForFences(ctx->device, 1, &fence, VK_TRUE, UINT64_MAX));
    return true;
fail:
    return false;
}

/* The median of v[0..n) (sorted in place). */
static double median(double *v, uint32_t n)
{
    qsort(v, n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The frames' wall times (mean, median when frame_ms, min) and, when gpu_ms (stage-major), the GPU's
 * median time per stage (timestamps). */
static void report_times(uint32_t frames, uint32_t w, uint32_t h, double *frame_ms, double frame_total,
                         double frame_min, double *gpu_ms)
{
    double med = frame_ms ? median(frame_ms, frames) : 0.0;
    fprintf(stderr,
            "schnee-view: %u frame(s) at %ux%u: mean %.2f ms, median %.2f ms, min %.2f ms (submit to fence, incl. "
            "readback on the last)\n",
            frames, w, h, frame_total / frames, med, frame_min);
    if (!gpu_ms) return;
    double stage[4];
    for (int k = 0; k < 4; ++k) stage[k] = median(gpu_ms + (size_t)k * frames, frames);
    fprintf(stderr,
            "schnee-view: GPU time per frame (timestamps, median): shadows %.3f ms, scene %.3f ms, tone map "
            "%.3f ms, total %.3f ms; of the scene, after the objects' raster (the probe pass) %.3f ms\n",
            stage[0], stage[1], stage[2], stage[0] + stage[1] + stage[2], stage[3]);
}

/* Writes the read-back RGBA (float linear, or 8-bit sRGB-encoded bytes) as RGB to `path`. */
static bool write_output(const char *path, const void *mapped, bool linear, uint32_t w, uint32_t h)
{
    /* Drop alpha: PNG/EXR outputs are RGB. 8-bit readback holds sRGB-encoded bytes already. */
    float *pixels = malloc((size_t)w * h * 3 * sizeof(float));
    if (!pixels) return false;
    for (size_t i = 0; i < (size_t)w * h; ++i)
        for (int c = 0; c < 3; ++c)
            pixels[i * 3 + c] =
                linear ? ((const float *)mapped)[i * 4 + c] : ((const uint8_t *)mapped)[i * 4 + c] / 255.0f;
    pb_error err = {0};
    bool ok = pb_image_write(path, w, h, 3, pixels, &err) == PB_SUCCESS;
    if (ok)
        fprintf(stderr, "schnee-view: wrote %s\n", path);
    else
        fprintf(stderr, "schnee-view: error: cannot write %s: %s\n", path, err.message);
    free(pixels);
    return ok;
}

int sv_run_headless(const sv_options *opt, sv_scene *scene, sv_probes *probes, const sv_sky *sky)
{
    sv_app_gpu gpu;
    sv_context *ctx = &gpu.ctx;
    sv_image out = {0};
    sv_buffer readback = {0};
    double *frame_ms = NULL, *gpu_ms = NULL; /* per frame: wall time; the GPU's per stage, stage-major */
    int rc = 1;
    const uint32_t w = opt->width, h = opt->height;
    const bool linear = float_output(opt->output);

    if (!sv_app_gpu_init(&gpu, opt, NULL, 0, NULL, NULL, false) ||
        !sv_app_gpu_renderer(&gpu, opt, scene, probes, sky, VK_FORMAT_R8G8B8A8_SRGB, w, h))
        goto done;
    /* Without the file's probes on the GPU an object on a dense grid reads its slot (docs/engine.md "Probe
     * buffers"); the index views name the object's probe and read none. */
    if (!gpu.renderer.file_probes && opt->debug_mode != SV_DEBUG_PROBE_INDEX && opt->debug_mode != SV_DEBUG_PROBE_COLOR)
        sv_probes_use_slots(probes, scene);
    if (!sv_image_create(ctx, w, h, VK_FORMAT_R8G8B8A8_SRGB,
                         VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                         VK_IMAGE_ASPECT_COLOR_BIT, &out) ||
        !sv_buffer_create(ctx, (VkDeviceSize)w * h * (linear ? 16 : 4), VK_BUFFER_USAGE_TRANSFER_DST_BIT, true,
                          &readback))
        goto done;
    fprintf(stderr,
            "schnee-view: device %s; Vulkan setup %.1f ms, scene upload %.1f ms; shader loops %s; per-pixel probes in "
            "the %s\n",
            ctx->properties.deviceName, gpu.setup_ms, gpu.upload_ms,
            gpu.renderer.unrolled_groups ? "unrolled" : "plain",
            gpu.renderer.probe_pass ? "probe pass (compute)" : "scene pass (fragment)");

    VkCommandBuffer cmd = gpu.cmd;
    uint32_t frames = opt->frames ? opt->frames : 1;
    double frame_total = 0.0, frame_min = 1e30;
    frame_ms = calloc(frames, sizeof *frame_ms); /* for the medians (benchmarks); NULL: none */
    gpu_ms = calloc((size_t)frames * 4, sizeof *gpu_ms);
    bool gpu_times = gpu_ms != NULL;
    for (uint32_t f = 0; f < frames; ++f) {
        bool last = f + 1 == frames;
        double fs = sv_now_ms();
        VkCommandBufferBeginInfo begin = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                          .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
        VK_CHECK(vkResetCommandBuffer(cmd, 0));
        VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
        sv_renderer_record(&gpu.renderer, cmd, scene, &gpu.view, out.image, out.view,
                           VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL);
        if (last) {
            if (linear)
                record_readback(cmd, gpu.renderer.hdr.image, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, w, h,
                                readback.buffer);
            else
                record_readback(cmd, out.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, w, h, readback.buffer);
        }
        VK_CHECK(vkEndCommandBuffer(cmd));
        if (!submit_and_wait(ctx, cmd, gpu.fence)) goto done;
        double ms = sv_now_ms() - fs;
        frame_total += ms;
        if (ms < frame_min) frame_min = ms;
        if (frame_ms) frame_ms[f] = ms;
        double stage[4];
        gpu_times = gpu_times && sv_renderer_gpu_times(&gpu.renderer, stage);
        for (int k = 0; gpu_times && k < 4; ++k) gpu_ms[(size_t)k * frames + f] = stage[k];
    }
    report_times(frames, w, h, frame_ms, frame_total, frame_min, gpu_times ? gpu_ms : NULL);
    if (!write_output(opt->output, readback.mapped, linear, w, h)) goto done;
    rc = 0;
done:
fail:
    free(frame_ms);
    free(gpu_ms);
    if (ctx->device) {
        vkDeviceWaitIdle(ctx->device);
        sv_buffer_destroy(ctx, &readback);
        sv_image_destroy(ctx, &out);
    }
    return sv_app_gpu_destroy(&gpu, rc);
}
