/* schnee-view: plays back a Schnee-probes glTF export (scene + baked SH probes) with Vulkan.
 * Command line: see usage() and docs/engine.md. */
#define _DEFAULT_SOURCE /* clock_gettime, mkstemps, strcasecmp under -std=c11 */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "schnee/pb_image.h"
#include "sv_app.h"
#include "sv_clock.h"
#include "sv_gpu_brick_view.h"

static void usage(FILE *f)
{
    char modes[128] = ""; /* "off|object|pixel|material" from the one table (shaders/sv_gpu.h) */
    for (uint32_t m = 0; m < SV_PROBE_MODE_COUNT; ++m)
        snprintf(modes + strlen(modes), sizeof(modes) - strlen(modes), "%s%s", m ? "|" : "", sv_probe_mode_name(m));
    fprintf(
        f,
        "usage: schnee-view SCENE.gltf|.glb [options]\n"
        "  --headless               render offscreen and write --output (no window)\n"
        "  --output PATH            headless output: .png/.jpg (tone mapped, sRGB) or .exr/.pfm (linear, before tone mapping)\n"
        "  --width W --height H     frame size (default 960x540)\n"
        "  --camera NAME            camera node or camera name (default: first camera, else frame the scene)\n"
        "  --exposure E             linear exposure multiplier before tone mapping (default 1)\n"
        "  --tonemap neutral|aces|none  operator (default neutral = Khronos PBR Neutral); --no-tonemap = none\n"
        "  --debug none|probe-color|probe-index|normals|brick-level|brick-validity  debug view (probe-index writes\n"
        "                           the index in R; brick-level / brick-validity, with --probe-path bricks: the\n"
        "                           level of the brick each pixel samples / the D of its sample, as --brick-view)\n"
        "  --no-direct              skip KHR_lights_punctual direct light, baked, mixed or realtime (probe +\n"
        "                           ambient + emission only; a baked light adds direct light only where no probe\n"
        "                           lights)\n"
        "  --probe-view             probe view: a small sphere per probe shaded with its SH + grid cell outlines\n"
        "                           (--probe-cells is the same)\n"
        "  --brick-view cells|texels|validity  with --probe-path bricks, the probe view shows the probe bricks\n"
        "                           (implies --probe-view): cells = one box per brick (colour by level: cyan 0,\n"
        "                           green 1, orange 2, pink 3, violet 4, white 5+) + the probe spheres (default);\n"
        "                           texels = the boxes + every brick texel as a sphere shaded with its N/D (magenta:\n"
        "                           D = 0, no probe; red tint: 0 < D < 1); validity = the texels coloured by D\n"
        "  --probe-mode %s  probe lighting for every material (default material =\n"
        "                           each material's VULKAN_SCHNEE_materials.probeMode, itself default object)\n"
        "  --probe-representation sh|ambientCube|material  how every material evaluates its probe (default\n"
        "                           material = each material's VULKAN_SCHNEE_materials.probeRepresentation,\n"
        "                           itself default sh); ambientCube = the cube fitted to each probe's SH\n"
        "  --probe-storage float|half  GPU storage of the SH coefficients and ambient cubes (default float)\n"
        "  --probe-path buffers|bricks  per-pixel probe lighting from probe bricks in 3D textures, hardware-filtered\n"
        "                           (default; octree, kd-tree and dense SH grids, back faces and visibility as the\n"
        "                           buffers; ambient cubes and tetrahedra keep the buffers; a device that cannot\n"
        "                           hold or filter them: a warning and the buffers) or from the storage buffers (the\n"
        "                           reference: the leaf search; docs/engine.md \"Probe bricks\")\n"
        "  --shader-loops auto|plain|unrolled  the scene shader's channel-group loops: unrolled (GPUs) or plain\n"
        "                           (CPU devices such as lavapipe, where unrolled is slower); default auto by the\n"
        "                           device type (docs/engine.md \"Probe bricks\")\n"
        "  --probe-pass auto|fragment|compute  where per-pixel probes are shaded: once per pixel in a compute\n"
        "                           pass after the scene pass (compute; auto = compute) or in the scene pass's\n"
        "                           fragment shader, every fragment drawn (docs/engine.md \"The per-pixel probe pass\")\n"
        "  --normal-bias B          per-pixel: move the sample point B grid spacings along the normal (default 0)\n"
        "  --shadow-res N           texels per side of each shadow map layer of a mixed/realtime light (a sun:\n"
        "                           one per cascade, a spot: one, a point light: six; default %u; at most %u;\n"
        "                           0 = no shadows)\n"
        "  --shadow-cascades N      shadow map layers (cascades) per mixed/realtime sun, each around a slice of\n"
        "                           the view's depth (1..%u, default %u; 1 = one map over the whole scene)\n"
        "  --no-sky                 ignore the scene's sky (no background, no specular, constant fallback)\n"
        "  --no-specular            no specular: no sky reflections, no lights' lobe (diffuse only)\n"
        "  --no-renorm              do not scale sky reflections by probe / sky irradiance\n"
        "  --look FX FY FZ AX AY AZ  camera at F looking at A (0.8 rad vertical fov) instead of the scene's\n"
        "  --write-brdf-lut PATH    write the engine's split-sum BRDF LUT (R = A, G = B) to PATH and exit\n"
        "  --write-sky-mips PREFIX  write the scene sky's GGX-prefiltered mips as PREFIX<level>.exr and exit\n"
        "  --fallback-radiance V    uniform radiance of fallback probe 0 (default %.2f)\n"
        "  --move NODE X Y Z        set a node's translation before rendering (objects are re-assigned)\n"
        "  --print-assignments      print each object's probe index and exit status as usual\n"
        "  --validation             enable VK_LAYER_KHRONOS_validation; any message fails the run (exit 3)\n"
        "  --allow-outside-paths    let the glTF reference files outside its folder tree (absolute paths, '..',\n"
        "                           symlinks leading out); only for scenes you trust\n"
        "  --frames N               headless: frames to render and time; window: quit after N frames\n"
        "  --screenshot PATH        window: write the last frame presented to PATH\n"
        "window keys: WASD/QE move, right mouse drag looks, Shift faster, P probe colours, C probe view,\n"
        "             B brick view (cycles cells, texels, validity; --probe-path bricks),\n"
        "             M probe mode (cycles material, object, pixel, off),\n"
        "             N next object, J/L/I/K/U/O move it (its probe is re-queried), Esc quits\n",
        modes, SV_SHADOW_DEFAULT_RES, SV_SHADOW_MAX_RES, SV_MAX_SHADOW_CASCADES, SV_SHADOW_DEFAULT_CASCADES,
        SV_FALLBACK_RADIANCE);
}

