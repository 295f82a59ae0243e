/* Probe grids: loading, header checks, lookup, GPU packing (see sv_probes.h). */
#include "sv_probes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "schnee/pb_ambient_cube.h"
#include "schnee/pb_embree_compat.h"
#include "schnee/pb_sh.h"
#include "sv_clock.h"
#include "sv_math.h"

static bool differs(float a, float b) { return fabsf(a - b) > 1e-5f * fmaxf(1.0f, fmaxf(fabsf(a), fabsf(b))); }

/* Warns about every field where the glTF entry disagrees with the file it names. */
static void check_entry(const sv_ext_probe_grid *e, const pb_shprobe *f, uint32_t index)
{
    const char *n = e->name[0] ? e->name : e->uri;
    if (e->probe_count != f->probe_count)
        fprintf(stderr,
                "schnee-view: warning: shProbeGrids[%u] '%s': probeCount %u but the file has %u (using the file)\n",
                index, n, e->probe_count, f->probe_count);
    if (e->max_band != f->max_band)
        fprintf(stderr,
                "schnee-view: warning: shProbeGrids[%u] '%s': maxBand %u but the file has %u (using the file)\n", index,
                n, e->max_band, f->max_band);
    for (int k = 0; k < 3; ++k) {
        if (e->grid_dims[k] != f->grid_dims[k]) {
            fprintf(
                stderr,
                "schnee-view: warning: shProbeGrids[%u] '%s': gridDims (%u, %u, %u) but the file has (%u, %u, %u) (using the file)\n",
                index, n, e->grid_dims[0], e->grid_dims[1], e->grid_dims[2], f->grid_dims[0], f->grid_dims[1],
                f->grid_dims[2]);
            break;
        }
    }
    for (int k = 0; k < 3; ++k) {
        if (differs(e->grid_origin[k], f->grid_origin[k])) {
            fprintf(
                stderr,
                "schnee-view: warning: shProbeGrids[%u] '%s': gridOrigin (%g, %g, %g) but the file has (%g, %g, %g) (using the file)\n",
                index, n, e->grid_origin[0], e->grid_origin[1], e->grid_origin[2], f->grid_origin[0], f->grid_origin[1],
                f->grid_origin[2]);
            break;
        }
    }
    if (differs(e->grid_spacing, f->grid_spacing))
        fprintf(stderr,
                "schnee-view: warning: shProbeGrids[%u] '%s': gridSpacing %g but the file has %g (using the file)\n",
                index, n, e->grid_spacing, f->grid_spacing);
    const float *axes = f->grid_axes;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            if (differs(e->grid_axes[r][c], axes[r * 3 + c])) {
                fprintf(stderr,
                        "schnee-view: warning: shProbeGrids[%u] '%s': gridAxes differ from the file's "
                        "(using the file)\n",
                        index, n);
                return;
            }
}

/* Before the bake's reader sees a grid's file: opened without blocking, a regular file of at most
 * SV_MAX_PROBE_FILE_BYTES that starts with the .shprobe magic (else it is not ours, and its
 * content is never quoted), whose header (pb_shprobe_read_header) implies exactly its size. */
static bool check_probe_file(const sv_ext_probe_grid *e, uint32_t index)
{
    char what[96];
    snprintf(what, sizeof what, "shProbeGrids[%u] '%.40s'", index, e->name);
    if (!e->path) {
        fprintf(stderr, "schnee-view: error: %s: '%s' has no resolvable path\n", what, e->uri);
        return false;
    }
    sv_gltf_error gerr = {0};
    uint64_t size = 0;
    int fd = sv_gltf_open_regular(e->path, what, SV_MAX_PROBE_FILE_BYTES, &size, &gerr);
    if (fd < 0) {
        fprintf(stderr, "schnee-view: error: %s\n", gerr.message);
        return false;
    }
    unsigned char magic[4] = {0};
    ssize_t n = read(fd, magic, sizeof magic);
    close(fd);
    static const unsigned char sphr[4] = {0x53, 0x50, 0x48, 0x52}; /* PB_SHPROBE_MAGIC on disk */
    if (n != 4 || memcmp(magic, sphr, 4) != 0) {
        fprintf(stderr, "schnee-view: error: %s: '%s' (%llu bytes) is not a .shprobe file (no \"SPHR\" magic)\n", what,
                e->path, (unsigned long long)size);
        return false;
    }
    pb_shprobe h;
    pb_error err = {0};
    if (pb_shprobe_read_header(e->path, &h, &err) != PB_SUCCESS) {
        fprintf(stderr, "schnee-view: error: %s: cannot read %s: %s\n", what, e->path,
                err.message[0] ? err.message : pb_result_string(err.code));
        return false;
    }
    return true;
}

