/* Scene upload, pipelines and frame recording (see sv_renderer.h). */
#define _DEFAULT_SOURCE /* clock_gettime, mkstemps, strcasecmp under -std=c11 */
#include "sv_renderer.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "schnee/pb_image.h"
#include "sv_math.h"

/* SPIR-V embedded at build time (glslc -mfmt=c), so the binary runs from any working directory. */
static const uint32_t mesh_vert_spv[] =
#include "mesh.vert.inc"
    ;
static const uint32_t mesh_frag_spv[] =
#include "mesh.frag.inc"
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

#define SV_VERTEX_FLOATS 8 /* position xyz, normal xyz, uv */

static void fail_msg(const char *what) { fprintf(stderr, "schnee-view: error: %s\n", what); }

/* The create-info every sampler here starts from: `filter` for magnification and minification,
 * `address` on all three axes, one mip level, no comparison; callers set what differs. */
static VkSamplerCreateInfo sampler_info(VkFilter filter, VkSamplerAddressMode address)
{
    return (VkSamplerCreateInfo){
        .sType = VK_STRUCTURE_TYPE_SAMPLER_CREATE_INFO,
        .magFilter = filter,
        .minFilter = filter,
        .mipmapMode = VK_SAMPLER_MIPMAP_MODE_NEAREST,
        .addressModeU = address,
        .addressModeV = address,
        .addressModeW = address,
        .maxLod = 0.0f,
    };
}

/* ---- geometry ------------------------------------------------------------------------------- */

/* Appends a UV sphere of radius 1 (for the probe-cell view) to the vertex/index arrays. */
enum { SPHERE_SEG = 32, SPHERE_RINGS = 16 };

static bool upload_geometry(sv_renderer *r, const sv_gltf *g)
{
    size_t prims = 0, verts = 0, idx = 0;
    for (uint32_t m = 0; m < g->mesh_count; ++m) {
        prims += g->meshes[m].primitive_count;
        for (uint32_t p = 0; p < g->meshes[m].primitive_count; ++p) {
            verts += g->meshes[m].primitives[p].vertex_count;
            idx += g->meshes[m].primitives[p].index_count;
        }
    }
    size_t sphere_verts = (SPHERE_SEG + 1) * (SPHERE_RINGS + 1), sphere_idx = SPHERE_SEG * SPHERE_RINGS * 6;
    if (verts + sphere_verts > INT32_MAX || idx + sphere_idx > UINT32_MAX) {
        fail_msg("scene too large (more than 2^31 vertices)");
        return false;
    }
    r->prim_first_index = calloc(prims + 1, sizeof(uint32_t));
    r->prim_index_count = calloc(prims + 1, sizeof(uint32_t));
    r->prim_vertex_offset = calloc(prims + 1, sizeof(int32_t));
    r->prim_material = calloc(prims + 1, sizeof(uint32_t));
    r->mesh_prim_base = calloc(g->mesh_count + 1, sizeof(uint32_t));
    float *v = malloc((verts + sphere_verts) * SV_VERTEX_FLOATS * sizeof(float));
    uint32_t *ix = malloc((idx + sphere_idx) * sizeof(uint32_t));
    bool ok = false;
    if (!r->prim_first_index || !r->prim_index_count || !r->prim_vertex_offset || !r->prim_material ||
        !r->mesh_prim_base || !v || !ix) {
        fail_msg("out of memory uploading geometry");
        goto done;
    }
    size_t vo = 0, io = 0, pi = 0;
    for (uint32_t m = 0; m < g->mesh_count; ++m) {
        r->mesh_prim_base[m] = (uint32_t)pi;
        for (uint32_t p = 0; p < g->meshes[m].primitive_count; ++p, ++pi) {
            const sv_gltf_primitive *pr = &g->meshes[m].primitives[p];
            r->prim_first_index[pi] = (uint32_t)io;
            r->prim_index_count[pi] = pr->index_count;
            r->prim_vertex_offset[pi] = (int32_t)vo;
            r->prim_material[pi] = pr->material >= 0 ? (uint32_t)pr->material : g->material_count;
            for (uint32_t k = 0; k < pr->vertex_count; ++k) {
                float *d = v + (vo + k) * SV_VERTEX_FLOATS;
                memcpy(d, pr->positions + 3 * (size_t)k, 3 * sizeof(float));
                if (pr->normals)
                    memcpy(d + 3, pr->normals + 3 * (size_t)k, 3 * sizeof(float));
                else
                    d[3] = 0, d[4] = 1, d[5] = 0;
                if (pr->texcoords0)
                    memcpy(d + 6, pr->texcoords0 + 2 * (size_t)k, 2 * sizeof(float));
                else
                    d[6] = d[7] = 0;
            }
            memcpy(ix + io, pr->indices, pr->index_count * sizeof(uint32_t));
            vo += pr->vertex_count;
            io += pr->index_count;
        }
    }
    r->sphere_vertex_offset = (int32_t)vo;
    r->sphere_first_index = (uint32_t)io;
    r->sphere_index_count = (uint32_t)sphere_idx;
    for (uint32_t ring = 0; ring <= SPHERE_RINGS; ++ring)
        for (uint32_t s = 0; s <= SPHERE_SEG; ++s) {
            float th = 3.14159265f * (float)ring / SPHERE_RINGS, ph = 6.2831853f * (float)s / SPHERE_SEG;
            float *d = v + (vo + ring * (SPHERE_SEG + 1) + s) * SV_VERTEX_FLOATS;
            d[0] = d[3] = sinf(th) * cosf(ph);
            d[1] = d[4] = cosf(th);
            d[2] = d[5] = sinf(th) * sinf(ph);
            d[6] = (float)s / SPHERE_SEG;
            d[7] = (float)ring / SPHERE_RINGS;
        }
    for (uint32_t ring = 0; ring < SPHERE_RINGS; ++ring)
        for (uint32_t s = 0; s < SPHERE_SEG; ++s) {
            uint32_t a = ring * (SPHERE_SEG + 1) + s, b = a + SPHERE_SEG + 1;
            uint32_t q[6] = {a, b, a + 1, a + 1, b, b + 1};
            memcpy(ix + io, q, sizeof(q));
            io += 6;
        }
    ok = sv_buffer_create_with_data(r->ctx, v, (verts + sphere_verts) * SV_VERTEX_FLOATS * sizeof(float),
                                    VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, &r->vertices) &&
         sv_buffer_create_with_data(r->ctx, ix, io * sizeof(uint32_t), VK_BUFFER_USAGE_INDEX_BUFFER_BIT, &r->indices);
done:
    free(v);
    free(ix);
    return ok;
}

/* ---- materials, textures, lights, probes ----------------------------------------------------- */

static int32_t texture_slot(const sv_gltf *g, const sv_gltf_texture_ref *ref)
{
    if (ref->texture < 0 || (uint32_t)ref->texture >= g->texture_count) return -1;
    if (g->textures[ref->texture].image < 0) return -1;
    return ref->texture;
}

static bool upload_materials(sv_renderer *r, const sv_gltf *g, const sv_ext *ext)
{
    uint32_t n = g->material_count + 1; /* + the glTF default material */
    sv_gpu_material *m = calloc(n, sizeof(*m));
    if (!m) return false;
    for (uint32_t i = 0; i < n; ++i) {
        if (i == g->material_count) { /* glTF spec defaults + DESIGN.md §5 defaults */
            for (int c = 0; c < 4; ++c) m[i].base_color[c] = 1.0f;
            m[i].sh_scale = SV_EXT_DEFAULT_SH_SCALE;
            m[i].ambient_term = SV_EXT_DEFAULT_AMBIENT_TERM;
            m[i].metallic = 1.0f;
            m[i].roughness = 1.0f;
            m[i].base_color_texture = m[i].emissive_texture = -1;
            m[i].probe_mode = SV_PROBE_MODE_OBJECT;
            m[i].probe_representation = SV_PROBE_REP_SH;
            continue;
        }
        const sv_gltf_material *s = &g->materials[i];
        memcpy(m[i].base_color, s->base_color_factor, sizeof(m[i].base_color));
        for (int c = 0; c < 3; ++c) m[i].emissive[c] = s->emissive_factor[c] * s->emissive_strength;
        m[i].sh_scale = ext->materials[i].sh_scale;
        m[i].ambient_term = ext->materials[i].ambient_term;
        m[i].metallic = s->metallic_factor;
        m[i].roughness = s->roughness_factor;
        m[i].base_color_texture = texture_slot(g, &s->base_color_texture);
        m[i].emissive_texture = texture_slot(g, &s->emissive_texture);
        m[i].probe_mode = ext->materials[i].probe_mode;
        m[i].probe_representation = ext->materials[i].probe_representation;
    }
    bool ok = sv_buffer_create_with_data(r->ctx, m, n * sizeof(*m), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->materials);
    free(m);
    return ok;
}

/* Copies `regions` of a filled staging buffer into `out` (all its levels go UNDEFINED → transfer
 * → shader-read), blocking, then frees the staging buffer. Shared by every sampled-image upload. */
static bool copy_staging_to_image(sv_renderer *r, sv_buffer *staging, sv_image *out, const VkBufferImageCopy *regions,
                                  uint32_t count)
{
    VkCommandBuffer cmd = sv_begin_one_shot(r->ctx);
    bool ok = cmd != VK_NULL_HANDLE;
    if (ok) {
        sv_image_barrier(cmd, out->image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                         VK_PIPELINE_STAGE_TRANSFER_BIT, VK_ACCESS_TRANSFER_WRITE_BIT);
        vkCmdCopyBufferToImage(cmd, staging->buffer, out->image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, count, regions);
        sv_image_barrier(cmd, out->image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                         VK_ACCESS_SHADER_READ_BIT);
        ok = sv_end_one_shot(r->ctx, cmd);
    }
    sv_buffer_destroy(r->ctx, staging);
    return ok;
}

/* Uploads RGBA8 sRGB pixels into a sampled image (blocking). */
static bool upload_rgba8(sv_renderer *r, const uint8_t *pixels, uint32_t w, uint32_t h, sv_image *out)
{
    if (!sv_image_create(r->ctx, w, h, VK_FORMAT_R8G8B8A8_SRGB,
                         VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT, out))
        return false;
    sv_buffer staging;
    if (!sv_buffer_create(r->ctx, (VkDeviceSize)w * h * 4, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true, &staging))
        return false;
    memcpy(staging.mapped, pixels, (size_t)w * h * 4);
    VkBufferImageCopy region = {
        .imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
        .imageExtent = {w, h, 1},
    };
    return copy_staging_to_image(r, &staging, out, &region, 1);
}