static bool parse_float(const char *s, float *out)
{
    char *end = NULL;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v) || fabs(v) > FLT_MAX) return false;
    *out = (float)v;
    return true;
}

static bool parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    char *end = NULL;
    errno = 0;
    unsigned long v = strtoul(s, &end, 10);
    if (errno || end == s || *end || s[0] == '-' || v < lo || v > hi) return false;
    *out = (uint32_t)v;
    return true;
}

/* The command line's options that take values, and how many (the rest are flags, parse_flag). */
static const struct {
    const char *name;
    int values;
} value_options[] = {
    {"--output", 1},         {"-o", 1},
    {"--width", 1},          {"--height", 1},
    {"--camera", 1},         {"--exposure", 1},
    {"--tonemap", 1},        {"--debug", 1},
    {"--probe-mode", 1},     {"--probe-representation", 1},
    {"--probe-storage", 1},  {"--normal-bias", 1},
    {"--shadow-res", 1},     {"--shadow-cascades", 1},
    {"--look", 6},           {"--write-brdf-lut", 1},
    {"--write-sky-mips", 1}, {"--fallback-radiance", 1},
    {"--move", 4},           {"--frames", 1},
    {"--screenshot", 1},     {"--probe-path", 1},
    {"--brick-view", 1},     {"--shader-loops", 1},
    {"--probe-pass", 1},
};

/* The values option `a` takes, 0 when it takes none or is not an option. */
static int option_values(const char *a)
{
    for (size_t k = 0; k < sizeof(value_options) / sizeof(value_options[0]); ++k)
        if (strcmp(a, value_options[k].name) == 0) return value_options[k].values;
    return 0;
}

