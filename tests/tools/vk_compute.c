/* Runs one compute shader once, for tests that check a GLSL include against the C core.
 *
 *   cc -O1 -o vk_compute tests/tools/vk_compute.c -ldl
 *   vk_compute SHADER.spv INPUT.bin OUTPUT.bin OUTPUT_BYTES GROUPS_X
 *
 * Binding 0 (set 0) is a storage buffer holding INPUT.bin, binding 1 a zeroed storage buffer of
 * OUTPUT_BYTES that is written to OUTPUT.bin after vkCmdDispatch(GROUPS_X, 1, 1). The Vulkan loader
 * is opened with dlopen (no link-time dependency); the first device with a compute queue is used
 * (lavapipe in CI, VK_ICD_FILENAMES selects another). With SCHNEE_VK_VALIDATION=1 the Khronos
 * validation layer is enabled and any message it prints makes the run fail (exit status 3).
 * Exit status 2: Vulkan unavailable; 1: any other error (printed).
 */
#define VK_NO_PROTOTYPES
#include <vulkan/vulkan.h>

#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHECK(call)                                                                                                    \
    do {                                                                                                               \
        VkResult r_ = (call);                                                                                          \
        if (r_ != VK_SUCCESS) {                                                                                        \
            fprintf(stderr, "%s:%d: %s failed: VkResult %d\n", __FILE__, __LINE__, #call, (int)r_);                    \
            exit(1);                                                                                                   \
        }                                                                                                              \
    } while (0)

static PFN_vkGetInstanceProcAddr gipa;
static int validation_messages;

#define LOAD(inst, name) PFN_##name name = (PFN_##name)gipa(inst, #name)

static void *read_file(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        exit(1);
    }
    fseek(f, 0, SEEK_END);
    *size = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    void *data = malloc(*size ? *size : 1);
    if (!data || fread(data, 1, *size, f) != *size) {
        fprintf(stderr, "cannot read %s\n", path);
        exit(1);
    }
    fclose(f);
    return data;
}

static VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                 VkDebugUtilsMessageTypeFlagsEXT type,
                                                 const VkDebugUtilsMessengerCallbackDataEXT *data, void *user)
{
    (void)type;
    (void)user;
    if (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) {
        fprintf(stderr, "validation: %s\n", data->pMessage);
        validation_messages++;
    }
    return VK_FALSE;
}

