/* Vulkan context and resource helpers (see sv_vk.h). */
#include "sv_vk.h"

#include <stdlib.h>
#include <string.h>

const char *sv_vk_result_name(VkResult r)
{
    switch (r) {
#define SV_CASE(x)                                                                                                     \
    case x: return #x
        SV_CASE(VK_SUCCESS);
        SV_CASE(VK_NOT_READY);
        SV_CASE(VK_TIMEOUT);
        SV_CASE(VK_EVENT_SET);
        SV_CASE(VK_EVENT_RESET);
        SV_CASE(VK_INCOMPLETE);
        SV_CASE(VK_ERROR_OUT_OF_HOST_MEMORY);
        SV_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY);
        SV_CASE(VK_ERROR_INITIALIZATION_FAILED);
        SV_CASE(VK_ERROR_DEVICE_LOST);
        SV_CASE(VK_ERROR_MEMORY_MAP_FAILED);
        SV_CASE(VK_ERROR_LAYER_NOT_PRESENT);
        SV_CASE(VK_ERROR_EXTENSION_NOT_PRESENT);
        SV_CASE(VK_ERROR_FEATURE_NOT_PRESENT);
        SV_CASE(VK_ERROR_INCOMPATIBLE_DRIVER);
        SV_CASE(VK_ERROR_TOO_MANY_OBJECTS);
        SV_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED);
        SV_CASE(VK_ERROR_FRAGMENTED_POOL);
        SV_CASE(VK_ERROR_UNKNOWN);
        SV_CASE(VK_ERROR_OUT_OF_POOL_MEMORY);
        SV_CASE(VK_ERROR_SURFACE_LOST_KHR);
        SV_CASE(VK_ERROR_NATIVE_WINDOW_IN_USE_KHR);
        SV_CASE(VK_SUBOPTIMAL_KHR);
        SV_CASE(VK_ERROR_OUT_OF_DATE_KHR);
        SV_CASE(VK_ERROR_VALIDATION_FAILED_EXT);
#undef SV_CASE
    default: return "VkResult(unknown)";
    }
}

static VKAPI_ATTR VkBool32 VKAPI_CALL debug_callback(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                     VkDebugUtilsMessageTypeFlagsEXT type,
                                                     const VkDebugUtilsMessengerCallbackDataEXT *data, void *user)
{
    sv_context *ctx = user;
    if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) {
        ctx->validation_errors++;
        fprintf(stderr, "schnee-view: validation error: %s\n", data->pMessage);
    } else if (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
        ctx->validation_warnings++;
        fprintf(stderr, "schnee-view: validation warning: %s\n", data->pMessage);
    }
    return VK_FALSE;
}

static bool layer_available(const char *name)
{
    uint32_t n = 0;
    if (vkEnumerateInstanceLayerProperties(&n, NULL) != VK_SUCCESS) return false;
    VkLayerProperties *props = calloc(n ? n : 1, sizeof(*props));
    if (!props) return false;
    bool found = false;
    if (vkEnumerateInstanceLayerProperties(&n, props) == VK_SUCCESS)
        for (uint32_t i = 0; i < n; ++i)
            if (strcmp(props[i].layerName, name) == 0) found = true;
    free(props);
    return found;
}

