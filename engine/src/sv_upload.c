/* Scene upload (see sv_upload.h): geometry, materials, textures, lights, probe buffers and the sky
 * go to the GPU once at start-up; per frame, the probes' per-object slots and, after an object's
 * first move, the visibility masks. */
#include "sv_upload.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "schnee/pb_image.h"
#include "sv_bricks.h"
#include "sv_shadows.h"

static void fail_msg(const char *what) { fprintf(stderr, "schnee-view: error: %s\n", what); }

/* ---- geometry ------------------------------------------------------------------------------- */

/* The probe view's UV sphere of radius 1 (appended after the scene's primitives): its resolution. */
enum { SPHERE_SEG = 32, SPHERE_RINGS = 16 };

/* Interleaves every primitive's positions, normals (default +Y) and uvs (default 0) into v and
 * its indices into ix, recording where each primitive starts; *vo, *io: vertices, indices written. */
static void copy_primitives(sv_renderer *r, const sv_gltf *g, float *v, uint32_t *ix, size_t *vo_out, size_t *io_out)
{
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
    *vo_out = vo;
    *io_out = io;
}

/* The UV sphere's vertices at vertex vo and its indices (relative to vo) at index io; returns the
 * indices written in all. */
static size_t append_sphere(float *v, uint32_t *ix, size_t vo, size_t io)
{
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
    return io;
}

bool sv_upload_geometry(sv_renderer *r, const sv_gltf *g)
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
    size_t vo = 0, io = 0;
    copy_primitives(r, g, v, ix, &vo, &io);
    r->sphere_vertex_offset = (int32_t)vo;
    r->sphere_first_index = (uint32_t)io;
    r->sphere_index_count = (uint32_t)sphere_idx;
    io = append_sphere(v, ix, vo, io);
    ok = sv_buffer_create_with_data(r->ctx, v, (verts + sphere_verts) * SV_VERTEX_FLOATS * sizeof(float),
                                    VK_BUFFER_USAGE_VERTEX_BUFFER_BIT, &r->vertices) &&
         sv_buffer_create_with_data(r->ctx, ix, io * sizeof(uint32_t), VK_BUFFER_USAGE_INDEX_BUFFER_BIT, &r->indices);
done:
    free(v);
    free(ix);
    return ok;
}

/* ---- materials, textures, lights, probes ----------------------------------------------------- */

int32_t sv_texture_slot(const sv_gltf *g, const sv_gltf_texture_ref *ref)
{
    if (ref->texture < 0 || (uint32_t)ref->texture >= g->texture_count) return -1;
    if (g->textures[ref->texture].image < 0) return -1;
    return ref->texture;
}

bool sv_upload_materials(sv_renderer *r, const sv_gltf *g, const sv_ext *ext)
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
        m[i].base_color_texture = sv_texture_slot(g, &s->base_color_texture);
        m[i].emissive_texture = sv_texture_slot(g, &s->emissive_texture);
        m[i].probe_mode = ext->materials[i].probe_mode;
        m[i].probe_representation = ext->materials[i].probe_representation;
    }
    bool ok = sv_buffer_create_with_data(r->ctx, m, n * sizeof(*m), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, &r->materials);
    free(m);
    return ok;
}

/* Copies `regions` of a filled staging buffer into `out` (all its levels go UNDEFINED → transfer
 * → shader-read), blocking, then frees the staging buffer. Shared by every sampled-image upload. */
bool sv_upload_staging_to_image(sv_renderer *r, sv_buffer *staging, sv_image *out, const VkBufferImageCopy *regions,
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
    return sv_upload_staging_to_image(r, &staging, out, &region, 1);
}

/* Reads a glTF image through the core's image layer (the same checks and limits either way): a file
 * beside the glTF (checked first: a FIFO or a huge file is refused), or the embedded bytes of a
 * bufferView or data: URI, decoded from memory. The mime type names the format where the content
 * does not. Returns false with a warning; the caller then uses white. */
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
    const char *name = img->name && *img->name ? img->name : "embedded";
    char label[288];
    snprintf(label, sizeof label, "%.256s%s", name, img->mime_type && strstr(img->mime_type, "jpeg") ? ".jpg" : ".png");
    if (pb_image_read_memory(img->data, img->size, label, out, &err) == PB_SUCCESS) return true;
    fprintf(stderr, "schnee-view: warning: embedded image '%s': %s (using white)\n", name, err.message);
    return false;
}

bool sv_upload_textures(sv_renderer *r, const sv_gltf *g)
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

bool sv_upload_lights(sv_renderer *r, const sv_gltf *g, const sv_ext *ext, uint32_t shadow_res)
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
        if (shadow_res && mode != SV_LIGHT_MODE_BAKED) l[i].spot[3] = (float)sv_shadows_assign(r, li, s, &cascades);
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

