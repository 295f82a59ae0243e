/* Schnee viewer — glTF 2.0 loader (`.gltf` + `.glb`), decoded to engine-ready data.
 *
 * How to use it:
 *   1. sv_gltf_desc desc = {0};             zero = defaults (see each field)
 *   2. sv_gltf *g = NULL; sv_gltf_error err = {0};
 *      if (sv_gltf_load_file("scene.gltf", &desc, &g, &err) != SV_GLTF_SUCCESS)
 *          fprintf(stderr, "%s\n", err.message);   e.g. "accessors[3]: bufferView 7 out of range"
 *   3. draw g->mesh_instances[i]: mesh g->meshes[inst.mesh], world matrix inst.world; each
 *      primitive has float positions/normals/texcoords and uint32 triangle-list indices, so the
 *      renderer needs no accessor logic. Print g->warnings (things skipped, not fatal).
 *   4. sv_gltf_free(g)                       frees everything the handle owns.
 *
 * Conventions: glTF is right-handed Y-up, which is engine space (DESIGN.md §2): nothing is
 * converted. Matrices are float[16] column-major as in glTF (element (row r, col c) at m[c*4 + r]),
 * mapping node-local to world. Distances in metres, angles in radians. Indices into the handle's
 * arrays are int32_t with -1 meaning "none". Strings are UTF-8, NUL-terminated, owned by the handle;
 * a missing "name" is the empty string "", never NULL.
 * Every index, offset, length, count and stride of the file is validated against the buffers with
 * overflow-safe arithmetic; malformed input returns an error naming the broken element and never
 * reads out of bounds. The loader has no global state and reads no file outside those the glTF
 * names (buffers; image files are only resolved to paths, not read). Supported and refused
 * features are listed in docs/gltf-loader.md.
 *
 * Extensions: the loader parses the glTF core and the KHR extensions it lists as supported; every
 * other extension object of a material, a light, a node, the default scene or the root is handed to
 * the application as raw JSON text (sv_gltf_extension, as cgltf does), for the application to parse
 * (the engine's VULKAN_SCHNEE_* parser is engine/ext/sv_ext.h). URIs inside such JSON resolve with
 * sv_gltf_resolve_uri, by the same rules as buffers and images.
 */
#ifndef SCHNEE_SV_GLTF_H
#define SCHNEE_SV_GLTF_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sv_gltf_result {
    SV_GLTF_SUCCESS = 0,
    SV_GLTF_ERROR_INVALID_ARGUMENT, /* NULL path/output, bad desc */
    SV_GLTF_ERROR_IO,               /* the file or an external buffer cannot be opened or read, or is
                                       not a regular file (FIFO, device, directory, symlink loop) */
    SV_GLTF_ERROR_JSON,             /* not parseable JSON (or GLB JSON chunk not JSON) */
    SV_GLTF_ERROR_FORMAT,           /* malformed glTF/GLB: bad index, range, type, count, ... */
    SV_GLTF_ERROR_UNSUPPORTED,      /* valid glTF this loader refuses (unknown required extension,
                                       glTF major version != 2, external URI without base dir) */
    SV_GLTF_ERROR_TOO_LARGE,        /* over desc.max_decoded_bytes */
    SV_GLTF_ERROR_OUT_OF_MEMORY,
    SV_GLTF_ERROR_OUTSIDE, /* a referenced file lies outside the glTF's folder tree (an absolute path,
                              '..' above it, or a symlink leading out); desc.allow_outside_paths */
    SV_GLTF_RESULT_COUNT_
} sv_gltf_result;

/* First error of a load with a human-readable detail. Zero-initialise before use. */
typedef struct sv_gltf_error {
    sv_gltf_result code;
    char message[512];
} sv_gltf_error;

