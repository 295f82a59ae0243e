/* GPU packing of the probe grids (see sv_probe_pack.h): SH and ambient cubes, full and half
 * storage, the per-pixel grids with their visibility masks (sv_probe_vis.h), the debug spheres. */
#include "sv_probe_pack.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "schnee/pb_ambient_cube.h"
#include "schnee/pb_sh.h"
#include "sv_probe_vis.h"

/* Resolves an octree's hanging nodes once into the entries after its probes (docs/engine.md
 * "Version 3 grids"). A hanging node j holds V_j = A_j / a_j with validity a_j and scale 1, where
 * A_j = sum_k w_k A(src_k), a_j = sum_k w_k a(src_k) in file order, and a probe's (A, a) = (m s V, m)
 * with m = 1 for validity > 0 else 0, s its scale. Then sum_c w_c m_c s_c V_c / sum_c w_c m_c over a
 * leaf's corners equals pb_interp_query_cotree's validity-dropped, renormalised weights over the probes
 * exactly (both are linear in the expansion). `sh` (entries: probes then hanging) or `cube`. */
static void resolve_hanging(const pb_shprobe *f, sv_gpu_probe *sh, sv_gpu_cube *cube)
{
    uint32_t P = f->probe_count, H = f->hanging_count;
    uint32_t nc = sh ? pb_sh_count(f->max_band) : 6u;
    if (nc > SV_SH_MAX_COEFFS) nc = SV_SH_MAX_COEFFS;
    size_t stride = 3u * nc + 1u; /* A (colours), a */
    double *acc = calloc(((size_t)P + H) * stride + 1, sizeof(double));
    if (!acc) return; /* the hanging entries stay 0 with validity 0: dropped, never garbage */
    for (uint32_t p = 0; p < P; ++p) {
        const float *prm = sh ? sh[p].params : cube[p].params;
        double m = prm[3] > 0.0f ? 1.0 : 0.0, sc = prm[1];
        double *a = acc + (size_t)p * stride;
        for (uint32_t k = 0; k < nc; ++k)
            for (int c = 0; c < 3; ++c) a[3 * k + c] = m * sc * (sh ? sh[p].sh[k][c] : cube[p].faces[k][c]);
        a[3 * nc] = m;
    }
    for (uint32_t j = 0; j < H; ++j) {
        double *a = acc + ((size_t)P + j) * stride;
        for (uint32_t k = 0; k < 4; ++k) {
            uint32_t src = f->hanging_sources[4u * j + k];
            double w = f->hanging_weights[4u * j + k];
            if (!(w > 0.0) || src >= P + j) continue; /* the reader checks sources are earlier */
            const double *b = acc + (size_t)src * stride;
            for (size_t q = 0; q < stride; ++q) a[q] += w * b[q];
        }
        double m = a[3 * nc];
        float *prm = sh ? sh[P + j].params : cube[P + j].params;
        prm[0] = (float)f->max_band;
        prm[1] = 1.0f;
        prm[2] = 0.0f;
        prm[3] = (float)m;
        for (uint32_t k = 0; k < nc; ++k)
            for (int c = 0; c < 3; ++c) {
                float v = m > 0.0 ? (float)(a[3 * k + c] / m) : 0.0f;
                if (sh)
                    sh[P + j].sh[k][c] = v;
                else
                    cube[P + j].faces[k][c] = v;
            }
    }
    free(acc);
}

