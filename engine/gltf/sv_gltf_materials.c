/* Loader: samplers, images, textures, materials. */
#include "sv_gltf_internal.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------- images, textures, materials */

bool svg_parse_samplers(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!svg_top_array(c, root, "samplers", &arr, &count)) return false;
    c->g->samplers = svg_xcalloc(c, count, sizeof *c->g->samplers);
    if (!c->g->samplers) return false;
    c->g->sampler_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "samplers[%u]", i);
        sv_gltf_sampler *s = &c->g->samplers[i];
        uint64_t v[4];
        if (!svg_get_uint(c, j, "magFilter", path, false, 0, 0, UINT32_MAX, &v[0]) ||
            !svg_get_uint(c, j, "minFilter", path, false, 0, 0, UINT32_MAX, &v[1]) ||
            !svg_get_uint(c, j, "wrapS", path, false, 10497, 0, UINT32_MAX, &v[2]) ||
            !svg_get_uint(c, j, "wrapT", path, false, 10497, 0, UINT32_MAX, &v[3]))
            return false;
        if (v[0] && v[0] != 9728 && v[0] != 9729) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.magFilter: %llu is not 9728 or 9729", path, (unsigned long long)v[0]);
            return false;
        }
        if (v[1] && v[1] != 9728 && v[1] != 9729 && !(v[1] >= 9984 && v[1] <= 9987)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.minFilter: %llu is not a glTF filter", path,
                     (unsigned long long)v[1]);
            return false;
        }
        for (int w = 2; w < 4; w++)
            if (v[w] != 33071 && v[w] != 33648 && v[w] != 10497) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.%s: %llu is not 33071, 33648 or 10497", path,
                         w == 2 ? "wrapS" : "wrapT", (unsigned long long)v[w]);
                return false;
            }
        s->mag_filter = (uint32_t)v[0];
        s->min_filter = (uint32_t)v[1];
        s->wrap_s = (uint32_t)v[2];
        s->wrap_t = (uint32_t)v[3];
        i++;
    }
    return true;
}

bool svg_parse_images(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!svg_top_array(c, root, "images", &arr, &count)) return false;
    c->g->images = svg_xcalloc(c, count, sizeof *c->g->images);
    if (!c->g->images) return false;
    c->g->image_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "images[%u]", i);
        sv_gltf_image *im = &c->g->images[i];
        const cJSON *uri;
        int32_t view;
        if (!svg_get_string(c, j, "name", path, &im->name) || !svg_get_string(c, j, "mimeType", path, &im->mime_type) ||
            !svg_get_typed(c, j, "uri", path, cJSON_String, &uri) ||
            !svg_get_index(c, j, "bufferView", path, false, c->view_count, "bufferViews", &view))
            return false;
        if ((uri != NULL) == (view >= 0)) {
            svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: needs exactly one of uri and bufferView", path);
            return false;
        }
        if (view >= 0) {
            im->data = svg_view_ptr(c, (uint32_t)view, 0);
            im->size = (size_t)c->views[view].length;
        } else if (strncmp(uri->valuestring, "data:", 5) == 0) {
            uint64_t n;
            char *mime = NULL;
            if (!svg_decode_data_uri(c, uri->valuestring, path, &im->data, &n, &mime)) {
                free(mime);
                return false;
            }
            im->size = (size_t)n;
            if (!im->mime_type[0] && mime) {
                free(im->mime_type);
                im->mime_type = mime;
            } else {
                free(mime);
            }
        } else {
            if (!c->g->base_dir) {
                svg_warn(c, "%s: external URI '%.200s' left unresolved (no base directory)", path, uri->valuestring);
            } else {
                bool literal;
                if (!(im->path = svg_resolve_uri(c, uri->valuestring, path, &literal))) return false;
                if (literal)
                    svg_warn(c, "%s: URI '%.200s' has a '%%' that is not a %%XX escape; taken literally", path,
                             uri->valuestring);
            }
        }
        i++;
    }
    return true;
}

bool svg_parse_textures(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!svg_top_array(c, root, "textures", &arr, &count)) return false;
    c->g->textures = svg_xcalloc(c, count, sizeof *c->g->textures);
    if (!c->g->textures) return false;
    c->g->texture_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48];
        snprintf(path, sizeof path, "textures[%u]", i);
        sv_gltf_texture *t = &c->g->textures[i];
        if (!svg_get_string(c, j, "name", path, &t->name) ||
            !svg_get_index(c, j, "source", path, false, c->g->image_count, "images", &t->image) ||
            !svg_get_index(c, j, "sampler", path, false, c->g->sampler_count, "samplers", &t->sampler))
            return false;
        if (t->image < 0) svg_warn(c, "%s: no source image (extension sources are not supported)", path);
        i++;
    }
    return true;
}