/* Reads a glTF image through OpenImageIO (embedded bytes go through a temporary file, since the
 * core's image API takes paths). Returns false with a warning; the caller then uses white. */
static bool read_gltf_image(const sv_gltf_image *img, pb_image *out)
{
    pb_error err = {0};
    if (img->path) {
        char msg[640];
        if (!sv_image_file_check(img->path, "image", SV_TEXTURE_MAX_PIXELS, msg, sizeof msg)) {
            fprintf(stderr, "schnee-view: warning: %s (using white)\n", msg);
            return false;
        }
        if (pb_image_read(img->path, out, &err) == PB_SUCCESS) return true;
        fprintf(stderr, "schnee-view: warning: image '%s': %s (using white)\n", img->path, err.message);
        return false;
    }
    if (!img->data || !img->size) return false;
    const char *suffix = strstr(img->mime_type, "jpeg") ? ".jpg" : ".png";
    char tmp[64];
    snprintf(tmp, sizeof(tmp), "/tmp/schnee-view-XXXXXX%s", suffix);
    int fd = mkstemps(tmp, (int)strlen(suffix));
    if (fd < 0) return false;
    bool ok = write(fd, img->data, img->size) == (ssize_t)img->size;
    close(fd);
    ok = ok && pb_image_read(tmp, out, &err) == PB_SUCCESS;
    if (!ok) fprintf(stderr, "schnee-view: warning: embedded image '%s': %s (using white)\n", img->name, err.message);
    unlink(tmp);
    return ok;
}

static bool upload_textures(sv_renderer *r, const sv_gltf *g)
{
    const uint8_t white[4] = {255, 255, 255, 255};
    if (!upload_rgba8(r, white, 1, 1, &r->white)) return false;
    r->textures = calloc(g->texture_count ? g->texture_count : 1, sizeof(sv_image));
    if (!r->textures) return false;
    r->texture_count = g->texture_count;
    for (uint32_t t = 0; t < g->texture_count; ++t) {
        if (g->textures[t].image < 0) continue;
        pb_image img = {0};
        if (!read_gltf_image(&g->images[g->textures[t].image], &img)) continue;
        size_t n = (size_t)img.width * img.height;
        uint8_t *px = malloc(n * 4);
        bool ok = px != NULL;
        for (size_t i = 0; ok && i < n; ++i)
            for (uint32_t c = 0; c < 4; ++c) {
                /* Grey images replicate their channel; a missing alpha is opaque. */
                float f = c == 3 ? (img.channels == 4   ? img.pixels[i * 4 + 3]
                                    : img.channels == 2 ? img.pixels[i * 2 + 1]
                                                        : 1.0f)
                                 : img.pixels[i * img.channels + (img.channels >= 3 ? c : 0)];
                f = f < 0 ? 0 : f > 1 ? 1 : f;
                px[i * 4 + c] = (uint8_t)lrintf(f * 255.0f);
            }
        if (ok) ok = upload_rgba8(r, px, img.width, img.height, &r->textures[t]);
        free(px);
        pb_image_free(&img);
        if (!ok) return false;
    }
    return true;
}

/* Which lights get shadow map layers (docs/engine.md "Shadows"): lights whose mode is mixed or
 * realtime (or no extension), in light-instance order, while SV_MAX_SHADOW_LAYERS lasts: a directional
 * light r->shadow_cascades layers (its cascades; as many as are left when fewer are, with a warning),
 * a spot light one (six, as a cube, when its outer cone is wider than SV_SPOT_SHADOW_MAX_ANGLE), a point
 * light six. A light that does not fit (a sun: no layer left) is unshadowed with a warning naming it.
 * None when shadow_res is 0. Returns the light's first layer or -1; *cascades = the layers a sun got. */
static int assign_shadow_layers(sv_renderer *r, const sv_gltf_light_instance *li, const sv_gltf_light *s,
                                uint32_t *cascades)
{
    const char *name = s->name ? s->name : "";
    bool sun = s->type == SV_GLTF_LIGHT_DIRECTIONAL;
    bool cube = s->type == SV_GLTF_LIGHT_POINT ||
                (s->type == SV_GLTF_LIGHT_SPOT && s->outer_cone_angle > SV_SPOT_SHADOW_MAX_ANGLE);
    uint32_t need = sun ? r->shadow_cascades : cube ? 6u : 1u;
    uint32_t left = SV_MAX_SHADOW_LAYERS - r->shadow_count;
    if (need > left && !(sun && left > 0)) {
        fprintf(stderr,
                "schnee-view: warning: light '%s' needs %u shadow map layer%s but only %u of %d are left; it is "
                "unshadowed\n",
                name, need, need == 1 ? "" : "s", left, SV_MAX_SHADOW_LAYERS);
        return -1;
    }
    if (need > left) { /* a sun: fewer, wider cascades rather than none */
        fprintf(stderr,
                "schnee-view: warning: light '%s' needs %u shadow map layers (cascades) but only %u of %d are left; "
                "it gets %u cascade%s\n",
                name, need, left, SV_MAX_SHADOW_LAYERS, left, left == 1 ? "" : "s");
        need = left;
    }
    int first = (int)r->shadow_count;
    static const float faces[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (uint32_t f = 0; f < need; ++f) {
        sv_shadow_layer *layer = &r->shadow_layers[r->shadow_count++];
        memcpy(layer->pos, li->position, sizeof(layer->pos));
        memcpy(layer->dir, cube ? faces[f] : li->direction, sizeof(layer->dir));
        layer->kind = sun ? SV_SHADOW_ORTHO : cube ? SV_SHADOW_CUBE : SV_SHADOW_SPOT;
        layer->tan_half = cube ? 1.0f : tanf(fmaxf(s->outer_cone_angle, 1e-3f));
        layer->cascade = sun ? f : 0;
        layer->cascades = sun ? need : 1;
    }
    *cascades = sun ? need : 0;
    return first;
}

static bool upload_lights(sv_renderer *r, const sv_gltf *g, const sv_ext *ext, uint32_t shadow_res)
{
    uint32_t n = g->light_instance_count;
    sv_gpu_light *l = calloc(n ? n : 1, sizeof(*l));
    if (!l) return false;
    for (uint32_t i = 0; i < n; ++i) {
        const sv_gltf_light_instance *li = &g->light_instances[i];
        const sv_gltf_light *s = &g->lights[li->light];
        memcpy(l[i].position_range, li->position, 3 * sizeof(float));
        l[i].position_range[3] = s->range;
        memcpy(l[i].direction_type, li->direction, 3 * sizeof(float));
        l[i].direction_type[3] = s->type == SV_GLTF_LIGHT_DIRECTIONAL ? 0.0f
                                 : s->type == SV_GLTF_LIGHT_POINT     ? 1.0f
                                                                      : 2.0f;
        float units = ext->light_scales ? ext->light_scales[li->light] : 1.0f;
        for (int c = 0; c < 3; ++c) l[i].color[c] = s->color[c] * s->intensity * units;
        /* KHR_lights_punctual: scale = 1 / max(0.001, cos(inner) - cos(outer)), offset = -cos(outer) * scale. */
        float scale = 1.0f / fmaxf(0.001f, cosf(s->inner_cone_angle) - cosf(s->outer_cone_angle));
        l[i].spot[0] = scale;
        l[i].spot[1] = -cosf(s->outer_cone_angle) * scale;
        sv_light_mode mode = ext->light_modes[li->light];
        l[i].spot[2] = (float)(mode == SV_LIGHT_MODE_BAKED   ? SV_LIGHT_BAKED
                               : mode == SV_LIGHT_MODE_MIXED ? SV_LIGHT_MIXED
                                                             : SV_LIGHT_REALTIME);
        l[i].spot[3] = -1.0f;
        uint32_t cascades = 0;
        if (shadow_res && mode != SV_LIGHT_MODE_BAKED) l[i].spot[3] = (float)assign_shadow_layers(r, li, s, &cascades);
        l[i].color[3] = (float)cascades;
    }
    r->light_count = n;
    bool ok =
        sv_buffer_create_with_data(r->ctx, l, (n ? n : 1) * sizeof(*l), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->lights);
    free(l);
    return ok;
}

/* Objects that left the static scene (moved at least once). */
static uint32_t count_movable(const sv_scene *scene)
{
    uint32_t n = 0;
    for (uint32_t i = 0; i < scene->object_count; ++i) n += scene->objects[i].movable;
    return n;
}

static bool upload_probes(sv_renderer *r, const sv_scene *scene, const sv_probes *probes, const sv_renderer_desc *desc)
{
    const sv_sky *sky = desc->sky && desc->sky->present ? desc->sky : NULL;
    sv_gpu_probe *p = sv_probes_pack(probes, desc->fallback_radiance, sky ? sky->sh : NULL, sky ? sky->max_band : 0);
    /* Half storage only when every value fits: an overflow would become Inf and shade the objects
     * lit by that probe dark (NaN) or white, silently. Then float storage, with a warning. */
    bool half = desc->half_probes;
    char msg[320];
    if (p && half && !sv_probes_fit_half(probes, p, msg, sizeof msg)) {
        fprintf(stderr, "schnee-view: warning: --probe-storage half: %s; using float storage\n", msg);
        half = false;
    }
    /* Ambient cubes (docs/ambient-cube.md §5) only when asked for: by the command line or by a
     * material. They follow the SH storage; a cube colour beyond the half range sends both to float. */
    bool want_cubes = desc->cube_probes || sv_probes_have_cube_grids(probes);
    for (uint32_t i = 0; i < scene->ext.material_count; ++i)
        want_cubes = want_cubes || scene->ext.materials[i].probe_representation == SV_PROBE_REP_AMBIENT_CUBE;
    sv_gpu_cube *cubes = p && want_cubes ? sv_probes_pack_all_cubes(probes, p) : NULL;
    if (cubes && half && !sv_probes_cubes_fit_half(probes, cubes, msg, sizeof msg)) {
        fprintf(stderr, "schnee-view: warning: --probe-storage half: %s; using float storage\n", msg);
        half = false;
    }
    /* The per-object slots of v3 grids follow the grids' entries (rewritten when objects move). */
    uint32_t count = probes->total + probes->slot_count;
    if (p && probes->slot_count) {
        sv_gpu_probe *grown = realloc(p, count * sizeof(*p));
        if (grown) memcpy(grown + probes->total, probes->slot_sh, probes->slot_count * sizeof(*p));
        p = grown;
        if (cubes) {
            sv_gpu_cube *gc = realloc(cubes, count * sizeof(*cubes));
            if (gc)
                memcpy(gc + probes->total, probes->slot_cube, probes->slot_count * sizeof(*cubes));
            else
                free(cubes);
            cubes = gc;
        }
    }
    sv_gpu_cube_half *cubes_half = cubes && half ? sv_probes_pack_cubes_half(cubes, count) : NULL;
    sv_gpu_probe_half *ph = p && half ? sv_probes_pack_half(p, count) : NULL;
    uint32_t nspheres = 0, ncells = 0, grid_cells = 0;
    sv_gpu_cell *cells = sv_probes_cells(probes, &nspheres, &ncells);
    sv_gpu_grid *grids = NULL;
    int32_t *cell_index = NULL;
    bool ok = p && cells && (!half || ph) && (!want_cubes || (cubes && (!half || cubes_half)));
    if (!ok) fail_msg("out of memory packing probes");
    ok = ok && sv_probes_gpu_grids(probes, scene, &grids, &cell_index, &grid_cells);
    /* Only the storage in use holds the probes; the other binding gets one zero entry. */
    static const sv_gpu_probe zero_probe;
    static const sv_gpu_probe_half zero_half;
    ok = ok && sv_buffer_create_with_data(r->ctx, half ? &zero_probe : (const void *)p,
                                          half ? sizeof(*p) : count * sizeof(*p), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                          &r->probes);
    ok = ok && sv_buffer_create_with_data(r->ctx, half ? (const void *)ph : &zero_half,
                                          half ? count * sizeof(*ph) : sizeof(*ph), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                          &r->probes_half);
    static const sv_gpu_cube zero_cube;
    static const sv_gpu_cube_half zero_cube_half;
    bool float_cubes = cubes && !half;
    ok = ok && sv_buffer_create_with_data(r->ctx, float_cubes ? (const void *)cubes : &zero_cube,
                                          float_cubes ? count * sizeof(*cubes) : sizeof(*cubes),
                                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->cubes);
    ok = ok && sv_buffer_create_with_data(r->ctx, cubes_half ? (const void *)cubes_half : &zero_cube_half,
                                          cubes_half ? count * sizeof(*cubes_half) : sizeof(*cubes_half),
                                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->cubes_half);
    ok = ok && sv_buffer_create_with_data(r->ctx, cells, (nspheres + ncells ? nspheres + ncells : 1) * sizeof(*cells),
                                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->cells);
    ok = ok && sv_buffer_create_with_data(r->ctx, grids, (probes->grid_count ? probes->grid_count : 1) * sizeof(*grids),
                                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->grids);
    ok = ok && sv_buffer_create_with_data(r->ctx, cell_index, (grid_cells ? grid_cells : 1) * sizeof(int32_t),
                                          VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->cell_index);
    r->probe_count = count;
    r->grid_count = probes->grid_count;
    r->probes_src = probes;
    r->masks_movable = count_movable(scene);
    /* The first frame rewrites the slots through upload_slots(), the path a moving object takes. */
    r->slots_uploaded = probes->slots_version - 1u;
    r->sphere_count = nspheres;
    r->outline_count = ncells;
    r->half_probes = half;
    r->has_cubes = cubes != NULL;
    free(cubes);
    free(cubes_half);
    free(p);
    free(ph);
    free(cells);
    free(grids);
    free(cell_index);
    return ok;
}

/* Uploads float texel data (levels[l]: width>>l x height>>l texels of texel_bytes) into a sampled
 * image with `count` mip levels (blocking). */
static bool upload_float_image(sv_renderer *r, VkFormat format, uint32_t texel_bytes, const float *const *levels,
                               const uint32_t *widths, const uint32_t *heights, uint32_t count, sv_image *out)
{
    VkFormatProperties fp;
    vkGetPhysicalDeviceFormatProperties(r->ctx->physical, format, &fp);
    if (!(fp.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT)) {
        fail_msg("the device cannot filter 32-bit float images linearly (needed for the sky)");
        return false;
    }
    if (!sv_image_create_mips(r->ctx, widths[0], heights[0], count, format,
                              VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, VK_IMAGE_ASPECT_COLOR_BIT,
                              out))
        return false;
    VkDeviceSize total = 0;
    for (uint32_t l = 0; l < count; ++l) total += (VkDeviceSize)widths[l] * heights[l] * texel_bytes;
    sv_buffer staging;
    if (!sv_buffer_create(r->ctx, total, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true, &staging)) return false;
    VkBufferImageCopy regions[SV_SKY_MAX_MIPS];
    VkDeviceSize off = 0;
    for (uint32_t l = 0; l < count && l < SV_SKY_MAX_MIPS; ++l) {
        size_t bytes = (size_t)widths[l] * heights[l] * texel_bytes;
        memcpy((uint8_t *)staging.mapped + off, levels[l], bytes);
        regions[l] = (VkBufferImageCopy){
            .bufferOffset = off,
            .imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, l, 0, 1},
            .imageExtent = {widths[l], heights[l], 1},
        };
        off += bytes;
    }
    return copy_staging_to_image(r, &staging, out, regions, count);
}

