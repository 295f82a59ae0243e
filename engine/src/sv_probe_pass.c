/* The deferred per-pixel probe pass (see sv_probe_pass.h). */
#include "sv_probe_pass.h"

#include <stdio.h>

static const uint32_t probe_pass_comp_spv[] =
#include "probe_pass.comp.inc"
    ;
/* With SV_UNROLL_GROUPS, as mesh.frag: the build a GPU takes (sv_shader_loops_unrolled). */
static const uint32_t probe_pass_comp_unrolled_spv[] =
#include "probe_pass.comp.unrolled.inc"
    ;

/* The G-buffer targets' formats, SV_GBUF_POINT first: the point's float bits stay bits in an integer target. */
static const VkFormat gbuf_formats[SV_GBUF_COUNT] = {VK_FORMAT_R32G32B32A32_UINT, VK_FORMAT_R32G32B32A32_SFLOAT,
                                                     VK_FORMAT_R32G32B32A32_SFLOAT, VK_FORMAT_R32G32B32A32_SFLOAT};

const VkFormat *sv_probe_pass_formats(void) { return gbuf_formats; }

bool sv_probe_pass_create(sv_renderer *r)
{
    VkDevice dev = r->ctx->device;
    if (r->ctx->properties.limits.maxColorAttachments < 1 + SV_GBUF_COUNT || !r->ctx->probe_pass_features) {
        fprintf(stderr,
                "schnee-view: warning: the device has %u colour attachments%s; the per-pixel probe pass needs %u and "
                "both: per-pixel probes are shaded in the scene pass\n",
                r->ctx->properties.limits.maxColorAttachments,
                r->ctx->probe_pass_features ? "" : " and lacks independentBlend or maintenance4", 1 + SV_GBUF_COUNT);
        r->probe_pass = false;
        return true;
    }
    VkDescriptorSetLayoutBinding b[1 + SV_GBUF_COUNT];
    for (uint32_t i = 0; i <= SV_GBUF_COUNT; ++i)
        b[i] =
            (VkDescriptorSetLayoutBinding){i, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1, VK_SHADER_STAGE_COMPUTE_BIT, NULL};
    VkDescriptorSetLayoutCreateInfo li = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
        .bindingCount = 1 + SV_GBUF_COUNT,
        .pBindings = b,
    };
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &li, NULL, &r->probe_pass_set_layout));
    VkDescriptorPoolSize size = {VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1 + SV_GBUF_COUNT};
    VkDescriptorPoolCreateInfo pi = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
        .maxSets = 1,
        .poolSizeCount = 1,
        .pPoolSizes = &size,
    };
    VK_CHECK(vkCreateDescriptorPool(dev, &pi, NULL, &r->probe_pass_pool));
    VkDescriptorSetAllocateInfo ai = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
        .descriptorPool = r->probe_pass_pool,
        .descriptorSetCount = 1,
        .pSetLayouts = &r->probe_pass_set_layout,
    };
    VK_CHECK(vkAllocateDescriptorSets(dev, &ai, &r->probe_pass_set));
    /* Sets 0 (the scene's), 1 (a material's: not read, keeps the set numbers) and 2 (this pass's). */
    VkDescriptorSetLayout sets[3] = {r->scene_set_layout, r->material_set_layout, r->probe_pass_set_layout};
    VkPipelineLayoutCreateInfo pl = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
        .setLayoutCount = 3,
        .pSetLayouts = sets,
    };
    VK_CHECK(vkCreatePipelineLayout(dev, &pl, NULL, &r->probe_pass_layout));
    VkShaderModule cs =
        r->unrolled_groups ? sv_shader_module(r->ctx, probe_pass_comp_unrolled_spv, sizeof probe_pass_comp_unrolled_spv)
                           : sv_shader_module(r->ctx, probe_pass_comp_spv, sizeof probe_pass_comp_spv);
    if (!cs) goto fail;
    VkBool32 half = r->half_probes ? VK_TRUE : VK_FALSE;
    VkSpecializationMapEntry entry = {SV_CONSTANT_HALF_PROBES, 0, sizeof(VkBool32)};
    VkSpecializationInfo spec = {1, &entry, sizeof(half), &half};
    VkComputePipelineCreateInfo ci = {
        .sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO,
        .stage = {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
                  .stage = VK_SHADER_STAGE_COMPUTE_BIT,
                  .module = cs,
                  .pName = "main",
                  .pSpecializationInfo = &spec},
        .layout = r->probe_pass_layout,
    };
    VkResult res = vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &ci, NULL, &r->probe_pass_pipeline);
    vkDestroyShaderModule(dev, cs, NULL);
    VK_CHECK(res);
    return true;
