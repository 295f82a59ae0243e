/* Probe bricks in the engine (see sv_bricks.h): build each tree grid's bricks with the core's pb_bricks,
 * lay the grids' pools and indirection grids side by side along z, upload both as 3D textures. Dense SH
 * grids (v1/v2, v3 structure grid) join the same pool as one cell-centred texture each (the core's
 * pb_grid_field, docs/grid-field.md), Z + 1 texels deep in each slab (one zero layer between grids). */
#include "sv_bricks.h"

#include <stdlib.h>
#include <string.h>

#include "schnee/pb_bricks.h"
#include "schnee/pb_grid_field.h"
#include "schnee/pb_sh.h"
#include "sv_brick_view.h"
#include "sv_bricks_vis.h"
#include "sv_upload.h"

/* Every grid's bricks (NULL where not bricked) and the combined textures' sizes. */
typedef struct brick_set {
    pb_bricks **b;
    pb_bricks_info *info;
    pb_grid_field **dense; /* dense SH grids' fields (NULL elsewhere): one texture of the grid each */
    uint32_t pool[3];      /* pool texels: x, y, groups * slab */
    uint32_t slab;         /* z texels of one channel group (every grid's pool depth, summed) */
    uint32_t groups;       /* channel groups of the grid with the most coefficients */
    uint32_t index[3];     /* indirection texels */
    uint64_t probes;       /* file probes of the bricked grids */
    bool f32;              /* the pool in RGBA32F (a texel beyond the half range) */
} brick_set;

/* "error" when the bricks were asked for (--probe-path bricks), else "warning": the default falls back to the
 * storage buffers where the device cannot hold or filter the bricks (sv_bricks_upload). */
static const char *s_level = "error";

static bool brickable(const sv_probe_grid *gr)
{
    return gr->tree && gr->file->representation != PB_SHPROBE_AMBIENT_CUBE;
}

/* A dense grid of SH probes: its field goes into the pool as a texture (SV_GRID_BRICKS without
 * SV_GRID_OCTREE); ambient-cube grids keep the buffers. */
static bool dense_texturable(const sv_probe_grid *gr)
{
    return !gr->tree && !gr->tetra && gr->file->grid && gr->file->representation != PB_SHPROBE_AMBIENT_CUBE;
}

/* pb_grid_field_build on the file's grid, coefficients (float64 copies), validity, scale and axes. The
 * neighbour masks stay in the cell buffer (the shader reads the home cell's). */
static bool build_dense(const sv_probe_grid *gr, uint32_t g, pb_grid_field **out)
{
    pb_error err = {0};
    pb_result rc = sv_grid_field_build(gr->file, out, &err);
    if (rc == PB_SUCCESS) return true;
    fprintf(stderr, "schnee-view: %s: --probe-path bricks: shProbeGrids[%u] '%s': %s\n", s_level, g, gr->name,
            err.message[0] ? err.message : pb_result_string(rc));
    return false;
}

/* pb_bricks_build on the file's coefficients (float64 copies), validity and scale, with the static
 * scene's tracer when there is one (step 5: leaf tables, visibility texels, brick table and records). */
static bool build_grid(const sv_probe_grid *gr, uint32_t g, sv_bricks_vis *vis, pb_bricks **out)
{
    const pb_shprobe *f = gr->file;
    uint32_t nc = pb_sh_count(f->max_band);
    size_t n = (size_t)f->probe_count * nc * 3u;
    double *c = malloc((n ? n : 1) * sizeof(double));
    if (!c) {
        fprintf(stderr, "schnee-view: %s: --probe-path bricks: out of memory for shProbeGrids[%u]\n", s_level, g);
        return false;
    }
    for (size_t i = 0; i < n; ++i) c[i] = f->coeffs[i];
    pb_bricks_desc d = {
        .tree = gr->tree, .coeff_count = nc, .coeffs = c, .validity = f->validity, .scale = f->probe_scale};
    sv_bricks_vis_desc(vis, &d);
    pb_error err = {0};
    pb_result rc = pb_bricks_build(&d, out, &err);
    free(c);
    if (rc == PB_SUCCESS) return true;
    fprintf(stderr, "schnee-view: %s: --probe-path bricks: shProbeGrids[%u] '%s': %s\n", s_level, g, gr->name,
            err.message[0] ? err.message : pb_result_string(rc));
    return false;
}