/* The probes packed for the GPU (sv_upload_probes): float or half SH, ambient cubes when asked for,
 * the probe view's cells, the grids and their cell index. */
typedef struct probe_pack {
    sv_gpu_probe *p;
    sv_gpu_probe_half *ph;
    sv_gpu_cube *cubes;
    sv_gpu_cube_half *cubes_half;
    sv_gpu_cell *cells;
    sv_gpu_grid *grids;
    int32_t *cell_index;
    uint32_t count; /* probes, the per-object slots of v3 grids included */
    uint32_t nspheres, ncells, grid_cells;
    bool half, want_cubes;
} probe_pack;

/* Packs the probes (false with a message when out of memory); free_probe_pack frees either way. */
static bool pack_probes(const sv_scene *scene, const sv_probes *probes, const sv_renderer_desc *desc, probe_pack *k)
{
    const sv_sky *sky = desc->sky && desc->sky->present ? desc->sky : NULL;
    k->p = sv_probes_pack(probes, desc->fallback_radiance, sky ? sky->sh : NULL, sky ? sky->max_band : 0);
    /* Half storage only when every value fits: an overflow would become Inf and shade the objects
     * lit by that probe dark (NaN) or white, silently. Then float storage, with a warning. */
    k->half = desc->half_probes;
    char msg[320];
    if (k->p && k->half && !sv_probes_fit_half(probes, k->p, msg, sizeof msg)) {
        fprintf(stderr, "schnee-view: warning: --probe-storage half: %s; using float storage\n", msg);
        k->half = false;
    }
    /* Ambient cubes (docs/ambient-cube.md §5) only when asked for: by the command line, by a
     * material or by an object (VULKAN_SCHNEE_node). They follow the SH storage; a cube colour
     * beyond the half range sends both to float. */
    k->want_cubes = desc->cube_probes || sv_probes_have_cube_grids(probes) || sv_scene_nodes_want_cubes(scene);
    for (uint32_t i = 0; i < scene->ext.material_count; ++i)
        k->want_cubes = k->want_cubes || scene->ext.materials[i].probe_representation == SV_PROBE_REP_AMBIENT_CUBE;
    k->cubes = k->p && k->want_cubes ? sv_probes_pack_all_cubes(probes, k->p) : NULL;
    if (k->cubes && k->half && !sv_probes_cubes_fit_half(probes, k->cubes, msg, sizeof msg)) {
        fprintf(stderr, "schnee-view: warning: --probe-storage half: %s; using float storage\n", msg);
        k->half = false;
    }
    /* The per-object slots of v3 grids follow the grids' entries (rewritten when objects move). */
    k->count = probes->total + probes->slot_count;
    if (k->p && probes->slot_count) {
        sv_gpu_probe *grown = realloc(k->p, k->count * sizeof(*k->p));
        if (grown) memcpy(grown + probes->total, probes->slot_sh, probes->slot_count * sizeof(*k->p));
        k->p = grown;
        if (k->cubes) {
            sv_gpu_cube *gc = realloc(k->cubes, k->count * sizeof(*k->cubes));
            if (gc)
                memcpy(gc + probes->total, probes->slot_cube, probes->slot_count * sizeof(*k->cubes));
            else
                free(k->cubes);
            k->cubes = gc;
        }
    }
    k->cubes_half = k->cubes && k->half ? sv_probes_pack_cubes_half(k->cubes, k->count) : NULL;
    k->ph = k->p && k->half ? sv_probes_pack_half(k->p, k->count) : NULL;
    k->cells = sv_probes_cells(probes, &k->nspheres, &k->ncells);
    bool ok = k->p && k->cells && (!k->half || k->ph) && (!k->want_cubes || (k->cubes && (!k->half || k->cubes_half)));
    if (!ok) fail_msg("out of memory packing probes");
    return ok && sv_probes_gpu_grids(probes, scene, &k->grids, &k->cell_index, &k->grid_cells);
}

/* The storage buffers of the packed probes. Only the storage in use (float or half) holds the probes
 * and the cubes; the other binding gets one zero entry. */
