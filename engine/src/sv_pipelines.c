/* Descriptors and pipelines (see sv_pipelines.h): the samplers, the three descriptor set layouts and
 * their sets, the pipeline layouts, and every graphics pipeline from one table of descriptions. */
#include "sv_pipelines.h"

#include <stdlib.h>
#include <string.h>

#include "sv_probe_pass.h"
#include "sv_upload.h"

/* SPIR-V embedded at build time (glslc -mfmt=c), so the binary runs from any working directory. */
static const uint32_t mesh_vert_spv[] =
#include "mesh.vert.inc"
    ;
static const uint32_t mesh_frag_spv[] =
#include "mesh.frag.inc"
    ;
/* mesh.frag built with SV_UNROLL_GROUPS (shaders/bricks.glsl SV_FOR_GROUPS): GPUs take it (SV_SHADER_LOOPS_*). */
static const uint32_t mesh_frag_unrolled_spv[] =
#include "mesh.frag.unrolled.inc"
    ;
/* mesh.frag built with SV_DEFERRED_PROBES: the scene pass of the per-pixel probe pass (sv_probe_pass.h). */
static const uint32_t mesh_frag_deferred_spv[] =
#include "mesh.frag.deferred.inc"
    ;
/* mesh.frag built with SV_LEAN_SCENE: the scene pass of a frame where no fragment asks for per-pixel probes. */
static const uint32_t mesh_frag_lean_spv[] =
#include "mesh.frag.lean.inc"
    ;
static const uint32_t probe_cells_vert_spv[] =
#include "probe_cells.vert.inc"
    ;
static const uint32_t probe_cells_frag_spv[] =
#include "probe_cells.frag.inc"
    ;
static const uint32_t probe_outline_vert_spv[] =
#include "probe_outline.vert.inc"
    ;
static const uint32_t probe_outline_frag_spv[] =
#include "probe_outline.frag.inc"
    ;
static const uint32_t probe_bricks_outline_vert_spv[] =
#include "probe_bricks_outline.vert.inc"
    ;
static const uint32_t probe_bricks_outline_frag_spv[] =
#include "probe_bricks_outline.frag.inc"
    ;
static const uint32_t probe_bricks_texels_vert_spv[] =
#include "probe_bricks_texels.vert.inc"
    ;
static const uint32_t probe_bricks_texels_frag_spv[] =
#include "probe_bricks_texels.frag.inc"
    ;
static const uint32_t sky_vert_spv[] =
#include "sky.vert.inc"
    ;
static const uint32_t sky_frag_spv[] =
#include "sky.frag.inc"
    ;
static const uint32_t fullscreen_vert_spv[] =
#include "fullscreen.vert.inc"
    ;
static const uint32_t tonemap_frag_spv[] =
#include "tonemap.frag.inc"
    ;
static const uint32_t shadow_vert_spv[] =
#include "shadow.vert.inc"
    ;

/* ---- samplers and descriptors --------------------------------------------------------------- */