static uint32_t max_u32(uint32_t a, uint32_t b) { return a > b ? a : b; }

/* The combined layout and each bricked grid's record (SV_GRID_BRICKS, sv_gpu_grid.bricks). */
static void plan(const sv_probes *probes, brick_set *s, sv_gpu_grid *grids)
{
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        if (s->dense[g]) { /* the grid's texture at z = slab offset, x = y = 0 (bricks.glsl grid_tex_irradiance) */
            pb_grid_field_info fi;
            pb_grid_field_get_info(s->dense[g], &fi);
            sv_gpu_grid *d = &grids[g];
            d->base[2] |= SV_GRID_BRICKS;
            d->bricks[0] = d->bricks[1] = 0;
            d->bricks[2] = s->slab;
            d->bricks[3] = fi.coeff_count;
            s->pool[0] = max_u32(s->pool[0], fi.dims[0]);
            s->pool[1] = max_u32(s->pool[1], fi.dims[1]);
            s->slab += fi.dims[2] + 1u;
            s->groups = max_u32(s->groups, fi.groups);
            s->probes += probes->grids[g].file->probe_count;
            continue;
        }
        if (!s->b[g]) continue;
        const pb_bricks_info *in = &s->info[g];
        sv_gpu_grid *d = &grids[g];
        d->base[2] |= SV_GRID_BRICKS;
        d->bricks[0] = s->index[2];
        d->bricks[1] = in->pool_bricks[0] | in->pool_bricks[1] << 16;
        d->bricks[2] = s->slab;
        d->bricks[3] = in->coeff_count;
        s->pool[0] = max_u32(s->pool[0], in->pool_texels[0]);
        s->pool[1] = max_u32(s->pool[1], in->pool_texels[1]);
        s->slab += in->pool_texels[2];
        s->groups = max_u32(s->groups, in->groups);
        s->index[0] = max_u32(s->index[0], in->indirection_dims[0]);
        s->index[1] = max_u32(s->index[1], in->indirection_dims[1]);
        s->index[2] += in->indirection_dims[2];
        s->probes += probes->grids[g].file->probe_count;
    }
    s->pool[2] = s->groups * s->slab;
    for (uint32_t g = 0; g < probes->grid_count; ++g)
        if (s->b[g] || s->dense[g]) grids[g].bricks[3] |= s->slab << 8;
}

/* The device takes 3D images of these sizes in these formats, sampled (the pool: with linear filtering). */
static bool fits_device(sv_renderer *r, const brick_set *s, VkFormat pool_format)
{
    uint32_t lim = r->ctx->properties.limits.maxImageDimension3D;
    const uint32_t *dims[2] = {s->pool, s->index};
    const char *what[2] = {"brick pool", "brick indirection"};
    VkFormat fmts[2] = {pool_format, VK_FORMAT_R32G32B32A32_UINT};
    for (int k = 0; k < 2; ++k) {
        VkImageFormatProperties ip;
        VkResult res = vkGetPhysicalDeviceImageFormatProperties(
            r->ctx->physical, fmts[k], VK_IMAGE_TYPE_3D, VK_IMAGE_TILING_OPTIMAL,
            VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, 0, &ip);
        uint32_t mx = res == VK_SUCCESS ? ip.maxExtent.width : 0;
        if (dims[k][0] > lim || dims[k][1] > lim || dims[k][2] > lim || res != VK_SUCCESS ||
            dims[k][0] > ip.maxExtent.width || dims[k][1] > ip.maxExtent.height || dims[k][2] > ip.maxExtent.depth) {
            fprintf(stderr,
                    "schnee-view: %s: --probe-path bricks: the %s needs a %u x %u x %u 3D texture, beyond the "
                    "device's limit (maxImageDimension3D %u, format extent %u); use --probe-path buffers\n",
                    s_level, what[k], dims[k][0], dims[k][1], dims[k][2], lim, mx);
            return false;
        }
    }
    VkFormatProperties fp;
    vkGetPhysicalDeviceFormatProperties(r->ctx->physical, pool_format, &fp);
    if (!(fp.optimalTilingFeatures & VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT)) {
        fprintf(stderr,
                "schnee-view: %s: --probe-path bricks: the device cannot filter %s 3D textures linearly; "
                "use --probe-path buffers\n",
                s_level, pool_format == VK_FORMAT_R32G32B32A32_SFLOAT ? "RGBA32F" : "RGBA16F");
        return false;
    }
    return true;
}