bool sv_create_instance(sv_context *ctx, bool validation, const char *const *extensions, uint32_t extension_count)
{
    const char *layer = "VK_LAYER_KHRONOS_validation";
    const char *exts[16];
    uint32_t n = 0;
    if (extension_count > 14) {
        fprintf(stderr, "schnee-view: error: too many instance extensions (%u)\n", extension_count);
        return false;
    }
    for (uint32_t i = 0; i < extension_count; ++i) exts[n++] = extensions[i];
    if (validation) {
        if (!layer_available(layer)) {
            fprintf(stderr,
                    "schnee-view: error: --validation needs %s, which is not installed "
                    "(Debian: vulkan-validationlayers)\n",
                    layer);
            return false;
        }
        exts[n++] = VK_EXT_DEBUG_UTILS_EXTENSION_NAME;
    }
    VkApplicationInfo app = {
        .sType = VK_STRUCTURE_TYPE_APPLICATION_INFO,
        .pApplicationName = "schnee-view",
        .applicationVersion = VK_MAKE_VERSION(0, 1, 0),
        .pEngineName = "schnee",
        .apiVersion = VK_API_VERSION_1_3,
    };
    VkDebugUtilsMessengerCreateInfoEXT messenger_info = {
        .sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
        .messageSeverity =
            VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT,
        .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT | VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                       VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT,
        .pfnUserCallback = debug_callback,
        .pUserData = ctx,
    };
    VkInstanceCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
        .pNext = validation ? &messenger_info : NULL, /* also covers vkCreate/DestroyInstance */
        .pApplicationInfo = &app,
        .enabledLayerCount = validation ? 1u : 0u,
        .ppEnabledLayerNames = &layer,
        .enabledExtensionCount = n,
        .ppEnabledExtensionNames = exts,
    };
    ctx->validation = validation;
    VK_CHECK(vkCreateInstance(&info, NULL, &ctx->instance));
    if (validation) {
        PFN_vkCreateDebugUtilsMessengerEXT create =
            (PFN_vkCreateDebugUtilsMessengerEXT)vkGetInstanceProcAddr(ctx->instance, "vkCreateDebugUtilsMessengerEXT");
        if (!create) {
            fprintf(stderr, "schnee-view: error: vkCreateDebugUtilsMessengerEXT not available\n");
            return false;
        }
        VK_CHECK(create(ctx->instance, &messenger_info, NULL, &ctx->messenger));
    }
    return true;
fail:
    return false;
}

static int device_rank(VkPhysicalDeviceType type)
{
    switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return 4;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return 3;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return 1;
    default: return 0;
    }
}

bool sv_pick_device(sv_context *ctx)
{
    uint32_t n = 0;
    VkPhysicalDevice *devices = NULL;
    VK_CHECK(vkEnumeratePhysicalDevices(ctx->instance, &n, NULL));
    if (n == 0) {
        fprintf(stderr, "schnee-view: error: no Vulkan device (install mesa-vulkan-drivers for lavapipe)\n");
        return false;
    }
    devices = calloc(n, sizeof(*devices));
    if (!devices) return false;
    VK_CHECK(vkEnumeratePhysicalDevices(ctx->instance, &n, devices));
    int best_rank = -1;
    for (uint32_t i = 0; i < n; ++i) {
        VkPhysicalDeviceProperties props;
        vkGetPhysicalDeviceProperties(devices[i], &props);
        if (props.apiVersion < VK_API_VERSION_1_3) continue;
        uint32_t qn = 0;
        vkGetPhysicalDeviceQueueFamilyProperties(devices[i], &qn, NULL);
        VkQueueFamilyProperties *qp = calloc(qn ? qn : 1, sizeof(*qp));
        if (!qp) break;
        vkGetPhysicalDeviceQueueFamilyProperties(devices[i], &qn, qp);
        for (uint32_t q = 0; q < qn; ++q) {
            if (!(qp[q].queueFlags & VK_QUEUE_GRAPHICS_BIT)) continue;
            if (ctx->surface) {
                VkBool32 present = VK_FALSE;
                if (vkGetPhysicalDeviceSurfaceSupportKHR(devices[i], q, ctx->surface, &present) != VK_SUCCESS ||
                    !present)
                    continue;
            }
            int rank = device_rank(props.deviceType);
            if (rank > best_rank) {
                best_rank = rank;
                ctx->physical = devices[i];
                ctx->queue_family = q;
                ctx->properties = props;
            }
            break;
        }
        free(qp);
    }
    free(devices);
    if (best_rank < 0) {
        fprintf(stderr, "schnee-view: error: no Vulkan 1.3 device with a graphics queue%s\n",
                ctx->surface ? " that can present to the window" : "");
        return false;
    }
    vkGetPhysicalDeviceMemoryProperties(ctx->physical, &ctx->memory);
    return true;
fail:
    free(devices);
    return false;
}