/* Sky mips (or a 1x1 black stand-in) and the BRDF LUT (always: the binding must hold an image). */
static bool upload_sky(sv_renderer *r, const sv_sky *sky)
{
    r->has_sky = sky && sky->present;
    bool ok;
    if (r->has_sky) {
        ok = upload_float_image(r, VK_FORMAT_R32G32B32A32_SFLOAT, 16, (const float *const *)sky->rgba, sky->width,
                                sky->height, sky->mip_count, &r->sky);
    } else {
        const float black[4] = {0, 0, 0, 1};
        const float *lv[1] = {black};
        uint32_t one = 1;
        ok = upload_float_image(r, VK_FORMAT_R32G32B32A32_SFLOAT, 16, lv, &one, &one, 1, &r->sky);
    }
    if (!ok) return false;
    float *lut = r->has_sky ? sv_brdf_lut(SV_BRDF_LUT_SIZE, SV_BRDF_LUT_SAMPLES) : calloc(2, sizeof(float));
    if (!lut) {
        fail_msg("out of memory for the BRDF LUT");
        return false;
    }
    const float *lv[1] = {lut};
    uint32_t size = r->has_sky ? SV_BRDF_LUT_SIZE : 1;
    ok = upload_float_image(r, VK_FORMAT_R32G32_SFLOAT, 8, lv, &size, &size, 1, &r->brdf_lut);
    free(lut);
    return ok;
}

/* ---- shadow maps ---------------------------------------------------------------------------- */

/* A depth format the device can render to and sample (D32 float preferred), and whether it filters
 * linearly (the hardware 2x2 bilinear comparison; nearest otherwise). */
static VkFormat pick_shadow_format(sv_context *ctx, bool *linear)
{
    VkFormat candidates[] = {VK_FORMAT_D32_SFLOAT, VK_FORMAT_D16_UNORM};
    const VkFormatFeatureFlags need =
        VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT;
    for (int i = 0; i < 2; ++i) {
        VkFormatProperties p;
        vkGetPhysicalDeviceFormatProperties(ctx->physical, candidates[i], &p);
        if ((p.optimalTilingFeatures & need) == need) {
            *linear = (p.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT) != 0;
            return candidates[i];
        }
    }
    *linear = false;
    return VK_FORMAT_D16_UNORM; /* required by the spec for depth attachments and sampling */
}

/* The shadow map array (shadow_count layers of shadow_res^2, or one 1x1 layer when no light is
 * shadowed: the binding needs an image), its per-layer views and the comparison sampler. The image is
 * left in SHADER_READ_ONLY_OPTIMAL, the layout every frame's shadow pass returns it to. */
static bool create_shadow_maps(sv_renderer *r, uint32_t shadow_res)
{
    sv_context *ctx = r->ctx;
    bool linear = false;
    r->shadow_format = pick_shadow_format(ctx, &linear);
    uint32_t max_dim = ctx->properties.limits.maxImageDimension2D;
    if (r->shadow_count && shadow_res > max_dim) {
        fprintf(stderr, "schnee-view: warning: --shadow-res %u exceeds the device's limit %u; using %u\n", shadow_res,
                max_dim, max_dim);
        shadow_res = max_dim;
    }
    r->shadow_res = r->shadow_count ? shadow_res : 1;
    uint32_t layers = r->shadow_count ? r->shadow_count : 1;
    if (!sv_image_create_layers(ctx, r->shadow_res, r->shadow_res, 1, layers, r->shadow_format,
                                VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT,
                                VK_IMAGE_ASPECT_DEPTH_BIT, &r->shadow))
        return false;
    for (uint32_t k = 0; k < r->shadow_count; ++k) {
        VkImageViewCreateInfo vi = {
            .sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO,
            .image = r->shadow.image,
            .viewType = VK_IMAGE_VIEW_TYPE_2D,
            .format = r->shadow_format,
            .subresourceRange = {VK_IMAGE_ASPECT_DEPTH_BIT, 0, 1, k, 1},
        };
        VK_CHECK(vkCreateImageView(ctx->device, &vi, NULL, &r->shadow_layer_views[k]));
    }
    VkSamplerCreateInfo si =
        sampler_info(linear ? VK_FILTER_LINEAR : VK_FILTER_NEAREST, VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_BORDER);
    si.compareEnable = VK_TRUE;
    si.compareOp = VK_COMPARE_OP_LESS_OR_EQUAL;
    si.borderColor = VK_BORDER_COLOR_FLOAT_OPAQUE_WHITE;
    VK_CHECK(vkCreateSampler(ctx->device, &si, NULL, &r->shadow_sampler));
    VkCommandBuffer cmd = sv_begin_one_shot(ctx);
    if (!cmd) return false;
    sv_image_barrier(cmd, r->shadow.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, 0,
                     VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, VK_ACCESS_SHADER_READ_BIT);
    return sv_end_one_shot(ctx, cmd);
fail:
    return false;
}

/* An orthonormal light basis: f = unit dir (straight down when degenerate), x = normalize(f x up),
 * y = x x f, with up = +Y, or +X when |f.y| > 0.99. */