sv_gpu_probe *sv_probes_pack(const sv_probes *probes, float fallback_radiance, const float (*sky_sh)[3],
                             uint32_t sky_band)
{
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
        const sv_probe_grid *gr = &probes->grids[g];
        const pb_shprobe *f = gr->file;
        bool sparse = gr->tree || gr->tetra, is_cube = f->representation == PB_SHPROBE_AMBIENT_CUBE;
        uint32_t nc = pb_sh_count(f->max_band);
        for (uint32_t p = 0; p < f->probe_count; ++p) {
            sv_gpu_probe *dst = &out[gr->base + p];
            dst->params[0] = (float)f->max_band;
            dst->params[1] = f->probe_scale ? f->probe_scale[p] : 1.0f;
            dst->params[2] = 0.0f; /* the file's per-probe ambient is not used (docs/shprobe-format.md) */
            float v = f->validity ? f->validity[p] : 1.0f;
            /* v3 interpolation drops probes of validity <= 0 and keeps the others at full weight
             * (pb_interp_options.validity); dense grids weight by the validity (docs/engine.md). */
            dst->params[3] = sparse ? (v > 0.0f ? 1.0f : 0.0f) : v;
            if (is_cube) { /* cube-only grid: no SH (the cube buffer holds the file's colours) */
                dst->params[0] = 0.0f;
                continue;
            }
            for (uint32_t i = 0; i < nc && i < SV_SH_MAX_COEFFS; ++i)
                for (int c = 0; c < 3; ++c) dst->sh[i][c] = f->coeffs[((size_t)p * nc + i) * 3 + (size_t)c];
        }
        if (gr->tree && !is_cube) resolve_hanging(f, out + gr->base, NULL);
    }
    return out;
}

uint16_t sv_half_from_float(float f)
{
    uint32_t x;
    memcpy(&x, &f, 4);
    uint32_t sign = (x >> 16) & 0x8000u, e = (x >> 23) & 0xFFu, m = x & 0x7FFFFFu;
    if (e == 0xFFu) return (uint16_t)(sign | 0x7C00u | (m ? 0x200u : 0u));
    int32_t he = (int32_t)e - 127 + 15;
    if (he >= 31) return (uint16_t)(sign | 0x7C00u); /* overflow: inf */
    if (he <= 0) {                                   /* subnormal or zero */
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

/* "shProbeGrids[g] 'name' probe k" for buffer index p, or the fallback probe 0. */
static void probe_where(const sv_probes *probes, uint32_t p, char *where, size_t cap)
{
    snprintf(where, cap, "the fallback probe 0 (the sky's SH)");
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const sv_probe_grid *gr = &probes->grids[g];
        if (p >= gr->base && p - gr->base < gr->file->probe_count)
            snprintf(where, cap, "shProbeGrids[%u] '%.60s' probe %u", g, gr->name, p - gr->base);
        else if (p >= gr->base && p - gr->base < gr->entries)
            snprintf(where, cap, "shProbeGrids[%u] '%.60s' hanging node %u", g, gr->name,
                     p - gr->base - gr->file->probe_count);
    }
}

bool sv_probes_fit_half(const sv_probes *probes, const sv_gpu_probe *packed, char *msg, size_t cap)
{
    for (uint32_t p = 0; p < probes->total; ++p) {
        const sv_gpu_probe *s = &packed[p];
        float worst = fabsf(s->params[1]);
        int at = -1; /* -1 = the scale */
        for (int i = 0; i < SV_SH_MAX_COEFFS; ++i)
            for (int c = 0; c < 3; ++c)
                if (!(fabsf(s->sh[i][c]) <= worst)) { /* also catches NaN */
                    worst = fabsf(s->sh[i][c]);
                    at = i;
                }
        if (worst <= SV_HALF_MAX) continue;
        char where[160];
        probe_where(probes, p, where, sizeof where);
        if (at < 0)
            snprintf(msg, cap, "%s: scale %g exceeds the half-float range (%g)", where, worst, SV_HALF_MAX);
        else
            snprintf(msg, cap, "%s: coefficient %d = %g exceeds the half-float range (%g)", where, at, worst,
                     SV_HALF_MAX);
        return false;
    }
    return true;
}

static uint32_t pack2(float a, float b)
{
    return (uint32_t)sv_half_from_float(a) | ((uint32_t)sv_half_from_float(b) << 16);
}

void sv_probe_to_half(const sv_gpu_probe *s, sv_gpu_probe_half *o)
{
    o->params[0] = pack2(s->params[0], s->params[1]);
    o->params[1] = pack2(s->params[3], 0.0f);
    for (uint32_t i = 0; i < SV_SH_MAX_COEFFS; ++i) {
        o->sh[i][0] = pack2(s->sh[i][0], s->sh[i][1]);
        o->sh[i][1] = pack2(s->sh[i][2], 0.0f);
    }
}

sv_gpu_probe_half *sv_probes_pack_half(const sv_gpu_probe *packed, uint32_t count)
{
    sv_gpu_probe_half *out = calloc(count ? count : 1, sizeof(*out));
    if (!out) return NULL;
    for (uint32_t p = 0; p < count; ++p) sv_probe_to_half(&packed[p], &out[p]);
    return out;
}

sv_gpu_cube *sv_probes_pack_cubes(const sv_gpu_probe *packed, uint32_t count)
{
    sv_gpu_cube *out = calloc(count ? count : 1, sizeof(*out));
    if (!out) return NULL;
    for (uint32_t p = 0; p < count; ++p) {
        const sv_gpu_probe *s = &packed[p];
        uint32_t band = (uint32_t)(s->params[0] + 0.5f);
        if (band > 4) band = 4;
        double coeffs[SV_SH_MAX_COEFFS * 3], cube[18];
        uint32_t n = (band + 1) * (band + 1);
        for (uint32_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c) coeffs[3 * i + c] = s->sh[i][c];
        pb_error err = {0};
        /* The packed coefficients are finite (the reader and the sky parser check), so the fit
         * cannot fail; should it, the probe stays a black cube rather than garbage. */
        if (pb_ambient_cube_from_sh(band, coeffs, PB_AMBIENT_CUBE_LEAST_SQUARES, cube, &err) != PB_SUCCESS)
            memset(cube, 0, sizeof cube);
        out[p].params[0] = s->params[0];
        out[p].params[1] = s->params[1];
        out[p].params[3] = s->params[3];
        for (int f = 0; f < 6; ++f)
            for (int c = 0; c < 3; ++c) out[p].faces[f][c] = (float)cube[3 * f + c];
    }
    return out;
}

sv_gpu_cube *sv_probes_pack_all_cubes(const sv_probes *probes, const sv_gpu_probe *packed)
{
    sv_gpu_cube *out = sv_probes_pack_cubes(packed, probes->total);
    if (!out) return NULL;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const sv_probe_grid *gr = &probes->grids[g];
        const pb_shprobe *f = gr->file;
        if (f->representation != PB_SHPROBE_AMBIENT_CUBE) continue;
        for (uint32_t p = 0; p < f->probe_count; ++p) {
            sv_gpu_cube *dst = &out[gr->base + p];
            memset(dst->faces, 0, sizeof dst->faces);
            dst->params[0] = (float)f->max_band;
            dst->params[1] = packed[gr->base + p].params[1];
            dst->params[3] = packed[gr->base + p].params[3];
            for (int j = 0; j < 6; ++j)
                for (int c = 0; c < 3; ++c) dst->faces[j][c] = f->coeffs[((size_t)p * 6 + (size_t)j) * 3 + (size_t)c];
        }
        if (gr->tree) resolve_hanging(f, NULL, out + gr->base);
    }
    return out;
}