bool sv_create_device(sv_context *ctx)
{
    float priority = 1.0f;
    VkDeviceQueueCreateInfo queue = {
        .sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
        .queueFamilyIndex = ctx->queue_family,
        .queueCount = 1,
        .pQueuePriorities = &priority,
    };
    /* Optional features, enabled where the device has them: independent blend and maintenance4 (the
     * compute shader's LocalSizeId, SPIR-V 1.6) for the probe pass (sv_probe_pass.h). */
    VkPhysicalDeviceVulkan13Features has13 = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES};
    VkPhysicalDeviceFeatures2 has = {.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2, .pNext = &has13};
    vkGetPhysicalDeviceFeatures2(ctx->physical, &has);
    ctx->probe_pass_features = has.features.independentBlend && has13.maintenance4;
    VkPhysicalDeviceVulkan13Features v13 = {
        .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES,
        .dynamicRendering = VK_TRUE,
        .maintenance4 = ctx->probe_pass_features,
    };
    VkPhysicalDeviceFeatures2 features = {
        .sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2,
        .pNext = &v13,
        .features.independentBlend = ctx->probe_pass_features,
    };
    const char *swapchain_ext = VK_KHR_SWAPCHAIN_EXTENSION_NAME;
    VkDeviceCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO,
        .pNext = &features,
        .queueCreateInfoCount = 1,
        .pQueueCreateInfos = &queue,
        .enabledExtensionCount = ctx->surface ? 1u : 0u,
        .ppEnabledExtensionNames = &swapchain_ext,
    };
    VK_CHECK(vkCreateDevice(ctx->physical, &info, NULL, &ctx->device));
    vkGetDeviceQueue(ctx->device, ctx->queue_family, 0, &ctx->queue);
    return true;
fail:
    return false;
}

bool sv_create_command_pool(sv_context *ctx)
{
    VkCommandPoolCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO,
        .flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT,
        .queueFamilyIndex = ctx->queue_family,
    };
    VK_CHECK(vkCreateCommandPool(ctx->device, &info, NULL, &ctx->command_pool));
    return true;
fail:
    return false;
}

void sv_context_destroy(sv_context *ctx)
{
    if (ctx->device) {
        vkDeviceWaitIdle(ctx->device);
        if (ctx->command_pool) vkDestroyCommandPool(ctx->device, ctx->command_pool, NULL);
        vkDestroyDevice(ctx->device, NULL);
    }
    if (ctx->surface) vkDestroySurfaceKHR(ctx->instance, ctx->surface, NULL);
    if (ctx->messenger) {
        PFN_vkDestroyDebugUtilsMessengerEXT destroy = (PFN_vkDestroyDebugUtilsMessengerEXT)vkGetInstanceProcAddr(
            ctx->instance, "vkDestroyDebugUtilsMessengerEXT");
        if (destroy) destroy(ctx->instance, ctx->messenger, NULL);
    }
    if (ctx->instance) vkDestroyInstance(ctx->instance, NULL);
    ctx->device = VK_NULL_HANDLE;
    ctx->instance = VK_NULL_HANDLE;
}

static bool find_memory_type(sv_context *ctx, uint32_t type_bits, VkMemoryPropertyFlags want, uint32_t *out)
{
    for (uint32_t i = 0; i < ctx->memory.memoryTypeCount; ++i)
        if ((type_bits & (1u << i)) && (ctx->memory.memoryTypes[i].propertyFlags & want) == want) {
            *out = i;
            return true;
        }
    fprintf(stderr, "schnee-view: error: no Vulkan memory type with properties 0x%x\n", (unsigned)want);
    return false;
}

bool sv_buffer_create(sv_context *ctx, VkDeviceSize size, VkBufferUsageFlags usage, bool host_visible, sv_buffer *out)
{
    memset(out, 0, sizeof(*out));
    if (size == 0) size = 16;
    VkBufferCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
        .size = size,
        .usage = usage,
        .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
    };
    VK_CHECK(vkCreateBuffer(ctx->device, &info, NULL, &out->buffer));
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(ctx->device, out->buffer, &req);
    VkMemoryPropertyFlags want = host_visible
                                     ? VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT
                                     : VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
    VkMemoryAllocateInfo alloc = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO, .allocationSize = req.size};
    if (!find_memory_type(ctx, req.memoryTypeBits, want, &alloc.memoryTypeIndex)) goto fail;
    VK_CHECK(vkAllocateMemory(ctx->device, &alloc, NULL, &out->memory));
    VK_CHECK(vkBindBufferMemory(ctx->device, out->buffer, out->memory, 0));
    if (host_visible) VK_CHECK(vkMapMemory(ctx->device, out->memory, 0, VK_WHOLE_SIZE, 0, &out->mapped));
    out->size = size;
    return true;
fail:
    sv_buffer_destroy(ctx, out);
    return false;
}