static void shadow_basis(const float dir[3], float x[3], float y[3], float f[3])
{
    memcpy(f, dir, 3 * sizeof(float));
    float fl = sqrtf(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    if (fl < 1e-12f) f[0] = 0, f[1] = -1, f[2] = 0, fl = 1;
    for (int k = 0; k < 3; ++k) f[k] /= fl;
    float up[3] = {0, 1, 0};
    if (fabsf(f[1]) > 0.99f) up[0] = 1, up[1] = 0;
    x[0] = f[1] * up[2] - f[2] * up[1], x[1] = f[2] * up[0] - f[0] * up[2], x[2] = f[0] * up[1] - f[1] * up[0];
    float xl = sqrtf(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    for (int k = 0; k < 3; ++k) x[k] /= xl;
    y[0] = x[1] * f[2] - x[2] * f[1], y[1] = x[2] * f[0] - x[0] * f[2], y[2] = x[0] * f[1] - x[1] * f[0];
}

/* Corner c (bit 0: x, bit 1: y, bit 2: z at hi) of the box [lo, hi]. */
static void box_corner(const float lo[3], const float hi[3], int c, float p[3])
{
    for (int k = 0; k < 3; ++k) p[k] = (c >> k) & 1 ? hi[k] : lo[k];
}

/* The extent [mn, mx] of the world bounds [lo, hi] along each of the three light-space axes (the 8
 * corners projected), each padded by 1 % plus 1 mm so that surfaces on the bounds stay inside. */
static void light_space_bounds(const float *axes[3], const float lo[3], const float hi[3], float mn[3], float mx[3])
{
    for (int a = 0; a < 3; ++a) mn[a] = INFINITY, mx[a] = -INFINITY;
    for (int c = 0; c < 8; ++c) {
        float p[3];
        box_corner(lo, hi, c, p);
        for (int a = 0; a < 3; ++a) {
            float d = axes[a][0] * p[0] + axes[a][1] * p[1] + axes[a][2] * p[2];
            mn[a] = fminf(mn[a], d);
            mx[a] = fmaxf(mx[a], d);
        }
    }
    for (int a = 0; a < 3; ++a) {
        float pad = 0.01f * (mx[a] - mn[a]) + 1e-3f;
        mn[a] -= pad;
        mx[a] += pad;
    }
}

/* World -> light clip of an orthographic box along the basis `axes` (x, y, f): x, y in [-1, 1] over
 * centre c ± half extent h, z in [0, 1] over [zmin, zmax] along f (Vulkan); params[1..3] of
 * sv_gpu_frame.shadow_params (params[0], the texel size, is the caller's). */
static void ortho_light_projection(const float *axes[3], const float c[2], const float h[2], float zmin, float zmax,
                                   uint32_t res, float m[16], float params[4])
{
    memset(m, 0, 16 * sizeof(float));
    for (int k = 0; k < 3; ++k) {
        m[4 * k + 0] = axes[0][k] / h[0];
        m[4 * k + 1] = axes[1][k] / h[1];
        m[4 * k + 2] = axes[2][k] / (zmax - zmin);
    }
    m[12] = -c[0] / h[0];
    m[13] = -c[1] / h[1];
    m[14] = -zmin / (zmax - zmin);
    m[15] = 1.0f;
    params[1] = 1.0f / (zmax - zmin);
    params[2] = 1.0f / (float)res;
    params[3] = (float)SV_SHADOW_ORTHO;
}

/* The light-space projection of a directional light's layer: an orthographic box along `dir` fitted
 * to the 8 corners of the world bounds [lo, hi] (x, y extents and depth range, each padded by 1 %
 * plus 1 mm so that surfaces on the bounds stay inside), world -> clip with x, y in [-1, 1] and z in
 * [0, 1] (Vulkan), and its shadow_params (see sv_gpu_frame). */
static void shadow_projection_ortho(const float dir[3], const float lo[3], const float hi[3], uint32_t res, float m[16],
                                    float params[4])
{
    float x[3], y[3], f[3];
    shadow_basis(dir, x, y, f);
    const float *axes[3] = {x, y, f};
    float mn[3], mx[3];
    light_space_bounds(axes, lo, hi, mn, mx);
    float centre[2], half[2];
    for (int a = 0; a < 2; ++a) {
        centre[a] = 0.5f * (mn[a] + mx[a]);
        half[a] = 0.5f * (mx[a] - mn[a]);
    }
    ortho_light_projection(axes, centre, half, mn[2], mx[2], res, m, params);
    params[0] = 2.0f * fmaxf(half[0], half[1]) / (float)res;
}

/* Cascades (docs/engine.md "Shadows"): the practical split's weight of the logarithmic split against
 * the uniform one. 0.9 keeps the near cascade a few metres deep when the view spans hundreds. */
#define SV_CASCADE_LAMBDA 0.9f

/* The camera seen by the cascades: its basis (from the view matrix's rows), the half extents of its
 * cross-section (per metre of depth for a perspective camera, metres for an orthographic one) and
 * its depth range [near, far] along the view direction clamped to the scene bounds. */
typedef struct cascade_view {
    float eye[3], right[3], up[3], fwd[3];
    float hx, hy;
    bool perspective;
    float near, far;
} cascade_view;

/* near = max(znear, the nearest corner of [lo, hi] along the view), far = min(zfar, the farthest).
 * False when the scene lies wholly outside the camera's depth range (the cascades then all fall back
 * to the whole scene's fit). */
static bool cascade_view_fit(const sv_view *v, float aspect, const float lo[3], const float hi[3], cascade_view *cv)
{
    for (int k = 0; k < 3; ++k) {
        cv->right[k] = v->view[4 * k + 0];
        cv->up[k] = v->view[4 * k + 1];
        cv->fwd[k] = -v->view[4 * k + 2];
        cv->eye[k] = v->camera_pos[k];
    }
    cv->perspective = v->yfov > 0.0f;
    cv->hy = cv->perspective ? tanf(0.5f * v->yfov) : v->ymag > 0 ? v->ymag : 1.0f;
    cv->hx = cv->hy * aspect;
    float dmin = INFINITY, dmax = -INFINITY;
    for (int c = 0; c < 8; ++c) {
        float p[3];
        box_corner(lo, hi, c, p);
        float d = 0.0f;
        for (int k = 0; k < 3; ++k) d += (p[k] - cv->eye[k]) * cv->fwd[k];
        dmin = fminf(dmin, d);
        dmax = fmaxf(dmax, d);
    }
    /* the camera's own far plane, as sv_view_projection sets it */
    float zfar =
        cv->perspective ? (v->zfar > 0.0f ? v->zfar : INFINITY) : (v->zfar > v->znear ? v->zfar : v->znear + 1000.0f);
    cv->near = fmaxf(dmin, v->znear);
    cv->far = fminf(dmax, zfar);
    return cv->far > cv->near;
}

/* Depth of split i of `count` (0 = near, count = far): the practical scheme
 * d_i = lambda * n * (f / n)^(i / C) + (1 - lambda) * (n + (f - n) * i / C) (uniform only when n <= 0,
 * an orthographic camera whose near plane is behind it). */
static float cascade_split(const cascade_view *cv, uint32_t i, uint32_t count)
{
    if (i == 0) return cv->near;
    if (i >= count) return cv->far;
    float t = (float)i / (float)count, n = cv->near, f = cv->far;
    float uniform = n + (f - n) * t;
    if (n <= 0.0f) return uniform;
    return SV_CASCADE_LAMBDA * n * powf(f / n, t) + (1.0f - SV_CASCADE_LAMBDA) * uniform;
}

/* The light-space projection of cascade `cascade` of a directional light's `count`: an orthographic
 * box along `dir` whose depth range is the whole scene's (as shadow_projection_ortho: casters outside
 * the view still cast) and whose x, y square encloses the bounding sphere of the view slice's 8
 * corners (centre = their mean, on the view axis; radius = the farthest corner: it does not change as
 * the camera turns), its radius rounded up to a power of 2^(1/4) (the texel size does not change as
 * the split depths drift a little) plus room for SV_SHADOW_CASCADE_MARGIN + 1 texels, at most the
 * scene's own square, kept inside the scene's box where it fits, and its centre snapped to whole
 * texels (the texel grid stays put in light space as the camera moves: no shimmering). */
static void shadow_projection_cascade(const float dir[3], const float lo[3], const float hi[3], const cascade_view *cv,
                                      uint32_t cascade, uint32_t count, uint32_t res, float m[16], float params[4])
{
    float x[3], y[3], f[3];
    shadow_basis(dir, x, y, f);
    const float *axes[3] = {x, y, f};
    float mn[3], mx[3];
    light_space_bounds(axes, lo, hi, mn, mx);
    /* the slice's corners, their mean and the bounding radius */
    float corner[8][3], centre[3] = {0, 0, 0};
    for (int c = 0; c < 8; ++c) {
        float d = cascade_split(cv, cascade + (uint32_t)(c >> 2), count);
        float sx = (c & 1 ? 1.0f : -1.0f) * cv->hx * (cv->perspective ? d : 1.0f);
        float sy = (c & 2 ? 1.0f : -1.0f) * cv->hy * (cv->perspective ? d : 1.0f);
        for (int k = 0; k < 3; ++k) {
            corner[c][k] = cv->eye[k] + d * cv->fwd[k] + sx * cv->right[k] + sy * cv->up[k];
            centre[k] += corner[c][k] / 8.0f;
        }
    }
    float radius2 = 0.0f;
    for (int c = 0; c < 8; ++c) {
        float d2 = 0.0f;
        for (int k = 0; k < 3; ++k) d2 += (corner[c][k] - centre[k]) * (corner[c][k] - centre[k]);
        radius2 = fmaxf(radius2, d2);
    }
    float radius = exp2f(ceilf(4.0f * log2f(fmaxf(sqrtf(radius2), 1e-4f))) / 4.0f);
    float h = radius * (1.0f + 4.0f * (SV_SHADOW_CASCADE_MARGIN + 1.0f) / (float)res);
    h = fminf(h, 0.5f * fmaxf(mx[0] - mn[0], mx[1] - mn[1]));
    float texel = 2.0f * h / (float)res, c2[2];
    for (int a = 0; a < 2; ++a) {
        float c = axes[a][0] * centre[0] + axes[a][1] * centre[1] + axes[a][2] * centre[2];
        c = mn[a] + h <= mx[a] - h ? fminf(fmaxf(c, mn[a] + h), mx[a] - h) : 0.5f * (mn[a] + mx[a]);
        c2[a] = roundf(c / texel) * texel;
    }
    ortho_light_projection(axes, c2, (const float[2]){h, h}, mn[2], mx[2], res, m, params);
    params[0] = texel;
}

/* The projection of a spot light's layer or a point light's cube face: a perspective frustum from
 * the light's position along the layer's axis, tan(half fov) = layer->tan_half * (1 + 8 / res) (the
 * margin keeps the 3x3 filter of a fragment at the cone's edge, or at a cube face's edge, about 4
 * texels inside the map), far = the farthest corner of the world bounds [lo, hi] padded by 1 % plus
 * 1 mm, near = the bounds' distance from the light, at least far / 1000 (a float depth keeps about
 * 6e-5 of far there). Clip w = depth along the axis; z / w in [0, 1] between near and far. */
static void shadow_projection_perspective(const sv_shadow_layer *layer, const float lo[3], const float hi[3],
                                          uint32_t res, float m[16], float params[4])
{
    float x[3], y[3], f[3];
    shadow_basis(layer->dir, x, y, f);
    const float *pos = layer->pos;
    float far = 0.0f, near2 = 0.0f;
    for (int k = 0; k < 3; ++k) {
        float a = fabsf(lo[k] - pos[k]), b = fabsf(hi[k] - pos[k]), c = fmaxf(a, b);
        far += c * c;
        float outside = pos[k] < lo[k] ? lo[k] - pos[k] : pos[k] > hi[k] ? pos[k] - hi[k] : 0.0f;
        near2 += outside * outside;
    }
    far = sqrtf(far);
    far += 0.01f * far + 1e-3f;
    float near = fmaxf(0.99f * sqrtf(near2), far * 1e-3f);
    float t = layer->tan_half * (1.0f + 8.0f / (float)res);
    float a = far / (far - near), b = -near * far / (far - near);
    float xp = x[0] * pos[0] + x[1] * pos[1] + x[2] * pos[2];
    float yp = y[0] * pos[0] + y[1] * pos[1] + y[2] * pos[2];
    float fp = f[0] * pos[0] + f[1] * pos[1] + f[2] * pos[2];
    memset(m, 0, 16 * sizeof(float));
    for (int k = 0; k < 3; ++k) {
        m[4 * k + 0] = x[k] / t;
        m[4 * k + 1] = y[k] / t;
        m[4 * k + 2] = a * f[k];
        m[4 * k + 3] = f[k];
    }
    m[12] = -xp / t;
    m[13] = -yp / t;
    m[14] = -a * fp + b;
    m[15] = -fp;
    params[0] = 2.0f * t / (float)res;
    params[1] = 0.0f;
    params[2] = 1.0f / (float)res;
    params[3] = (float)layer->kind;
}

/* ---- descriptors and pipelines -------------------------------------------------------------- */

static bool create_descriptors(sv_renderer *r, const sv_gltf *g)
{
    VkDevice dev = r->ctx->device;
    VkSamplerCreateInfo si = sampler_info(VK_FILTER_LINEAR, VK_SAMPLER_ADDRESS_MODE_REPEAT);
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

    const VkShaderStageFlags vf = VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT;
    /* Set 0; the first 10 are buffers (in the order of bufs[] below), the last 3 images. */
    VkDescriptorSetLayoutBinding scene_b[SV_SCENE_BINDING_COUNT] = {
        {SV_BINDING_FRAME, VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1, vf, NULL},
        {SV_BINDING_MATERIALS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_PROBES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_LIGHTS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_CELLS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_VERTEX_BIT, NULL},
        {SV_BINDING_GRIDS, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, vf, NULL},
        {SV_BINDING_CELL_INDEX, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_PROBES_HALF, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_CUBES, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_CUBES_HALF, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_SKY, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_BRDF_LUT, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_SHADOW, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    };
    VkDescriptorSetLayoutCreateInfo li = {
        .sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO,
        .bindingCount = SV_SCENE_BINDING_COUNT,
        .pBindings = scene_b,
    };
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &li, NULL, &r->scene_set_layout));
    /* Set 1, per material: separate sets rather than a sampler array, since lavapipe (and Vulkan
     * 1.0 in general) need not support dynamically indexed sampler arrays. */
    VkDescriptorSetLayoutBinding mat_b[2] = {
        {SV_BINDING_BASE_COLOR_TEX, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
        {SV_BINDING_EMISSIVE_TEX, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1, VK_SHADER_STAGE_FRAGMENT_BIT, NULL},
    };
    li.bindingCount = 2;
    li.pBindings = mat_b;
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &li, NULL, &r->material_set_layout));
    VkDescriptorSetLayoutBinding tone_b = {SV_BINDING_HDR, VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 1,
                                           VK_SHADER_STAGE_FRAGMENT_BIT, NULL};
    li.bindingCount = 1;
    li.pBindings = &tone_b;
    VK_CHECK(vkCreateDescriptorSetLayout(dev, &li, NULL, &r->tonemap_set_layout));

    VkDescriptorPoolSize sizes[] = {
        {VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, 1},
        {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, 9},
        {VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER, 2 * r->material_count + 4},
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
    for (uint32_t m = 0; m < r->material_count; ++m) {
        ai.descriptorSetCount = 1;
        ai.pSetLayouts = &r->material_set_layout;
        VK_CHECK(vkAllocateDescriptorSets(dev, &ai, &r->material_sets[m]));
        int32_t tex[2] = {-1, -1};
        if (m < g->material_count) {
            tex[0] = texture_slot(g, &g->materials[m].base_color_texture);
            tex[1] = texture_slot(g, &g->materials[m].emissive_texture);
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
        vkUpdateDescriptorSets(dev, 1, &mw, 0, NULL);
    }

    enum { SCENE_BUFFERS = 10 };
    VkDescriptorBufferInfo bufs[SCENE_BUFFERS] = {
        {r->frame.buffer, 0, VK_WHOLE_SIZE},      {r->materials.buffer, 0, VK_WHOLE_SIZE},
        {r->probes.buffer, 0, VK_WHOLE_SIZE},     {r->lights.buffer, 0, VK_WHOLE_SIZE},
        {r->cells.buffer, 0, VK_WHOLE_SIZE},      {r->grids.buffer, 0, VK_WHOLE_SIZE},
        {r->cell_index.buffer, 0, VK_WHOLE_SIZE}, {r->probes_half.buffer, 0, VK_WHOLE_SIZE},
        {r->cubes.buffer, 0, VK_WHOLE_SIZE},      {r->cubes_half.buffer, 0, VK_WHOLE_SIZE},
    };
    VkDescriptorImageInfo imgs[3] = {
        {r->sky_sampler, r->sky.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
        {r->lut_sampler, r->brdf_lut.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
        {r->shadow_sampler, r->shadow.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL},
    };
    VkWriteDescriptorSet w[SV_SCENE_BINDING_COUNT];
    for (uint32_t i = 0; i < SV_SCENE_BINDING_COUNT; ++i)
        w[i] = (VkWriteDescriptorSet){
            .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
            .dstSet = r->scene_set,
            .dstBinding = scene_b[i].binding,
            .descriptorCount = 1,
            .descriptorType = scene_b[i].descriptorType,
            .pBufferInfo = i < SCENE_BUFFERS ? &bufs[i] : NULL,
            .pImageInfo = i >= SCENE_BUFFERS ? &imgs[i - SCENE_BUFFERS] : NULL,
        };
    vkUpdateDescriptorSets(dev, SV_SCENE_BINDING_COUNT, w, 0, NULL);
    return true;
fail:
    return false;
}

typedef struct pipeline_desc {
    const uint32_t *vs;
    size_t vs_size;
    const uint32_t *fs; /* NULL: no fragment stage (depth only) */
    size_t fs_size;
    VkPipelineLayout layout;
    VkFormat color_format;            /* VK_FORMAT_UNDEFINED = no colour attachment */
    VkFormat depth_format;            /* VK_FORMAT_UNDEFINED = no depth */
    uint32_t attribute_count;         /* vertex attributes the vertex shader reads (0 = no vertex buffer) */
    VkPrimitiveTopology topology;     /* 0 = triangle list */
    bool no_depth_test;               /* with a depth attachment: neither test nor write (background) */
    const VkSpecializationInfo *spec; /* fragment and vertex stage constants, or NULL */
} pipeline_desc;

static VkPipeline create_pipeline(sv_context *ctx, const pipeline_desc *d)
{
    VkPipeline pipe = VK_NULL_HANDLE;
    VkShaderModule vs = sv_shader_module(ctx, d->vs, d->vs_size);
    VkShaderModule fs = d->fs ? sv_shader_module(ctx, d->fs, d->fs_size) : VK_NULL_HANDLE;
    if (!vs || (d->fs && !fs)) goto fail;
    VkPipelineShaderStageCreateInfo stages[2] = {
        {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
         .stage = VK_SHADER_STAGE_VERTEX_BIT,
         .module = vs,
         .pName = "main",
         .pSpecializationInfo = d->spec},
        {.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO,
         .stage = VK_SHADER_STAGE_FRAGMENT_BIT,
         .module = fs,
         .pName = "main",
         .pSpecializationInfo = d->spec},
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
    VkPipelineInputAssemblyStateCreateInfo ia = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO,
        .topology = d->topology,
    };
    VkPipelineViewportStateCreateInfo vp = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO, .viewportCount = 1, .scissorCount = 1};
    /* No culling: glTF meshes from Blender are often open; back faces get a flipped normal. */
    VkPipelineRasterizationStateCreateInfo rs = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO,
        .polygonMode = VK_POLYGON_MODE_FILL,
        .cullMode = VK_CULL_MODE_NONE,
        /* glTF is CCW; Vulkan measures winding in framebuffer space (y down), which the y-flipped
         * projection matches, so CCW stays CCW. */
        .frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE,
        .lineWidth = 1.0f,
    };
    VkPipelineMultisampleStateCreateInfo ms = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO,
        .rasterizationSamples = VK_SAMPLE_COUNT_1_BIT,
    };
    VkPipelineDepthStencilStateCreateInfo ds = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO,
        .depthTestEnable = d->depth_format != VK_FORMAT_UNDEFINED && !d->no_depth_test,
        .depthWriteEnable = d->depth_format != VK_FORMAT_UNDEFINED && !d->no_depth_test,
        .depthCompareOp = VK_COMPARE_OP_LESS,
    };
    VkPipelineColorBlendAttachmentState blend = {.colorWriteMask = 0xF};
    VkPipelineColorBlendStateCreateInfo cb = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO,
        .attachmentCount = d->color_format != VK_FORMAT_UNDEFINED ? 1 : 0,
        .pAttachments = &blend,
    };
    VkDynamicState dyn[2] = {VK_DYNAMIC_STATE_VIEWPORT, VK_DYNAMIC_STATE_SCISSOR};
    VkPipelineDynamicStateCreateInfo dy = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_DYNAMIC_STATE_CREATE_INFO, .dynamicStateCount = 2, .pDynamicStates = dyn};
    VkPipelineRenderingCreateInfo rendering = {
        .sType = VK_STRUCTURE_TYPE_PIPELINE_RENDERING_CREATE_INFO,
        .colorAttachmentCount = d->color_format != VK_FORMAT_UNDEFINED ? 1 : 0,
        .pColorAttachmentFormats = &d->color_format,
        .depthAttachmentFormat = d->depth_format,
    };
    VkGraphicsPipelineCreateInfo info = {
        .sType = VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO,
        .pNext = &rendering,
        .stageCount = d->fs ? 2 : 1,
        .pStages = stages,
        .pVertexInputState = &vi,
        .pInputAssemblyState = &ia,
        .pViewportState = &vp,
        .pRasterizationState = &rs,
        .pMultisampleState = &ms,
        .pDepthStencilState = &ds,
        .pColorBlendState = &cb,
        .pDynamicState = &dy,
        .layout = d->layout,
    };
    VK_CHECK(vkCreateGraphicsPipelines(ctx->device, VK_NULL_HANDLE, 1, &info, NULL, &pipe));