/* Sets the flag `a` names; false when `a` is not a flag. */
static bool parse_flag(const char *a, sv_options *o)
{
    if (strcmp(a, "--headless") == 0)
        o->headless = true;
    else if (strcmp(a, "--no-tonemap") == 0)
        o->tonemap = SV_TONEMAP_NONE;
    else if (strcmp(a, "--no-direct") == 0)
        o->no_direct = true;
    else if (strcmp(a, "--probe-cells") == 0 || strcmp(a, "--probe-view") == 0)
        o->show_cells = true;
    else if (strcmp(a, "--no-sky") == 0)
        o->no_sky = true;
    else if (strcmp(a, "--no-specular") == 0)
        o->no_specular = true;
    else if (strcmp(a, "--no-renorm") == 0)
        o->no_renorm = true;
    else if (strcmp(a, "--print-assignments") == 0)
        o->print_assignments = true;
    else if (strcmp(a, "--allow-outside-paths") == 0)
        o->allow_outside_paths = true;
    else if (strcmp(a, "--validation") == 0)
        o->validation = true;
    else
        return false;
    return true;
}

/* Prints the usage error of a bad value and returns 2. */
static int bad_value(const char *a, const char *v)
{
    fprintf(stderr, "schnee-view: error: bad value '%s' for %s\n", v, a);
    return 2;
}

/* Options whose value is one of a few names; -1 when `a` is none of them, else 0 or 2 (bad value). */
static int parse_choice(const char *a, const char *v, sv_options *o)
{
    int k;
    if (strcmp(a, "--tonemap") == 0) {
        static const uint32_t ops[] = {SV_TONEMAP_PBR_NEUTRAL, SV_TONEMAP_ACES, SV_TONEMAP_NONE};
        static const char *const names[] = {"neutral", "aces", "none"};
        for (k = 0; k < 3 && strcmp(v, names[k]) != 0; ++k) continue;
        if (k == 3) return bad_value(a, v);
        o->tonemap = ops[k];
    } else if (strcmp(a, "--debug") == 0) {
        static const uint32_t modes[] = {SV_DEBUG_NONE,    SV_DEBUG_PROBE_COLOR, SV_DEBUG_PROBE_INDEX,
                                         SV_DEBUG_NORMALS, SV_DEBUG_BRICK_LEVEL, SV_DEBUG_BRICK_VALIDITY};
        static const char *const names[] = {"none",    "probe-color", "probe-index",
                                            "normals", "brick-level", "brick-validity"};
        for (k = 0; k < 6 && strcmp(v, names[k]) != 0; ++k) continue;
        if (k == 6) return bad_value(a, v);
        o->debug_mode = modes[k];
    } else if (strcmp(a, "--probe-mode") == 0) {
        if ((k = sv_probe_mode_from_name(v, 1)) < 0) return bad_value(a, v);
        o->probe_mode = (uint32_t)k;
    } else if (strcmp(a, "--probe-representation") == 0) {
        if ((k = sv_probe_representation_from_name(v, 1)) < 0) return bad_value(a, v);
        o->probe_representation = (uint32_t)k;
    } else if (strcmp(a, "--probe-storage") == 0) {
        if (strcmp(v, "float") != 0 && strcmp(v, "half") != 0) return bad_value(a, v);
        o->half_probes = strcmp(v, "half") == 0;
    } else if (strcmp(a, "--brick-view") == 0) {
        static const char *const names[SV_BRICK_VIEW_COUNT] = {"cells", "texels", "validity"};
        for (k = 0; k < (int)SV_BRICK_VIEW_COUNT && strcmp(v, names[k]) != 0; ++k) continue;
        if (k == (int)SV_BRICK_VIEW_COUNT) return bad_value(a, v);
        o->brick_view = (uint32_t)k;
        o->show_cells = o->brick_view_given = true;
    } else if (strcmp(a, "--probe-path") == 0) {
        if (strcmp(v, "buffers") != 0 && strcmp(v, "bricks") != 0) return bad_value(a, v);
        o->bricks = strcmp(v, "bricks") == 0;
        o->bricks_given = true;
    } else if (strcmp(a, "--shader-loops") == 0) {
        static const char *const names[3] = {"auto", "plain", "unrolled"}; /* SV_SHADER_LOOPS_* */
        for (k = 0; k < 3 && strcmp(v, names[k]) != 0; ++k) continue;
        if (k == 3) return bad_value(a, v);
        o->shader_loops = (uint32_t)k;
    } else if (strcmp(a, "--probe-pass") == 0) {
        static const char *const names[3] = {"auto", "fragment", "compute"}; /* SV_PROBE_PASS_* */
        for (k = 0; k < 3 && strcmp(v, names[k]) != 0; ++k) continue;
        if (k == 3) return bad_value(a, v);
        o->probe_pass = (uint32_t)k;
    } else {
        return -1;
    }
    return 0;
}