int main(int argc, char **argv)
{
    if (argc != 6) {
        fprintf(stderr, "usage: %s SHADER.spv INPUT.bin OUTPUT.bin OUTPUT_BYTES GROUPS_X\n", argv[0]);
        return 1;
    }
    size_t spv_size, in_size;
    void *spv = read_file(argv[1], &spv_size);
    void *input = read_file(argv[2], &in_size);
    const size_t out_size = (size_t)strtoull(argv[4], NULL, 10);
    const uint32_t groups = (uint32_t)strtoul(argv[5], NULL, 10);

    void *lib = dlopen("libvulkan.so.1", RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "no Vulkan loader: %s\n", dlerror());
        return 2;
    }
    gipa = (PFN_vkGetInstanceProcAddr)dlsym(lib, "vkGetInstanceProcAddr");
    LOAD(NULL, vkCreateInstance);

    const int validate = getenv("SCHNEE_VK_VALIDATION") && strcmp(getenv("SCHNEE_VK_VALIDATION"), "1") == 0;
    const char *layers[] = {"VK_LAYER_KHRONOS_validation"};
    const char *exts[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME};
    VkApplicationInfo app = {.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO, .apiVersion = VK_API_VERSION_1_1};
    VkInstanceCreateInfo ici = {.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO,
                                .pApplicationInfo = &app,
                                .enabledLayerCount = validate ? 1u : 0u,
                                .ppEnabledLayerNames = layers,
                                .enabledExtensionCount = validate ? 1u : 0u,
                                .ppEnabledExtensionNames = exts};
    VkInstance inst;
    if (vkCreateInstance(&ici, NULL, &inst) != VK_SUCCESS) {
        fprintf(stderr, "vkCreateInstance failed\n");
        return 2;
    }
    LOAD(inst, vkDestroyInstance);
    LOAD(inst, vkEnumeratePhysicalDevices);
    LOAD(inst, vkGetPhysicalDeviceQueueFamilyProperties);
    LOAD(inst, vkGetPhysicalDeviceMemoryProperties);
    LOAD(inst, vkCreateDevice);
    LOAD(inst, vkGetDeviceProcAddr);
    VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
    if (validate) {
        LOAD(inst, vkCreateDebugUtilsMessengerEXT);
        VkDebugUtilsMessengerCreateInfoEXT mci = {.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT,
                                                  .messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                                                                     VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT,
                                                  .messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                                                                 VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT,
                                                  .pfnUserCallback = on_message};
        CHECK(vkCreateDebugUtilsMessengerEXT(inst, &mci, NULL, &messenger));
    }

    uint32_t ndev = 0;
    CHECK(vkEnumeratePhysicalDevices(inst, &ndev, NULL));
    VkPhysicalDevice devs[16];
    if (ndev > 16) ndev = 16;
    CHECK(vkEnumeratePhysicalDevices(inst, &ndev, devs));
    VkPhysicalDevice phys = VK_NULL_HANDLE;
    uint32_t family = 0;
    for (uint32_t d = 0; d < ndev && phys == VK_NULL_HANDLE; d++) {
        uint32_t nq = 0;
        vkGetPhysicalDeviceQueueFamilyProperties(devs[d], &nq, NULL);
        VkQueueFamilyProperties qp[16];
        if (nq > 16) nq = 16;
        vkGetPhysicalDeviceQueueFamilyProperties(devs[d], &nq, qp);
        for (uint32_t q = 0; q < nq; q++)
            if (qp[q].queueFlags & VK_QUEUE_COMPUTE_BIT) {
                phys = devs[d];
                family = q;
                break;
            }
    }
    if (phys == VK_NULL_HANDLE) {
        fprintf(stderr, "no Vulkan device with a compute queue\n");
        return 2;
    }
    const float prio = 1.0f;
    VkDeviceQueueCreateInfo qci = {.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO,
                                   .queueFamilyIndex = family,
                                   .queueCount = 1,
                                   .pQueuePriorities = &prio};
    VkDeviceCreateInfo dci = {
        .sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO, .queueCreateInfoCount = 1, .pQueueCreateInfos = &qci};
    VkDevice dev;
    CHECK(vkCreateDevice(phys, &dci, NULL, &dev));