/* A grid's texture (groups, z, y, x, RGBA; px × py × pz texels per group) into the combined pool: group
 * grp at (0, 0, grp · slab + zoff). */
static void copy_slabs(const brick_set *s, const uint8_t *tmp, size_t groups, size_t px, size_t py, size_t pz,
                       uint32_t zoff, uint8_t *out)
{
    size_t elem = s->f32 ? 4 : 2;
    for (size_t grp = 0; grp < groups; ++grp)
        for (size_t z = 0; z < pz; ++z)
            for (size_t y = 0; y < py; ++y) {
                size_t src = ((grp * pz + z) * py + y) * px * 4u;
                size_t dz = grp * s->slab + zoff + z, dst = ((dz * s->pool[1] + y) * s->pool[0]) * 4u;
                memcpy(out + dst * elem, tmp + src * elem, px * 4u * elem);
            }
}

/* Grid g's pool (pb_bricks_pool_f16/_f32: groups, z, y, x, RGBA) into the combined pool at its slab offset. */
static bool copy_pool(const brick_set *s, uint32_t g, uint32_t zoff, uint8_t *out, bool *overflow)
{
    const pb_bricks_info *in = &s->info[g];
    size_t elem = s->f32 ? 4 : 2, px = in->pool_texels[0], py = in->pool_texels[1], pz = in->pool_texels[2];
    uint64_t cap = (uint64_t)in->groups * px * py * pz * 4u;
    uint8_t *tmp = malloc((size_t)cap * elem);
    if (!tmp) return false;
    pb_error err = {0};
    pb_result rc = s->f32 ? pb_bricks_pool_f32(s->b[g], (float *)tmp, cap, &err)
                          : pb_bricks_pool_f16(s->b[g], (uint16_t *)tmp, cap, &err);
    *overflow = rc == PB_ERROR_TOO_LARGE;
    if (rc == PB_SUCCESS) copy_slabs(s, tmp, in->groups, px, py, pz, zoff, out);
    free(tmp);
    return rc == PB_SUCCESS;
}

/* Grid g's dense texture (pb_grid_field_texture_f16/_f32: groups, z, y, x, RGBA) at (0, 0, zoff) of each slab. */
static bool copy_dense(const brick_set *s, uint32_t g, uint32_t zoff, uint8_t *out, bool *overflow)
{
    pb_grid_field_info fi;
    pb_grid_field_get_info(s->dense[g], &fi);
    size_t elem = s->f32 ? 4 : 2, px = fi.dims[0], py = fi.dims[1], pz = fi.dims[2];
    uint64_t cap = (uint64_t)fi.groups * px * py * pz * 4u;
    uint8_t *tmp = malloc((size_t)cap * elem);
    if (!tmp) return false;
    pb_error err = {0};
    pb_result rc = s->f32 ? pb_grid_field_texture_f32(s->dense[g], (float *)tmp, cap, &err)
                          : pb_grid_field_texture_f16(s->dense[g], (uint16_t *)tmp, cap, &err);
    *overflow = rc == PB_ERROR_TOO_LARGE;
    if (rc == PB_SUCCESS) copy_slabs(s, tmp, fi.groups, px, py, pz, zoff, out);
    free(tmp);
    return rc == PB_SUCCESS;
}