/* The shadow options, whose errors say what the value means. */
static int parse_shadow_option(const char *a, const char *v, sv_options *o)
{
    if (strcmp(a, "--shadow-res") == 0 && !parse_u32(v, 0, SV_SHADOW_MAX_RES, &o->shadow_res)) {
        fprintf(stderr,
                "schnee-view: error: bad value '%s' for --shadow-res (shadow map size in texels, 0 = no shadows, "
                "at most %u)\n",
                v, SV_SHADOW_MAX_RES);
        return 2;
    }
    if (strcmp(a, "--shadow-cascades") == 0 && !parse_u32(v, 1, SV_MAX_SHADOW_CASCADES, &o->shadow_cascades)) {
        fprintf(stderr, "schnee-view: error: bad value '%s' for --shadow-cascades (shadow map layers per sun, 1..%u)\n",
                v, SV_MAX_SHADOW_CASCADES);
        return 2;
    }
    return 0;
}

/* An option with values v[0..option_values(a)): 0, or 2 on a usage error (message printed). */
static int parse_value_option(const char *a, char **v, sv_options *o, const char **write_sky_mips)
{
    int rc = parse_choice(a, v[0], o);
    if (rc >= 0) return rc;
    if (strcmp(a, "--shadow-res") == 0 || strcmp(a, "--shadow-cascades") == 0) return parse_shadow_option(a, v[0], o);
    if (strcmp(a, "--output") == 0 || strcmp(a, "-o") == 0) {
        o->output = v[0];
    } else if (strcmp(a, "--width") == 0 || strcmp(a, "--height") == 0) {
        if (!parse_u32(v[0], 1, 16384, a[2] == 'w' ? &o->width : &o->height)) return bad_value(a, v[0]);
    } else if (strcmp(a, "--camera") == 0) {
        o->camera = v[0];
    } else if (strcmp(a, "--exposure") == 0) {
        if (!parse_float(v[0], &o->exposure) || o->exposure < 0) return bad_value(a, v[0]);
    } else if (strcmp(a, "--normal-bias") == 0) {
        if (!parse_float(v[0], &o->normal_bias) || o->normal_bias < 0 || o->normal_bias > 1) return bad_value(a, v[0]);
    } else if (strcmp(a, "--look") == 0) {
        for (int k = 0; k < 6; ++k)
            if (!parse_float(v[k], k < 3 ? &o->look_from[k] : &o->look_at[k - 3])) return bad_value(a, v[k]);
        o->look = true;
    } else if (strcmp(a, "--write-brdf-lut") == 0) {
        o->write_brdf_lut = v[0];
    } else if (strcmp(a, "--write-sky-mips") == 0) {
        *write_sky_mips = v[0];
    } else if (strcmp(a, "--fallback-radiance") == 0) {
        if (!parse_float(v[0], &o->fallback_radiance) || o->fallback_radiance < 0) return bad_value(a, v[0]);
    } else if (strcmp(a, "--move") == 0) {
        if (o->move_count == SV_MAX_MOVES) {
            fprintf(stderr, "schnee-view: error: at most %d --move options\n", SV_MAX_MOVES);
            return 2;
        }
        sv_move *m = &o->moves[o->move_count++];
        m->node = v[0];
        for (int k = 0; k < 3; ++k)
            if (!parse_float(v[1 + k], &m->translation[k])) return bad_value(a, v[1 + k]);
    } else if (strcmp(a, "--frames") == 0) {
        if (!parse_u32(v[0], 1, 1000000, &o->frames)) return bad_value(a, v[0]);
    } else if (strcmp(a, "--screenshot") == 0) {
        o->screenshot = v[0];
    }
    return 0;
}