bool sv_buffer_create_with_data(sv_context *ctx, const void *data, VkDeviceSize size, VkBufferUsageFlags usage,
                                sv_buffer *out)
{
    sv_buffer staging;
    memset(out, 0, sizeof(*out));
    if (!sv_buffer_create(ctx, size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true, &staging)) return false;
    if (size) memcpy(staging.mapped, data, (size_t)size);
    bool ok = sv_buffer_create(ctx, size, usage | VK_BUFFER_USAGE_TRANSFER_DST_BIT, false, out);
    if (ok) {
        VkCommandBuffer cmd = sv_begin_one_shot(ctx);
        ok = cmd != VK_NULL_HANDLE;
        if (ok) {
            VkBufferCopy region = {.size = staging.size};
            vkCmdCopyBuffer(cmd, staging.buffer, out->buffer, 1, &region);
            ok = sv_end_one_shot(ctx, cmd);
        }
    }
    sv_buffer_destroy(ctx, &staging);
    if (!ok) sv_buffer_destroy(ctx, out);
    return ok;
}

void sv_buffer_destroy(sv_context *ctx, sv_buffer *b)
{
    if (b->buffer) vkDestroyBuffer(ctx->device, b->buffer, NULL);
    if (b->memory) vkFreeMemory(ctx->device, b->memory, NULL);
    memset(b, 0, sizeof(*b));
}

bool sv_image_create(sv_context *ctx, uint32_t width, uint32_t height, VkFormat format, VkImageUsageFlags usage,
                     VkImageAspectFlags aspect, sv_image *out)
{
    return sv_image_create_mips(ctx, width, height, 1, format, usage, aspect, out);
}

bool sv_image_create_mips(sv_context *ctx, uint32_t width, uint32_t height, uint32_t mip_levels, VkFormat format,
                          VkImageUsageFlags usage, VkImageAspectFlags aspect, sv_image *out)
{
    return sv_image_create_layers(ctx, width, height, mip_levels, 0, format, usage, aspect, out);
}

/* A 2D image (depth 0) with its 2D or 2D-array view, or a 3D image (depth > 0, one level and layer). */
static bool image_create(sv_context *ctx, uint32_t width, uint32_t height, uint32_t depth, uint32_t mip_levels,
                         uint32_t layers, VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect,
                         sv_image *out)
{
    memset(out, 0, sizeof(*out));
    VkImageCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO,
        .imageType = depth ? VK_IMAGE_TYPE_3D : VK_IMAGE_TYPE_2D,
        .format = format,
        .extent = {width, height, depth ? depth : 1},
        .mipLevels = mip_levels,
        .arrayLayers = layers ? layers : 1,
        .samples = VK_SAMPLE_COUNT_1_BIT,
        .tiling = VK_IMAGE_TILING_OPTIMAL,
        .usage = usage,
        .sharingMode = VK_SHARING_MODE_EXCLUSIVE,
        .initialLayout = VK_IMAGE_LAYOUT_UNDEFINED,
    };
    VK_CHECK(vkCreateImage(ctx->device, &info, NULL, &out->image));
    VkMemoryRequirements req;
    vkGetImageMemoryRequirements(ctx->device, out->image, &req);
    VkMemoryAllocateInfo alloc = {.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO, .allocationSize = req.size};
    if (!find_memory_type(ctx, req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, &alloc.memoryTypeIndex))
        goto fail;
    VK_CHECK(vkAllocateMemory(ctx->device, &alloc, NULL, &out->memory));
    VK_CHECK(vkBindImageMemory(ctx->device, out->image, out->memory, 0));
    VkImageViewCreateInfo view = {
        .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
        .image = out->image,
        .viewType = depth    ? VK_IMAGE_VIEW_TYPE_3D
                    : layers ? VK_IMAGE_VIEW_TYPE_2D_ARRAY
                             : VK_IMAGE_VIEW_TYPE_2D,
        .format = format,
        .subresourceRange = {aspect, 0, mip_levels, 0, layers ? layers : 1},
    };
    VK_CHECK(vkCreateImageView(ctx->device, &view, NULL, &out->view));
    out->mip_levels = mip_levels;
    out->format = format;
    out->width = width;
    out->height = height;
    return true;
fail:
    sv_image_destroy(ctx, out);
    return false;
}

