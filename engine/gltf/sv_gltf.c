/* glTF 2.0 loader: JSON (libcjson) + GLB container, validated and decoded to engine-ready arrays.
 *
 * Order of work: container (GLB or JSON) → asset/extensionsRequired → buffers → bufferViews →
 * accessors (all ranges validated up front) → samplers/images/textures/materials → meshes (decoded)
 * → cameras/lights → nodes (parents, cycles, world matrices) → default scene (instances, raw
 * application extensions). Every allocation hangs off the sv_gltf handle as soon as it is made, so one
 * sv_gltf_free() cleans up after success and after an error at any point.
 */
#include "sv_gltf_internal.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GLB_MAGIC      0x46546C67u /* "glTF" */
#define GLB_CHUNK_JSON 0x4E4F534Au /* "JSON" */
#define GLB_CHUNK_BIN  0x004E4942u /* "BIN\0" */

/* ---------------------------------------------------------------- top level */

static bool check_asset(ctx_ *c, const cJSON *root)
{
    const cJSON *asset, *version, *req;
    if (!svg_get_typed(c, root, "asset", "(root)", cJSON_Object, &asset)) return false;
    if (!asset) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "asset: missing (not a glTF file?)");
        return false;
    }
    if (!svg_get_typed(c, asset, "version", "asset", cJSON_String, &version)) return false;
    if (!version) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "asset.version: missing");
        return false;
    }
    if (strncmp(version->valuestring, "2.", 2) != 0) {
        svg_fail(c, SV_GLTF_ERROR_UNSUPPORTED, "asset.version: '%.20s' is not glTF 2.x", version->valuestring);
        return false;
    }
    if (!svg_get_typed(c, root, "extensionsRequired", "(root)", cJSON_Array, &req)) return false;
    static const char *supported[] = {"KHR_lights_punctual", "KHR_materials_emissive_strength",
                                      "KHR_mesh_quantization"};
    const cJSON *e;
    uint32_t i = 0;
    if (req) cJSON_ArrayForEach(e, req)
        {
            if (!cJSON_IsString(e)) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "extensionsRequired[%u]: expected a string", i);
                return false;
            }
            bool ok = false;
            for (size_t k = 0; k < sizeof supported / sizeof supported[0]; k++)
                ok |= strcmp(e->valuestring, supported[k]) == 0;
            for (uint32_t k = 0; k < c->desc.app_extension_count && c->desc.app_extensions; k++)
                ok |= c->desc.app_extensions[k] && strcmp(e->valuestring, c->desc.app_extensions[k]) == 0;
            if (!ok) {
                svg_fail(c, SV_GLTF_ERROR_UNSUPPORTED, "extensionsRequired: '%.60s' is not supported", e->valuestring);
                return false;
            }
            i++;
        }
    return true;
}

static uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* Splits a GLB into its JSON and BIN chunks (pointers into data). */
static bool parse_glb(ctx_ *c, const uint8_t *data, size_t size, const char **json, size_t *json_size)
{
    if (size < 20) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "GLB: %zu bytes is too short for a header and a chunk", size);
        return false;
    }
    uint32_t version = rd32(data + 4), length = rd32(data + 8);
    if (version != 2) {
        svg_fail(c, SV_GLTF_ERROR_UNSUPPORTED, "GLB: container version %u is not 2", version);
        return false;
    }
    if (length > size || length < 20) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "GLB: header length %u but the data has %zu bytes (truncated?)", length,
                 size);
        return false;
    }
    size_t pos = 12;
    uint32_t index = 0;
    *json = NULL;
    while (pos < length) {
        if (length - pos < 8) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "GLB: chunk %u header truncated at byte %zu", index, pos);
            return false;
        }
        uint32_t clen = rd32(data + pos), ctype = rd32(data + pos + 4);
        pos += 8;
        if (clen > length - pos) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "GLB: chunk %u length %u exceeds the file (%zu bytes left)", index, clen,
                     (size_t)length - pos);
            return false;
        }
        if (index == 0) {
            if (ctype != GLB_CHUNK_JSON) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "GLB: first chunk is not JSON (type 0x%08x)", ctype);
                return false;
            }
            *json = (const char *)data + pos;
            *json_size = clen;
        } else if (index == 1 && ctype == GLB_CHUNK_BIN) {
            c->glb_bin = data + pos;
            c->glb_bin_size = clen;
        } /* other chunks are ignored, as the spec asks */
        pos += clen;
        index++;
    }
    return true;
}

