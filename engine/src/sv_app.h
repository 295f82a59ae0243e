/* schnee-view application layer: command-line options, the initial camera, and the two front
 * ends (headless, window) that share the scene, probes and renderer. */
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
    bool validation; /* enable the validation layer; any message fails the run (exit 3) */
    bool print_assignments;
    bool show_cells;
    sv_move moves[SV_MAX_MOVES];
    uint32_t move_count;
    uint32_t frames;        /* window: quit after this many frames (0 = run until closed);
                                  headless: frames rendered (timed), default 1 */
    const char *screenshot; /* window: write the last presented frame here */
    float fallback_radiance;
    uint32_t probe_mode;        /* SV_PROBE_MODE_*, default _MATERIAL (each material's probeMode) */
    bool half_probes;           /* --probe-storage half */
    float normal_bias;          /* --normal-bias, grid spacings (default 0) */
    bool no_specular;           /* --no-specular: no sky reflections */
    bool no_renorm;             /* --no-renorm: sky specular not scaled by probe / sky irradiance */
    bool no_sky;                /* --no-sky: ignore the glTF's sky */
    const char *write_brdf_lut; /* --write-brdf-lut PATH: write the split-sum LUT and exit */
    bool look;                  /* --look FROM_X FROM_Y FROM_Z AT_X AT_Y AT_Z: free camera (0.8 rad fov) */
    float look_from[3], look_at[3];
} sv_options;

/* Camera for the first frame: --camera, else the first glTF camera, else one framing the scene
 * bounds from +Z and a little above. False (with a message) if --camera names no camera. */
bool sv_app_initial_view(const sv_options *opt, const sv_scene *scene, sv_view *view);

/* Prints one line per object: `object <index> '<name>' probe <buffer index> center (x, y, z)`. */
void sv_app_print_assignments(const sv_scene *scene);

/* Checks the validation counters; prints a summary and returns false if any message was seen. */
bool sv_app_validation_clean(const sv_context *ctx);

int sv_run_headless(const sv_options *opt, sv_scene *scene, sv_probes *probes, const sv_sky *sky);
int sv_run_window(const sv_options *opt, sv_scene *scene, sv_probes *probes, const sv_sky *sky);

/* The renderer description for the options and the loaded sky. */
sv_renderer_desc sv_app_renderer_desc(const sv_options *opt, const sv_sky *sky);

double sv_now_ms(void);

#endif
