/* Probe grids: loading, header checks, lookup, GPU packing (see sv_probes.h). */
#include "sv_probes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "schnee/pb_sh.h"

static bool differs(float a, float b) { return fabsf(a - b) > 1e-5f * fmaxf(1.0f, fmaxf(fabsf(a), fabsf(b))); }

/* The file's grid axes (rows X, Y, Z); all-zero (never set) means identity. */
static const float *file_axes(const pb_shprobe *f) {
    static const float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int i = 0; i < 9; ++i)
        if (f->grid_axes[i] != 0.0f) return f->grid_axes;
    return identity;
}

/* Warns about every field where the glTF entry disagrees with the file it names. */
static void check_entry(const sv_gltf_probe_grid *e, const pb_shprobe *f, uint32_t index) {
    const char *n = e->name[0] ? e->name : e->uri;
    if (e->probe_count != f->probe_count)
        fprintf(stderr, "schnee-view: warning: shProbeGrids[%u] '%s': probeCount %u but the file has %u (using the file)\n",
                index, n, e->probe_count, f->probe_count);
    if (e->max_band != f->max_band)
        fprintf(stderr, "schnee-view: warning: shProbeGrids[%u] '%s': maxBand %u but the file has %u (using the file)\n",
                index, n, e->max_band, f->max_band);
    for (int k = 0; k < 3; ++k) {
        if (e->grid_dims[k] != f->grid_dims[k]) {
            fprintf(stderr, "schnee-view: warning: shProbeGrids[%u] '%s': gridDims (%u, %u, %u) but the file has (%u, %u, %u) (using the file)\n",
                    index, n, e->grid_dims[0], e->grid_dims[1], e->grid_dims[2], f->grid_dims[0], f->grid_dims[1],
                    f->grid_dims[2]);
            break;
        }
    }
    for (int k = 0; k < 3; ++k) {
        if (differs(e->grid_origin[k], f->grid_origin[k])) {
            fprintf(stderr, "schnee-view: warning: shProbeGrids[%u] '%s': gridOrigin (%g, %g, %g) but the file has (%g, %g, %g) (using the file)\n",
                    index, n, e->grid_origin[0], e->grid_origin[1], e->grid_origin[2], f->grid_origin[0],
                    f->grid_origin[1], f->grid_origin[2]);
            break;
        }
    }
    if (differs(e->grid_spacing, f->grid_spacing))
        fprintf(stderr, "schnee-view: warning: shProbeGrids[%u] '%s': gridSpacing %g but the file has %g (using the file)\n",
                index, n, e->grid_spacing, f->grid_spacing);
    const float *axes = file_axes(f);
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            if (differs(e->grid_axes[r][c], axes[r * 3 + c])) {
                fprintf(stderr, "schnee-view: warning: shProbeGrids[%u] '%s': gridAxes differ from the file's "
                                "(using the file)\n", index, n);
                return;
            }
}

bool sv_probes_load(const sv_gltf *gltf, sv_probes *out) {
    memset(out, 0, sizeof(*out));
    out->total = 1;
    if (gltf->probe_grid_count == 0) return true;
    out->grids = calloc(gltf->probe_grid_count, sizeof(sv_probe_grid));
    if (!out->grids) {
        fprintf(stderr, "schnee-view: error: out of memory for probe grids\n");
        return false;
    }
    for (uint32_t i = 0; i < gltf->probe_grid_count; ++i) {
        const sv_gltf_probe_grid *e = &gltf->probe_grids[i];
        pb_error err = {0};
        pb_shprobe *f = NULL;
        if (pb_shprobe_read(e->path, &f, &err) != PB_SUCCESS) {
            fprintf(stderr, "schnee-view: error: shProbeGrids[%u] '%s': cannot read %s: %s\n", i, e->name, e->path,
                    err.message[0] ? err.message : pb_result_string(err.code));
            sv_probes_destroy(out);
            return false;
        }
        check_entry(e, f, i);
        if (f->probe_count > UINT32_MAX - out->total) {
            fprintf(stderr, "schnee-view: error: shProbeGrids[%u]: too many probes in total\n", i);
            pb_shprobe_destroy(f);
            sv_probes_destroy(out);
            return false;
        }
        out->grids[out->grid_count].file = f;
        out->grids[out->grid_count].base = out->total;
        out->grids[out->grid_count].name = e->name;
        out->grid_count++;
        out->total += f->probe_count;
    }
    return true;
}