/* The combined pool in RGBA16F, or RGBA32F (s->f32 set) when some texel exceeds the half range. */
static void *fill_pool(const sv_probes *probes, brick_set *s, size_t *bytes)
{
    for (int pass = 0; pass < 2; ++pass) {
        size_t elem = s->f32 ? 4 : 2;
        *bytes = (size_t)s->pool[0] * s->pool[1] * s->pool[2] * 4u * elem;
        uint8_t *out = calloc(*bytes ? *bytes : 1, 1);
        if (!out) return NULL;
        bool ok = true, overflow = false;
        uint32_t zoff = 0;
        for (uint32_t g = 0; ok && g < probes->grid_count; ++g) {
            if (s->dense[g]) {
                pb_grid_field_info fi;
                pb_grid_field_get_info(s->dense[g], &fi);
                ok = copy_dense(s, g, zoff, out, &overflow);
                zoff += fi.dims[2] + 1u;
                continue;
            }
            if (!s->b[g]) continue;
            ok = copy_pool(s, g, zoff, out, &overflow);
            zoff += s->info[g].pool_texels[2];
        }
        if (ok) return out;
        free(out);
        if (!overflow || s->f32) return NULL;
        fprintf(stderr, "schnee-view: warning: --probe-path bricks: a brick texel exceeds the half-float range; "
                        "the pool is RGBA32F\n");
        s->f32 = true;
    }
    return NULL;
}

/* The combined indirection: each grid's entries at its z offset, PB_BRICKS_NONE elsewhere. */
static uint32_t *fill_index(const sv_probes *probes, const brick_set *s, size_t *bytes)
{
    size_t n = (size_t)s->index[0] * s->index[1] * s->index[2];
    *bytes = n * 16u;
    uint32_t *out = calloc(n ? 4 * n : 4, sizeof(uint32_t));
    if (!out) return NULL;
    for (size_t i = 0; i < n; ++i) out[4 * i] = PB_BRICKS_NONE;
    uint32_t zoff = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        if (!s->b[g]) continue;
        const uint32_t *src = pb_bricks_indirection(s->b[g]), *d = s->info[g].indirection_dims;
        for (size_t z = 0; z < d[2]; ++z)
            for (size_t y = 0; y < d[1]; ++y)
                memcpy(out + (((zoff + z) * s->index[1] + y) * s->index[0]) * 4u, src + ((z * d[1] + y) * d[0]) * 4u,
                       (size_t)d[0] * 16u);
        zoff += d[2];
    }
    return out;
}

/* A sampled 3D image of dims filled from `data` (blocking). */
static bool upload_3d(sv_renderer *r, const uint32_t dims[3], VkFormat format, const void *data, size_t bytes,
                      sv_image *out)
{
    if (!sv_image_create_3d(r->ctx, dims[0], dims[1], dims[2], format,
                            VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT, out))
        return false;
    sv_buffer staging;
    if (!sv_buffer_create(r->ctx, bytes, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, true, &staging)) return false;
    memcpy(staging.mapped, data, bytes);
    VkBufferImageCopy region = {
        .imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1},
        .imageExtent = {dims[0], dims[1], dims[2]},
    };
    return sv_upload_staging_to_image(r, &staging, out, &region, 1);
}

/* The storage buffers the same grids take on the buffers path (--probe-path buffers): their entries
 * (probes and hanging nodes); a tree grid's leaves with visibility tables and a kd tree's split nodes; a
 * dense grid's cell index and neighbour mask (4 B each per cell). */
static uint64_t buffer_bytes(const sv_renderer *r, const sv_probes *probes, const brick_set *s)
{
    uint64_t bytes = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        if (!s->b[g] && !s->dense[g]) continue;
        const pb_shprobe *f = probes->grids[g].file;
        bytes +=
            (uint64_t)probes->grids[g].entries * (r->half_probes ? sizeof(sv_gpu_probe_half) : sizeof(sv_gpu_probe));
        if (s->dense[g]) {
            bytes += (uint64_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2] * 8u;
            continue;
        }
        bytes += (uint64_t)f->element_count * (SV_LEAF_INTS + SV_LEAF_VIS_INTS) * 4u;
        if (f->structure == PB_SHPROBE_KDTREE) bytes += (uint64_t)f->split_node_count * 4u;
    }
    return bytes;
}