/* Set 0: the first 11 are buffers (in the order of scene_buffers() below), the last 5 images. */
enum { SCENE_BUFFERS = 11 };
#define SV_VF (VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT)
/* What the probe pass's compute shader reads too (shaders/probe_pass.comp: the frame, the probes, the grids). */
#define SV_FC  (VK_SHADER_STAGE_FRAGMENT_BIT | VK_SHADER_STAGE_COMPUTE_BIT)
#define SV_VFC (SV_VF | VK_SHADER_STAGE_COMPUTE_BIT)
static const VkDescriptorSetLayoutBinding scene_bindings[SV_SCENE_BINDING_COUNT] = {
    {SV_BINDING_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, SV_VFC, NULL},
    {SV_BINDING_MATERIALS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    {SV_BINDING_PROBES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, SV_FC, NULL},
    {SV_BINDING_LIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    {SV_BINDING_CELLS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT, NULL},
    {SV_BINDING_GRIDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, SV_VFC, NULL},
    {SV_BINDING_CELL_INDEX, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, SV_FC, NULL},
    {SV_BINDING_PROBES_HALF, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, SV_FC, NULL},
    {SV_BINDING_CUBES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, SV_FC, NULL},
    {SV_BINDING_CUBES_HALF, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, SV_FC, NULL},
    {SV_BINDING_BRICK_VIS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, SV_FC, NULL},
    {SV_BINDING_SKY, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    {SV_BINDING_BRDF_LUT, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    {SV_BINDING_SHADOW, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    {SV_BINDING_BRICK_POOL, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, SV_FC, NULL},
    {SV_BINDING_BRICK_INDEX, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, SV_FC, NULL},
};
/* Set 1, per material: separate sets rather than a sampler array, since lavapipe (and Vulkan 1.0 in
 * general) need not support dynamically indexed sampler arrays. */
static const VkDescriptorSetLayoutBinding material_bindings[2] = {
    {SV_BINDING_BASE_COLOR_TEX, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    {SV_BINDING_EMISSIVE_TEX, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
};
static const VkDescriptorSetLayoutBinding tonemap_binding = {SV_BINDING_HDR, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
                                                             1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL};

static bool create_samplers(sv_renderer *r)
{
    VkDevice dev = r->ctx->device;
    VkSamplerCreateInfo si = sv_sampler_info(VK_FILTER_LINEAR, VK_SAMPLER_ADDRESS_MODE_REPEAT);
    VK_CHECK(vkCreateSampler(dev, &si, NULL, &r->sampler));
    si.magFilter = si.minFilter = VK_FILTER_NEAREST;
    si.addressModeU = si.addressModeV = si.addressModeW = VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE;
    VK_CHECK(vkCreateSampler(dev, &si, NULL, &r->hdr_sampler));
    /* LUT: bilinear, clamped; sky: bilinear + linear between mips, u wraps (longitude), v clamps. */
    si.magFilter = si.minFilter = VK_FILTER_LINEAR;
    VK_CHECK(vkCreateSampler(dev, &si, NULL, &r->lut_sampler));
    si.addressModeU = VK_SAMPLER_ADDRESS_MODE_REPEAT;
    si.mipmapMode = VK_SAMPLER_MIPMAP_MODE_LINEAR;
    si.maxLod = VK_LOD_CLAMP_NONE;
    VK_CHECK(vkCreateSampler(dev, &si, NULL, &r->sky_sampler));
    return true;
fail:
    return false;
}

/* The three set layouts, the pool, the scene and tone-map sets and one set per material. */
static bool create_sets(sv_renderer *r)
{
    VkDevice dev = r->ctx->device;
    VkDescriptorSetLayoutCreateInfo li = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
        .bindingCount = SV_SCENE_BINDING_COUNT,
        .pBindings = scene_bindings,
    };
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &li, NULL, &r->scene_set_layout));
    li.bindingCount = 2;
    li.pBindings = material_bindings;
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &li, NULL, &r->material_set_layout));
    li.bindingCount = 1;
    li.pBindings = &tonemap_binding;
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &li, NULL, &r->tonemap_set_layout));
    VkDescriptorPoolSize sizes[] = {
        {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
        {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 10},
        {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 2 * r->material_count + 6},
    };
    VkDescriptorPoolCreateInfo pi = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO,
        .maxSets = 2 + r->material_count,
        .poolSizeCount = 3,
        .pPoolSizes = sizes,
    };
    VK_CHECK(vkCreateDescriptorPool(dev, &pi, NULL, &r->pool));
    VkDescriptorSetLayout layouts[2] = {r->scene_set_layout, r->tonemap_set_layout};
    VkDescriptorSet sets[2];
    VkDescriptorSetAllocateInfo ai = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO,
        .descriptorPool = r->pool,
        .descriptorSetCount = 2,
        .pSetLayouts = layouts,
    };
    VK_CHECK(vkAllocateDescriptorSets(dev, &ai, sets));
    r->scene_set = sets[0];
    r->tonemap_set = sets[1];
    r->material_sets = calloc(r->material_count, sizeof(VkDescriptorSet));
    if (!r->material_sets) return false;
    ai.descriptorSetCount = 1;
    ai.pSetLayouts = &r->material_set_layout;
    for (uint32_t m = 0; m < r->material_count; ++m) VK_CHECK(vkAllocateDescriptorSets(dev, &ai, &r->material_sets[m]));
    return true;
fail:
    return false;
}