bool sv_probes_have_cube_grids(const sv_probes *probes)
{
    for (uint32_t g = 0; g < probes->grid_count; ++g)
        if (probes->grids[g].file->representation == PB_SHPROBE_AMBIENT_CUBE) return true;
    return false;
}

sv_gpu_cube_half *sv_probes_pack_cubes_half(const sv_gpu_cube *cubes, uint32_t count)
{
    sv_gpu_cube_half *out = calloc(count ? count : 1, sizeof(*out));
    if (!out) return NULL;
    for (uint32_t p = 0; p < count; ++p) sv_cube_to_half(&cubes[p], &out[p]);
    return out;
}

void sv_cube_to_half(const sv_gpu_cube *s, sv_gpu_cube_half *o)
{
    o->params[0] = pack2(s->params[0], s->params[1]);
    o->params[1] = pack2(s->params[3], 0.0f);
    for (int f = 0; f < 6; ++f) {
        o->faces[f][0] = pack2(s->faces[f][0], s->faces[f][1]);
        o->faces[f][1] = pack2(s->faces[f][2], 0.0f);
    }
}

bool sv_probes_cubes_fit_half(const sv_probes *probes, const sv_gpu_cube *cubes, char *msg, size_t cap)
{
    for (uint32_t p = 0; p < probes->total; ++p) {
        for (int f = 0; f < 6; ++f)
            for (int c = 0; c < 3; ++c) {
                float v = fabsf(cubes[p].faces[f][c]);
                if (v <= SV_HALF_MAX) continue; /* NaN fails too */
                char where[160];
                probe_where(probes, p, where, sizeof where);
                snprintf(msg, cap, "%s: ambient-cube face %d channel %d = %g exceeds the half-float range (%g)", where,
                         f, c, v, SV_HALF_MAX);
                return false;
            }
    }
    return true;
}

