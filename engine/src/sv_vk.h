/* Vulkan context of schnee-view: instance (+ validation messenger), device, queue, command pool,
 * and the small buffer/image helpers every other module uses.
 *
 * Setup is one plain function per step, called in this order (the window path creates its surface
 * between the instance and the device so the device pick can require presentation):
 *   sv_create_instance -> [glfwCreateWindowSurface] -> sv_pick_device -> sv_create_device
 *   -> sv_create_command_pool ... sv_context_destroy
 * VK_CHECK reports file, line and the VkResult name, then jumps to the function's `fail` label.
 */
#ifndef SV_VK_H
#define SV_VK_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <vulkan/vulkan.h>

const char *sv_vk_result_name(VkResult r);

#define VK_CHECK(call)                                                                                                 \
    do {                                                                                                               \
        VkResult vk_check_result_ = (call);                                                                            \
        if (vk_check_result_ != VK_SUCCESS) {                                                                          \
            fprintf(stderr, "schnee-view: error: %s:%d: %s failed: %s\n", __FILE__, __LINE__, #call,                   \
                    sv_vk_result_name(vk_check_result_));                                                              \
            goto fail;                                                                                                 \
        }                                                                                                              \
    } while (0)

typedef struct sv_context {
    VkInstance instance;
    VkDebugUtilsMessengerEXT messenger;
    VkSurfaceKHR surface; /* VK_NULL_HANDLE on the headless path */
    VkPhysicalDevice physical;
    VkPhysicalDeviceProperties properties;
    VkPhysicalDeviceMemoryProperties memory;
    VkDevice device;
    uint32_t queue_family;
    VkQueue queue;
    VkCommandPool command_pool;
    bool validation;            /* VK_LAYER_KHRONOS_validation enabled */
    bool probe_pass_features;   /* independentBlend and maintenance4 enabled (the probe pass, sv_probe_pass.h) */
    uint32_t validation_errors; /* counted by the debug messenger */
    uint32_t validation_warnings;
} sv_context;

/* Instance with `extension_count` extra extensions (e.g. GLFW's surface ones). With validation,
 * enables VK_LAYER_KHRONOS_validation + a messenger that prints and counts messages; fails with a
 * clear message when the layer is missing. */
bool sv_create_instance(sv_context *ctx, bool validation, const char *const *extensions, uint32_t extension_count);
/* Picks a Vulkan 1.3 device with a graphics queue (and presentation to ctx->surface if set);
 * discrete > integrated > virtual > CPU. */
bool sv_pick_device(sv_context *ctx);
bool sv_create_device(sv_context *ctx);
bool sv_create_command_pool(sv_context *ctx);
/* Destroys everything the context holds (the surface too), in reverse order. */
void sv_context_destroy(sv_context *ctx);

/* --- resources ------------------------------------------------------------------------------- */

typedef struct sv_buffer {
    VkBuffer buffer;
    VkDeviceMemory memory;
    VkDeviceSize size;
    void *mapped; /* host-visible buffers stay mapped */
} sv_buffer;

typedef struct sv_image {
    VkImage image;
    VkDeviceMemory memory;
    VkImageView view;
    VkFormat format;
    uint32_t width, height;
    uint32_t mip_levels;
} sv_image;

/* Host-visible coherent buffer (mapped) when host_visible, else device-local. size 0 is bumped
 * to 16 bytes so empty scene arrays still bind. */
bool sv_buffer_create(sv_context *ctx, VkDeviceSize size, VkBufferUsageFlags usage, bool host_visible, sv_buffer *out);
/* Device-local buffer filled from `data` through a staging copy (blocking). */
bool sv_buffer_create_with_data(sv_context *ctx, const void *data, VkDeviceSize size, VkBufferUsageFlags usage,
                                sv_buffer *out);
void sv_buffer_destroy(sv_context *ctx, sv_buffer *b);

bool sv_image_create(sv_context *ctx, uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage,
                     VkImageAspectFlags aspect, sv_image *out);
/* Same with `mip_levels` levels (the view covers all of them). */
bool sv_image_create_mips(sv_context *ctx, uint32_t width, uint32_t height, uint32_t mip_levels, VkFormat format,
                          VkImageUsageFlags usage, VkImageAspectFlags aspect, sv_image *out);
/* Same with `layers` array layers and a 2D-array view over all of them; layers 0 = one layer and a
 * plain 2D view (sv_image_create_mips). */
bool sv_image_create_layers(sv_context *ctx, uint32_t width, uint32_t height, uint32_t mip_levels, uint32_t layers,
                            VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect, sv_image *out);
/* A 3D colour image of width x height x depth texels, one level, with a 3D view. */
bool sv_image_create_3d(sv_context *ctx, uint32_t width, uint32_t height, uint32_t depth, VkFormat format,
                        VkImageUsageFlags usage, sv_image *out);
void sv_image_destroy(sv_context *ctx, sv_image *img);

/* One-shot command buffer: begin, (record), end + submit + wait. */
VkCommandBuffer sv_begin_one_shot(sv_context *ctx);
bool sv_end_one_shot(sv_context *ctx, VkCommandBuffer cmd);

/* A dynamic-rendering attachment of `view` in `layout` (clear value zero: black, alpha 0, or depth 0). */
VkRenderingAttachmentInfo sv_attachment(VkImageView view, VkImageLayout layout, VkAttachmentLoadOp load,
                                        VkAttachmentStoreOp store);
/* Layout transition (every mip level and array layer) with a full-pipeline barrier scoped to the
 * given stages and accesses. */
void sv_image_barrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect, VkImageLayout from,
                      VkImageLayout to, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                      VkPipelineStageFlags dst_stage, VkAccessFlags dst_access);

/* The create-info every sampler of the renderer starts from: `filter` for magnification and
 * minification, `address` on all three axes, one mip level, no comparison; callers set what differs. */
VkSamplerCreateInfo sv_sampler_info(VkFilter filter, VkSamplerAddressMode address);
VkShaderModule sv_shader_module(sv_context *ctx, const uint32_t *code, size_t size_bytes);

#endif
