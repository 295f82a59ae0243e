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

sv_gpu_probe *sv_probes_pack(const sv_probes *probes, float fallback_radiance, const float (*sky_sh)[3],
                             uint32_t sky_band) {
    sv_gpu_probe *out = calloc(probes->total, sizeof(sv_gpu_probe));
    if (!out) return NULL;
    out[0].params[1] = 1.0f;
    out[0].params[3] = 1.0f;
    if (sky_sh) {
        /* The sky's own radiance SH: an object outside every grid is lit by the open sky. */
        out[0].params[0] = (float)sky_band;
        for (uint32_t i = 0; i < pb_sh_count(sky_band) && i < SV_SH_MAX_COEFFS; ++i)
            for (int c = 0; c < 3; ++c) out[0].sh[i][c] = sky_sh[i][c];
    } else {
        /* Uniform radiance L: L_00 = ∫ L Y_0 dω = L · 0.282094792 · 4π, all other coefficients 0. */
        float l00 = fallback_radiance * 0.282094792f * 4.0f * 3.14159265358979f;
        for (int c = 0; c < 3; ++c) out[0].sh[0][c] = l00;
    }
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        uint32_t nc = pb_sh_count(f->max_band);
        for (uint32_t p = 0; p < f->probe_count; ++p) {
            sv_gpu_probe *dst = &out[probes->grids[g].base + p];
            dst->params[0] = (float)f->max_band;
            dst->params[1] = f->probe_scale ? f->probe_scale[p] : 1.0f;
            dst->params[2] = f->probe_ambient ? f->probe_ambient[p] : f->default_ambient;
            dst->params[3] = f->validity ? f->validity[p] : 1.0f;
            for (uint32_t i = 0; i < nc && i < SV_SH_MAX_COEFFS; ++i)
                for (int c = 0; c < 3; ++c) dst->sh[i][c] = f->coeffs[((size_t)p * nc + i) * 3 + (size_t)c];
        }
    }
    return out;
}

uint16_t sv_half_from_float(float f) {
    uint32_t x;
    memcpy(&x, &f, 4);
    uint32_t sign = (x >> 16) & 0x8000u, e = (x >> 23) & 0xFFu, m = x & 0x7FFFFFu;
    if (e == 0xFFu) return (uint16_t)(sign | 0x7C00u | (m ? 0x200u : 0u));
    int32_t he = (int32_t)e - 127 + 15;
    if (he >= 31) return (uint16_t)(sign | 0x7C00u); /* overflow: inf */
    if (he <= 0) {                                     /* subnormal or zero */
        if (he < -10) return (uint16_t)sign;
        m |= 0x800000u;
        uint32_t shift = (uint32_t)(14 - he);
        uint32_t hm = m >> shift, rem = m & ((1u << shift) - 1u), half = 1u << (shift - 1u);
        if (rem > half || (rem == half && (hm & 1u))) hm++;
        return (uint16_t)(sign | hm);
    }
    uint32_t hm = m >> 13, rem = m & 0x1FFFu;
    uint32_t h = sign | ((uint32_t)he << 10) | hm;
    if (rem > 0x1000u || (rem == 0x1000u && (hm & 1u))) h++; /* carries into the exponent correctly */
    return (uint16_t)h;
}

static uint32_t pack2(float a, float b) {
    return (uint32_t)sv_half_from_float(a) | ((uint32_t)sv_half_from_float(b) << 16);
}

sv_gpu_probe_half *sv_probes_pack_half(const sv_gpu_probe *packed, uint32_t count) {
    sv_gpu_probe_half *out = calloc(count ? count : 1, sizeof(*out));
    if (!out) return NULL;
    for (uint32_t p = 0; p < count; ++p) {
        const sv_gpu_probe *s = &packed[p];
        out[p].params[0] = pack2(s->params[0], s->params[1]);
        out[p].params[1] = pack2(s->params[3], s->params[2]);
        for (uint32_t i = 0; i < SV_SH_MAX_COEFFS; ++i) {
            out[p].sh[i][0] = pack2(s->sh[i][0], s->sh[i][1]);
            out[p].sh[i][1] = pack2(s->sh[i][2], 0.0f);
        }
    }
    return out;
}

