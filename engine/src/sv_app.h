/* schnee-view application layer. Who calls whom (no cycle):
 *   main.c (options, loading)  ->  sv_headless.c / sv_window.c (front ends)  ->  sv_app.c
 * sv_app.c holds what both front ends share: the initial camera, the renderer description, the
 * one GPU setup path (sv_app_gpu_*) and the validation verdict. */
#ifndef SV_APP_H
#define SV_APP_H

#include "sv_probes.h"
#include "sv_renderer.h"
#include "sv_scene.h"

#define SV_MAX_MOVES 16

typedef struct sv_move {
    const char *node;
    float translation[3];
} sv_move;

typedef struct sv_options {
    const char *scene_path;
    bool headless;
    const char *output;     /* headless: .png/.jpg/... (tone mapped) or .exr (linear, before tone mapping) */
    uint32_t width, height; /* default 960 x 540 */
    const char *camera;     /* camera node or camera name; NULL = first camera, else frame the bounds */
    float exposure;         /* default 1 */
    uint32_t tonemap;       /* SV_TONEMAP_*, default PBR Neutral */
    uint32_t debug_mode;    /* SV_DEBUG_* */
    bool no_direct;
    bool validation;          /* enable the validation layer; any message fails the run (exit 3) */
    bool allow_outside_paths; /* --allow-outside-paths: glTF URIs may leave the glTF's folder */
    bool print_assignments;
    bool show_cells;
    uint32_t brick_view;   /* --brick-view: SV_BRICK_VIEW_* (default cells), with --probe-path bricks */
    bool brick_view_given; /* --brick-view was given */
    sv_move moves[SV_MAX_MOVES];
    uint32_t move_count;
    uint32_t frames;        /* window: quit after this many frames (0 = run until closed);
                                  headless: frames rendered (timed), default 1 */
    const char *screenshot; /* window: write the last presented frame here */
    float fallback_radiance;
    uint32_t probe_mode;           /* SV_PROBE_MODE_*, default _MATERIAL (each material's probeMode) */
    uint32_t probe_representation; /* SV_PROBE_REP_*, default _MATERIAL (each material's probeRepresentation) */
    bool half_probes;              /* --probe-storage half */
    bool bricks;                   /* --probe-path bricks (default): per-pixel probes from the probe bricks */
    bool bricks_given;             /* --probe-path given (bricks then required: no fallback to buffers) */
    uint32_t shader_loops;         /* --shader-loops: SV_SHADER_LOOPS_* (default auto) */
    uint32_t probe_pass;           /* --probe-pass: SV_PROBE_PASS_* (default auto) */
    float normal_bias;             /* --normal-bias, grid spacings (default 0) */
    uint32_t shadow_res;           /* --shadow-res, texels per shadow map side (default 2048, 0 = off) */
    uint32_t shadow_cascades;      /* --shadow-cascades, layers per shadowed sun (1..4, default 4) */
    bool no_specular;              /* --no-specular: no sky reflections */
    bool no_renorm;                /* --no-renorm: sky specular not scaled by probe / sky irradiance */
    bool no_sky;                   /* --no-sky: ignore the glTF's sky */
    const char *write_brdf_lut;    /* --write-brdf-lut PATH: write the split-sum LUT and exit */
    bool look;                     /* --look FROM_X FROM_Y FROM_Z AT_X AT_Y AT_Z: free camera (0.8 rad fov) */
    float look_from[3], look_at[3];
} sv_options;

/* Camera for the first frame: --camera, else the first glTF camera, else one framing the scene
 * bounds from +Z and a little above. False (with a message) if --camera names no camera. */
bool sv_app_initial_view(const sv_options *opt, const sv_scene *scene, sv_view *view);

/* Prints `object <i> '<name>' probe <buffer index> center (x, y, z)` per object; for a probe
 * interpolated from a version 3 grid (a per-object slot) a second line
 * `  grid <g> weights <n>: <index>:<w> ...`. */
void sv_app_print_assignments(const sv_scene *scene, const sv_probes *probes);

/* Checks the validation counters; prints a summary and returns false if any message was seen. */
bool sv_app_validation_clean(const sv_context *ctx);

/* The renderer description for the options and the loaded sky. */
sv_renderer_desc sv_app_renderer_desc(const sv_options *opt, const sv_sky *sky);

/* What both front ends set up the same way: context, one command buffer + fence, the renderer and
 * the first view. */
typedef struct sv_app_gpu {
    sv_context ctx;
    sv_renderer renderer;
    VkCommandBuffer cmd;
    VkFence fence;
    sv_view view;
    double setup_ms, upload_ms; /* Vulkan setup, scene upload */
} sv_app_gpu;

/* Instance (with `extensions`), then make_surface (window; NULL headless), device, command pool,
 * command buffer and fence (created signalled when asked). False with a message on failure; call
 * sv_app_gpu_destroy anyway. */
bool sv_app_gpu_init(sv_app_gpu *gpu, const sv_options *opt, const char *const *extensions, uint32_t extension_count,
                     bool (*make_surface)(sv_context *ctx, void *user), void *user, bool fence_signaled);
/* The renderer for `format` at width x height, and gpu->view from the options. */
bool sv_app_gpu_renderer(sv_app_gpu *gpu, const sv_options *opt, const sv_scene *scene, const sv_probes *probes,
                         const sv_sky *sky, VkFormat format, uint32_t width, uint32_t height);
/* Waits for the device, destroys the renderer, fence and context (the caller destroys its own
 * objects first); returns rc, or 3 when rc is 0 but validation reported messages. */
int sv_app_gpu_destroy(sv_app_gpu *gpu, int rc);

/* The front ends (sv_headless.c, sv_window.c); exit status as documented in docs/engine.md. */
int sv_run_headless(const sv_options *opt, sv_scene *scene, sv_probes *probes, const sv_sky *sky);
int sv_run_window(const sv_options *opt, sv_scene *scene, sv_probes *probes, const sv_sky *sky);

#endif