/* Keeps the bricks' figures for sv_bricks_report (printed once the storage buffers exist). */
static void keep_stats(sv_renderer *r, const sv_probes *probes, const brick_set *s, size_t pool_bytes,
                       size_t index_bytes)
{
    memset(&r->brick_stats, 0, sizeof r->brick_stats);
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        if (s->b[g]) r->brick_stats.bricks += s->info[g].brick_count, r->brick_stats.texels += s->info[g].texel_count;
        if (s->dense[g]) ++r->brick_stats.dense;
    }
    r->brick_stats.probes = s->probes;
    r->brick_stats.pool_bytes = pool_bytes;
    r->brick_stats.index_bytes = index_bytes;
    r->brick_stats.buffers_path_bytes = buffer_bytes(r, probes, s);
    memcpy(r->brick_stats.pool, s->pool, sizeof s->pool);
    memcpy(r->brick_stats.index, s->index, sizeof s->index);
    r->brick_stats.groups = s->groups;
    r->brick_stats.f32 = s->f32;
}

void sv_bricks_report(const sv_renderer *r, uint64_t gpu_bytes, uint64_t file_probes)
{
    if (!r->bricks) return;
    if (r->brick_stats.dense)
        fprintf(stderr, "schnee-view: probe bricks: %llu dense grid(s) as cell-centred textures\n",
                (unsigned long long)r->brick_stats.dense);
    double per = r->brick_stats.probes ? 1.0 / (double)r->brick_stats.probes : 0.0;
    fprintf(stderr,
            "schnee-view: probe bricks: %llu bricks (%llu texels) of %llu probes; pool %u x %u x %u %s (%u groups), "
            "%llu B; indirection %u x %u x %u, %llu B; GPU memory %.1f B per probe (storage buffers, %s: %.1f B per "
            "probe); allocated %.1f B per file probe (the bricks, brick tables, records and the storage buffers "
            "this run uploads: the probe memory line)\n",
            (unsigned long long)r->brick_stats.bricks, (unsigned long long)r->brick_stats.texels,
            (unsigned long long)r->brick_stats.probes, r->brick_stats.pool[0], r->brick_stats.pool[1],
            r->brick_stats.pool[2], r->brick_stats.f32 ? "RGBA32F" : "RGBA16F", r->brick_stats.groups,
            (unsigned long long)r->brick_stats.pool_bytes, r->brick_stats.index[0], r->brick_stats.index[1],
            r->brick_stats.index[2], (unsigned long long)r->brick_stats.index_bytes,
            (double)(r->brick_stats.pool_bytes + r->brick_stats.index_bytes) * per, r->half_probes ? "half" : "float",
            (double)r->brick_stats.buffers_path_bytes * per,
            file_probes ? (double)gpu_bytes / (double)file_probes : 0.0);
}

/* Builds every bricked grid's bricks, plans, checks and uploads the pool and the indirection. Returns 1 on
 * success, 0 on a failure after the GPU objects were touched, -1 on one before (the core's refusal, memory,
 * the device's limits or filtering: the stand-ins are still bound, so the buffers can take over). */
static int upload_bricks(sv_renderer *r, const sv_probes *probes, brick_set *s, sv_gpu_grid *grids, sv_bricks_vis *vis)
{
    bool any = false;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        if (dense_texturable(&probes->grids[g])) {
            if (!build_dense(&probes->grids[g], g, &s->dense[g])) return -1;
            any = true;
            continue;
        }
        if (!brickable(&probes->grids[g])) continue;
        if (!build_grid(&probes->grids[g], g, vis, &s->b[g])) return -1;
        pb_bricks_get_info(s->b[g], &s->info[g]);
        any = true;
    }
    if (!any) return 1; /* no tree or dense SH grid: the stand-ins stay bound, every grid takes the buffers */
    plan(probes, s, grids);
    size_t pool_bytes = 0, index_bytes = 0;
    void *pool = fill_pool(probes, s, &pool_bytes);
    uint32_t *index = pool ? fill_index(probes, s, &index_bytes) : NULL;
    VkFormat pf = s->f32 ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R16G16B16A16_SFLOAT;
    if (!pool || !index) fprintf(stderr, "schnee-view: %s: --probe-path bricks: out of memory for the pool\n", s_level);
    if (!pool || !index || !fits_device(r, s, pf)) {
        free(pool);
        free(index);
        return -1;
    }
    bool ok = sv_bricks_vis_upload(r, vis, s->b, probes->grid_count, index, s->index);
    if (ok) {
        sv_image_destroy(r->ctx, &r->brick_pool);
        if (s->index[2]) sv_image_destroy(r->ctx, &r->brick_index);
        /* Dense grids alone: no indirection (the 1x1x1 stand-in stays bound). */
        ok = upload_3d(r, s->pool, pf, pool, pool_bytes, &r->brick_pool) &&
             (!s->index[2] || upload_3d(r, s->index, VK_FORMAT_R32G32B32A32_UINT, index, index_bytes, &r->brick_index));
    }
    if (ok) keep_stats(r, probes, s, pool_bytes, index_bytes);
    r->bricks = ok;
    free(pool);
    free(index);
    return ok ? 1 : 0;
}