/* Load options. Zero-initialised = defaults. */
typedef struct sv_gltf_desc {
    const char *base_dir;              /* sv_gltf_load_memory only: folder that relative URIs (buffers,
                                   images, sv_gltf_resolve_uri) resolve against. NULL = external
                                   buffers are refused (SV_GLTF_ERROR_UNSUPPORTED), image paths
                                   stay NULL with a warning; data: URIs and GLB chunks still
                                   work. sv_gltf_load_file uses the file's own folder. */
    uint64_t max_decoded_bytes;        /* cap on all buffers read + all decoded arrays together;
                                   0 = 4 GiB. Exceeding it is SV_GLTF_ERROR_TOO_LARGE. */
    bool keep_shared_normals;          /* default false: a primitive without NORMAL gets flat normals
                                   (vertices un-welded per triangle, as the glTF spec requires);
                                   true: normals stay NULL and the renderer decides. */
    bool non_triangles_are_errors;     /* default false: POINTS/LINES* primitives are skipped with a
                                      warning; true: they are SV_GLTF_ERROR_UNSUPPORTED. Triangle
                                      strips and fans are always converted to lists. */
    bool allow_outside_paths;          /* default false: every URI must stay inside base_dir's tree
                                          (no absolute path, no '..' above it, no symlink leading
                                          out: SV_GLTF_ERROR_OUTSIDE); true for trusted scenes */
    const char *const *app_extensions; /* extensions the application parses itself from the raw
                                          JSON: accepted in extensionsRequired. NULL = none. */
    uint32_t app_extension_count;
} sv_gltf_desc;

/* An extension object the loader does not parse: its name and the object as compact JSON text
 * (e.g. name "VULKAN_SCHNEE_materials", json "{\"shScale\":2}"). Owned by the handle. */
typedef struct sv_gltf_extension {
    char *name;
    char *json;
} sv_gltf_extension;

typedef enum sv_gltf_alpha_mode {
    SV_GLTF_ALPHA_OPAQUE = 0,
    SV_GLTF_ALPHA_MASK,
    SV_GLTF_ALPHA_BLEND,
} sv_gltf_alpha_mode;

/* A material's reference to a texture. texture = -1: none (the other fields then hold defaults). */
typedef struct sv_gltf_texture_ref {
    int32_t texture;   /* index into sv_gltf.textures, or -1 */
    uint32_t texcoord; /* which TEXCOORD_n set (0 or 1 are decoded; others are warned about) */
    float scale;       /* normalTexture.scale / occlusionTexture.strength; 1 otherwise */
} sv_gltf_texture_ref;

typedef struct sv_gltf_material {
    char *name;
    float base_color_factor[4];                     /* linear RGBA, default (1,1,1,1) */
    sv_gltf_texture_ref base_color_texture;         /* sRGB-encoded texture */
    float metallic_factor;                          /* default 1 */
    float roughness_factor;                         /* default 1 */
    sv_gltf_texture_ref metallic_roughness_texture; /* G = roughness, B = metallic */
    sv_gltf_texture_ref normal_texture;
    sv_gltf_texture_ref occlusion_texture;
    float emissive_factor[3]; /* linear RGB, default (0,0,0) */
    float emissive_strength;  /* KHR_materials_emissive_strength, default 1 */
    sv_gltf_texture_ref emissive_texture;
    sv_gltf_alpha_mode alpha_mode; /* default OPAQUE */
    float alpha_cutoff;            /* default 0.5 (used only by MASK) */
    bool double_sided;             /* default false */
    sv_gltf_extension *extensions; /* other than KHR_materials_emissive_strength */
    uint32_t extension_count;
} sv_gltf_material;

typedef struct sv_gltf_sampler {
    uint32_t mag_filter; /* GL enum (9728 NEAREST, 9729 LINEAR), 0 = unspecified */
    uint32_t min_filter; /* GL enum (9728..9987), 0 = unspecified */
    uint32_t wrap_s;     /* GL enum: 33071 CLAMP_TO_EDGE, 33648 MIRRORED_REPEAT, 10497 REPEAT (default) */
    uint32_t wrap_t;
} sv_gltf_sampler;

typedef struct sv_gltf_image {
    char *name;
    char *path;          /* resolved file path of an external image (percent-decoded uri, relative
                              to the glTF's folder), or NULL when the image is embedded (or, loaded
                              from memory without desc.base_dir, unresolved: a warning says so) */
    const uint8_t *data; /* embedded bytes (bufferView or data: URI), or NULL; owned by the handle */
    size_t size;         /* bytes at data */
    char *mime_type;     /* "image/png", "image/jpeg", ... or "" when not given */
} sv_gltf_image;

typedef struct sv_gltf_texture {
    char *name;
    int32_t image;   /* index into images, or -1 (e.g. only an unsupported extension source) */
    int32_t sampler; /* index into samplers, or -1 = default sampler (repeat, linear) */
} sv_gltf_texture;

/* One triangle-list primitive, decoded. Every array has vertex_count elements (of 2, 3 or 4 floats);
 * normalized integer attributes are converted to float per the glTF spec. */