void sv_probes_destroy(sv_probes *probes) {
    for (uint32_t i = 0; i < probes->grid_count; ++i) pb_shprobe_destroy(probes->grids[i].file);
    free(probes->grids);
    memset(probes, 0, sizeof(*probes));
}

uint32_t sv_probes_lookup(const sv_probes *probes, const float point[3]) {
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        int32_t idx = pb_shprobe_lookup(probes->grids[g].file, point);
        if (idx >= 0 && (uint32_t)idx < probes->grids[g].file->probe_count) return probes->grids[g].base + (uint32_t)idx;
    }
    return 0;
}

uint32_t sv_probes_assign(const sv_probes *probes, sv_scene *scene) {
    uint32_t n = 0;
    for (uint32_t i = 0; i < scene->object_count; ++i) {
        sv_object *o = &scene->objects[i];
        if (!o->needs_probe) continue;
        o->needs_probe = false;
        n++;
        if (o->aabb_min[0] > o->aabb_max[0]) { /* empty mesh: no bounds, no position */
            o->probe = 0;
            continue;
        }
        float c[3] = {0.5f * (o->aabb_min[0] + o->aabb_max[0]), 0.5f * (o->aabb_min[1] + o->aabb_max[1]),
                      0.5f * (o->aabb_min[2] + o->aabb_max[2])};
        o->probe = sv_probes_lookup(probes, c);
    }
    return n;
}

sv_gpu_probe *sv_probes_pack(const sv_probes *probes, float fallback_radiance) {
    sv_gpu_probe *out = calloc(probes->total, sizeof(sv_gpu_probe));
    if (!out) return NULL;
    /* Uniform radiance L: L_00 = ∫ L Y_0 dω = L · 0.282094792 · 4π, all other coefficients 0. */
    float l00 = fallback_radiance * 0.282094792f * 4.0f * 3.14159265358979f;
    out[0].params[0] = 0.0f;
    out[0].params[1] = 1.0f;
    out[0].params[2] = 0.0f;
    for (int c = 0; c < 3; ++c) out[0].sh[0][c] = l00;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        uint32_t nc = pb_sh_count(f->max_band);
        for (uint32_t p = 0; p < f->probe_count; ++p) {
            sv_gpu_probe *dst = &out[probes->grids[g].base + p];
            dst->params[0] = (float)f->max_band;
            dst->params[1] = f->probe_scale ? f->probe_scale[p] : 1.0f;
            dst->params[2] = f->probe_ambient ? f->probe_ambient[p] : f->default_ambient;
            for (uint32_t i = 0; i < nc && i < SV_SH_MAX_COEFFS; ++i)
                for (int c = 0; c < 3; ++c) dst->sh[i][c] = f->coeffs[((size_t)p * nc + i) * 3 + (size_t)c];
        }
    }
    return out;
}

sv_gpu_cell *sv_probes_cells(const sv_probes *probes, uint32_t *count) {
    size_t n = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        size_t cells = (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
        for (size_t i = 0; i < cells; ++i) n += f->grid[i] >= 0;
    }
    *count = 0;
    sv_gpu_cell *out = calloc(n ? n : 1, sizeof(sv_gpu_cell));
    if (!out) return NULL;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        uint32_t X = f->grid_dims[0], Y = f->grid_dims[1], Z = f->grid_dims[2];
        for (uint32_t z = 0; z < Z; ++z)
            for (uint32_t y = 0; y < Y; ++y)
                for (uint32_t x = 0; x < X; ++x) {
                    int32_t idx = f->grid[x + (size_t)y * X + (size_t)z * X * Y];
                    if (idx < 0) continue;
                    sv_gpu_cell *c = &out[(*count)++];
                    const float *ax = file_axes(f);
                    float u[3] = {((float)x + 0.5f) * f->grid_spacing, ((float)y + 0.5f) * f->grid_spacing,
                                  ((float)z + 0.5f) * f->grid_spacing};
                    for (int k = 0; k < 3; ++k)
                        c->center_radius[k] = f->grid_origin[k] + u[0] * ax[k] + u[1] * ax[3 + k] + u[2] * ax[6 + k];
                    c->center_radius[3] = 0.15f * f->grid_spacing;
                    c->probe[0] = probes->grids[g].base + (uint32_t)idx;
                }
    }
    return out;
}