bool sv_image_create_layers(sv_context *ctx, uint32_t width, uint32_t height, uint32_t mip_levels, uint32_t layers,
                            VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect, sv_image *out)
{
    return image_create(ctx, width, height, 0, mip_levels, layers, format, usage, aspect, out);
}

bool sv_image_create_3d(sv_context *ctx, uint32_t width, uint32_t height, uint32_t depth, VkFormat format,
                        VkImageUsageFlags usage, sv_image *out)
{
    return image_create(ctx, width, height, depth ? depth : 1, 1, 0, format, usage, VK_IMAGE_ASPECT_COLOR_BIT, out);
}

void sv_image_destroy(sv_context *ctx, sv_image *img)
{
    if (img->view) vkDestroyImageView(ctx->device, img->view, NULL);
    if (img->image) vkDestroyImage(ctx->device, img->image, NULL);
    if (img->memory) vkFreeMemory(ctx->device, img->memory, NULL);
    memset(img, 0, sizeof(*img));
}

VkCommandBuffer sv_begin_one_shot(sv_context *ctx)
{
    VkCommandBuffer cmd = VK_NULL_HANDLE;
    VkCommandBufferAllocateInfo alloc = {
        .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
        .commandPool = ctx->command_pool,
        .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
        .commandBufferCount = 1,
    };
    VK_CHECK(vkAllocateCommandBuffers(ctx->device, &alloc, &cmd));
    VkCommandBufferBeginInfo begin = {
        .sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
        .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT,
    };
    VK_CHECK(vkBeginCommandBuffer(cmd, &begin));
    return cmd;
fail:
    if (cmd) vkFreeCommandBuffers(ctx->device, ctx->command_pool, 1, &cmd);
    return VK_NULL_HANDLE;
}

bool sv_end_one_shot(sv_context *ctx, VkCommandBuffer cmd)
{
    bool ok = false;
    VK_CHECK(vkEndCommandBuffer(cmd));
    VkSubmitInfo submit = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1, .pCommandBuffers = &cmd};
    VK_CHECK(vkQueueSubmit(ctx->queue, 1, &submit, VK_NULL_HANDLE));
    VK_CHECK(vkQueueWaitIdle(ctx->queue));
    ok = true;
fail:
    vkFreeCommandBuffers(ctx->device, ctx->command_pool, 1, &cmd);
    return ok;
}

VkRenderingAttachmentInfo sv_attachment(VkImageView view, VkImageLayout layout, VkAttachmentLoadOp load,
                                        VkAttachmentStoreOp store)
{
    return (VkRenderingAttachmentInfo){
        .sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO,
        .imageView = view,
        .imageLayout = layout,
        .loadOp = load,
        .storeOp = store,
    };
}

void sv_image_barrier(VkCommandBuffer cmd, VkImage image, VkImageAspectFlags aspect, VkImageLayout from,
                      VkImageLayout to, VkPipelineStageFlags src_stage, VkAccessFlags src_access,
                      VkPipelineStageFlags dst_stage, VkAccessFlags dst_access)
{
    VkImageMemoryBarrier b = {
        .sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER,
        .srcAccessMask = src_access,
        .dstAccessMask = dst_access,
        .oldLayout = from,
        .newLayout = to,
        .srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
        .dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED,
        .image = image,
        .subresourceRange = {aspect, 0, VK_REMAINING_MIP_LEVELS, 0, VK_REMAINING_ARRAY_LAYERS},
    };
    vkCmdPipelineBarrier(cmd, src_stage, dst_stage, 0, 0, NULL, 0, NULL, 1, &b);
}

VkShaderModule sv_shader_module(sv_context *ctx, const uint32_t *code, size_t size_bytes)
{
    VkShaderModule m = VK_NULL_HANDLE;
    VkShaderModuleCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO,
        .codeSize = size_bytes,
        .pCode = code,
    };
    VK_CHECK(vkCreateShaderModule(ctx->device, &info, NULL, &m));
    return m;
fail:
    return VK_NULL_HANDLE;
}

VkSamplerCreateInfo sv_sampler_info(VkFilter filter, VkSamplerAddressMode address)
{
    return (VkSamplerCreateInfo){
        .sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
        .magFilter = filter,
        .minFilter = filter,
        .mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
        .addressModeU = address,
        .addressModeV = address,
        .addressModeW = address,
        .maxLod = 0.0f,
    };
}
