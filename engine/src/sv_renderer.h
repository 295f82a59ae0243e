/* The renderer shared by the headless and the windowed path: scene GPU data, pipelines, and one
 * function that records a whole frame into a caller-provided output image:
 *   scene pass  -> HDR target (RGBA32F, linear scene-referred radiance) + depth
 *   tonemap pass -> output image (exposure, operator, sRGB)
 * The headless path reads back either image; the window passes swapchain images.
 *
 * The renderer lives in rooms (docs/engine.md "Architecture"), each its own .c and header:
 *   sv_renderer.c     this driver: create over the rooms, render targets, the frame recorder
 *                     (frame uniform, shadow pass, scene pass, tone-map pass), destroy
 *   sv_upload.c       scene and probe data to GPU buffers and images; per-frame slot/mask updates
 *   sv_shadows.c      shadow layers, the shadow map array and its depth-only pass
 *   sv_shadow_math.c  the light-space fitting (cascades, spot, cube faces): pure math, no Vulkan
 *   sv_pipelines.c    samplers, descriptor sets, and every pipeline from one table of descriptions
 *   sv_probe_pass.c   the per-pixel probe pass: G-buffer, compute pipeline, the dispatch
 */
#ifndef SV_RENDERER_H
#define SV_RENDERER_H

#include "sv_gpu.h"
#include "sv_probes.h"
#include "sv_scene.h"
#include "sv_shadow_math.h"
#include "sv_sky.h"
#include "sv_vk.h"

typedef struct sv_view {
    float view[16];    /* world -> camera (camera looks along -Z) */
    float yfov;        /* radians (perspective); 0 = orthographic with ymag */
    float ymag, xmag;  /* orthographic half extents */
    float znear, zfar; /* zfar 0 = infinite (perspective) */
    float camera_pos[3];
    uint32_t debug_mode; /* SV_DEBUG_* */
    uint32_t flags;      /* SV_FRAME_* */
    float exposure;
    uint32_t tonemap;              /* SV_TONEMAP_* */
    bool show_cells;               /* probe view: a sphere per probe + the grid cell outlines */
    uint32_t brick_view;           /* SV_BRICK_VIEW_*: the probe view with bricks (sv_brick_view.h) */
    uint32_t probe_mode;           /* SV_PROBE_MODE_*, _MATERIAL = each material's own */
    uint32_t probe_representation; /* SV_PROBE_REP_*, _MATERIAL = each material's own (a zeroed view: SH) */
    float normal_bias;             /* per-pixel sample offset along n, in grid spacings (default 0) */
} sv_view;

/* What the renderer uploads besides the scene. Zero-initialised means: no half storage, no sky
 * and a BLACK fallback probe (fallback_radiance 0 is a valid value, e.g. --fallback-radiance 0);
 * start from SV_RENDERER_DESC_DEFAULT for the documented defaults. */
typedef struct sv_renderer_desc {
    float fallback_radiance;  /* uniform radiance of probe 0 when there is no sky (default
                                 SV_FALLBACK_RADIANCE; 0 = black) */
    bool half_probes;         /* half-float probe storage (sv_gpu_probe_half) instead of float */
    const sv_sky *sky;        /* NULL or !present: no background, no specular, constant fallback */
    bool cube_probes;         /* fill the ambient-cube buffer even when no material asks for cubes
                                 (--probe-representation ambientCube); docs/ambient-cube.md §5 */
    uint32_t shadow_res;      /* shadow map size per layer (--shadow-res, default
                                 SV_SHADOW_DEFAULT_RES); 0 = no shadows */
    uint32_t shadow_cascades; /* layers (cascades) per shadowed directional light, 1..SV_MAX_SHADOW_CASCADES
                                 (--shadow-cascades, default SV_SHADOW_DEFAULT_CASCADES; 0 selects it); 1 = one
                                 map over the whole scene bounds */
    bool bricks;              /* --probe-path bricks (the default): corner/kd tree and dense SH grids also
                                 resampled into probe bricks (3D textures, sv_bricks.h) that per-pixel shading
                                 samples; false = the storage buffers only (--probe-path buffers) */
    bool bricks_required;     /* asked for explicitly: a brick set the device cannot hold is an error (exit 1);
                                 else a warning and the storage buffers */
    uint32_t shader_loops;    /* --shader-loops: SV_SHADER_LOOPS_* (default AUTO) */
    uint32_t probe_pass;      /* --probe-pass: SV_PROBE_PASS_* (default AUTO), sv_probe_pass.h */
    bool probe_view;          /* the probe view may be drawn in this run (--probe-view, --brick-view, or the
                                 window, whose C and B keys turn it on): its spheres read the file's probes and
                                 the cell buffer, so they are uploaded (docs/engine.md "Probe buffers") */
} sv_renderer_desc;
/* Which build of mesh.frag a device gets (shaders/bricks.glsl SV_FOR_GROUPS): AUTO = the unrolled channel-group
 * loops on a GPU, the plain loops on a CPU device (lavapipe), where the unrolled ones cost 1.6-1.9x. */