/* Set 1 of every material: its base-colour and emissive textures, white where it has none. */
static void write_material_sets(sv_renderer *r, const sv_gltf *g)
{
    for (uint32_t m = 0; m < r->material_count; ++m) {
        int32_t tex[2] = {-1, -1};
        if (m < g->material_count) {
            tex[0] = sv_texture_slot(g, &g->materials[m].base_color_texture);
            tex[1] = sv_texture_slot(g, &g->materials[m].emissive_texture);
        }
        VkDescriptorImageInfo ii[2]; /* SV_BINDING_BASE_COLOR_TEX, SV_BINDING_EMISSIVE_TEX (consecutive) */
        for (int k = 0; k < 2; ++k) {
            ii[k].sampler = r->sampler;
            ii[k].imageView = tex[k] >= 0 && r->textures[tex[k]].view ? r->textures[tex[k]].view : r->white.view;
            ii[k].imageLayout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
        }
        VkWriteDescriptorSet mw = {
            .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
            .dstSet = r->material_sets[m],
            .dstBinding = SV_BINDING_BASE_COLOR_TEX,
            .descriptorCount = 2,
            .descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
            .pImageInfo = ii,
        };
        vkUpdateDescriptorSets(r->ctx->device, 1, &mw, 0, NULL);
    }
}