fail:
    if (vs) vkDestroyShaderModule(ctx->device, vs, NULL);
    if (fs) vkDestroyShaderModule(ctx->device, fs, NULL);
    return pipe;
}

static bool create_pipelines(sv_renderer *r)
{
    VkDevice dev = r->ctx->device;
    VkPushConstantRange scene_push = {VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                                      sizeof(sv_gpu_draw)};
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

    VkBool32 half = r->half_probes ? VK_TRUE : VK_FALSE;
    VkSpecializationMapEntry entry = {SV_CONSTANT_HALF_PROBES, 0, sizeof(VkBool32)};
    VkSpecializationInfo spec = {1, &entry, sizeof(half), &half};
    pipeline_desc d = {mesh_vert_spv,
                       sizeof(mesh_vert_spv),
                       mesh_frag_spv,
                       sizeof(mesh_frag_spv),
                       r->scene_layout,
                       r->hdr_format,
                       r->depth_format,
                       3,
                       VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST,
                       false,
                       &spec};
    r->mesh_pipeline = create_pipeline(r->ctx, &d);
    d.vs = probe_cells_vert_spv;
    d.vs_size = sizeof(probe_cells_vert_spv);
    d.fs = probe_cells_frag_spv;
    d.fs_size = sizeof(probe_cells_frag_spv);
    d.attribute_count = 2; /* position, normal */
    r->cells_pipeline = create_pipeline(r->ctx, &d);
    d.vs = probe_outline_vert_spv;
    d.vs_size = sizeof(probe_outline_vert_spv);
    d.fs = probe_outline_frag_spv;
    d.fs_size = sizeof(probe_outline_frag_spv);
    d.attribute_count = 0;
    d.topology = VK_PRIMITIVE_TOPOLOGY_LINE_LIST;
    r->outline_pipeline = create_pipeline(r->ctx, &d);
    d.vs = sky_vert_spv;
    d.vs_size = sizeof(sky_vert_spv);
    d.fs = sky_frag_spv;
    d.fs_size = sizeof(sky_frag_spv);
    d.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
    d.no_depth_test = true;
    r->sky_pipeline = create_pipeline(r->ctx, &d);
    pipeline_desc t = {fullscreen_vert_spv,
                       sizeof(fullscreen_vert_spv),
                       tonemap_frag_spv,
                       sizeof(tonemap_frag_spv),
                       r->tonemap_layout,
                       r->output_format,
                       VK_FORMAT_UNDEFINED,
                       0,
                       VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST,
                       false,
                       NULL};
    r->tonemap_pipeline = create_pipeline(r->ctx, &t);
    if (r->shadow_count) { /* depth only: positions, the light's matrix in the push constants */
        VkPushConstantRange shadow_push = {VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(sv_gpu_shadow_draw)};
        li.setLayoutCount = 0;
        li.pSetLayouts = NULL;
        li.pPushConstantRanges = &shadow_push;
        VK_CHECK(vkCreatePipelineLayout(dev, &li, NULL, &r->shadow_layout));
        pipeline_desc sd = {shadow_vert_spv,
                            sizeof(shadow_vert_spv),
                            NULL,
                            0,
                            r->shadow_layout,
                            VK_FORMAT_UNDEFINED,
                            r->shadow_format,
                            1,
                            VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST,
                            false,
                            NULL};
        r->shadow_pipeline = create_pipeline(r->ctx, &sd);
        if (!r->shadow_pipeline) return false;
    }
    return r->mesh_pipeline && r->cells_pipeline && r->outline_pipeline && r->sky_pipeline && r->tonemap_pipeline;
fail:
    return false;
}