/* The defaults of every option (docs/engine.md "Command line"). */
static void default_options(sv_options *o)
{
    memset(o, 0, sizeof(*o));
    o->width = 960;
    o->height = 540;
    o->exposure = 1.0f;
    o->tonemap = SV_TONEMAP_PBR_NEUTRAL;
    o->fallback_radiance = SV_FALLBACK_RADIANCE;
    o->probe_mode = SV_PROBE_MODE_MATERIAL;
    o->probe_representation = SV_PROBE_REP_MATERIAL;
    o->bricks = true; /* --probe-path bricks (issue 30 item 4) */
    o->shadow_res = SV_SHADOW_DEFAULT_RES;
    o->shadow_cascades = SV_SHADOW_DEFAULT_CASCADES;
}

/* Returns 0 on success, 2 on a usage error (message printed). */
/* write_sky_mips: --write-sky-mips PREFIX (a one-shot dump, kept out of sv_options), else NULL. */
static int parse_args(int argc, char **argv, sv_options *o, const char **write_sky_mips)
{
    default_options(o);
    *write_sky_mips = NULL;
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            exit(0);
        }
        if (parse_flag(a, o)) continue;
        int n = option_values(a);
        if (n && i + n >= argc) {
            fprintf(stderr, "schnee-view: error: %s needs %d value(s)\n", a, n);
            return 2;
        }
        if (n) {
            if (parse_value_option(a, argv + i + 1, o, write_sky_mips)) return 2;
            i += n;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "schnee-view: error: unknown option '%s' (see --help)\n", a);
            return 2;
        } else if (!o->scene_path) {
            o->scene_path = a;
        } else {
            fprintf(stderr, "schnee-view: error: more than one scene given ('%s', '%s')\n", o->scene_path, a);
            return 2;
        }
    }
    if (!o->scene_path && !o->write_brdf_lut) {
        usage(stderr);
        return 2;
    }
    if (*write_sky_mips && (!o->scene_path || o->no_sky)) {
        fprintf(stderr, "schnee-view: error: --write-sky-mips needs a scene with a sky (and no --no-sky)\n");
        return 2;
    }
    if (o->brick_view_given && !o->bricks)
        fprintf(stderr, "schnee-view: warning: --brick-view needs --probe-path bricks; the probe view shows the "
                        "probes and cells\n");
    if (o->headless && !o->output && !o->print_assignments) {
        fprintf(stderr, "schnee-view: error: --headless needs --output PATH\n");
        return 2;
    }
    return 0;
}

/* --write-brdf-lut: the table the renderer uploads, as an image (R = A, G = B, B = 0). */
static int write_brdf_lut(const char *path)
{
    float *lut = sv_brdf_lut(SV_BRDF_LUT_SIZE, SV_BRDF_LUT_SAMPLES);
    float *rgb = malloc((size_t)SV_BRDF_LUT_SIZE * SV_BRDF_LUT_SIZE * 3 * sizeof(float));
    int rc = 1;
    if (lut && rgb) {
        /* Row j = roughness (j + 0.5) / size from the top, column i = NoV (i + 0.5) / size. */
        for (size_t t = 0; t < (size_t)SV_BRDF_LUT_SIZE * SV_BRDF_LUT_SIZE; ++t) {
            rgb[t * 3 + 0] = lut[t * 2 + 0];
            rgb[t * 3 + 1] = lut[t * 2 + 1];
            rgb[t * 3 + 2] = 0.0f;
        }
        pb_error err = {0};
        if (pb_image_write(path, SV_BRDF_LUT_SIZE, SV_BRDF_LUT_SIZE, 3, rgb, &err) == PB_SUCCESS)
            rc = 0;
        else
            fprintf(stderr, "schnee-view: error: cannot write %s: %s\n", path, err.message);
    }
    free(lut);
    free(rgb);
    return rc;
}

/* --write-sky-mips: each level of the chain the renderer uploads, RGB, as PREFIX<level>.exr
 * (level 0 = the sky image, level k = GGX-prefiltered at roughness k / (mip_count - 1)). */