/* Set 0: the scene's buffers and images, in the order of scene_bindings. */
static void write_scene_set(sv_renderer *r)
{
    VkDescriptorBufferInfo bufs[SCENE_BUFFERS] = {
        {r->frame.buffer, 0, VK_WHOLE_SIZE},      {r->materials.buffer, 0, VK_WHOLE_SIZE},
        {r->probes.buffer, 0, VK_WHOLE_SIZE},     {r->lights.buffer, 0, VK_WHOLE_SIZE},
        {r->cells.buffer, 0, VK_WHOLE_SIZE},      {r->grids.buffer, 0, VK_WHOLE_SIZE},
        {r->cell_index.buffer, 0, VK_WHOLE_SIZE}, {r->probes_half.buffer, 0, VK_WHOLE_SIZE},
        {r->cubes.buffer, 0, VK_WHOLE_SIZE},      {r->cubes_half.buffer, 0, VK_WHOLE_SIZE},
        {r->brick_vis.buffer, 0, VK_WHOLE_SIZE},
    };
    VkDescriptorImageInfo imgs[SV_SCENE_BINDING_COUNT - SCENE_BUFFERS] = {
        {r->sky_sampler, r->sky.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
        {r->lut_sampler, r->brdf_lut.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
        {r->shadow_sampler, r->shadow.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
        {r->brick_sampler, r->brick_pool.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
        {r->brick_index_sampler, r->brick_index.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
    };
    VkWriteDescriptorSet w[SV_SCENE_BINDING_COUNT];
    for (uint32_t i = 0; i < SV_SCENE_BINDING_COUNT; ++i)
        w[i] = (VkWriteDescriptorSet){
            .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
            .dstSet = r->scene_set,
            .dstBinding = scene_bindings[i].binding,
            .descriptorCount = 1,
            .descriptorType = scene_bindings[i].descriptorType,
            .pBufferInfo = i < SCENE_BUFFERS ? &bufs[i] : NULL,
            .pImageInfo = i >= SCENE_BUFFERS ? &imgs[i - SCENE_BUFFERS] : NULL,
        };
    vkUpdateDescriptorSets(r->ctx->device, SV_SCENE_BINDING_COUNT, w, 0, NULL);
}

bool sv_pipelines_create_descriptors(sv_renderer *r, const sv_gltf *g)
{
    if (!create_samplers(r) || !create_sets(r)) return false;
    write_material_sets(r, g);
    write_scene_set(r);
    return true;
}

/* ---- the pipeline table --------------------------------------------------------------------- */

enum { LAYOUT_SCENE, LAYOUT_TONEMAP, LAYOUT_SHADOW }; /* pipeline_desc.layout */
/* pipeline_desc.color; TARGET_GBUF: the HDR target and the probe pass's G-buffer (sv_probe_pass_formats) */
enum { TARGET_NONE, TARGET_HDR, TARGET_OUTPUT, TARGET_GBUF };
enum { DEPTH_NONE, DEPTH_SCENE, DEPTH_SHADOW }; /* pipeline_desc.depth */

/* One graphics pipeline: shaders, vertex layout, targets and fixed-function state. Every pipeline
 * has one viewport and scissor (dynamic), fills polygons, and takes glTF's CCW winding: Vulkan
 * measures winding in framebuffer space (y down), which the y-flipped projection matches. */
typedef struct pipeline_desc {
    const uint32_t *vs;
    size_t vs_size;
    const uint32_t *fs; /* NULL: no fragment stage (depth only) */
    size_t fs_size;
    uint8_t layout;           /* LAYOUT_*: the scene's (sets 0 and 1 + sv_gpu_draw), tone map's or shadow pass's */
    uint8_t color;            /* TARGET_*: the colour attachment's format (r->hdr_format, r->output_format) */
    uint8_t depth;            /* DEPTH_*: the depth attachment's format (r->depth_format, r->shadow_format) */
    bool depth_test;          /* with a depth attachment: test LESS and write (false: neither, the background) */
    bool blend;               /* colour: alpha blending over the target (false: replace) */
    VkCullModeFlags cull;     /* VK_CULL_MODE_NONE: glTF meshes from Blender are often open; back faces get a
                                 flipped normal in the shader */
    uint32_t attribute_count; /* vertex attributes read (position, normal, uv: SV_VERTEX_FLOATS), 0 = none */
    VkPrimitiveTopology topology;
    bool half_probes_constant; /* specialised with SV_CONSTANT_HALF_PROBES (the scene's probe storage) */
    bool gbuf_writes;          /* TARGET_GBUF: the fragment shader writes the G-buffer (else masked off) */
} pipeline_desc;

#define SV_SPV(name) name##_spv, sizeof(name##_spv)
#define SV_NO_SPV    NULL, 0
static const pipeline_desc pipeline_table[SV_PIPELINE_COUNT] = {
    [SV_PIPELINE_MESH] = {SV_SPV(mesh_vert), SV_SPV(mesh_frag), LAYOUT_SCENE, TARGET_HDR, DEPTH_SCENE, true, false,
                          VK_CULL_MODE_NONE, 3, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, true},
    [SV_PIPELINE_CELLS] = {SV_SPV(probe_cells_vert), SV_SPV(probe_cells_frag), LAYOUT_SCENE, TARGET_HDR, DEPTH_SCENE,
                           true, false, VK_CULL_MODE_NONE, 2, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, true},
    [SV_PIPELINE_OUTLINE] = {SV_SPV(probe_outline_vert), SV_SPV(probe_outline_frag), LAYOUT_SCENE, TARGET_HDR,
                             DEPTH_SCENE, true, false, VK_CULL_MODE_NONE, 0, VK_PRIMITIVE_TOPOLOGY_LINE_LIST, true},
    [SV_PIPELINE_BRICK_OUTLINE] = {SV_SPV(probe_bricks_outline_vert), SV_SPV(probe_bricks_outline_frag), LAYOUT_SCENE,
                                   TARGET_HDR, DEPTH_SCENE, true, false, VK_CULL_MODE_NONE, 0,
                                   VK_PRIMITIVE_TOPOLOGY_LINE_LIST, false},
    [SV_PIPELINE_BRICK_TEXELS] = {SV_SPV(probe_bricks_texels_vert), SV_SPV(probe_bricks_texels_frag), LAYOUT_SCENE,
                                  TARGET_HDR, DEPTH_SCENE, true, false, VK_CULL_MODE_NONE, 1,
                                  VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, false},
    [SV_PIPELINE_SKY] = {SV_SPV(sky_vert), SV_SPV(sky_frag), LAYOUT_SCENE, TARGET_HDR, DEPTH_SCENE, false, false,
                         VK_CULL_MODE_NONE, 0, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, true},
    [SV_PIPELINE_MESH_DEFERRED] = {SV_SPV(mesh_vert), SV_SPV(mesh_frag_deferred), LAYOUT_SCENE, TARGET_GBUF,
                                   DEPTH_SCENE, true, false, VK_CULL_MODE_NONE, 3, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST,
                                   true, true},
    [SV_PIPELINE_MESH_LEAN] = {SV_SPV(mesh_vert), SV_SPV(mesh_frag_lean), LAYOUT_SCENE, TARGET_HDR, DEPTH_SCENE, true,
                               false, VK_CULL_MODE_NONE, 3, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, true},
    [SV_PIPELINE_SKY_DEFERRED] = {SV_SPV(sky_vert), SV_SPV(sky_frag), LAYOUT_SCENE, TARGET_GBUF, DEPTH_SCENE, false,
                                  false, VK_CULL_MODE_NONE, 0, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, true, false},
    [SV_PIPELINE_TONEMAP] = {SV_SPV(fullscreen_vert), SV_SPV(tonemap_frag), LAYOUT_TONEMAP, TARGET_OUTPUT, DEPTH_NONE,
                             false, false, VK_CULL_MODE_NONE, 0, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, false},
    [SV_PIPELINE_SHADOW] = {SV_SPV(shadow_vert), SV_NO_SPV, LAYOUT_SHADOW, TARGET_NONE, DEPTH_SHADOW, true, false,
                            VK_CULL_MODE_NONE, 1, VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST, false},
};

/* The scene's layout (sets 0, 1 and sv_gpu_draw), the tone map's (its set and sv_gpu_tonemap) and,
 * with shadowed lights, the shadow pass's (no set; the light's matrix in sv_gpu_shadow_draw). */
static bool create_layouts(sv_renderer *r)
{
    VkDevice dev = r->ctx->device;
    VkPushConstantRange scene_push = {SV_VF, 0, sizeof(sv_gpu_draw)};
    VkDescriptorSetLayout set_layouts[2] = {r->scene_set_layout, r->material_set_layout};
    VkPipelineLayoutCreateInfo li = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO,
        .setLayoutCount = 2,
        .pSetLayouts = set_layouts,
        .pushConstantRangeCount = 1,
        .pPushConstantRanges = &scene_push,
    };
    VK_CHECK(vkCreatePipelineLayout(dev, &li, NULL, &r->scene_layout));
    VkPushConstantRange tone_push = {VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(sv_gpu_tonemap)};
    li.setLayoutCount = 1;
    li.pSetLayouts = &r->tonemap_set_layout;
    li.pPushConstantRanges = &tone_push;
    VK_CHECK(vkCreatePipelineLayout(dev, &li, NULL, &r->tonemap_layout));
    if (r->shadow_count) {
        VkPushConstantRange shadow_push = {VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(sv_gpu_shadow_draw)};
        li.setLayoutCount = 0;
        li.pSetLayouts = NULL;
        li.pPushConstantRanges = &shadow_push;
        VK_CHECK(vkCreatePipelineLayout(dev, &li, NULL, &r->shadow_layout));
    }
    return true;
fail:
    return false;
}

/* The fixed-function state of a description that does not depend on the renderer. */
typedef struct fixed_state {
    VkPipelineInputAssemblyStateCreateInfo ia;
    VkPipelineViewportStateCreateInfo vp;
    VkPipelineRasterizationStateCreateInfo rs;
    VkPipelineMultisampleStateCreateInfo ms;
    VkPipelineDepthStencilStateCreateInfo ds;
    VkPipelineColorBlendAttachmentState blend[1 + SV_GBUF_COUNT];
    VkPipelineColorBlendStateCreateInfo cb;
    VkDynamicState dyn[2];
    VkPipelineDynamicStateCreateInfo dy;
} fixed_state;

static void fill_fixed_state(const pipeline_desc *d, uint32_t colors, bool has_depth, fixed_state *s)
{
    s->ia = (VkPipelineInputAssemblyStateCreateInfo){
        .sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO, .topology = d->topology};
    s->vp = (VkPipelineViewportStateCreateInfo){
        .sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO, .viewportCount = 1, .scissorCount = 1};
    s->rs = (VkPipelineRasterizationStateCreateInfo){
        .sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
        .polygonMode = VK_POLYGON_MODE_FILL,
        .cullMode = d->cull,
        .frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE,
        .lineWidth = 1.0f,
    };
    s->ms = (VkPipelineMultisampleStateCreateInfo){
        .sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
        .rasterizationSamples = VK_SAMPLE_COUNT_1_BIT,
    };
    s->ds = (VkPipelineDepthStencilStateCreateInfo){
        .sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO,
        .depthTestEnable = has_depth && d->depth_test,
        .depthWriteEnable = has_depth && d->depth_test,
        .depthCompareOp = VK_COMPARE_OP_LESS,
    };
    s->blend[0] = (VkPipelineColorBlendAttachmentState){.colorWriteMask = 0xF};
    for (uint32_t i = 1; i < colors; ++i)
        s->blend[i] = (VkPipelineColorBlendAttachmentState){.colorWriteMask = d->gbuf_writes ? 0xF : 0u};
    if (d->blend)
        s->blend[0] = (VkPipelineColorBlendAttachmentState){
            .blendEnable = VK_TRUE,
            .srcColorBlendFactor = VK_BLEND_FACTOR_SRC_ALPHA,
            .dstColorBlendFactor = VK_BLEND_FACTOR_ONE_MINUS_SRC_ALPHA,
            .colorBlendOp = VK_BLEND_OP_ADD,
            .srcAlphaBlendFactor = VK_BLEND_FACTOR_ONE,
            .dstAlphaBlendFactor = VK_BLEND_FACTOR_ONE_MINUS_SRC_ALPHA,
            .alphaBlendOp = VK_BLEND_OP_ADD,
            .colorWriteMask = 0xF,
        };
    s->cb = (VkPipelineColorBlendStateCreateInfo){
        .sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
        .attachmentCount = colors,
        .pAttachments = s->blend,
    };
    s->dyn[0] = VK_DYNAMIC_STATE_VIEWPORT;
    s->dyn[1] = VK_DYNAMIC_STATE_SCISSOR;
    s->dy = (VkPipelineDynamicStateCreateInfo){.sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO,
                                               .dynamicStateCount = 2,
                                               .pDynamicStates = s->dyn};
}

/* The pipeline of one table entry, for this renderer's formats, layouts and probe storage. */
static VkPipeline create_pipeline(sv_renderer *r, const pipeline_desc *d, const VkSpecializationInfo *spec)
{
    sv_context *ctx = r->ctx;
    VkPipeline pipe = VK_NULL_HANDLE;
    const VkFormat colors[] = {VK_FORMAT_UNDEFINED, r->hdr_format, r->output_format, r->hdr_format};
    const VkFormat depths[] = {VK_FORMAT_UNDEFINED, r->depth_format, r->shadow_format};
    const VkPipelineLayout layouts[] = {r->scene_layout, r->tonemap_layout, r->shadow_layout};
    VkFormat depth = depths[d->depth];
    VkFormat color[1 + SV_GBUF_COUNT] = {colors[d->color]};
    uint32_t color_count = d->color == TARGET_NONE ? 0u : 1u;
    if (d->color == TARGET_GBUF) {
        for (uint32_t i = 0; i < SV_GBUF_COUNT; ++i) color[1 + i] = sv_probe_pass_formats()[i];
        color_count = 1 + SV_GBUF_COUNT;
    }
    const VkSpecializationInfo *sp = d->half_probes_constant ? spec : NULL;
    VkShaderModule vs = sv_shader_module(ctx, d->vs, d->vs_size);
    VkShaderModule fs = d->fs ? sv_shader_module(ctx, d->fs, d->fs_size) : VK_NULL_HANDLE;
    if (!vs || (d->fs && !fs)) goto fail;
    VkPipelineShaderStageCreateInfo stages[2] = {
        {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
         .stage = VK_SHADER_STAGE_VERTEX_BIT,
         .module = vs,
         .pName = "main",
         .pSpecializationInfo = sp},
        {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
         .stage = VK_SHADER_STAGE_FRAGMENT_BIT,
         .module = fs,
         .pName = "main",
         .pSpecializationInfo = sp},
    };
    VkVertexInputBindingDescription binding = {0, SV_VERTEX_FLOATS * sizeof(float), VK_VERTEX_INPUT_RATE_VERTEX};
    VkVertexInputAttributeDescription attrs[3] = {
        {SV_LOCATION_POSITION, 0, VK_FORMAT_R32G32B32_SFLOAT, 0},
        {SV_LOCATION_NORMAL, 0, VK_FORMAT_R32G32B32_SFLOAT, 3 * sizeof(float)},
        {SV_LOCATION_UV, 0, VK_FORMAT_R32G32_SFLOAT, 6 * sizeof(float)},
    };
    VkPipelineVertexInputStateCreateInfo vi = {.sType = VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
    if (d->attribute_count) {
        vi.vertexBindingDescriptionCount = 1;
        vi.pVertexBindingDescriptions = &binding;
        vi.vertexAttributeDescriptionCount = d->attribute_count;
        vi.pVertexAttributeDescriptions = attrs;
    }
    fixed_state s;
    fill_fixed_state(d, color_count, depth != VK_FORMAT_UNDEFINED, &s);
    VkPipelineRenderingCreateInfo rendering = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO,
        .colorAttachmentCount = color_count,
        .pColorAttachmentFormats = color,
        .depthAttachmentFormat = depth,
    };
    VkGraphicsPipelineCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
        .pNext = &rendering,
        .stageCount = d->fs ? 2 : 1,
        .pStages = stages,
        .pVertexInputState = &vi,
        .pInputAssemblyState = &s.ia,
        .pViewportState = &s.vp,
        .pRasterizationState = &s.rs,
        .pMultisampleState = &s.ms,
        .pDepthStencilState = &s.ds,
        .pColorBlendState = &s.cb,
        .pDynamicState = &s.dy,
        .layout = layouts[d->layout],
    };
    VK_CHECK(vkCreateGraphicsPipelines(ctx->device, VK_NULL_HANDLE, 1, &info, NULL, &pipe));
fail:
    if (vs) vkDestroyShaderModule(ctx->device, vs, NULL);
    if (fs) vkDestroyShaderModule(ctx->device, fs, NULL);
    return pipe;
}

bool sv_pipelines_create(sv_renderer *r)
{
    if (!create_layouts(r)) return false;
    VkBool32 half = r->half_probes ? VK_TRUE : VK_FALSE;
    VkSpecializationMapEntry entry = {SV_CONSTANT_HALF_PROBES, 0, sizeof(VkBool32)};
    VkSpecializationInfo spec = {1, &entry, sizeof(half), &half};
    for (uint32_t i = 0; i < SV_PIPELINE_COUNT; ++i) {
        if (pipeline_table[i].layout == LAYOUT_SHADOW && !r->shadow_count) continue; /* no shadow pass */
        if (pipeline_table[i].color == TARGET_GBUF && !r->probe_pass) continue;      /* no probe pass */
        if (i == SV_PIPELINE_MESH_LEAN && !r->lean_scene) continue;                  /* --probe-pass fragment */
        pipeline_desc d = pipeline_table[i];
        if (i == SV_PIPELINE_MESH && r->unrolled_groups) {
            d.fs = mesh_frag_unrolled_spv;
            d.fs_size = sizeof(mesh_frag_unrolled_spv);
        }
        r->pipelines[i] = create_pipeline(r, &d, &spec);
        if (!r->pipelines[i]) return false;
    }
    return true;
}

bool sv_shader_loops_unrolled(uint32_t shader_loops, VkPhysicalDeviceType type)
{
    if (shader_loops == SV_SHADER_LOOPS_AUTO) return type != VK_PHYSICAL_DEVICE_TYPE_CPU;
    return shader_loops == SV_SHADER_LOOPS_UNROLLED;
}

void sv_pipelines_destroy(sv_renderer *r)
{
    VkDevice dev = r->ctx->device;
    for (uint32_t i = 0; i < SV_PIPELINE_COUNT; ++i)
        if (r->pipelines[i]) vkDestroyPipeline(dev, r->pipelines[i], NULL);
    VkPipelineLayout layouts[3] = {r->shadow_layout, r->scene_layout, r->tonemap_layout};
    for (int i = 0; i < 3; ++i)
        if (layouts[i]) vkDestroyPipelineLayout(dev, layouts[i], NULL);
    if (r->pool) vkDestroyDescriptorPool(dev, r->pool, NULL);
    VkDescriptorSetLayout sets[3] = {r->scene_set_layout, r->material_set_layout, r->tonemap_set_layout};
    for (int i = 0; i < 3; ++i)
        if (sets[i]) vkDestroyDescriptorSetLayout(dev, sets[i], NULL);
    VkSampler samplers[4] = {r->sampler, r->hdr_sampler, r->sky_sampler, r->lut_sampler};
    for (int i = 0; i < 4; ++i)
        if (samplers[i]) vkDestroySampler(dev, samplers[i], NULL);
    free(r->material_sets);
}