typedef struct sv_gltf_primitive {
    uint32_t vertex_count;
    float *positions;       /* xyz, mesh-local, always present */
    float *normals;         /* xyz, or NULL when absent and desc.keep_shared_normals */
    bool normals_generated; /* normals were computed (flat) because the file had none */
    float *tangents;        /* xyzw (w = bitangent sign), or NULL */
    float *texcoords0;      /* uv, or NULL */
    float *texcoords1;      /* uv, or NULL */
    float *colors0;         /* rgba linear (RGB sources get a = 1), or NULL */
    uint32_t index_count;   /* multiple of 3 */
    uint32_t *indices;      /* always present (0..n-1 generated when the file has none); each < vertex_count */
    int32_t material;       /* index into materials, or -1 = default material */
    float aabb_min[3];      /* mesh-local bounds of the decoded positions */
    float aabb_max[3];
} sv_gltf_primitive;

typedef struct sv_gltf_mesh {
    char *name;
    sv_gltf_primitive *primitives; /* only triangle primitives that decoded; may be 0 of them */
    uint32_t primitive_count;
    float aabb_min[3]; /* union of the primitives' bounds (min > max when empty) */
    float aabb_max[3];
} sv_gltf_mesh;

typedef struct sv_gltf_node {
    char *name;
    int32_t parent;     /* -1 for a root */
    uint32_t *children; /* child node indices */
    uint32_t child_count;
    int32_t mesh;         /* -1 none */
    int32_t camera;       /* -1 none */
    int32_t light;        /* KHR_lights_punctual light index, -1 none */
    float translation[3]; /* TRS as in the file (identity when the node uses "matrix") */
    float rotation[4];    /* unit quaternion x, y, z, w */
    float scale[3];
    bool has_matrix;               /* the file gave "matrix" instead of TRS */
    float local[16];               /* local transform (from matrix or T*R*S), column-major */
    float world[16];               /* parent chain product, column-major; computed for every node */
    bool in_scene;                 /* reachable from the default scene */
    sv_gltf_extension *extensions; /* the node's, other than KHR_lights_punctual */
    uint32_t extension_count;
} sv_gltf_node;

typedef enum sv_gltf_camera_type {
    SV_GLTF_CAMERA_PERSPECTIVE = 0,
    SV_GLTF_CAMERA_ORTHOGRAPHIC,
} sv_gltf_camera_type;

typedef struct sv_gltf_camera {
    char *name;
    sv_gltf_camera_type type;
    float yfov;         /* perspective: vertical field of view, radians */
    float aspect_ratio; /* perspective: width / height, 0 = unspecified (use the viewport's) */
    float xmag, ymag;   /* orthographic: half extents, metres */
    float znear;        /* metres */
    float zfar;         /* metres; 0 = infinite (perspective only) */
} sv_gltf_camera;

typedef enum sv_gltf_light_type {
    SV_GLTF_LIGHT_DIRECTIONAL = 0,
    SV_GLTF_LIGHT_POINT,
    SV_GLTF_LIGHT_SPOT,
} sv_gltf_light_type;

typedef struct sv_gltf_light {
    char *name;
    sv_gltf_light_type type;
    float color[3];                /* linear RGB, default (1,1,1) */
    float intensity;               /* directional: lux; point/spot: candela; default 1 */
    float range;                   /* metres, 0 = infinite (the default) */
    float inner_cone_angle;        /* spot: radians, default 0 */
    float outer_cone_angle;        /* spot: radians, default pi/4 */
    sv_gltf_extension *extensions; /* the light's extensions */
    uint32_t extension_count;
} sv_gltf_light;

/* Instances: one per node of the default scene that uses a mesh / camera / light. */
typedef struct sv_gltf_mesh_instance {
    uint32_t node;
    uint32_t mesh;
    float world[16];   /* = nodes[node].world */
    float aabb_min[3]; /* world-space AABB of the mesh's bounds under world (8 corners transformed) */
    float aabb_max[3];
} sv_gltf_mesh_instance;

typedef struct sv_gltf_camera_instance {
    uint32_t node;
    uint32_t camera;
    float world[16]; /* camera-to-world; the camera looks along its local -Z, up +Y */
} sv_gltf_camera_instance;

typedef struct sv_gltf_light_instance {
    uint32_t node;
    uint32_t light;
    float world[16];
    float position[3];  /* world-space origin of the node */
    float direction[3]; /* world-space unit direction the light points (node's local -Z) */
} sv_gltf_light_instance;