static int write_sky_mips(const sv_sky *sky, const char *prefix)
{
    for (uint32_t l = 0; l < sky->mip_count; ++l) {
        size_t n = (size_t)sky->width[l] * sky->height[l];
        float *rgb = malloc(n * 3 * sizeof(float));
        size_t len = strlen(prefix) + 16;
        char *path = malloc(len);
        if (!rgb || !path) {
            free(rgb);
            free(path);
            fprintf(stderr, "schnee-view: error: out of memory writing the sky mips\n");
            return 1;
        }
        snprintf(path, len, "%s%u.exr", prefix, l);
        for (size_t t = 0; t < n; ++t)
            for (int c = 0; c < 3; ++c) rgb[t * 3 + c] = sky->rgba[l][t * 4 + c];
        pb_error err = {0};
        bool ok = pb_image_write(path, sky->width[l], sky->height[l], 3, rgb, &err) == PB_SUCCESS;
        if (!ok)
            fprintf(stderr, "schnee-view: error: cannot write %s: %s\n", path, err.message);
        else
            fprintf(stderr, "schnee-view: wrote %s (%ux%u)\n", path, sky->width[l], sky->height[l]);
        free(rgb);
        free(path);
        if (!ok) return 1;
    }
    return 0;
}

int main(int argc, char **argv)
{
    sv_options opt;
    const char *sky_mips_prefix;
    int rc = parse_args(argc, argv, &opt, &sky_mips_prefix);
    if (rc) return rc;
    if (opt.write_brdf_lut) return write_brdf_lut(opt.write_brdf_lut);

    sv_scene scene;
    sv_probes probes;
    double t0 = sv_now_ms();
    if (!sv_scene_load(opt.scene_path, opt.allow_outside_paths, &scene)) return 1;
    double t1 = sv_now_ms();
    if (!sv_probes_load(&scene.ext, &probes)) {
        sv_scene_destroy(&scene);
        return 1;
    }
    double t2 = sv_now_ms();
    fprintf(stderr,
            "schnee-view: loaded %s: %u object(s), %u probe grid(s), %u probe(s) + fallback; "
            "scene %.1f ms, probes %.1f ms\n",
            opt.scene_path, scene.object_count, probes.grid_count, probes.total - 1, t1 - t0, t2 - t1);

    sv_sky sky = {0};
    if (!opt.no_sky) {
        double ts = sv_now_ms();
        if (!sv_sky_load(&scene.ext, &sky)) {
            rc = 1;
            goto done;
        }
        if (sky.present)
            fprintf(stderr, "schnee-view: sky %s: %ux%u, %u prefiltered mip(s), band %u; %.1f ms\n", scene.ext.sky.path,
                    sky.width[0], sky.height[0], sky.mip_count, sky.max_band, sv_now_ms() - ts);
    }
    if (sky_mips_prefix) {
        if (sky.present)
            rc = write_sky_mips(&sky, sky_mips_prefix);
        else {
            fprintf(stderr, "schnee-view: error: --write-sky-mips: %s has no sky\n", opt.scene_path);
            rc = 1;
        }
        goto done;
    }
    probes.probe_mode_override = opt.probe_mode; /* for the §5 mismatch warning */
    probes.probe_rep_override = opt.probe_representation;
    sv_probes_assign(&probes, &scene);
    for (uint32_t i = 0; i < opt.move_count; ++i) {
        int32_t node = sv_scene_find_node(&scene, opt.moves[i].node);
        if (node < 0) {
            fprintf(stderr, "schnee-view: error: --move: no node named '%s'\n", opt.moves[i].node);
            rc = 2;
            goto done;
        }
        sv_scene_set_translation(&scene, (uint32_t)node, opt.moves[i].translation);
        uint32_t n = sv_probes_assign(&probes, &scene);
        fprintf(stderr, "schnee-view: moved '%s'; %u object(s) re-assigned\n", opt.moves[i].node, n);
    }
    if (opt.print_assignments) sv_app_print_assignments(&scene, &probes);
    if (opt.headless && !opt.output) goto done; /* --print-assignments only */
    rc = opt.headless ? sv_run_headless(&opt, &scene, &probes, &sky) : sv_run_window(&opt, &scene, &probes, &sky);
done:
    sv_sky_destroy(&sky);
    sv_probes_destroy(&probes);
    sv_scene_destroy(&scene);
    return rc;
}