#define DLOAD(name) PFN_##name name = (PFN_##name)vkGetDeviceProcAddr(dev, #name)
    DLOAD(vkDestroyDevice);
    DLOAD(vkGetDeviceQueue);
    DLOAD(vkCreateBuffer);
    DLOAD(vkDestroyBuffer);
    DLOAD(vkGetBufferMemoryRequirements);
    DLOAD(vkAllocateMemory);
    DLOAD(vkFreeMemory);
    DLOAD(vkBindBufferMemory);
    DLOAD(vkMapMemory);
    DLOAD(vkUnmapMemory);
    DLOAD(vkCreateShaderModule);
    DLOAD(vkDestroyShaderModule);
    DLOAD(vkCreateDescriptorSetLayout);
    DLOAD(vkDestroyDescriptorSetLayout);
    DLOAD(vkCreatePipelineLayout);
    DLOAD(vkDestroyPipelineLayout);
    DLOAD(vkCreateComputePipelines);
    DLOAD(vkDestroyPipeline);
    DLOAD(vkCreateDescriptorPool);
    DLOAD(vkDestroyDescriptorPool);
    DLOAD(vkAllocateDescriptorSets);
    DLOAD(vkUpdateDescriptorSets);
    DLOAD(vkCreateCommandPool);
    DLOAD(vkDestroyCommandPool);
    DLOAD(vkAllocateCommandBuffers);
    DLOAD(vkBeginCommandBuffer);
    DLOAD(vkEndCommandBuffer);
    DLOAD(vkCmdBindPipeline);
    DLOAD(vkCmdBindDescriptorSets);
    DLOAD(vkCmdDispatch);
    DLOAD(vkCmdPipelineBarrier);
    DLOAD(vkCreateFence);
    DLOAD(vkDestroyFence);
    DLOAD(vkQueueSubmit);
    DLOAD(vkWaitForFences);
    VkQueue queue;
    vkGetDeviceQueue(dev, family, 0, &queue);

    /* Two host-visible, host-coherent storage buffers. */
    VkPhysicalDeviceMemoryProperties mp;
    vkGetPhysicalDeviceMemoryProperties(phys, &mp);
    const size_t sizes[2] = {in_size, out_size};
    VkBuffer buf[2];
    VkDeviceMemory mem[2];
    void *mapped[2];
    for (int b = 0; b < 2; b++) {
        VkBufferCreateInfo bci = {.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO,
                                  .size = sizes[b] ? sizes[b] : 4,
                                  .usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                  .sharingMode = VK_SHARING_MODE_EXCLUSIVE};
        CHECK(vkCreateBuffer(dev, &bci, NULL, &buf[b]));
        VkMemoryRequirements req;
        vkGetBufferMemoryRequirements(dev, buf[b], &req);
        const VkMemoryPropertyFlags want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        uint32_t type = UINT32_MAX;
        for (uint32_t t = 0; t < mp.memoryTypeCount && type == UINT32_MAX; t++)
            if ((req.memoryTypeBits & (1u << t)) && (mp.memoryTypes[t].propertyFlags & want) == want) type = t;
        if (type == UINT32_MAX) {
            fprintf(stderr, "no host-visible coherent memory type\n");
            return 1;
        }
        VkMemoryAllocateInfo mai = {
            .sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO, .allocationSize = req.size, .memoryTypeIndex = type};
        CHECK(vkAllocateMemory(dev, &mai, NULL, &mem[b]));
        CHECK(vkBindBufferMemory(dev, buf[b], mem[b], 0));
        CHECK(vkMapMemory(dev, mem[b], 0, VK_WHOLE_SIZE, 0, &mapped[b]));
    }
    memcpy(mapped[0], input, in_size);
    memset(mapped[1], 0, out_size);

    VkDescriptorSetLayoutBinding bindings[2];
    for (uint32_t b = 0; b < 2; b++)
        bindings[b] = (VkDescriptorSetLayoutBinding){.binding = b,
                                                     .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                                     .descriptorCount = 1,
                                                     .stageFlags = VK_SHADER_STAGE_COMPUTE_BIT};
    VkDescriptorSetLayoutCreateInfo dslci = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO, .bindingCount = 2, .pBindings = bindings};
    VkDescriptorSetLayout dsl;
    CHECK(vkCreateDescriptorSetLayout(dev, &dslci, NULL, &dsl));
    VkPipelineLayoutCreateInfo plci = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO, .setLayoutCount = 1, .pSetLayouts = &dsl};
    VkPipelineLayout pl;
    CHECK(vkCreatePipelineLayout(dev, &plci, NULL, &pl));
    VkShaderModuleCreateInfo smci = {
        .sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO, .codeSize = spv_size, .pCode = (const uint32_t *)spv};
    VkShaderModule sm;
    CHECK(vkCreateShaderModule(dev, &smci, NULL, &sm));
    VkComputePipelineCreateInfo cpci = {.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
                                        .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                                                  .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                                                  .module = sm,
                                                  .pName = "main"},
                                        .layout = pl};
    VkPipeline pipe;
    CHECK(vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &cpci, NULL, &pipe));
    VkDescriptorPoolSize ps = {.type = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, .descriptorCount = 2};
    VkDescriptorPoolCreateInfo dpci = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO, .maxSets = 1, .poolSizeCount = 1, .pPoolSizes = &ps};
    VkDescriptorPool dp;
    CHECK(vkCreateDescriptorPool(dev, &dpci, NULL, &dp));
    VkDescriptorSetAllocateInfo dsai = {.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
                                        .descriptorPool = dp,
                                        .descriptorSetCount = 1,
                                        .pSetLayouts = &dsl};
    VkDescriptorSet ds;
    CHECK(vkAllocateDescriptorSets(dev, &dsai, &ds));
    VkDescriptorBufferInfo dbi[2] = {{buf[0], 0, VK_WHOLE_SIZE}, {buf[1], 0, VK_WHOLE_SIZE}};
    VkWriteDescriptorSet w[2];
    for (uint32_t b = 0; b < 2; b++)
        w[b] = (VkWriteDescriptorSet){.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
                                      .dstSet = ds,
                                      .dstBinding = b,
                                      .descriptorCount = 1,
                                      .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                      .pBufferInfo = &dbi[b]};
    vkUpdateDescriptorSets(dev, 2, w, 0, NULL);

    VkCommandPoolCreateInfo cpi = {.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO, .queueFamilyIndex = family};
    VkCommandPool pool;
    CHECK(vkCreateCommandPool(dev, &cpi, NULL, &pool));
    VkCommandBufferAllocateInfo cbai = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO,
                                        .commandPool = pool,
                                        .level = VK_COMMAND_BUFFER_LEVEL_PRIMARY,
                                        .commandBufferCount = 1};
    VkCommandBuffer cb;
    CHECK(vkAllocateCommandBuffers(dev, &cbai, &cb));
    VkCommandBufferBeginInfo cbbi = {.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO,
                                     .flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT};
    CHECK(vkBeginCommandBuffer(cb, &cbbi));
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, pipe);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, pl, 0, 1, &ds, 0, NULL);
    vkCmdDispatch(cb, groups, 1, 1);
    /* Make the shader writes visible to the host read after the fence. */
    VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                          .srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT,
                          .dstAccessMask = VK_ACCESS_HOST_READ_BIT};
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &mb, 0, NULL, 0,
                         NULL);
    CHECK(vkEndCommandBuffer(cb));
    VkFenceCreateInfo fci = {.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence fence;
    CHECK(vkCreateFence(dev, &fci, NULL, &fence));
    VkSubmitInfo si = {.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO, .commandBufferCount = 1, .pCommandBuffers = &cb};
    CHECK(vkQueueSubmit(queue, 1, &si, fence));
    CHECK(vkWaitForFences(dev, 1, &fence, VK_TRUE, UINT64_MAX));

    FILE *out = fopen(argv[3], "wb");
    if (!out || fwrite(mapped[1], 1, out_size, out) != out_size || fclose(out) != 0) {
        fprintf(stderr, "cannot write %s\n", argv[3]);
        return 1;
    }

    vkDestroyFence(dev, fence, NULL);
    vkDestroyCommandPool(dev, pool, NULL);
    vkDestroyDescriptorPool(dev, dp, NULL);
    vkDestroyPipeline(dev, pipe, NULL);
    vkDestroyShaderModule(dev, sm, NULL);
    vkDestroyPipelineLayout(dev, pl, NULL);
    vkDestroyDescriptorSetLayout(dev, dsl, NULL);
    for (int b = 0; b < 2; b++) {
        vkUnmapMemory(dev, mem[b]);
        vkDestroyBuffer(dev, buf[b], NULL);
        vkFreeMemory(dev, mem[b], NULL);
    }
    vkDestroyDevice(dev, NULL);
    if (messenger != VK_NULL_HANDLE) {
        LOAD(inst, vkDestroyDebugUtilsMessengerEXT);
        vkDestroyDebugUtilsMessengerEXT(inst, messenger, NULL);
    }
    vkDestroyInstance(inst, NULL);
    free(spv);
    free(input);
    return validation_messages ? 3 : 0;
}