static bool load_document(ctx_ *c, const uint8_t *data, size_t size)
{
    const char *json = (const char *)data;
    size_t json_size = size;
    if (size >= 4 && rd32(data) == GLB_MAGIC) {
        c->is_glb = true;
        if (!parse_glb(c, data, size, &json, &json_size)) return false;
    }
    /* cJSON gets a NUL-terminated copy: its length-bounded parser then cannot read past the chunk
     * even on a parser bug (libcjson is not built with sanitizers). */
    if (!svg_take_budget(c, (uint64_t)json_size + 1, "glTF JSON")) return false;
    char *text = svg_xcalloc(c, (uint64_t)json_size + 1, 1);
    if (!text) return false;
    memcpy(text, json, json_size);
    json = text;
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(json, json_size, &end, false);
    if (!root) {
        size_t at = end && end >= json ? (size_t)(end - json) : 0;
        svg_fail(c, SV_GLTF_ERROR_JSON, "%s: invalid JSON near byte %zu", c->is_glb ? "GLB JSON chunk" : "glTF", at);
        free(text);
        return false;
    }
    for (const char *p = end; p && p < json + json_size; p++)
        if (*p != ' ' && *p != '\t' && *p != '\n' && *p != '\r' && *p != '\0') {
            cJSON_Delete(root);
            svg_fail(c, SV_GLTF_ERROR_JSON, "glTF: trailing data after the JSON value at byte %zu", (size_t)(p - json));
            free(text);
            return false;
        }
    bool ok = true;
    if (!cJSON_IsObject(root)) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "glTF: the JSON root is not an object");
        ok = false;
    }
    ok = ok && check_asset(c, root) && svg_parse_buffers(c, root) && svg_parse_views(c, root) &&
         svg_parse_accessors(c, root) && svg_parse_samplers(c, root) && svg_parse_images(c, root) &&
         svg_parse_textures(c, root) && svg_parse_materials(c, root) && svg_parse_meshes(c, root) &&
         svg_parse_cameras(c, root) && svg_parse_lights(c, root) && svg_parse_nodes(c, root) &&
         svg_parse_scene(c, root);
    static const char *const consumed[] = {"KHR_lights_punctual", NULL};
    ok = ok && svg_get_extensions(c, root, "(root)", consumed, &c->g->extensions, &c->g->extension_count);
    cJSON_Delete(root);
    free(text);
    return ok;
}