enum { SV_SHADER_LOOPS_AUTO, SV_SHADER_LOOPS_PLAIN, SV_SHADER_LOOPS_UNROLLED };
bool sv_shader_loops_unrolled(uint32_t shader_loops, VkPhysicalDeviceType type);
/* Where per-pixel probes are shaded (docs/engine.md "The per-pixel probe pass"): AUTO = COMPUTE; FRAGMENT = in
 * the scene pass's fragment shader, every fragment drawn; COMPUTE = the deferred probe pass, once per pixel. */
enum { SV_PROBE_PASS_AUTO, SV_PROBE_PASS_FRAGMENT, SV_PROBE_PASS_COMPUTE };
#define SV_SHADOW_DEFAULT_RES 2048u
#define SV_SHADOW_MAX_RES     8192u
#define SV_RENDERER_DESC_DEFAULT                                                                                       \
    {                                                                                                                  \
        .fallback_radiance = SV_FALLBACK_RADIANCE, .half_probes = false, .sky = NULL, .cube_probes = false,            \
        .shadow_res = SV_SHADOW_DEFAULT_RES, .shadow_cascades = SV_SHADOW_DEFAULT_CASCADES, .bricks = true,            \
        .bricks_required = false                                                                                       \
    }

/* The graphics pipelines, one per row of the table in sv_pipelines.c. */
typedef enum sv_pipeline_id {
    SV_PIPELINE_MESH,          /* the scene's objects into the HDR target */
    SV_PIPELINE_CELLS,         /* probe view: a sphere per probe */
    SV_PIPELINE_OUTLINE,       /* probe view: grid cell outlines */
    SV_PIPELINE_BRICK_OUTLINE, /* brick view: a brick's region outline (sv_brick_view.h) */
    SV_PIPELINE_BRICK_TEXELS,  /* brick view: a brick's texels as spheres */
    SV_PIPELINE_SKY,           /* the background, behind everything */
    SV_PIPELINE_MESH_DEFERRED, /* the objects into the HDR target and the G-buffer (sv_probe_pass.h) */
    SV_PIPELINE_MESH_LEAN,     /* the objects of a frame without per-pixel probes (no grid lookup in the shader) */
    SV_PIPELINE_SKY_DEFERRED,  /* the background, with the G-buffer attached (not written) */
    SV_PIPELINE_TONEMAP,       /* HDR target -> output image */
    SV_PIPELINE_SHADOW,        /* depth only, into a shadow map layer (only with shadowed lights) */
    SV_PIPELINE_COUNT
} sv_pipeline_id;