static VkFormat pick_depth_format(sv_context *ctx)
{
    VkFormat candidates[] = {VK_FORMAT_D32_SFLOAT, VK_FORMAT_X8_D24_UNORM_PACK32, VK_FORMAT_D16_UNORM};
    for (int i = 0; i < 3; ++i) {
        VkFormatProperties p;
        vkGetPhysicalDeviceFormatProperties(ctx->physical, candidates[i], &p);
        if (p.optimalTilingFeatures & VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT) return candidates[i];
    }
    return VK_FORMAT_D16_UNORM;
}

/* The timestamp query pool where the queue family writes timestamps (lavapipe and GPUs do). */
static bool create_timestamps(sv_renderer *r)
{
    sv_context *ctx = r->ctx;
    uint32_t n = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(ctx->physical, &n, NULL);
    VkQueueFamilyProperties *q = calloc(n ? n : 1, sizeof *q);
    if (!q) return false;
    vkGetPhysicalDeviceQueueFamilyProperties(ctx->physical, &n, q);
    uint32_t bits = ctx->queue_family < n ? q[ctx->queue_family].timestampValidBits : 0;
    free(q);
    if (!bits || ctx->properties.limits.timestampPeriod <= 0.0f) return true; /* no timestamps: none reported */
    r->timestamp_mask = bits >= 64 ? ~UINT64_C(0) : (UINT64_C(1) << bits) - 1;
    VkQueryPoolCreateInfo qi = {.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO,
                                .queryType = VK_QUERY_TYPE_TIMESTAMP,
                                .queryCount = SV_TIMESTAMPS};
    VK_CHECK(vkCreateQueryPool(ctx->device, &qi, NULL, &r->timestamps));
    return true;
fail:
    return false;
}

bool sv_renderer_create(sv_renderer *r, sv_context *ctx, const sv_scene *scene, const sv_probes *probes,
                        VkFormat output_format, const sv_renderer_desc *desc)
{
    memset(r, 0, sizeof(*r));
    r->ctx = ctx;
    r->hdr_format = VK_FORMAT_R32G32B32A32_SFLOAT; /* exact linear values for .exr output */
    r->depth_format = pick_depth_format(ctx);
    r->output_format = output_format;
    r->encode_srgb = output_format != VK_FORMAT_B8G8R8A8_SRGB && output_format != VK_FORMAT_R8G8B8A8_SRGB;
    r->shadow_cascades = desc->shadow_cascades ? desc->shadow_cascades : SV_SHADOW_DEFAULT_CASCADES;
    if (r->shadow_cascades > SV_MAX_SHADOW_CASCADES) r->shadow_cascades = SV_MAX_SHADOW_CASCADES;
    const sv_gltf *g = scene->gltf;
    if (!upload_geometry(r, g) || !upload_materials(r, g, &scene->ext) || !upload_textures(r, g) ||
        !upload_lights(r, g, &scene->ext, desc->shadow_res) || !create_shadow_maps(r, desc->shadow_res) ||
        !upload_probes(r, scene, probes, desc) || !upload_sky(r, desc->sky))
        return false;
    if (!sv_buffer_create(ctx, sizeof(sv_gpu_frame), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT, true, &r->frame)) return false;
    r->material_count = g->material_count + 1;
    return create_descriptors(r, g) && create_pipelines(r) && create_timestamps(r);
}

bool sv_renderer_gpu_times(sv_renderer *r, double ms[3])
{
    uint64_t t[SV_TIMESTAMPS];
    if (!r->timestamps || vkGetQueryPoolResults(r->ctx->device, r->timestamps, 0, SV_TIMESTAMPS, sizeof t, t,
                                                sizeof t[0], VK_QUERY_RESULT_64_BIT) != VK_SUCCESS)
        return false;
    double period_ms = r->ctx->properties.limits.timestampPeriod * 1e-6;
    for (int k = 0; k < 3; ++k) ms[k] = (double)((t[k + 1] - t[k]) & r->timestamp_mask) * period_ms;
    return true;
}

bool sv_renderer_resize(sv_renderer *r, uint32_t width, uint32_t height)
{
    sv_context *ctx = r->ctx;
    vkDeviceWaitIdle(ctx->device);
    sv_image_destroy(ctx, &r->hdr);
    sv_image_destroy(ctx, &r->depth);
    if (!sv_image_create(ctx, width, height, r->hdr_format,
                         VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_SAMPLED_BIT |
                             VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                         VK_IMAGE_ASPECT_COLOR_BIT, &r->hdr) ||
        !sv_image_create(ctx, width, height, r->depth_format, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                         VK_IMAGE_ASPECT_DEPTH_BIT, &r->depth))
        return false;
    r->width = width;
    r->height = height;
    VkDescriptorImageInfo img = {r->hdr_sampler, r->hdr.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL};
    VkWriteDescriptorSet w = {
        .sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET,
        .dstSet = r->tonemap_set,
        .dstBinding = SV_BINDING_HDR,
        .descriptorCount = 1,
        .descriptorType = VK_DESCRIPTOR_TYPE_COMBINED_IMAGE_SAMPLER,
        .pImageInfo = &img,
    };
    vkUpdateDescriptorSets(ctx->device, 1, &w, 0, NULL);
    return true;
}

void sv_view_projection(const sv_view *v, float aspect, float m[16])
{
    memset(m, 0, 16 * sizeof(float));
    if (v->yfov > 0.0f) {
        float f = 1.0f / tanf(0.5f * v->yfov);
        m[0] = f / aspect;
        m[5] = -f; /* Vulkan clip space: y down */
        m[11] = -1.0f;
        if (v->zfar > 0.0f) {
            m[10] = v->zfar / (v->znear - v->zfar);
            m[14] = v->znear * v->zfar / (v->znear - v->zfar);
        } else {
            m[10] = -1.0f;
            m[14] = -v->znear;
        }
    } else {
        float ymag = v->ymag > 0 ? v->ymag : 1.0f;
        float xmag = ymag * aspect; /* keep pixels square in the viewport */
        float zfar = v->zfar > v->znear ? v->zfar : v->znear + 1000.0f;
        m[0] = 1.0f / xmag;
        m[5] = -1.0f / ymag;
        m[10] = -1.0f / (zfar - v->znear);
        m[14] = -v->znear / (zfar - v->znear);
        m[15] = 1.0f;
    }
}

/* Inverse-transpose of the upper 3x3 as three vec4 columns. */
static void normal_matrix(const float m[16], float out[3][4])
{
    float a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[2], h = m[6], i = m[10];
    float A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
    float D = -(b * i - c * h), E = a * i - c * g, F = -(a * h - b * g);
    float G = b * f - c * e, H = -(a * f - c * d), I = a * e - b * d;
    float det = a * A + b * B + c * C;
    float s = fabsf(det) > 1e-20f ? 1.0f / det : 0.0f;
    /* inverse-transpose = cofactor matrix / det; column k of it. */
    float cols[3][3] = {{A, B, C}, {D, E, F}, {G, H, I}};
    for (int k = 0; k < 3; ++k) {
        for (int r = 0; r < 3; ++r) out[k][r] = cols[k][r] * s;
        out[k][3] = 0.0f;
    }
}