static sv_gltf_result load(const uint8_t *data, size_t size, uint8_t *owned, const char *base_dir,
                           const sv_gltf_desc *desc, sv_gltf **out, sv_gltf_error *err, uint64_t already)
{
    ctx_ c = {0};
    c.err = err;
    if (desc) c.desc = *desc;
    if (!c.desc.max_decoded_bytes) c.desc.max_decoded_bytes = 4ull << 30;
    c.budget = c.desc.max_decoded_bytes > already ? c.desc.max_decoded_bytes - already : 0;
    c.g = calloc(1, sizeof *c.g);
    struct sv_gltf_internal_ *in = calloc(1, sizeof *in);
    if (!c.g || !in) {
        free(c.g);
        free(in);
        free(owned);
        return svg_fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    c.g->internal_ = in;
    in->allow_outside_paths = c.desc.allow_outside_paths;
    /* The input stays alive with the handle: GLB BIN chunks and images point into it. */
    if (owned && !svg_own_blob(&c, owned)) {
        sv_gltf_free(c.g);
        return c.result;
    }
    if (base_dir && !(c.g->base_dir = svg_xstrdup(&c, base_dir))) {
        sv_gltf_free(c.g);
        return c.result;
    }
    bool ok = load_document(&c, data, size);
    free(c.buf_data);
    free(c.buf_size);
    free(c.views);
    free(c.accs);
    if (!ok) {
        if (c.result == SV_GLTF_SUCCESS) svg_fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
        sv_gltf_free(c.g);
        return c.result;
    }
    *out = c.g;
    return SV_GLTF_SUCCESS;
}

sv_gltf_result sv_gltf_load_memory(const void *data, size_t size, const sv_gltf_desc *desc, sv_gltf **out,
                                   sv_gltf_error *err)
{
    ctx_ c = {0};
    c.err = err;
    if (!out || (!data && size))
        return svg_fail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_gltf_load_memory: NULL argument");
    *out = NULL;
    /* GLB chunks and embedded images point into the data, so the handle keeps its own copy. */
    uint8_t *copy = malloc(size ? size : 1);
    if (!copy) return svg_fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory (%zu bytes)", size);
    if (size) memcpy(copy, data, size);
    return load(copy, size, copy, desc ? desc->base_dir : NULL, desc, out, err, size);
}

sv_gltf_result sv_gltf_load_file(const char *path, const sv_gltf_desc *desc, sv_gltf **out, sv_gltf_error *err)
{
    ctx_ c = {0};
    c.err = err;
    if (!out || !path) return svg_fail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_gltf_load_file: NULL argument");
    *out = NULL;
    c.desc.max_decoded_bytes = desc && desc->max_decoded_bytes ? desc->max_decoded_bytes : 4ull << 30;
    c.budget = c.desc.max_decoded_bytes;
    sv_gltf tmp = {0};
    c.g = &tmp;
    uint8_t *data;
    uint64_t size;
    if (!svg_read_file(&c, path, 0, path, &data, &size)) return c.result;
    char *dir = svg_path_dirname(path);
    if (!dir) {
        free(data);
        return svg_fail(&c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    sv_gltf_result r = load(data, (size_t)size, data, dir, desc, out, err, size);
    free(dir);
    return r;
}

void sv_gltf_free(sv_gltf *g)
{
    if (!g) return;
    for (uint32_t i = 0; g->meshes && i < g->mesh_count; i++) {
        for (uint32_t p = 0; p < g->meshes[i].primitive_count; p++) svg_free_primitive(&g->meshes[i].primitives[p]);
        free(g->meshes[i].primitives);
        free(g->meshes[i].name);
    }
    free(g->meshes);
    for (uint32_t i = 0; g->materials && i < g->material_count; i++) {
        free(g->materials[i].name);
        svg_free_extensions(g->materials[i].extensions, g->materials[i].extension_count);
    }
    free(g->materials);
    for (uint32_t i = 0; g->textures && i < g->texture_count; i++) free(g->textures[i].name);
    free(g->textures);
    for (uint32_t i = 0; g->images && i < g->image_count; i++) {
        free(g->images[i].name);
        free(g->images[i].path);
        free(g->images[i].mime_type);
    }
    free(g->images);
    free(g->samplers);
    for (uint32_t i = 0; g->nodes && i < g->node_count; i++) {
        free(g->nodes[i].name);
        free(g->nodes[i].children);
        svg_free_extensions(g->nodes[i].extensions, g->nodes[i].extension_count);
    }
    free(g->nodes);
    for (uint32_t i = 0; g->cameras && i < g->camera_count; i++) free(g->cameras[i].name);
    free(g->cameras);
    for (uint32_t i = 0; g->lights && i < g->light_count; i++) {
        free(g->lights[i].name);
        svg_free_extensions(g->lights[i].extensions, g->lights[i].extension_count);
    }
    free(g->lights);
    free(g->mesh_instances);
    free(g->camera_instances);
    free(g->light_instances);
    svg_free_extensions(g->scene_extensions, g->scene_extension_count);
    svg_free_extensions(g->extensions, g->extension_count);
    for (uint32_t i = 0; g->warnings && i < g->warning_count; i++) free(g->warnings[i]);
    free(g->warnings);
    free(g->scene_name);
    free(g->base_dir);
    if (g->internal_) {
        for (uint32_t i = 0; i < g->internal_->blob_count; i++) free(g->internal_->blobs[i]);
        free(g->internal_->blobs);
        free(g->internal_);
    }
    free(g);
}

const char *sv_gltf_result_string(sv_gltf_result r)
{
    switch (r) {
    case SV_GLTF_SUCCESS: return "success";
    case SV_GLTF_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case SV_GLTF_ERROR_IO: return "I/O error";
    case SV_GLTF_ERROR_JSON: return "invalid JSON";
    case SV_GLTF_ERROR_FORMAT: return "malformed glTF";
    case SV_GLTF_ERROR_UNSUPPORTED: return "unsupported glTF feature";
    case SV_GLTF_ERROR_TOO_LARGE: return "too large";
    case SV_GLTF_ERROR_OUT_OF_MEMORY: return "out of memory";
    case SV_GLTF_ERROR_OUTSIDE: return "file outside the glTF's folder";
    default: return "unknown result";
    }
}

int32_t sv_gltf_find_camera(const sv_gltf *g, const char *name)
{
    if (!g || !name) return -1;
    for (uint32_t i = 0; i < g->camera_instance_count; i++) {
        const sv_gltf_camera_instance *ci = &g->camera_instances[i];
        if (strcmp(g->nodes[ci->node].name, name) == 0 || strcmp(g->cameras[ci->camera].name, name) == 0)
            return (int32_t)i;
    }
    return -1;
}

sv_gltf_result sv_gltf_resolve_uri(const sv_gltf *g, const char *uri, const char *what, char **path,
                                   bool *literal_percent, sv_gltf_error *err)
{
    ctx_ c = {0};
    c.err = err;
    if (!path) return svg_fail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_gltf_resolve_uri: NULL argument");
    *path = NULL;
    if (!g || !uri || !what) return svg_fail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_gltf_resolve_uri: NULL argument");
    if (!g->base_dir) return SV_GLTF_SUCCESS;
    c.g = (sv_gltf *)g; /* read only: svg_resolve_uri reads base_dir and never warns here */
    *path = svg_resolve_uri(&c, uri, what, literal_percent);
    return *path ? SV_GLTF_SUCCESS : c.result;
}

const char *sv_gltf_find_extension(const sv_gltf_extension *ext, uint32_t count, const char *name)
{
    for (uint32_t i = 0; ext && name && i < count; i++)
        if (strcmp(ext[i].name, name) == 0) return ext[i].json;
    return NULL;
}