typedef struct sv_gltf {
    int32_t scene; /* default scene ("scene", else 0), -1 when the file has no scenes */
    char *scene_name;

    sv_gltf_mesh *meshes;
    uint32_t mesh_count;
    sv_gltf_material *materials;
    uint32_t material_count;
    sv_gltf_texture *textures;
    uint32_t texture_count;
    sv_gltf_image *images;
    uint32_t image_count;
    sv_gltf_sampler *samplers;
    uint32_t sampler_count;
    sv_gltf_node *nodes;
    uint32_t node_count;
    sv_gltf_camera *cameras;
    uint32_t camera_count;
    sv_gltf_light *lights;
    uint32_t light_count;

    /* Flattened default scene, in depth-first node order. */
    sv_gltf_mesh_instance *mesh_instances;
    uint32_t mesh_instance_count;
    sv_gltf_camera_instance *camera_instances;
    uint32_t camera_instance_count;
    sv_gltf_light_instance *light_instances;
    uint32_t light_instance_count;
    float scene_aabb_min[3]; /* union of mesh_instances' AABBs (min > max when none) */
    float scene_aabb_max[3];

    sv_gltf_extension *scene_extensions; /* the default scene's extensions */
    uint32_t scene_extension_count;
    sv_gltf_extension *extensions; /* the root's, other than KHR_lights_punctual */
    uint32_t extension_count;

    char **warnings;
    uint32_t warning_count; /* non-fatal, e.g. skipped primitives */
    char *base_dir;         /* folder URIs were resolved against, or NULL */

    struct sv_gltf_internal_ *internal_; /* private: owned buffers */
} sv_gltf;

/* Loads a .gltf (JSON; buffers from external files or data: URIs) or .glb (detected by its magic,
 * not the extension). On success *out owns everything; on failure *out is NULL and err (if non-NULL)
 * holds the first error. */
sv_gltf_result sv_gltf_load_file(const char *path, const sv_gltf_desc *desc, sv_gltf **out, sv_gltf_error *err);

/* Same from bytes in memory (JSON or GLB, detected by magic). The bytes are copied as needed;
 * the caller may free them afterwards. External URIs need desc->base_dir. */
sv_gltf_result sv_gltf_load_memory(const void *data, size_t size, const sv_gltf_desc *desc, sv_gltf **out,
                                   sv_gltf_error *err);

/* Resolves a relative URI found in the file (e.g. in an application extension) to a file path by
 * the loader's rules for buffers: percent-decoded (a '%' without two hex digits stays literal and
 * sets *literal_percent, which may be NULL, for the caller to warn), no scheme, against
 * g->base_dir and inside its tree unless the load allowed outside paths. On success *path is
 * malloc'ed (caller frees), or NULL when the handle has no base directory (loaded from memory
 * without desc.base_dir: the caller decides; nothing is an error then). `what` prefixes the
 * error message. */
sv_gltf_result sv_gltf_resolve_uri(const sv_gltf *gltf, const char *uri, const char *what, char **path,
                                   bool *literal_percent, sv_gltf_error *err);

/* A .gltf (JSON) file larger than this is refused (SV_GLTF_ERROR_TOO_LARGE); a GLB is bounded by
 * its header's length and desc.max_decoded_bytes. */
#define SV_GLTF_MAX_JSON_BYTES (512ull << 20)

/* Opens a file for reading the way the loader opens every referenced file: without blocking
 * (O_NONBLOCK, so a FIFO cannot hang the open), then checked on the descriptor (fstat): only a
 * regular file of at most max_bytes (0 = no limit) is accepted; a FIFO, device, directory or
 * symlink loop is SV_GLTF_ERROR_IO, a larger file SV_GLTF_ERROR_TOO_LARGE, each with a message
 * naming `what` and the path (never the file's content). Returns the descriptor (caller closes)
 * and *size, or -1. */
int sv_gltf_open_regular(const char *path, const char *what, uint64_t max_bytes, uint64_t *size, sv_gltf_error *err);

/* Raw JSON of extension `name` in a list, or NULL. */
const char *sv_gltf_find_extension(const sv_gltf_extension *ext, uint32_t count, const char *name);

/* Frees the handle and everything it owns. NULL is allowed. */
void sv_gltf_free(sv_gltf *gltf);

/* Static English name of a result code. */
const char *sv_gltf_result_string(sv_gltf_result result);

/* Index into camera_instances of the first camera whose node name or camera name equals `name`,
 * or -1. */
int32_t sv_gltf_find_camera(const sv_gltf *gltf, const char *name);

#ifdef __cplusplus
}
#endif
#endif