/* vkCmdUpdateBuffer of `size` bytes at `offset`, in the 65536-byte pieces the command allows. */
static void update_buffer(VkCommandBuffer cmd, VkBuffer buf, VkDeviceSize offset, const void *data, size_t size)
{
    for (size_t o = 0; o < size; o += 65536) {
        size_t n = size - o < 65536 ? size - o : 65536;
        vkCmdUpdateBuffer(cmd, buf, offset + o, n, (const char *)data + o);
    }
}

/* Rewrites the per-object probe slots (v3 grids, sv_probes_assign) when they changed since the last
 * upload: before the frame's rendering, in the storage in use, then a barrier to the shaders. */
static void upload_slots(sv_renderer *r, VkCommandBuffer cmd)
{
    const sv_probes *P = r->probes_src;
    if (!P || !P->slot_count || P->slots_version == r->slots_uploaded) return;
    r->slots_uploaded = P->slots_version;
    uint32_t n = P->slot_count, base = P->total;
    if (r->half_probes) {
        sv_gpu_probe_half *h = calloc(n, sizeof *h);
        sv_gpu_cube_half *ch = r->has_cubes ? calloc(n, sizeof *ch) : NULL;
        if (!h || (r->has_cubes && !ch)) {
            free(h);
            free(ch);
            return;
        }
        bool clamped = false;
        for (uint32_t i = 0; i < n; ++i) {
            /* A slot blends scale x colour, which can exceed the half range where each factor fits:
             * clamped to +-65504 (never Inf), with a warning. */
            sv_gpu_probe sp = P->slot_sh[i];
            sv_gpu_cube sc = P->slot_cube[i];
            for (int k = 0; k < SV_SH_MAX_COEFFS; ++k)
                for (int c = 0; c < 3; ++c) {
                    float v = fminf(fmaxf(sp.sh[k][c], -SV_HALF_MAX), SV_HALF_MAX);
                    clamped |= v != sp.sh[k][c];
                    sp.sh[k][c] = v;
                }
            for (int k = 0; k < 6; ++k)
                for (int c = 0; c < 3; ++c) {
                    float v = fminf(fmaxf(sc.faces[k][c], -SV_HALF_MAX), SV_HALF_MAX);
                    clamped |= v != sc.faces[k][c];
                    sc.faces[k][c] = v;
                }
            sv_probe_to_half(&sp, &h[i]);
            if (ch) sv_cube_to_half(&sc, &ch[i]);
        }
        if (clamped && !r->slot_clamp_warned) {
            r->slot_clamp_warned = true;
            fprintf(stderr, "schnee-view: warning: --probe-storage half: an object's interpolated probe exceeds the "
                            "half-float range (65504); clamped\n");
        }
        update_buffer(cmd, r->probes_half.buffer, (VkDeviceSize)base * sizeof *h, h, n * sizeof *h);
        if (ch) update_buffer(cmd, r->cubes_half.buffer, (VkDeviceSize)base * sizeof *ch, ch, n * sizeof *ch);
        free(h);
        free(ch);
    } else {
        update_buffer(cmd, r->probes.buffer, (VkDeviceSize)base * sizeof(sv_gpu_probe), P->slot_sh,
                      n * sizeof(sv_gpu_probe));
        if (r->has_cubes)
            update_buffer(cmd, r->cubes.buffer, (VkDeviceSize)base * sizeof(sv_gpu_cube), P->slot_cube,
                          n * sizeof(sv_gpu_cube));
    }
    VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                          .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                          .dstAccessMask = VK_ACCESS_SHADER_READ_BIT};
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_VERTEX_SHADER_BIT | VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0, 1, &mb, 0,
                         NULL, 0, NULL);
}

/* When objects left the static scene since the masks were traced (the window's first move of an
 * object), traces the per-pixel visibility masks again without them and rewrites the cell buffer
 * (same layout, so the grid buffer stays valid): a one-time hitch of the mask time per newly moved
 * object (docs/engine.md "Static scene"). */
static void retrace_masks(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene)
{
    uint32_t movable = count_movable(scene);
    if (!r->probes_src || movable == r->masks_movable) return;
    r->masks_movable = movable;
    sv_gpu_grid *grids = NULL;
    int32_t *cells = NULL;
    uint32_t n = 0;
    if (!sv_probes_gpu_grids(r->probes_src, scene, &grids, &cells, &n)) return;
    if ((VkDeviceSize)n * sizeof(int32_t) <= r->cell_index.size) {
        update_buffer(cmd, r->cell_index.buffer, 0, cells, n * sizeof(int32_t));
        VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                              .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                              .dstAccessMask = VK_ACCESS_SHADER_READ_BIT};
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0, 1, &mb, 0,
                             NULL, 0, NULL);
    }
    free(grids);
    free(cells);
}

/* The shadow pass (docs/engine.md "Shadows"): every layer cleared to depth 1, then every opaque or
 * masked primitive of every object drawn depth-only from its light; the array ends in
 * SHADER_READ_ONLY_OPTIMAL for the scene pass. */
static void record_shadows(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, const sv_gpu_frame *frame)
{
    const sv_gltf *g = scene->gltf;
    sv_image_barrier(cmd, r->shadow.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    VkViewport viewport = {0, 0, (float)r->shadow_res, (float)r->shadow_res, 0.0f, 1.0f};
    VkRect2D scissor = {{0, 0}, {r->shadow_res, r->shadow_res}};
    VkDeviceSize zero = 0;
    for (uint32_t k = 0; k < r->shadow_count; ++k) {
        VkRenderingAttachmentInfo depth = {
            .sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO,
            .imageView = r->shadow_layer_views[k],
            .imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
            .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
            .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
            .clearValue.depthStencil = {1.0f, 0},
        };
        VkRenderingInfo ri = {
            .sType = VK_STRUCTURE_TYPE_RENDERING_INFO,
            .renderArea = scissor,
            .layerCount = 1,
            .pDepthAttachment = &depth,
        };
        vkCmdBeginRendering(cmd, &ri);
        vkCmdSetViewport(cmd, 0, 1, &viewport);
        vkCmdSetScissor(cmd, 0, 1, &scissor);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->shadow_pipeline);
        vkCmdBindVertexBuffers(cmd, 0, 1, &r->vertices.buffer, &zero);
        vkCmdBindIndexBuffer(cmd, r->indices.buffer, 0, VK_INDEX_TYPE_UINT32);
        for (uint32_t o = 0; o < scene->object_count; ++o) {
            const sv_object *obj = &scene->objects[o];
            sv_gpu_shadow_draw draw;
            sv_mat4_mul(frame->shadow_view_proj[k], obj->world, draw.light_mvp);
            vkCmdPushConstants(cmd, r->shadow_layout, VK_SHADER_STAGE_VERTEX_BIT, 0, sizeof(draw), &draw);
            const sv_gltf_mesh *mesh = &g->meshes[obj->mesh];
            for (uint32_t p = 0; p < mesh->primitive_count; ++p) {
                uint32_t pi = r->mesh_prim_base[obj->mesh] + p;
                uint32_t mat = r->prim_material[pi];
                if (!r->prim_index_count[pi] ||
                    (mat < g->material_count && g->materials[mat].alpha_mode == SV_GLTF_ALPHA_BLEND))
                    continue;
                vkCmdDrawIndexed(cmd, r->prim_index_count[pi], 1, r->prim_first_index[pi], r->prim_vertex_offset[pi],
                                 0);
            }
        }
        vkCmdEndRendering(cmd);
    }
    sv_image_barrier(cmd, r->shadow.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                     VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                     VK_ACCESS_SHADER_READ_BIT);
}