typedef struct sv_renderer {
    sv_context *ctx;
    VkFormat hdr_format, depth_format, output_format;
    bool encode_srgb; /* output format is UNORM: the shader applies the sRGB curve */

    sv_buffer vertices, indices, frame, materials, probes, probes_half, cubes, cubes_half, lights, cells, grids,
        cell_index;
    uint32_t *prim_first_index; /* per primitive, flattened over meshes */
    uint32_t *prim_index_count;
    int32_t *prim_vertex_offset;
    uint32_t *prim_material;
    uint32_t *mesh_prim_base; /* per mesh: first flattened primitive */
    uint32_t sphere_first_index, sphere_index_count;
    int32_t sphere_vertex_offset;
    uint32_t light_count, sphere_count, outline_count, probe_count, grid_count;
    /* The file's probes (and the cell buffer) are uploaded only where a shader of this run reads them
     * (docs/engine.md "Probe buffers"): false under --probe-path bricks when every grid is a bricked tree
     * grid or tetrahedra, SH only, without the probe view; the probe buffer then holds the fallback and the per-object slots (probe_rebase = total - 1:
     * slot entry = draw.probe_index - probe_rebase) and the cell index one dummy entry. Under --probe-path
     * bricks the cell buffer (probe view) is uploaded only with sv_renderer_desc.probe_view. */
    bool file_probes;
    uint32_t probe_rebase;
    /* What sv_bricks_upload made, for the memory report (sv_bricks_report) once the buffers exist. */
    struct {
        uint64_t bricks, texels, probes, dense, pool_bytes, index_bytes, buffers_path_bytes;
        uint32_t pool[3], index[3], groups;
        bool f32;
    } brick_stats;
    bool half_probes;
    bool unrolled_groups; /* mesh.frag with SV_UNROLL_GROUPS (sv_shader_loops_unrolled) */
    bool has_cubes;       /* the cube buffer (float or half by half_probes) holds the probes' ambient cubes */
    bool has_sky;
    const sv_probes *probes_src; /* the probes uploaded (their per-object slots are re-uploaded) */
    uint32_t slots_uploaded;     /* probes_src->slots_version last written to the GPU */
    uint32_t masks_movable;      /* movable objects when the visibility masks were last traced */
    bool slot_clamp_warned;      /* a half-storage slot was clamped to the half range (warned once) */
    sv_image sky, brdf_lut;      /* prefiltered equirect mips (1x1 black without a sky), split-sum LUT */
    VkSampler sky_sampler, lut_sampler;

    /* Probe bricks (sv_bricks.h, --probe-path bricks): the pool (one slab of z per channel group) and the
     * indirection; 1x1x1 stand-ins when off. */
    sv_image brick_pool, brick_index;
    sv_buffer brick_vis; /* brick tables and visibility records (sv_bricks_vis.h); one zero row when off */
    VkSampler brick_sampler, brick_index_sampler; /* linear / nearest, clamp to edge */
    bool bricks;                                  /* the bricks are uploaded: SV_FRAME_BRICKS */
    struct sv_brick_view *brick_view;             /* the bricks' regions for the brick view; NULL without */

    sv_image *textures; /* per glTF texture (image NULL when it could not be read) */
    uint32_t texture_count;
    sv_image white; /* bound where a material has no texture */
    VkSampler sampler, hdr_sampler;
    VkDescriptorSetLayout scene_set_layout, material_set_layout, tonemap_set_layout;
    VkDescriptorPool pool;
    VkDescriptorSet scene_set, tonemap_set;
    VkDescriptorSet *material_sets; /* set 1 per material, the glTF default material last */
    uint32_t material_count;
    VkPipelineLayout scene_layout, tonemap_layout;
    VkPipeline pipelines[SV_PIPELINE_COUNT]; /* by sv_pipeline_id; VK_NULL_HANDLE where not made */

    sv_image hdr, depth;
    uint32_t width, height;

    /* The deferred per-pixel probe pass (sv_probe_pass.h): on unless --probe-pass fragment or the device
     * lacks the attachments; the G-buffer at the targets' size, the compute pipeline and its set. */
    bool probe_pass;
    bool lean_scene;  /* frames without per-pixel probes take SV_PIPELINE_MESH_LEAN (not --probe-pass fragment) */
    bool pixel_modes; /* a material or node asks for per-pixel probes (for --probe-mode material) */
    sv_image gbuf[SV_GBUF_COUNT];
    VkDescriptorSetLayout probe_pass_set_layout;
    VkDescriptorPool probe_pass_pool;
    VkDescriptorSet probe_pass_set;
    VkPipelineLayout probe_pass_layout;
    VkPipeline probe_pass_pipeline;

    /* Shadow maps (docs/engine.md "Shadows"): one depth layer per cascade of a shadowed directional
     * light and per spot light, six per point light (a 1x1 single layer, never rendered, when none),
     * rendered at the start of every frame. */
    sv_image shadow;
    VkImageView shadow_layer_views[SV_MAX_SHADOW_LAYERS]; /* per layer, the depth attachment of the shadow pass */
    VkSampler shadow_sampler;                             /* LESS_OR_EQUAL compare, white border (lit outside) */
    VkPipelineLayout shadow_layout; /* with pipelines[SV_PIPELINE_SHADOW]: made only when shadow_count > 0 */
    VkFormat shadow_format;
    uint32_t shadow_res;      /* texels per side of a layer */
    uint32_t shadow_count;    /* layers rendered, 0..SV_MAX_SHADOW_LAYERS */
    uint32_t shadow_cascades; /* layers asked for per shadowed directional light (desc.shadow_cascades) */
    sv_shadow_layer shadow_layers[SV_MAX_SHADOW_LAYERS];

    /* GPU timestamps of the last recorded frame (SV_TIMESTAMPS queries: its start, after the shadow
     * maps, after the scene pass, after tone mapping); VK_NULL_HANDLE where the queue has none. */
    VkQueryPool timestamps;
    uint64_t timestamp_mask; /* the queue's timestampValidBits as a mask */
} sv_renderer;

#define SV_TIMESTAMPS 5

/* The GPU time of the last frame's stages in ms (timestamps; wait for the frame's fence first):
 * ms[0] shadow maps (with the probes' slot upload and mask retrace before them), ms[1] the scene pass
 * (sky, meshes, the probe pass, cells), ms[2] tone mapping to the output, ms[3] the part of ms[1] from the
 * end of the objects' raster to the end of the scene pass: the probe pass's dispatch (and the probe view
 * after it), 0 without. False where the queue has no timestamps. */
bool sv_renderer_gpu_times(sv_renderer *r, double ms[4]);

/* Uploads the scene (geometry, materials, textures, lights) and the probes, builds pipelines for
 * `output_format`. Prints a clear message and returns false on failure (call destroy anyway). */
bool sv_renderer_create(sv_renderer *r, sv_context *ctx, const sv_scene *scene, const sv_probes *probes,
                        VkFormat output_format, const sv_renderer_desc *desc);
/* (Re)creates the HDR and depth targets at width x height. */
bool sv_renderer_resize(sv_renderer *r, uint32_t width, uint32_t height);
/* Records one frame. The caller has waited for the previous frame (the frame uniform is written
 * here). Leaves the HDR target in SHADER_READ_ONLY_OPTIMAL and the output in `out_final`. */
void sv_renderer_record(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, const sv_view *view,
                        VkImage out_image, VkImageView out_view, VkImageLayout out_final);
void sv_renderer_destroy(sv_renderer *r);

/* Projection for the view at the given aspect (width / height), Vulkan clip space. */
void sv_view_projection(const sv_view *view, float aspect, float out[16]);

#endif