bool sv_probes_gpu_grids(const sv_probes *probes, sv_gpu_grid **grids_out, int32_t **cells_out,
                         uint32_t *cell_count) {
    size_t n = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        n += (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
    }
    *grids_out = NULL;
    *cells_out = NULL;
    *cell_count = 0;
    if (n > UINT32_MAX) {
        fprintf(stderr, "schnee-view: error: probe grids have more than 2^32 cells in total\n");
        return false;
    }
    sv_gpu_grid *grids = calloc(probes->grid_count ? probes->grid_count : 1, sizeof(*grids));
    int32_t *cells = calloc(n ? n : 1, sizeof(int32_t));
    if (!grids || !cells) {
        free(grids);
        free(cells);
        fprintf(stderr, "schnee-view: error: out of memory for the probe grids\n");
        return false;
    }
    size_t off = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        const float *ax = file_axes(f);
        sv_gpu_grid *d = &grids[g];
        for (int k = 0; k < 3; ++k) d->origin_spacing[k] = f->grid_origin[k];
        d->origin_spacing[3] = f->grid_spacing;
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) d->axes[r][k] = ax[r * 3 + k];
        for (int k = 0; k < 3; ++k) d->dims[k] = f->grid_dims[k];
        d->dims[3] = (uint32_t)off;
        d->base[0] = probes->grids[g].base;
        size_t cn = (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
        memcpy(cells + off, f->grid, cn * sizeof(int32_t));
        off += cn;
    }
    *grids_out = grids;
    *cells_out = cells;
    *cell_count = (uint32_t)n;
    return true;
}

sv_gpu_cell *sv_probes_cells(const sv_probes *probes, uint32_t *sphere_count, uint32_t *cell_count) {
    size_t n = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        size_t cells = (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
        for (size_t i = 0; i < cells; ++i) n += f->grid[i] >= 0;
    }
    uint32_t spheres = probes->total - 1;
    *sphere_count = *cell_count = 0;
    sv_gpu_cell *out = calloc(spheres + n ? spheres + n : 1, sizeof(sv_gpu_cell));
    float *acc = calloc(spheres ? spheres : 1, 4 * sizeof(float)); /* sum of cell centres, count */
    if (!out || !acc) {
        free(out);
        free(acc);
        return NULL;
    }
    sv_gpu_cell *cells = out + spheres;
    uint32_t nc = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        const float *ax = file_axes(f);
        uint32_t X = f->grid_dims[0], Y = f->grid_dims[1], Z = f->grid_dims[2];
        for (uint32_t z = 0; z < Z; ++z)
            for (uint32_t y = 0; y < Y; ++y)
                for (uint32_t x = 0; x < X; ++x) {
                    int32_t idx = f->grid[x + (size_t)y * X + (size_t)z * X * Y];
                    if (idx < 0) continue;
                    sv_gpu_cell *c = &cells[nc++];
                    float u[3] = {((float)x + 0.5f) * f->grid_spacing, ((float)y + 0.5f) * f->grid_spacing,
                                  ((float)z + 0.5f) * f->grid_spacing};
                    for (int k = 0; k < 3; ++k)
                        c->center_radius[k] = f->grid_origin[k] + u[0] * ax[k] + u[1] * ax[3 + k] + u[2] * ax[6 + k];
                    c->center_radius[3] = 0.5f * f->grid_spacing;
                    uint32_t pi = probes->grids[g].base + (uint32_t)idx;
                    c->probe[0] = pi;
                    c->probe[1] = g;
                    float *a = acc + 4 * (size_t)(pi - 1);
                    for (int k = 0; k < 3; ++k) a[k] += c->center_radius[k];
                    a[3] += 1.0f;
                }
    }
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        for (uint32_t p = 0; p < f->probe_count; ++p) {
            uint32_t pi = probes->grids[g].base + p;
            sv_gpu_cell *s = &out[pi - 1];
            const float *a = acc + 4 * (size_t)(pi - 1);
            for (int k = 0; k < 3; ++k)
                s->center_radius[k] = f->positions ? f->positions[3 * (size_t)p + k] : a[3] > 0 ? a[k] / a[3] : 0.0f;
            /* A probe no cell maps to and without a position has nowhere to be drawn: radius 0. */
            s->center_radius[3] = (f->positions || a[3] > 0) ? 0.1f * f->grid_spacing : 0.0f;
            s->probe[0] = pi;
            s->probe[1] = g;
        }
    }
    free(acc);
    *sphere_count = spheres;
    *cell_count = nc;
    return out;
}