void sv_renderer_record(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene, const sv_view *view,
                        VkImage out_image, VkImageView out_view, VkImageLayout out_final)
{
    sv_gpu_frame frame = {0};
    float proj[16];
    sv_view_projection(view, (float)r->width / (float)r->height, proj);
    sv_mat4_mul(proj, view->view, frame.view_proj);
    if (!sv_mat4_invert(frame.view_proj, frame.inv_view_proj)) sv_mat4_identity(frame.inv_view_proj);
    memcpy(frame.camera_pos, view->camera_pos, 3 * sizeof(float));
    frame.camera_pos[3] = r->has_sky ? (float)r->sky.mip_levels : 0.0f;
    frame.light_count = r->light_count;
    frame.debug_mode = view->debug_mode;
    frame.flags = view->flags | (r->has_sky ? SV_FRAME_SKY : 0u);
    frame.probe_count = r->probe_count;
    frame.grid_count = r->grid_count;
    frame.probe_mode = view->probe_mode;
    /* Without a cube buffer (no material and no --probe-representation asked for cubes) an
     * ambient-cube override would read zeros: it falls back to SH. */
    frame.probe_representation = view->probe_representation == SV_PROBE_REP_AMBIENT_CUBE && !r->has_cubes
                                     ? SV_PROBE_REP_SH
                                     : view->probe_representation;
    frame.normal_bias = view->normal_bias;
    /* Shadow maps: fitted to the scene's current bounds (objects move) and, for a sun's cascades, to
     * the view, so recomputed every frame. */
    bool shadows = r->shadow_count && scene->aabb_min[0] <= scene->aabb_max[0];
    cascade_view cv;
    memset(&cv, 0, sizeof(cv));
    bool sliced = shadows && r->shadow_cascades > 1 &&
                  cascade_view_fit(view, (float)r->width / (float)r->height, scene->aabb_min, scene->aabb_max, &cv);
    for (uint32_t k = 0; shadows && k < r->shadow_count; ++k) {
        const sv_shadow_layer *layer = &r->shadow_layers[k];
        if (layer->kind == SV_SHADOW_ORTHO && layer->cascades > 1 && sliced)
            shadow_projection_cascade(layer->dir, scene->aabb_min, scene->aabb_max, &cv, layer->cascade,
                                      layer->cascades, r->shadow_res, frame.shadow_view_proj[k],
                                      frame.shadow_params[k]);
        else if (layer->kind == SV_SHADOW_ORTHO)
            shadow_projection_ortho(layer->dir, scene->aabb_min, scene->aabb_max, r->shadow_res,
                                    frame.shadow_view_proj[k], frame.shadow_params[k]);
        else
            shadow_projection_perspective(layer, scene->aabb_min, scene->aabb_max, r->shadow_res,
                                          frame.shadow_view_proj[k], frame.shadow_params[k]);
    }
    memcpy(r->frame.mapped, &frame, sizeof(frame));
    if (r->timestamps) {
        vkCmdResetQueryPool(cmd, r->timestamps, 0, SV_TIMESTAMPS);
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, r->timestamps, 0);
    }
    upload_slots(r, cmd);
    retrace_masks(r, cmd, scene);
    if (shadows) record_shadows(r, cmd, scene, &frame);
    if (r->timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r->timestamps, 1);

    sv_image_barrier(cmd, r->hdr.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                     VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0,
                     VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
    sv_image_barrier(cmd, r->depth.image, VK_IMAGE_ASPECT_DEPTH_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT,
                     VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT | VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT,
                     VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT | VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT);
    VkRenderingAttachmentInfo color = {
        .sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO,
        .imageView = r->hdr.view,
        .imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
        .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
        .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
        .clearValue.color = {{0.0f, 0.0f, 0.0f, 0.0f}}, /* background is black, alpha 0 */
    };
    VkRenderingAttachmentInfo depth = {
        .sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO,
        .imageView = r->depth.view,
        .imageLayout = VK_IMAGE_LAYOUT_DEPTH_ATTACHMENT_OPTIMAL,
        .loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR,
        .storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE,
        .clearValue.depthStencil = {1.0f, 0},
    };
    VkRenderingInfo ri = {
        .sType = VK_STRUCTURE_TYPE_RENDERING_INFO,
        .renderArea = {{0, 0}, {r->width, r->height}},
        .layerCount = 1,
        .colorAttachmentCount = 1,
        .pColorAttachments = &color,
        .pDepthAttachment = &depth,
    };
    VkViewport viewport = {0, 0, (float)r->width, (float)r->height, 0.0f, 1.0f};
    VkRect2D scissor = {{0, 0}, {r->width, r->height}};
    vkCmdBeginRendering(cmd, &ri);
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->scene_layout, SV_SET_SCENE, 1, &r->scene_set, 0,
                            NULL);
    /* Set 1 must be bound for every pipeline of this layout: the default material's set. */
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->scene_layout, SV_SET_MATERIAL, 1,
                            &r->material_sets[r->material_count - 1], 0, NULL);
    uint32_t bound_material = r->material_count - 1;
    if (r->has_sky && view->debug_mode == SV_DEBUG_NONE) {
        sv_gpu_draw none = {0};
        vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                           sizeof(none), &none);
        vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->sky_pipeline);
        vkCmdDraw(cmd, 3, 1, 0, 0);
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->mesh_pipeline);
    VkDeviceSize zero = 0;
    vkCmdBindVertexBuffers(cmd, 0, 1, &r->vertices.buffer, &zero);
    vkCmdBindIndexBuffer(cmd, r->indices.buffer, 0, VK_INDEX_TYPE_UINT32);
    const sv_gltf *g = scene->gltf;
    for (uint32_t o = 0; o < scene->object_count; ++o) {
        const sv_object *obj = &scene->objects[o];
        sv_gpu_draw draw = {0};
        memcpy(draw.model, obj->world, sizeof(draw.model));
        normal_matrix(obj->world, draw.normal_matrix);
        draw.probe_index = obj->probe;
        draw.object_index = o;
        const float *w = obj->world; /* column-major: det of the upper 3x3 */
        float det = w[0] * (w[5] * w[10] - w[9] * w[6]) - w[4] * (w[1] * w[10] - w[9] * w[2]) +
                    w[8] * (w[1] * w[6] - w[5] * w[2]);
        draw.flags = (det < 0.0f ? SV_DRAW_MIRRORED : 0u) | (obj->movable ? SV_DRAW_MOVABLE : 0u) | obj->probe_flags;
        const sv_gltf_mesh *mesh = &g->meshes[obj->mesh];
        for (uint32_t p = 0; p < mesh->primitive_count; ++p) {
            uint32_t pi = r->mesh_prim_base[obj->mesh] + p;
            if (!r->prim_index_count[pi]) continue;
            draw.material_index = r->prim_material[pi];
            if (draw.material_index != bound_material) {
                bound_material = draw.material_index;
                vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->scene_layout, SV_SET_MATERIAL, 1,
                                        &r->material_sets[bound_material], 0, NULL);
            }
            vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                               sizeof(draw), &draw);
            vkCmdDrawIndexed(cmd, r->prim_index_count[pi], 1, r->prim_first_index[pi], r->prim_vertex_offset[pi], 0);
        }
    }
    if (view->show_cells && r->sphere_count + r->outline_count) {
        sv_gpu_draw draw = {0};
        sv_mat4_identity(draw.model);
        vkCmdPushConstants(cmd, r->scene_layout, VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                           sizeof(draw), &draw);
        if (r->sphere_count) {
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->cells_pipeline);
            vkCmdDrawIndexed(cmd, r->sphere_index_count, r->sphere_count, r->sphere_first_index,
                             r->sphere_vertex_offset, 0);
        }
        if (r->outline_count) { /* cell entries follow the spheres in the instance buffer */
            vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->outline_pipeline);
            vkCmdDraw(cmd, 24, r->outline_count, 0, r->sphere_count);
        }
    }
    vkCmdEndRendering(cmd);
    if (r->timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r->timestamps, 2);

    sv_image_barrier(cmd, r->hdr.image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                     VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT,
                     VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT,
                     VK_ACCESS_SHADER_READ_BIT);
    sv_image_barrier(cmd, out_image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_UNDEFINED,
                     VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, 0,
                     VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT);
    VkRenderingAttachmentInfo out = {
        .sType = VK_STRUCTURE_TYPE_RENDERING_ATTACHMENT_INFO,
        .imageView = out_view,
        .imageLayout = VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
        .loadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE,
        .storeOp = VK_ATTACHMENT_STORE_OP_STORE,
    };
    ri.pColorAttachments = &out;
    ri.pDepthAttachment = NULL;
    vkCmdBeginRendering(cmd, &ri);
    vkCmdSetViewport(cmd, 0, 1, &viewport);
    vkCmdSetScissor(cmd, 0, 1, &scissor);
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->tonemap_pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, r->tonemap_layout, 0, 1, &r->tonemap_set, 0, NULL);
    sv_gpu_tonemap tm = {view->exposure, view->tonemap, r->encode_srgb ? 1u : 0u, 0};
    vkCmdPushConstants(cmd, r->tonemap_layout, VK_SHADER_STAGE_FRAGMENT_BIT, 0, sizeof(tm), &tm);
    vkCmdDraw(cmd, 3, 1, 0, 0);
    vkCmdEndRendering(cmd);
    if (r->timestamps) vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, r->timestamps, 3);
    VkPipelineStageFlags dst_stage = out_final == VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL
                                         ? VK_PIPELINE_STAGE_TRANSFER_BIT
                                         : VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT;
    VkAccessFlags dst_access = out_final == VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL ? VK_ACCESS_TRANSFER_READ_BIT : 0;
    sv_image_barrier(cmd, out_image, VK_IMAGE_ASPECT_COLOR_BIT, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, out_final,
                     VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT, VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT, dst_stage,
                     dst_access);
}

void sv_renderer_destroy(sv_renderer *r)
{
    sv_context *ctx = r->ctx;
    if (!ctx || !ctx->device) return;
    VkDevice dev = ctx->device;
    vkDeviceWaitIdle(dev);
    if (r->timestamps) vkDestroyQueryPool(dev, r->timestamps, NULL);
    if (r->mesh_pipeline) vkDestroyPipeline(dev, r->mesh_pipeline, NULL);
    if (r->cells_pipeline) vkDestroyPipeline(dev, r->cells_pipeline, NULL);
    if (r->outline_pipeline) vkDestroyPipeline(dev, r->outline_pipeline, NULL);
    if (r->sky_pipeline) vkDestroyPipeline(dev, r->sky_pipeline, NULL);
    if (r->tonemap_pipeline) vkDestroyPipeline(dev, r->tonemap_pipeline, NULL);
    if (r->shadow_pipeline) vkDestroyPipeline(dev, r->shadow_pipeline, NULL);
    if (r->shadow_layout) vkDestroyPipelineLayout(dev, r->shadow_layout, NULL);
    if (r->shadow_sampler) vkDestroySampler(dev, r->shadow_sampler, NULL);
    for (uint32_t k = 0; k < SV_MAX_SHADOW_LAYERS; ++k)
        if (r->shadow_layer_views[k]) vkDestroyImageView(dev, r->shadow_layer_views[k], NULL);
    sv_image_destroy(ctx, &r->shadow);
    if (r->scene_layout) vkDestroyPipelineLayout(dev, r->scene_layout, NULL);
    if (r->tonemap_layout) vkDestroyPipelineLayout(dev, r->tonemap_layout, NULL);
    if (r->pool) vkDestroyDescriptorPool(dev, r->pool, NULL);
    if (r->scene_set_layout) vkDestroyDescriptorSetLayout(dev, r->scene_set_layout, NULL);
    if (r->material_set_layout) vkDestroyDescriptorSetLayout(dev, r->material_set_layout, NULL);
    if (r->tonemap_set_layout) vkDestroyDescriptorSetLayout(dev, r->tonemap_set_layout, NULL);
    if (r->sampler) vkDestroySampler(dev, r->sampler, NULL);
    if (r->hdr_sampler) vkDestroySampler(dev, r->hdr_sampler, NULL);
    if (r->sky_sampler) vkDestroySampler(dev, r->sky_sampler, NULL);
    if (r->lut_sampler) vkDestroySampler(dev, r->lut_sampler, NULL);
    sv_image_destroy(ctx, &r->sky);
    sv_image_destroy(ctx, &r->brdf_lut);
    for (uint32_t i = 0; i < r->texture_count; ++i) sv_image_destroy(ctx, &r->textures[i]);
    free(r->textures);
    free(r->material_sets);
    sv_image_destroy(ctx, &r->white);
    sv_image_destroy(ctx, &r->hdr);
    sv_image_destroy(ctx, &r->depth);
    sv_buffer *bufs[] = {&r->vertices, &r->indices,    &r->frame,  &r->materials, &r->probes, &r->probes_half,
                         &r->cubes,    &r->cubes_half, &r->lights, &r->cells,     &r->grids,  &r->cell_index};
    for (size_t i = 0; i < sizeof(bufs) / sizeof(bufs[0]); ++i) sv_buffer_destroy(ctx, bufs[i]);
    free(r->prim_first_index);
    free(r->prim_index_count);
    free(r->prim_vertex_offset);
    free(r->prim_material);
    free(r->mesh_prim_base);
    memset(r, 0, sizeof(*r));
}
