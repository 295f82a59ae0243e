/* The engine's own glTF extensions (DESIGN.md §5, docs/export.md), parsed from the raw extension
 * JSON the generic loader hands over (sv_gltf_extension), outside the loader:
 *   scene   VULKAN_SCHNEE_engine_properties: shProbeGrids[] and sky
 *   material VULKAN_SCHNEE_materials: shScale, ambientTerm, probeMode, probeRepresentation
 *   light   VULKAN_SCHNEE_light: mode, intensityScale
 *   node    VULKAN_SCHNEE_node: probeMode, probeRepresentation (the object's own, over its materials')
 *
 *   sv_gltf_desc desc = {.app_extensions = sv_ext_names, .app_extension_count = SV_EXT_NAME_COUNT};
 *   sv_gltf_load_file(path, &desc, &g, &err);
 *   sv_ext ext; if (sv_ext_parse(g, &ext, &err) != SV_GLTF_SUCCESS) ... err.message names the element
 *   ... ext.materials[i], ext.light_modes[i], ext.probe_grids, ext.sky, ext.warnings ...
 *   sv_ext_free(&ext);
 *
 * A malformed material or light extension is an error (the message names the element); a malformed
 * node field (docs/export.md "Node") is a warning and the node follows its materials; a malformed
 * shProbeGrids entry or sky is skipped with a warning (the rest of the scene still renders and falls
 * back to probe 0 there, DESIGN.md §7). Probe-grid and sky URIs resolve with sv_gltf_resolve_uri.
 */
#ifndef SCHNEE_SV_EXT_H
#define SCHNEE_SV_EXT_H

#include "sv_gltf.h"

#define SV_EXT_NAME_COUNT 4u
/* "VULKAN_SCHNEE_engine_properties", "VULKAN_SCHNEE_materials", "VULKAN_SCHNEE_light",
 * "VULKAN_SCHNEE_node". */
extern const char *const sv_ext_names[SV_EXT_NAME_COUNT];

/* VULKAN_SCHNEE_materials defaults (also those of a material without the extension and of the glTF
 * default material). */
#define SV_EXT_DEFAULT_SH_SCALE     1.0f
#define SV_EXT_DEFAULT_AMBIENT_TERM 0.1f

/* VULKAN_SCHNEE_light.mode: whether the bake already holds the light. A light without the
 * extension is realtime (a glTF from another tool has no baked probes holding its light). */
typedef enum sv_light_mode {
    SV_LIGHT_MODE_REALTIME = 0, /* "realtime": left out of the bake; always direct light */
    SV_LIGHT_MODE_BAKED,        /* "baked": in the probes; direct light only where no probe lights a surface */
    SV_LIGHT_MODE_MIXED,        /* "mixed": its bounced light is in the probes, its direct light is not: always
                                   direct light, shadowed (docs/engine.md "Shadows") */
} sv_light_mode;

typedef struct sv_ext_material {
    bool present;                  /* the material has VULKAN_SCHNEE_materials */
    float sh_scale;                /* default SV_EXT_DEFAULT_SH_SCALE */
    float ambient_term;            /* default SV_EXT_DEFAULT_AMBIENT_TERM */
    uint32_t probe_mode;           /* SV_PROBE_MODE_OFF/OBJECT/PIXEL (shaders/sv_gpu.h), default OBJECT */
    uint32_t probe_representation; /* SV_PROBE_REP_SH/AMBIENT_CUBE (shaders/sv_gpu.h), default SH */
} sv_ext_material;

/* nodes[i].extensions.VULKAN_SCHNEE_node (docs/export.md "Node: VULKAN_SCHNEE_node"): the object's
 * own probe mode and representation, which replace its materials' for the node's mesh primitives.
 * A field that is absent, or whose value is not understood (a warning says so), is _MATERIAL. */
typedef struct sv_ext_node {
    uint32_t probe_mode;           /* SV_PROBE_MODE_OFF/OBJECT/PIXEL, or SV_PROBE_MODE_MATERIAL = as its materials */
    uint32_t probe_representation; /* SV_PROBE_REP_SH/AMBIENT_CUBE, or SV_PROBE_REP_MATERIAL = as its materials */
} sv_ext_node;

/* scenes[scene].extensions.VULKAN_SCHNEE_engine_properties.shProbeGrids[i]. */
typedef struct sv_ext_probe_grid {
    char *name; /* "" when absent */
    char *uri;  /* as written in the file */
    char *path; /* resolved (sv_gltf_resolve_uri); NULL without a base directory (a warning says so) */
    uint32_t probe_count;
    uint32_t max_band;
    float grid_origin[3];
    uint32_t grid_dims[3];
    float grid_spacing;
    float grid_axes[3][3]; /* rows = X, Y, Z axis; identity when absent */
    /* docs/ambient-cube.md §4 "glTF" and docs/engine.md: what the file holds (.shprobe v3 header
     * fields), compared with the file like the fields above. Absent = the version 1/2 values. */
    uint32_t representation; /* "sh" (default) = 0, "ambientCube" = 1 (pb_shprobe_representation) */
    uint32_t storage;        /* "float32" (default) = 0, "float16" = 1 (pb_shprobe_storage) */
    uint32_t structure;      /* "grid" (default) = 0, "octree" = 1, "tetrahedra" = 2 (pb_shprobe_structure) */
} sv_ext_probe_grid;

/* Names of the entry's representation / storage / structure values (index = the value), NULL past
 * the end; the same strings the exporter writes (docs/ambient-cube.md §4). */
const char *sv_ext_grid_representation_name(uint32_t v);
const char *sv_ext_grid_storage_name(uint32_t v);
const char *sv_ext_grid_structure_name(uint32_t v);

/* ...VULKAN_SCHNEE_engine_properties.sky: the world captured by the bake (equirect HDR + its
 * radiance SH, engine space). */
typedef struct sv_ext_sky {
    bool present;
    char *uri;         /* as written */
    char *path;        /* resolved like a grid's uri */
    uint32_t max_band; /* 0..4, the band of sh */
    float sh[25][3];   /* radiance projection L_i, RGB; entries past the band are 0 */
} sv_ext_sky;

typedef struct sv_ext {
    sv_ext_material *materials; /* one per glTF material */
    uint32_t material_count;
    sv_light_mode *light_modes; /* one per KHR_lights_punctual light */
    float *light_scales;        /* one per light: VULKAN_SCHNEE_light.intensityScale (default 1) */
    uint32_t light_count;
    sv_ext_node *nodes; /* one per glTF node (_MATERIAL fields without the extension) */
    uint32_t node_count;
    sv_ext_probe_grid *probe_grids;
    uint32_t probe_grid_count;
    sv_ext_sky sky;
    char **warnings; /* skipped grid entries / sky, unresolved URIs */
    uint32_t warning_count;
} sv_ext;

/* Parses the extensions of a loaded glTF. On failure *out is empty (nothing to free) and err holds
 * the first error (SV_GLTF_ERROR_FORMAT, or _OUT_OF_MEMORY, or the resolver's code for a URI). */
sv_gltf_result sv_ext_parse(const sv_gltf *gltf, sv_ext *out, sv_gltf_error *err);
void sv_ext_free(sv_ext *ext);

#endif