static bool parse_texref(ctx_ *c, const cJSON *obj, const char *key, const char *path, const char *scale_key,
                         sv_gltf_texture_ref *ref)
{
    const cJSON *j;
    ref->texture = -1;
    ref->texcoord = 0;
    ref->scale = 1.0f;
    if (!svg_get_typed(c, obj, key, path, cJSON_Object, &j)) return false;
    if (!j) return true;
    char p[96];
    snprintf(p, sizeof p, "%s.%s", path, key);
    uint64_t tc;
    if (!svg_get_index(c, j, "index", p, true, c->g->texture_count, "textures", &ref->texture) ||
        !svg_get_uint(c, j, "texCoord", p, false, 0, 0, 255, &tc) ||
        (scale_key && !svg_get_float(c, j, scale_key, p, false, 1.0f, -FLT_MAX, FLT_MAX, &ref->scale)))
        return false;
    ref->texcoord = (uint32_t)tc;
    if (tc > 1) svg_warn(c, "%s: TEXCOORD_%u is not decoded (only 0 and 1)", p, ref->texcoord);
    return true;
}

bool svg_parse_materials(ctx_ *c, const cJSON *root)
{
    const cJSON *arr, *j;
    uint32_t count;
    if (!svg_top_array(c, root, "materials", &arr, &count)) return false;
    c->g->materials = svg_xcalloc(c, count, sizeof *c->g->materials);
    if (!c->g->materials) return false;
    c->g->material_count = count;
    uint32_t i = 0;
    cJSON_ArrayForEach(j, arr)
    {
        char path[48], pbr_path[80], ext_path[80];
        snprintf(path, sizeof path, "materials[%u]", i);
        snprintf(pbr_path, sizeof pbr_path, "%s.pbrMetallicRoughness", path);
        snprintf(ext_path, sizeof ext_path, "%s.extensions", path);
        sv_gltf_material *m = &c->g->materials[i];
        const float white[4] = {1, 1, 1, 1};
        memcpy(m->base_color_factor, white, sizeof white);
        const cJSON *pbr, *ext, *alpha, *strength = NULL;
        if (!svg_get_string(c, j, "name", path, &m->name) ||
            !svg_get_typed(c, j, "pbrMetallicRoughness", path, cJSON_Object, &pbr) ||
            !svg_get_typed(c, j, "extensions", path, cJSON_Object, &ext) ||
            !svg_get_typed(c, j, "alphaMode", path, cJSON_String, &alpha) ||
            !svg_get_float(c, j, "alphaCutoff", path, false, 0.5f, 0.0, FLT_MAX, &m->alpha_cutoff) ||
            !svg_get_bool(c, j, "doubleSided", path, false, &m->double_sided) ||
            !svg_get_floats(c, j, "emissiveFactor", path, 3, m->emissive_factor, NULL) ||
            !parse_texref(c, j, "normalTexture", path, "scale", &m->normal_texture) ||
            !parse_texref(c, j, "occlusionTexture", path, "strength", &m->occlusion_texture) ||
            !parse_texref(c, j, "emissiveTexture", path, NULL, &m->emissive_texture))
            return false;
        m->metallic_factor = m->roughness_factor = 1.0f;
        m->base_color_texture.texture = m->metallic_roughness_texture.texture = -1;
        m->base_color_texture.scale = m->metallic_roughness_texture.scale = 1.0f;
        if (pbr && (!svg_get_floats(c, pbr, "baseColorFactor", pbr_path, 4, m->base_color_factor, NULL) ||
                    !svg_get_float(c, pbr, "metallicFactor", pbr_path, false, 1.0f, 0.0, 1.0, &m->metallic_factor) ||
                    !svg_get_float(c, pbr, "roughnessFactor", pbr_path, false, 1.0f, 0.0, 1.0, &m->roughness_factor) ||
                    !parse_texref(c, pbr, "baseColorTexture", pbr_path, NULL, &m->base_color_texture) ||
                    !parse_texref(c, pbr, "metallicRoughnessTexture", pbr_path, NULL, &m->metallic_roughness_texture)))
            return false;
        m->alpha_mode = SV_GLTF_ALPHA_OPAQUE;
        if (alpha) {
            if (strcmp(alpha->valuestring, "MASK") == 0)
                m->alpha_mode = SV_GLTF_ALPHA_MASK;
            else if (strcmp(alpha->valuestring, "BLEND") == 0)
                m->alpha_mode = SV_GLTF_ALPHA_BLEND;
            else if (strcmp(alpha->valuestring, "OPAQUE") != 0) {
                svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s.alphaMode: '%.40s' is not OPAQUE, MASK or BLEND", path,
                         alpha->valuestring);
                return false;
            }
        }
        m->emissive_strength = 1.0f;
        static const char *const consumed[] = {"KHR_materials_emissive_strength", NULL};
        if ((ext && !svg_get_typed(c, ext, "KHR_materials_emissive_strength", ext_path, cJSON_Object, &strength)) ||
            !svg_get_extensions(c, j, path, consumed, &m->extensions, &m->extension_count))
            return false;
        if (strength) {
            char p[112];
            snprintf(p, sizeof p, "%s.KHR_materials_emissive_strength", ext_path);
            if (!svg_get_float(c, strength, "emissiveStrength", p, false, 1.0f, 0.0, FLT_MAX, &m->emissive_strength))
                return false;
        }
        i++;
    }
    return true;
}