bool sv_bricks_upload(sv_renderer *r, const sv_scene *scene, const sv_probes *probes, sv_gpu_grid *grids, bool enabled,
                      bool required)
{
    s_level = required ? "error" : "warning";
    VkSamplerCreateInfo si = sv_sampler_info(VK_FILTER_LINEAR, VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE);
    VK_CHECK(vkCreateSampler(r->ctx->device, &si, NULL, &r->brick_sampler));
    si = sv_sampler_info(VK_FILTER_NEAREST, VK_SAMPLER_ADDRESS_MODE_CLAMP_TO_EDGE);
    VK_CHECK(vkCreateSampler(r->ctx->device, &si, NULL, &r->brick_index_sampler));
    static const uint16_t zero_half[4] = {0, 0, 0, 0};
    static const uint32_t no_brick[4] = {PB_BRICKS_NONE, 0, 0, 0};
    const uint32_t one[3] = {1, 1, 1};
    if (!upload_3d(r, one, VK_FORMAT_R16G16B16A16_SFLOAT, zero_half, sizeof zero_half, &r->brick_pool) ||
        !upload_3d(r, one, VK_FORMAT_R32G32B32A32_UINT, no_brick, sizeof no_brick, &r->brick_index) ||
        !sv_bricks_vis_standin(r))
        return false;
    if (!enabled || !probes->grid_count) return true;
    brick_set s = {0};
    s.b = calloc(probes->grid_count, sizeof *s.b);
    s.info = calloc(probes->grid_count, sizeof *s.info);
    s.dense = calloc(probes->grid_count, sizeof *s.dense);
    sv_bricks_vis vis;
    sv_bricks_vis_begin(&vis, scene);
    int up = s.b && s.info && s.dense ? upload_bricks(r, probes, &s, grids, &vis) : -1;
    if (!s.b || !s.info || !s.dense) fprintf(stderr, "schnee-view: %s: --probe-path bricks: out of memory\n", s_level);
    if (up < 0 && !required) { /* the default path: the storage buffers take every grid */
        for (uint32_t g = 0; g < probes->grid_count; ++g) {
            grids[g].base[2] &= ~(uint32_t)SV_GRID_BRICKS;
            memset(grids[g].bricks, 0, sizeof grids[g].bricks);
        }
        r->bricks = false;
        fprintf(stderr, "schnee-view: warning: probe bricks unavailable (above); per-pixel probes from the storage "
                        "buffers (--probe-path buffers)\n");
        up = 1;
    }
    bool ok = up > 0;
    if (ok && r->bricks) ok = sv_brick_view_capture(r, s.b, probes->grid_count); /* the brick view's regions */
    sv_bricks_vis_end(&vis);
    for (uint32_t g = 0; s.b && g < probes->grid_count; ++g) pb_bricks_destroy(s.b[g]);
    for (uint32_t g = 0; s.dense && g < probes->grid_count; ++g) pb_grid_field_destroy(s.dense[g]);
    free(s.dense);
    free(s.b);
    free(s.info);
    return ok;
fail:
    return false;
}

void sv_bricks_destroy(sv_renderer *r)
{
    sv_image_destroy(r->ctx, &r->brick_pool);
    sv_image_destroy(r->ctx, &r->brick_index);
    sv_buffer_destroy(r->ctx, &r->brick_vis);
    if (r->brick_sampler) vkDestroySampler(r->ctx->device, r->brick_sampler, NULL);
    if (r->brick_index_sampler) vkDestroySampler(r->ctx->device, r->brick_index_sampler, NULL);
    r->brick_sampler = r->brick_index_sampler = VK_NULL_HANDLE;
}