static bool create_probe_buffers(sv_renderer *r, const sv_probes *probes, const probe_pack *k)
{
    static const sv_gpu_probe zero_probe;
    static const sv_gpu_probe_half zero_half;
    static const sv_gpu_cube zero_cube;
    static const sv_gpu_cube_half zero_cube_half;
    const VkBufferUsageFlags ssbo = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    bool half = k->half, float_cubes = k->cubes && !half;
    uint32_t count = k->count, cells = k->nspheres + k->ncells;
    return sv_buffer_create_with_data(r->ctx, half ? &zero_probe : (const void *)k->p,
                                      half ? sizeof(*k->p) : count * sizeof(*k->p), ssbo, &r->probes) &&
           sv_buffer_create_with_data(r->ctx, half ? (const void *)k->ph : &zero_half,
                                      half ? count * sizeof(*k->ph) : sizeof(*k->ph), ssbo, &r->probes_half) &&
           sv_buffer_create_with_data(r->ctx, float_cubes ? (const void *)k->cubes : &zero_cube,
                                      float_cubes ? count * sizeof(*k->cubes) : sizeof(*k->cubes), ssbo, &r->cubes) &&
           sv_buffer_create_with_data(r->ctx, k->cubes_half ? (const void *)k->cubes_half : &zero_cube_half,
                                      k->cubes_half ? count * sizeof(*k->cubes_half) : sizeof(*k->cubes_half), ssbo,
                                      &r->cubes_half) &&
           sv_buffer_create_with_data(r->ctx, k->cells, (cells ? cells : 1) * sizeof(*k->cells), ssbo, &r->cells) &&
           sv_buffer_create_with_data(
               r->ctx, k->grids, (probes->grid_count ? probes->grid_count : 1) * sizeof(*k->grids), ssbo, &r->grids) &&
           sv_buffer_create_with_data(r->ctx, k->cell_index, (k->grid_cells ? k->grid_cells : 1) * sizeof(int32_t),
                                      ssbo, &r->cell_index);
}

/* Whether a shader of this run can read the file's probes or the whole cell index (docs/engine.md "Probe
 * buffers"): always on the buffers path (--probe-path buffers, as before); with the bricks, the probe view
 * (its spheres), ambient cubes (per pixel they take the buffers path) and any grid that is neither bricked
 * (a tree grid's bricks or a dense grid's texture, step 5 included) nor tetrahedra: grids of cubes, grids
 * the bricks did not take (the device's fallback). Tetrahedra are read per object only, through the
 * object's slot (per pixel skips them); so is a dense grid per object (sv_probes_use_slots). */
static bool file_probes_read(const sv_probes *probes, const sv_renderer_desc *desc, const probe_pack *k)
{
    if (!desc->bricks || desc->probe_view || k->want_cubes) return true;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        uint32_t f = k->grids[g].base[2];
        if (f & SV_GRID_CUBE_ONLY) return true;
        if (!(f & (SV_GRID_TETRA | SV_GRID_BRICKS))) return true;
    }
    return false;
}

/* Cell-index entries of every dense grid's cells (sv_probes_gpu_grids: the cell indices, then as many
 * masks, then the trees' entries). */
static uint32_t dense_cells(const sv_probes *probes)
{
    uint64_t n = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        if (!probes->grids[g].tree && !probes->grids[g].tetra && f->grid)
            n += (uint64_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
    }
    return (uint32_t)n;
}

/* The probe buffer without the file's probes: the fallback (entry 0), then the per-object slots moved down
 * from entry `total` to entry 1. The cell index keeps the dense grids' neighbour masks alone (a dense grid's
 * texture reads its home cell's, grid_tex_irradiance), their records pointing there; else one dummy entry
 * (create_probe_buffers). */
static void keep_fallback_and_slots(probe_pack *k, const sv_probes *probes)
{
    uint32_t n = probes->slot_count, t = probes->total, cells = dense_cells(probes);
    memmove(k->p + 1, k->p + t, n * sizeof *k->p);
    if (k->ph) memmove(k->ph + 1, k->ph + t, n * sizeof *k->ph);
    k->count = 1u + n;
    memmove(k->cell_index, k->cell_index + cells, cells * sizeof *k->cell_index);
    for (uint32_t g = 0; g < probes->grid_count; ++g)
        if (!(k->grids[g].base[2] & (SV_GRID_OCTREE | SV_GRID_TETRA))) k->grids[g].base[1] -= cells;
    k->grid_cells = cells;
}

/* The `probe bricks:` line (sv_bricks_report) and the `probe memory:` line: every probe texture and storage
 * buffer as allocated (the 1x1x1 stand-ins and the one-entry dummies included), per file probe. */