bool sv_probes_load(const sv_ext *ext, sv_probes *out)
{
    memset(out, 0, sizeof(*out));
    out->total = 1;
    if (ext->probe_grid_count == 0) return true;
    out->grids = calloc(ext->probe_grid_count, sizeof(sv_probe_grid));
    if (!out->grids) {
        fprintf(stderr, "schnee-view: error: out of memory for probe grids\n");
        return false;
    }
    for (uint32_t i = 0; i < ext->probe_grid_count; ++i) {
        const sv_ext_probe_grid *e = &ext->probe_grids[i];
        pb_error err = {0};
        pb_shprobe *f = NULL;
        if (!check_probe_file(e, i)) {
            sv_probes_destroy(out);
            return false;
        }
        if (pb_shprobe_read(e->path, &f, &err) != PB_SUCCESS) {
            fprintf(stderr, "schnee-view: error: shProbeGrids[%u] '%s': cannot read %s: %s\n", i, e->name, e->path,
                    err.message[0] ? err.message : pb_result_string(err.code));
            sv_probes_destroy(out);
            return false;
        }
        /* Version 3 adds sparse structures and ambient cubes (docs/shprobe-format.md); this engine
         * shades dense SH grids only, so anything else is refused here rather than misread. */
        if (f->structure != PB_SHPROBE_GRID || !f->grid || f->representation != PB_SHPROBE_SH) {
            fprintf(stderr,
                    "schnee-view: error: shProbeGrids[%u] '%s': %s is a version %u file with a %s of %s; this "
                    "engine reads dense grids of SH only (bake or resample to a version 1/2 grid)\n",
                    i, e->name, e->path, f->version,
                    f->structure == PB_SHPROBE_OCTREE  ? "corner octree"
                    : f->structure == PB_SHPROBE_TETRA ? "tetrahedral mesh"
                                                       : "grid",
                    f->representation == PB_SHPROBE_SH ? "SH" : "ambient cubes");
            pb_shprobe_destroy(f);
            sv_probes_destroy(out);
            return false;
        }
        /* The reader returns identity axes for v1 and refuses all-zero or non-orthonormal ones on disk,
         * so all-zero never means "identity" here; a unit X axis row is checked as a guard. */
        double ax2 = (double)f->grid_axes[0] * f->grid_axes[0] + (double)f->grid_axes[1] * f->grid_axes[1] +
                     (double)f->grid_axes[2] * f->grid_axes[2];
        if (!(fabs(ax2 - 1.0) < 1e-3)) {
            fprintf(stderr, "schnee-view: error: shProbeGrids[%u] '%s': %s has no unit grid axes\n", i, e->name,
                    e->path);
            pb_shprobe_destroy(f);
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

void sv_probes_destroy(sv_probes *probes)
{
    for (uint32_t i = 0; i < probes->grid_count; ++i) pb_shprobe_destroy(probes->grids[i].file);
    free(probes->grids);
    memset(probes, 0, sizeof(*probes));
}

uint32_t sv_probes_lookup(const sv_probes *probes, const float point[3])
{
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        int32_t idx = pb_shprobe_lookup(probes->grids[g].file, point);
        if (idx >= 0 && (uint32_t)idx < probes->grids[g].file->probe_count)
            return probes->grids[g].base + (uint32_t)idx;
    }
    return 0;
}

uint32_t sv_probes_assign(const sv_probes *probes, sv_scene *scene)
{
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
        const pb_shprobe *f = probes->grids[g].file;
        uint32_t nc = pb_sh_count(f->max_band);
        for (uint32_t p = 0; p < f->probe_count; ++p) {
            sv_gpu_probe *dst = &out[probes->grids[g].base + p];
            dst->params[0] = (float)f->max_band;
            dst->params[1] = f->probe_scale ? f->probe_scale[p] : 1.0f;
            dst->params[2] = 0.0f; /* the file's per-probe ambient is not used (docs/shprobe-format.md) */
            dst->params[3] = f->validity ? f->validity[p] : 1.0f;
            for (uint32_t i = 0; i < nc && i < SV_SH_MAX_COEFFS; ++i)
                for (int c = 0; c < 3; ++c) dst->sh[i][c] = f->coeffs[((size_t)p * nc + i) * 3 + (size_t)c];
        }
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

sv_gpu_probe_half *sv_probes_pack_half(const sv_gpu_probe *packed, uint32_t count)
{
    sv_gpu_probe_half *out = calloc(count ? count : 1, sizeof(*out));
    if (!out) return NULL;
    for (uint32_t p = 0; p < count; ++p) {
        const sv_gpu_probe *s = &packed[p];
        out[p].params[0] = pack2(s->params[0], s->params[1]);
        out[p].params[1] = pack2(s->params[3], 0.0f);
        for (uint32_t i = 0; i < SV_SH_MAX_COEFFS; ++i) {
            out[p].sh[i][0] = pack2(s->sh[i][0], s->sh[i][1]);
            out[p].sh[i][1] = pack2(s->sh[i][2], 0.0f);
        }
    }
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

sv_gpu_cube_half *sv_probes_pack_cubes_half(const sv_gpu_cube *cubes, uint32_t count)
{
    sv_gpu_cube_half *out = calloc(count ? count : 1, sizeof(*out));
    if (!out) return NULL;
    for (uint32_t p = 0; p < count; ++p) {
        const sv_gpu_cube *s = &cubes[p];
        out[p].params[0] = pack2(s->params[0], s->params[1]);
        out[p].params[1] = pack2(s->params[3], 0.0f);
        for (int f = 0; f < 6; ++f) {
            out[p].faces[f][0] = pack2(s->faces[f][0], s->faces[f][1]);
            out[p].faces[f][1] = pack2(s->faces[f][2], 0.0f);
        }
    }
    return out;
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

void sv_cell_centre(const pb_shprobe *f, int x, int y, int z, float out[3])
{
    const float *ax = f->grid_axes;
    float h = f->grid_spacing, l[3] = {((float)x + 0.5f) * h, ((float)y + 0.5f) * h, ((float)z + 0.5f) * h};
    for (int k = 0; k < 3; ++k)
        out[k] = f->grid_origin[k] + l[0] * ax[0 * 3 + k] + l[1] * ax[1 * 3 + k] + l[2] * ax[2 * 3 + k];
}

/* Embree scene of every object's triangles in world space (the load-time transforms); NULL when
 * the scene has no triangles. */
static RTCScene build_occluders(RTCDevice dev, const sv_scene *scene, size_t *tri_count)
{
    RTCScene rs = rtcNewScene(dev);
    const sv_gltf *g = scene->gltf;
    *tri_count = 0;
    for (uint32_t o = 0; o < scene->object_count; ++o) {
        const sv_object *obj = &scene->objects[o];
        const sv_gltf_mesh *mesh = &g->meshes[obj->mesh];
        for (uint32_t p = 0; p < mesh->primitive_count; ++p) {
            const sv_gltf_primitive *pr = &mesh->primitives[p];
            if (pr->index_count < 3 || !pr->vertex_count) continue;
            RTCGeometry geo = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
            float *v = rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                               pr->vertex_count);
            uint32_t *ix = rtcSetNewGeometryBuffer(geo, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                   3 * sizeof(uint32_t), pr->index_count / 3);
            if (!v || !ix) {
                rtcReleaseGeometry(geo);
                continue;
            }
            for (uint32_t k = 0; k < pr->vertex_count; ++k)
                sv_mat4_point(obj->world, pr->positions + 3 * (size_t)k, v + 3 * (size_t)k);
            memcpy(ix, pr->indices, (size_t)(pr->index_count / 3) * 3 * sizeof(uint32_t));
            rtcCommitGeometry(geo);
            rtcAttachGeometry(rs, geo);
            rtcReleaseGeometry(geo);
            *tri_count += pr->index_count / 3;
        }
    }
    rtcCommitScene(rs);
    return rs;
}

/* Neighbour visibility masks, one uint32 per cell in the layout of the concatenated cell grids:
 * bit (dx+1) + 3(dy+1) + 9(dz+1) (d in {-1,0,1}^3; bit 13 = the cell itself, always set) is set
 * when the segment between the centres of the cell and of its neighbour at offset d crosses no
 * scene triangle (Embree occlusion ray, both sides). Empty cells, and cells whose neighbour is
 * empty or outside the grid, keep the bit set (no information, no change to the weights). */
static uint32_t *visibility_masks(const sv_probes *probes, const sv_scene *scene, size_t n)
{
    uint32_t *masks = malloc((n ? n : 1) * sizeof(uint32_t));
    if (!masks) return NULL;
    for (size_t i = 0; i < n; ++i) masks[i] = (1u << 27) - 1u;
    if (!scene || !scene->object_count) return masks;
    double t0 = sv_now_ms();
    /* A bounded Embree thread pool (docs/engine.md): at most SV_EMBREE_MAX_THREADS, never more than
     * the online CPUs, no thread pinning. */
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    unsigned threads = cpus > 0 && cpus < SV_EMBREE_MAX_THREADS ? (unsigned)cpus : SV_EMBREE_MAX_THREADS;
    char config[64];
    snprintf(config, sizeof config, "threads=%u,set_affinity=0", threads);
    RTCDevice dev = rtcNewDevice(config);
    if (!dev) {
        fprintf(stderr, "schnee-view: warning: Embree device failed; per-pixel probes without visibility masks\n");
        return masks;
    }
    size_t tris = 0, rays = 0;
    RTCScene rs = build_occluders(dev, scene, &tris);
    size_t off = 0;
    for (uint32_t g = 0; g < probes->grid_count && tris; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        int X = (int)f->grid_dims[0], Y = (int)f->grid_dims[1], Z = (int)f->grid_dims[2];
        float eps = 1e-4f;
        for (int z = 0; z < Z; ++z)
            for (int y = 0; y < Y; ++y)
                for (int x = 0; x < X; ++x) {
                    size_t ci = (size_t)x + (size_t)X * ((size_t)y + (size_t)Y * z);
                    if (f->grid[ci] < 0) continue;
                    float a[3];
                    sv_cell_centre(f, x, y, z, a);
                    /* Each pair once: the 13 offsets after the centre in bit order, both cells' bits. */
                    for (int k = 14; k < 27; ++k) {
                        int dx = k % 3 - 1, dy = (k / 3) % 3 - 1, dz = k / 9 - 1;
                        int nx = x + dx, ny = y + dy, nz = z + dz;
                        if (nx < 0 || ny < 0 || nz < 0 || nx >= X || ny >= Y || nz >= Z) continue;
                        size_t cj = (size_t)nx + (size_t)X * ((size_t)ny + (size_t)Y * nz);
                        if (f->grid[cj] < 0) continue;
                        float b[3];
                        sv_cell_centre(f, nx, ny, nz, b);
                        struct RTCRay ray = {0};
                        ray.org_x = a[0], ray.org_y = a[1], ray.org_z = a[2];
                        ray.dir_x = b[0] - a[0], ray.dir_y = b[1] - a[1], ray.dir_z = b[2] - a[2];
                        ray.tnear = eps;
                        ray.tfar = 1.0f - eps;
                        ray.mask = 0xFFFFFFFFu;
                        pb_rtc_occluded1(rs, &ray);
                        ++rays;
                        if (ray.tfar < 0.0f) { /* occluded: -inf */
                            masks[off + ci] &= ~(1u << k);
                            masks[off + cj] &= ~(1u << (26 - k)); /* the opposite offset */
                        }
                    }
                }
        off += (size_t)X * Y * Z;
    }
    rtcReleaseScene(rs);
    rtcReleaseDevice(dev);
    fprintf(stderr, "schnee-view: probe visibility masks: %zu segment(s) against %zu triangle(s) in %.1f ms\n", rays,
            tris, sv_now_ms() - t0);
    return masks;
}

bool sv_probes_gpu_grids(const sv_probes *probes, const sv_scene *scene, sv_gpu_grid **grids_out, int32_t **cells_out,
                         uint32_t *cell_count)
{
    size_t n = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        n += (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
    }
    *grids_out = NULL;
    *cells_out = NULL;
    *cell_count = 0;
    if (2 * n > UINT32_MAX) {
        fprintf(stderr, "schnee-view: error: probe grids have more than 2^31 cells in total\n");
        return false;
    }
    sv_gpu_grid *grids = calloc(probes->grid_count ? probes->grid_count : 1, sizeof(*grids));
    int32_t *cells = calloc(n ? 2 * n : 1, sizeof(int32_t));
    uint32_t *masks = visibility_masks(probes, scene, n);
    if (!grids || !cells || !masks) {
        free(grids);
        free(cells);
        free(masks);
        fprintf(stderr, "schnee-view: error: out of memory for the probe grids\n");
        return false;
    }
    size_t off = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        const float *ax = f->grid_axes;
        sv_gpu_grid *d = &grids[g];
        for (int k = 0; k < 3; ++k) d->origin_spacing[k] = f->grid_origin[k];
        d->origin_spacing[3] = f->grid_spacing;
        for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) d->axes[r][k] = ax[r * 3 + k];
        for (int k = 0; k < 3; ++k) d->dims[k] = f->grid_dims[k];
        d->dims[3] = (uint32_t)off;
        d->base[0] = probes->grids[g].base;
        d->base[1] = (uint32_t)(n + off); /* the grid's visibility masks follow all cell indices */
        size_t cn = (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
        memcpy(cells + off, f->grid, cn * sizeof(int32_t));
        memcpy(cells + n + off, masks + off, cn * sizeof(uint32_t));
        off += cn;
    }
    free(masks);
    *grids_out = grids;
    *cells_out = cells;
    *cell_count = (uint32_t)(2 * n);
    return true;
}

sv_gpu_cell *sv_probes_cells(const sv_probes *probes, uint32_t *sphere_count, uint32_t *cell_count)
{
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