bool sv_probes_gpu_grids(const sv_probes *probes, const sv_scene *scene, sv_gpu_grid **grids_out, int32_t **cells_out,
                         uint32_t *cell_count)
{
    size_t n = 0, leaves = 0, nodes = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        if (probes->grids[g].tree)
            leaves += f->element_count;
        else if (f->grid)
            n += (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
        if (probes->grids[g].tree && f->structure == PB_SHPROBE_KDTREE) nodes += f->split_node_count;
    }
    *grids_out = NULL;
    *cells_out = NULL;
    *cell_count = 0;
    /* Cell indices, masks, leaves, leaf visibility tables, then the kd trees' split-tree nodes. */
    size_t ints = 2 * n + (SV_LEAF_INTS + SV_LEAF_VIS_INTS) * leaves + nodes;
    if (ints > INT32_MAX) {
        fprintf(stderr, "schnee-view: error: probe grids have more than 2^31 cell and leaf entries in total\n");
        return false;
    }
    sv_gpu_grid *grids = calloc(probes->grid_count ? probes->grid_count : 1, sizeof(*grids));
    int32_t *cells = calloc(ints ? ints : 1, sizeof(int32_t));
    uint8_t *leaf_masks = malloc((leaves ? leaves : 1) * 64);
    uint32_t *masks = leaf_masks ? sv_probe_visibility_masks(probes, scene, n, leaf_masks, leaves) : NULL;
    if (!grids || !cells || !masks || !leaf_masks) {
        free(grids);
        free(cells);
        free(masks);
        free(leaf_masks);
        fprintf(stderr, "schnee-view: error: out of memory for the probe grids\n");
        return false;
    }
    size_t off = 0, loff = 0, leaf_base = 2 * n, mask_base = 2 * n + SV_LEAF_INTS * leaves;
    size_t node_off = mask_base + SV_LEAF_VIS_INTS * leaves;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const sv_probe_grid *gr = &probes->grids[g];
        const pb_shprobe *f = gr->file;
        const float *ax = f->grid_axes;
        sv_gpu_grid *d = &grids[g];
        for (int k = 0; k < 3; ++k) d->origin_spacing[k] = f->grid_origin[k];
        d->origin_spacing[3] = f->grid_spacing;
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) d->axes[r][k] = ax[r * 3 + k];
        for (int k = 0; k < 3; ++k) d->dims[k] = f->grid_dims[k];
        d->base[0] = gr->base;
        d->base[2] = f->representation == PB_SHPROBE_AMBIENT_CUBE ? SV_GRID_CUBE_ONLY : 0u;
        if (gr->tetra) {
            d->base[2] |= SV_GRID_TETRA;
            continue;
        }
        if (gr->tree) {
            d->base[2] |= SV_GRID_OCTREE;
            d->base[3] = f->element_count;
            d->dims[3] = (uint32_t)(leaf_base + SV_LEAF_INTS * loff);
            d->base[1] = (uint32_t)(mask_base + SV_LEAF_VIS_INTS * loff);
            if (f->structure == PB_SHPROBE_KDTREE) { /* the split tree as stored (docs/shprobe-format.md) */
                uint32_t R = f->root_level;
                d->base[2] |= SV_GRID_KDTREE;
                d->tree[0] = (uint32_t)node_off;
                d->tree[1] = R;
                d->tree[2] = (uint32_t)(((uint64_t)f->grid_dims[0] + (1u << R) - 1u) >> R);
                d->tree[3] = (uint32_t)(((uint64_t)f->grid_dims[1] + (1u << R) - 1u) >> R);
                memcpy(cells + node_off, f->split_nodes, (size_t)f->split_node_count * sizeof(uint32_t));
                node_off += f->split_node_count;
            }
            for (uint32_t i = 0; i < f->element_count; ++i) {
                const uint32_t *l = f->leaves + 4u * i;
                int32_t *o = cells + leaf_base + SV_LEAF_INTS * (loff + i);
                memcpy(o, l, 4 * sizeof(uint32_t)); /* x, y, z, level(s); ints 5..7 reserved (0) */
                memcpy(o + 8, f->leaf_corners + 8u * i, 8 * sizeof(int32_t));
                const uint8_t *vis = leaf_masks + 64u * (loff + i);
                memcpy(cells + mask_base + SV_LEAF_VIS_INTS * (loff + i), vis, 64);
                /* SV_LEAF_BLOCKED: the shader reads the table only where a surface crosses the leaf
                 * (everywhere else v_c = 1 and the weights are the plain ones, exactly). */
                for (int b = 0; b < 64; ++b)
                    if (vis[b] != PB_VIS_CLEAR) o[4] = 1;
            }
            loff += f->element_count;
            continue;
        }
        d->dims[3] = (uint32_t)off;
        d->base[1] = (uint32_t)(n + off); /* the grid's visibility masks follow all cell indices */
        size_t cn = (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
        memcpy(cells + off, f->grid, cn * sizeof(int32_t));
        memcpy(cells + n + off, masks + off, cn * sizeof(uint32_t));
        off += cn;
    }
    free(masks);
    free(leaf_masks);
    *grids_out = grids;
    *cells_out = cells;
    *cell_count = (uint32_t)ints;
    return true;
}