static void report_memory(const sv_renderer *r, const sv_probes *probes)
{
    uint64_t file = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) file += probes->grids[g].file->probe_count;
    if (!probes->grid_count) return;
    const sv_buffer *b[] = {&r->probes, &r->probes_half, &r->cubes,     &r->cubes_half,
                            &r->cells,  &r->grids,       &r->cell_index};
    uint64_t sz[7], buffers = 0;
    for (int i = 0; i < 7; ++i) buffers += sz[i] = b[i]->size;
    /* The stand-ins: a 1x1x1 RGBA16F pool (8 B) and RGBA32UI indirection (16 B; kept with dense grids only). */
    uint64_t pool = r->bricks ? r->brick_stats.pool_bytes : 8u;
    uint64_t index = r->bricks && r->brick_stats.index_bytes ? r->brick_stats.index_bytes : 16u;
    uint64_t total = pool + index + r->brick_vis.size + buffers;
    sv_bricks_report(r, total, file);
    fprintf(stderr,
            "schnee-view: probe memory: %llu B on the GPU for %llu file probe(s), %.1f B per probe: pool %llu B, "
            "indirection %llu B, brick tables and records %llu B, storage buffers %llu B (probes %llu, probes half "
            "%llu, cubes %llu, cubes half %llu, cells %llu, grids %llu, cell index %llu); %s %u entries\n",
            (unsigned long long)total, (unsigned long long)file, file ? (double)total / (double)file : 0.0,
            (unsigned long long)pool, (unsigned long long)index, (unsigned long long)r->brick_vis.size,
            (unsigned long long)buffers, (unsigned long long)sz[0], (unsigned long long)sz[1],
            (unsigned long long)sz[2], (unsigned long long)sz[3], (unsigned long long)sz[4], (unsigned long long)sz[5],
            (unsigned long long)sz[6],
            r->file_probes ? "file probes uploaded: the probe buffer holds"
                           : "file probes not uploaded (no shader of this run reads them): the probe buffer holds the "
                             "fallback and the per-object slots,",
            r->probe_count);
}

bool sv_upload_probes(sv_renderer *r, const sv_scene *scene, const sv_probes *probes, const sv_renderer_desc *desc)
{
    probe_pack k = {0};
    bool ok = pack_probes(scene, probes, desc, &k);
    r->half_probes = k.half;
    /* The bricks (--probe-path bricks) mark their grids' records before the grid buffer is made. */
    ok = ok && sv_bricks_upload(r, scene, probes, k.grids, desc->bricks, desc->bricks_required);
    r->file_probes = !ok || file_probes_read(probes, desc, &k);
    if (!r->file_probes) keep_fallback_and_slots(&k, probes);
    /* Only the probe view reads the cell buffer (--probe-path buffers keeps its uploads as they were). */
    if (desc->bricks && !desc->probe_view) k.nspheres = k.ncells = 0;
    r->probe_rebase = r->file_probes ? 0u : probes->total - 1u;
    ok = ok && create_probe_buffers(r, probes, &k);
    r->probe_count = k.count;
    r->grid_count = probes->grid_count;
    r->probes_src = probes;
    r->masks_movable = count_movable(scene);
    /* The first frame rewrites the slots through sv_upload_probe_slots(), the path a moving object takes. */
    r->slots_uploaded = probes->slots_version - 1u;
    r->sphere_count = k.nspheres;
    r->outline_count = k.ncells;
    r->half_probes = k.half;
    r->has_cubes = k.cubes != NULL;
    free(k.cubes);
    free(k.cubes_half);
    free(k.p);
    free(k.ph);
    free(k.cells);
    free(k.grids);
    free(k.cell_index);
    if (ok) report_memory(r, probes);
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
    return sv_upload_staging_to_image(r, &staging, out, regions, count);
}

/* Sky mips (or a 1x1 black stand-in) and the BRDF LUT (always: the binding must hold an image). */
bool sv_upload_sky(sv_renderer *r, const sv_sky *sky)
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
void sv_upload_probe_slots(sv_renderer *r, VkCommandBuffer cmd)
{
    const sv_probes *P = r->probes_src;
    if (!P || !P->slot_count || P->slots_version == r->slots_uploaded) return;
    r->slots_uploaded = P->slots_version;
    uint32_t n = P->slot_count, base = P->total - r->probe_rebase; /* after the file's probes, or at 1 */
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
void sv_upload_retrace_masks(sv_renderer *r, VkCommandBuffer cmd, const sv_scene *scene)
{
    uint32_t movable = count_movable(scene);
    /* Without the file's probes the cell index holds the dense grids' masks alone (keep_fallback_and_slots). */
    uint32_t skip = r->probes_src && !r->file_probes ? dense_cells(r->probes_src) : 0;
    if (!r->probes_src || (!r->file_probes && !skip) || movable == r->masks_movable) return;
    r->masks_movable = movable;
    sv_gpu_grid *grids = NULL;
    int32_t *cells = NULL;
    uint32_t n = 0;
    if (!sv_probes_gpu_grids(r->probes_src, scene, &grids, &cells, &n)) return;
    if (skip) n = skip; /* the masks, which follow the dense cells' indices */
    if ((VkDeviceSize)n * sizeof(int32_t) <= r->cell_index.size) {
        update_buffer(cmd, r->cell_index.buffer, 0, cells + skip, n * sizeof(int32_t));
        VkMemoryBarrier mb = {.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER,
                              .srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT,
                              .dstAccessMask = VK_ACCESS_SHADER_READ_BIT};
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_FRAGMENT_SHADER_BIT, 0, 1, &mb, 0,
                             NULL, 0, NULL);
    }
    free(grids);
    free(cells);
}