fail:
    return false;
}

bool sv_probe_pass_resize(sv_renderer *r)
{
    if (!r->probe_pass) return true;
    VkDescriptorImageInfo ii[1 + SV_GBUF_COUNT];
    ii[0] = (VkDescriptorImageInfo){VK_NULL_HANDLE, r->hdr.view, VK_IMAGE_LAYOUT_GENERAL};
    for (uint32_t i = 0; i < SV_GBUF_COUNT; ++i) {
        sv_image_destroy(r->ctx, &r->gbuf[i]);
        if (!sv_image_create(r->ctx, r->width, r->height, gbuf_formats[i],
                             VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_STORAGE_BIT,
                             VK_IMAGE_ASPECT_COLOR_BIT, &r->gbuf[i]))
            return false;
        ii[1 + i] = (VkDescriptorImageInfo){VK_NULL_HANDLE, r->gbuf[i].view, VK_IMAGE_LAYOUT_GENERAL};
    }
    VkWriteDescriptorSet w = {
        .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
        .dstSet = r->probe_pass_set,
        .dstBinding = 0,
        .descriptorCount = 1 + SV_GBUF_COUNT,
        .descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_IMAGE,
        .pImageInfo = ii,
    };
    vkUpdateDescriptorSets(r->ctx->device, 1, &w, 0, NULL);
    return true;
}

/* Some fragment of a frame of `view` can ask for per-pixel probes. */
static bool wants_pixel(const sv_renderer *r, const sv_view *view)
{
    return view->probe_mode == SV_PROBE_MODE_PIXEL || (view->probe_mode == SV_PROBE_MODE_MATERIAL && r->pixel_modes);
}

bool sv_probe_pass_active(const sv_renderer *r, const sv_view *view)
{
    return r->probe_pass && view->debug_mode == SV_DEBUG_NONE && wants_pixel(r, view);
}

bool sv_probe_pass_lean(const sv_renderer *r, const sv_view *view)
{
    return view->debug_mode == SV_DEBUG_NONE && !wants_pixel(r, view);
}

void sv_probe_pass_begin(const sv_renderer *r, VkCommandBuffer cmd, VkRenderingAttachmentInfo att[SV_GBUF_COUNT])
{
    for (uint32_t i = 0; i < SV_GBUF_COUNT; ++i) {
        sv_image_barrier(cmd, r->gbuf[i].image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                         VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0,
                         VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
        /* Only the point target is read where no per-pixel fragment wrote (its meta): the others need no clear. */
        att[i] = sv_attachment(r->gbuf[i].view, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                               i == 0 ? VK_ATTACHMENT_LOAD_OP_CLEAR : VK_ATTACHMENT_LOAD_OP_DONT_CARE,
                               VK_ATTACHMENT_STORE_OP_STORE); /* the point target cleared to meta 0 */
    }
}

void sv_probe_pass_record(const sv_renderer *r, VkCommandBuffer cmd)
{
    sv_image_barrier(cmd, r->hdr.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                     VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                     VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                     VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT);
    for (uint32_t i = 0; i < SV_GBUF_COUNT; ++i)
        sv_image_barrier(cmd, r->gbuf[i].image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                         VK_IMAGE_LAYOUT_GENERAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                         VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                         VK_ACCESS_SHADER_READ_BIT);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, r->probe_pass_pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, r->probe_pass_layout, SV_SET_SCENE, 1, &r->scene_set,
                            0, NULL);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, r->probe_pass_layout, SV_SET_PROBE_PASS, 1,
                            &r->probe_pass_set, 0, NULL);
    vkCmdDispatch(cmd, (r->width + SV_PROBE_PASS_GROUP - 1) / SV_PROBE_PASS_GROUP,
                  (r->height + SV_PROBE_PASS_GROUP - 1) / SV_PROBE_PASS_GROUP, 1);
}

void sv_probe_pass_destroy(sv_renderer *r)
{
    VkDevice dev = r->ctx->device;
    for (uint32_t i = 0; i < SV_GBUF_COUNT; ++i) sv_image_destroy(r->ctx, &r->gbuf[i]);
    if (r->probe_pass_pipeline) vkDestroyPipeline(dev, r->probe_pass_pipeline, NULL);
    if (r->probe_pass_layout) vkDestroyPipelineLayout(dev, r->probe_pass_layout, NULL);
    if (r->probe_pass_pool) vkDestroyDescriptorPool(dev, r->probe_pass_pool, NULL);
    if (r->probe_pass_set_layout) vkDestroyDescriptorSetLayout(dev, r->probe_pass_set_layout, NULL);
}