/* One probe-view outline per leaf of an octree or kd tree grid: the box's centre, probe.z its packed
 * levels (lx | ly << 8 | lz << 16; the outline's edges are 2^l_a min cells, a dense cell's 0 gives one
 * spacing). Octree frames have identity axes (pb_interp_from_shprobe). Returns the outlines written. */
static uint32_t leaf_outlines(const pb_shprobe *f, uint32_t g, uint32_t base, sv_gpu_cell *out)
{
    for (uint32_t i = 0; i < f->element_count; ++i) {
        const uint32_t *l = f->leaves + 4u * i;
        uint32_t packed = f->structure == PB_SHPROBE_KDTREE ? l[3] : PB_LEVELS_PACK(l[3], l[3], l[3]);
        for (int k = 0; k < 3; ++k) {
            double size = (double)(1u << (packed >> (8 * k) & 255u));
            out[i].center_radius[k] = (float)(f->grid_origin[k] + f->grid_spacing * ((double)l[k] + 0.5 * size));
        }
        out[i].center_radius[3] = 0.0f;
        out[i].probe[0] = base + (uint32_t)f->leaf_corners[8u * i]; /* the leaf's corner 0 */
        out[i].probe[1] = g;
        out[i].probe[2] = packed;
    }
    return f->element_count;
}

sv_gpu_cell *sv_probes_cells(const sv_probes *probes, uint32_t *sphere_count, uint32_t *cell_count)
{
    size_t n = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        if (probes->grids[g].tree) n += f->element_count; /* octree, kd tree: one outline per leaf */
        if (!f->grid) continue;                           /* tetrahedra: spheres only */
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
        if (probes->grids[g].tree) nc += leaf_outlines(f, g, probes->grids[g].base, cells + nc);
        if (!f->grid) continue;
        uint32_t X = f->grid_dims[0], Y = f->grid_dims[1], Z = f->grid_dims[2];
        for (uint32_t z = 0; z < Z; ++z)
            for (uint32_t y = 0; y < Y; ++y)
                for (uint32_t x = 0; x < X; ++x) {
                    int32_t idx = f->grid[x + (size_t)y * X + (size_t)z * X * Y];
                    if (idx < 0) continue;
                    sv_gpu_cell *c = &cells[nc++];
                    sv_cell_centre(f, (int)x, (int)y, (int)z, c->center_radius);
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
