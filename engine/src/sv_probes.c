/* Probe grids: loading, header checks, lookup, GPU packing (see sv_probes.h). */
#include "sv_probes.h"

#include <float.h>
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
    struct {
        const char *key;
        uint32_t entry, file;
        const char *(*name)(uint32_t);
    } fields[3] = {{"representation", e->representation, f->representation, sv_ext_grid_representation_name},
                   {"storage", e->storage, f->storage, sv_ext_grid_storage_name},
                   {"structure", e->structure, f->structure, sv_ext_grid_structure_name}};
    for (int k = 0; k < 3; ++k)
        if (fields[k].entry != fields[k].file) {
            const char *fn = fields[k].name(fields[k].file);
            fprintf(stderr,
                    "schnee-view: warning: shProbeGrids[%u] '%s': %s '%s' but the file has '%s' (using the file)\n",
                    index, n, fields[k].key, fields[k].name(fields[k].entry), fn ? fn : "?");
        }
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

/* The core reader's message, without the "<path>: " it may already start with (the engine's own
 * line names the path once). */
static const char *reader_message(const pb_error *err, const char *path)
{
    const char *m = err->message[0] ? err->message : pb_result_string(err->code);
    size_t n = strlen(path);
    if (strncmp(m, path, n) == 0 && m[n] == ':' && m[n + 1] == ' ') return m + n + 2;
    return m;
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
        fprintf(stderr, "schnee-view: error: %s: cannot read %s: %s\n", what, e->path, reader_message(&err, e->path));
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
                    reader_message(&err, e->path));
            sv_probes_destroy(out);
            return false;
        }
        /* Version 3 (docs/shprobe-format.md): an octree or tetrahedra file gets the CPU interpolation
         * of the core (per object; the octree is also sampled per pixel on the GPU). */
        pb_cotree *tree = NULL;
        pb_tetra *tetra = NULL;
        if (f->structure != PB_SHPROBE_GRID && pb_interp_from_shprobe(f, &tree, &tetra, &err) != PB_SUCCESS) {
            fprintf(stderr, "schnee-view: error: shProbeGrids[%u] '%s': %s: %s\n", i, e->name, e->path,
                    err.message[0] ? err.message : pb_result_string(err.code));
            pb_shprobe_destroy(f);
            sv_probes_destroy(out);
            return false;
        }
        if (f->structure == PB_SHPROBE_GRID && !f->grid) { /* the reader guarantees it; a guard */
            fprintf(stderr, "schnee-view: error: shProbeGrids[%u] '%s': %s has no occupancy grid\n", i, e->name,
                    e->path);
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
            pb_cotree_destroy(tree);
            pb_tetra_destroy(tetra);
            pb_shprobe_destroy(f);
            sv_probes_destroy(out);
            return false;
        }
        check_entry(e, f, i);
        uint32_t entries = f->probe_count + (f->structure == PB_SHPROBE_OCTREE ? f->hanging_count : 0u);
        if (entries < f->probe_count || entries > UINT32_MAX / 2 - out->total) {
            fprintf(stderr, "schnee-view: error: shProbeGrids[%u]: too many probes in total\n", i);
            pb_cotree_destroy(tree);
            pb_tetra_destroy(tetra);
            pb_shprobe_destroy(f);
            sv_probes_destroy(out);
            return false;
        }
        sv_probe_grid *gr = &out->grids[out->grid_count++];
        gr->file = f;
        gr->base = out->total;
        gr->entries = entries;
        gr->name = e->name;
        gr->tree = tree;
        gr->tetra = tetra;
        out->total += entries;
    }
    return true;
}

static void static_vis_destroy(sv_static_vis *v);

void sv_probes_destroy(sv_probes *probes)
{
    for (uint32_t i = 0; i < probes->grid_count; ++i) {
        pb_shprobe_destroy(probes->grids[i].file);
        pb_cotree_destroy(probes->grids[i].tree);
        pb_tetra_destroy(probes->grids[i].tetra);
    }
    free(probes->grids);
    free(probes->slot_sh);
    free(probes->slot_cube);
    free(probes->slot_weights);
    free(probes->warned);
    static_vis_destroy(probes->vis);
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

/* ---- the static scene: probe visibility for per-object queries (docs/engine.md "Static scene") ---- */

struct sv_static_vis {
    RTCDevice dev;
    RTCScene scene;        /* every object's triangles at load, one geometry per primitive */
    uint32_t *geom_object; /* geometry id -> object index */
    uint32_t geom_count;
};

/* A bounded Embree device (docs/engine.md): at most SV_EMBREE_MAX_THREADS threads, never more than the
 * online CPUs, no thread pinning. NULL on failure. */
static RTCDevice new_embree_device(void)
{
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    unsigned threads = cpus > 0 && cpus < SV_EMBREE_MAX_THREADS ? (unsigned)cpus : SV_EMBREE_MAX_THREADS;
    char config[64];
    snprintf(config, sizeof config, "threads=%u,set_affinity=0", threads);
    return rtcNewDevice(config);
}

/* Embree scene of the objects' triangles in world space (current transforms): every object, or
 * (static_only) those never moved. geom_object (optional) gets geometry id -> object index. */
static RTCScene build_scene(RTCDevice dev, const sv_scene *scene, bool static_only, enum RTCSceneFlags flags,
                            size_t *tri_count, uint32_t **geom_object, uint32_t *geom_count)
{
    RTCScene rs = rtcNewScene(dev);
    rtcSetSceneFlags(rs, flags);
    const sv_gltf *g = scene->gltf;
    *tri_count = 0;
    uint32_t n = 0, cap = 0;
    uint32_t *map = NULL;
    for (uint32_t o = 0; o < scene->object_count; ++o) {
        const sv_object *obj = &scene->objects[o];
        if (static_only && obj->movable) continue;
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
            uint32_t id = rtcAttachGeometry(rs, geo);
            rtcReleaseGeometry(geo);
            *tri_count += pr->index_count / 3;
            if (geom_object) {
                if (id >= cap) {
                    uint32_t nc = cap ? 2 * cap : 64;
                    while (nc <= id) nc *= 2;
                    uint32_t *m = realloc(map, nc * sizeof(uint32_t));
                    if (!m) continue;
                    for (uint32_t k = cap; k < nc; ++k) m[k] = UINT32_MAX;
                    map = m;
                    cap = nc;
                }
                map[id] = o;
                if (id + 1 > n) n = id + 1;
            }
        }
    }
    rtcCommitScene(rs);
    if (geom_object) {
        *geom_object = map;
        *geom_count = n;
    }
    return rs;
}

static void static_vis_destroy(sv_static_vis *v)
{
    if (!v) return;
    if (v->scene) rtcReleaseScene(v->scene);
    if (v->dev) rtcReleaseDevice(v->dev);
    free(v->geom_object);
    free(v);
}

/* Every object's triangles; which ones occlude is decided per ray (vis_filter): the static set. */
static sv_static_vis *static_vis_create(const sv_scene *scene)
{
    sv_static_vis *v = calloc(1, sizeof *v);
    if (!v) return NULL;
    v->dev = new_embree_device();
    if (!v->dev) {
        fprintf(stderr, "schnee-view: warning: Embree device failed; per-object probes without visibility\n");
        free(v);
        return NULL;
    }
    size_t tris = 0;
    v->scene =
        build_scene(v->dev, scene, false, PB_RTC_SCENE_FLAG_FILTER_IN_CALL, &tris, &v->geom_object, &v->geom_count);
    return v;
}

typedef struct vis_ray_ctx {
    pb_rtc_context ctx; /* first member: the filter's args->context */
    const sv_scene *scene;
    const sv_static_vis *vis;
    uint32_t self; /* the queried object: never blocks its own probes */
} vis_ray_ctx;

/* Rejects hits on the queried object and on objects that have moved (not in the static set). */
static void vis_filter(const struct RTCFilterFunctionNArguments *args)
{
    const vis_ray_ctx *r = (const vis_ray_ctx *)args->context;
    for (unsigned i = 0; i < args->N; i++) {
        if (!args->valid[i]) continue;
        unsigned geom = ((const unsigned *)args->hit)[6 * args->N + i];
        uint32_t o = geom < r->vis->geom_count ? r->vis->geom_object[geom] : UINT32_MAX;
        if (o == r->self || (o < r->scene->object_count && r->scene->objects[o].movable)) args->valid[i] = 0;
    }
}

typedef struct vis_query {
    const sv_static_vis *vis;
    const sv_scene *scene;
    uint32_t self;
    const float *positions; /* the grid's probe positions */
} vis_query;

/* pb_visible_fn: the segment probe -> point crosses no static triangle (both sides). */
static bool probe_visible(void *user, uint32_t probe, const double point[3])
{
    const vis_query *q = user;
    if (!q->vis || !q->positions) return true;
    const float *a = q->positions + 3 * (size_t)probe;
    struct RTCRayHit rh;
    memset(&rh, 0, sizeof rh);
    rh.ray.org_x = a[0], rh.ray.org_y = a[1], rh.ray.org_z = a[2];
    rh.ray.dir_x = (float)(point[0] - a[0]), rh.ray.dir_y = (float)(point[1] - a[1]);
    rh.ray.dir_z = (float)(point[2] - a[2]);
    rh.ray.tnear = 1e-4f;
    rh.ray.tfar = 1.0f - 1e-4f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    vis_ray_ctx rc;
    memset(&rc, 0, sizeof rc);
    rc.scene = q->scene;
    rc.vis = q->vis;
    rc.self = q->self;
    pb_rtc_intersect1_filtered(q->vis->scene, &rc.ctx, vis_filter, &rh);
    return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID;
}

/* ---- per-object assignment --------------------------------------------------------------------- */

/* World-space bounds of a grid: the box of a dense grid or octree lattice (its 8 corners under the
 * axes), the probes' bounds for tetrahedra. */
static void grid_bounds(const pb_shprobe *f, float lo[3], float hi[3])
{
    for (int k = 0; k < 3; ++k) lo[k] = FLT_MAX, hi[k] = -FLT_MAX;
    if (f->structure == PB_SHPROBE_TETRA) {
        for (uint32_t p = 0; p < f->probe_count; ++p)
            for (int k = 0; k < 3; ++k) {
                lo[k] = fminf(lo[k], f->positions[3 * (size_t)p + k]);
                hi[k] = fmaxf(hi[k], f->positions[3 * (size_t)p + k]);
            }
        return;
    }
    for (int c = 0; c < 8; ++c) {
        float l[3] = {(c & 1) ? (float)f->grid_dims[0] * f->grid_spacing : 0.0f,
                      (c & 2) ? (float)f->grid_dims[1] * f->grid_spacing : 0.0f,
                      (c & 4) ? (float)f->grid_dims[2] * f->grid_spacing : 0.0f};
        for (int k = 0; k < 3; ++k) {
            const float *ax = f->grid_axes;
            float w = f->grid_origin[k] + l[0] * ax[k] + l[1] * ax[3 + k] + l[2] * ax[6 + k];
            lo[k] = fminf(lo[k], w);
            hi[k] = fmaxf(hi[k], w);
        }
    }
}

/* docs/ambient-cube.md §5 mismatch rule: a material that asks for SH where the probe is a cube-only
 * grid's is shaded with the cube; name each (material, grid) pair once. Per object: the grid the
 * object's probe came from (`g_object`, UINT32_MAX = none); per pixel: every cube-only grid whose
 * bounds the object's bounds overlap. */
static void warn_mismatch(sv_probes *P, const sv_scene *scene, const sv_object *o, uint32_t g_object)
{
    const sv_gltf *gl = scene->gltf;
    uint32_t nm = gl->material_count + 1; /* the glTF default material last */
    if (!P->warned) {
        P->warned = calloc((size_t)nm * (P->grid_count ? P->grid_count : 1), 1);
        if (!P->warned) return;
    }
    const sv_gltf_mesh *mesh = &gl->meshes[o->mesh];
    for (uint32_t pi = 0; pi < mesh->primitive_count; ++pi) {
        int32_t mi = mesh->primitives[pi].material;
        uint32_t m = mi >= 0 && (uint32_t)mi < gl->material_count ? (uint32_t)mi : gl->material_count;
        const sv_ext_material *em = m < gl->material_count ? &scene->ext.materials[m] : NULL;
        uint32_t mode = P->probe_mode_override < SV_PROBE_MODE_MATERIAL ? P->probe_mode_override
                        : em                                            ? em->probe_mode
                                                                        : SV_PROBE_MODE_OBJECT;
        uint32_t rep = P->probe_rep_override < SV_PROBE_REP_MATERIAL ? P->probe_rep_override
                       : em                                          ? em->probe_representation
                                                                     : SV_PROBE_REP_SH;
        if (rep != SV_PROBE_REP_SH || mode == SV_PROBE_MODE_OFF) continue;
        for (uint32_t g = 0; g < P->grid_count; ++g) {
            const pb_shprobe *f = P->grids[g].file;
            if (f->representation != PB_SHPROBE_AMBIENT_CUBE) continue;
            bool hit = g == g_object; /* per object; tetrahedra per pixel fall back to per object */
            if (mode == SV_PROBE_MODE_PIXEL && f->structure != PB_SHPROBE_TETRA) {
                float lo[3], hi[3];
                grid_bounds(f, lo, hi);
                hit = true;
                for (int k = 0; k < 3; ++k) hit = hit && o->aabb_max[k] >= lo[k] && o->aabb_min[k] <= hi[k];
            }
            uint8_t *w = &P->warned[(size_t)m * P->grid_count + g];
            if (!hit || *w) continue;
            *w = 1;
            fprintf(stderr,
                    "schnee-view: warning: material '%s' asks for SH probes but shProbeGrids[%u] '%s' holds ambient "
                    "cubes only; shaded with the cube (docs/ambient-cube.md §5)\n",
                    m < gl->material_count && gl->materials[m].name ? gl->materials[m].name : "(default)", g,
                    P->grids[g].name);
        }
    }
}

/* Blends the weighted probes of grid g into one slot: SH (or cube) colours sum w_k * scale_k * C_k. */
static void blend_slot(const sv_probes *P, uint32_t g, const pb_interp_weights *w, sv_gpu_probe *sh, sv_gpu_cube *cube,
                       sv_object_weights *ow)
{
    const sv_probe_grid *gr = &P->grids[g];
    const pb_shprobe *f = gr->file;
    uint32_t nc = pb_shprobe_colour_count(f);
    if (nc > SV_SH_MAX_COEFFS) nc = SV_SH_MAX_COEFFS;
    bool is_cube = f->representation == PB_SHPROBE_AMBIENT_CUBE;
    double acc[SV_SH_MAX_COEFFS * 3] = {0};
    ow->grid = g;
    ow->count = w->count;
    for (uint32_t i = 0; i < w->count; ++i) {
        uint32_t p = w->probe[i];
        double wi = w->weight[i] * (f->probe_scale ? (double)f->probe_scale[p] : 1.0);
        for (uint32_t k = 0; k < nc; ++k)
            for (int c = 0; c < 3; ++c) acc[3 * k + c] += wi * f->coeffs[((size_t)p * nc + k) * 3 + (size_t)c];
        ow->probe[i] = gr->base + p;
        ow->weight[i] = (float)w->weight[i];
    }
    memset(sh, 0, sizeof *sh);
    memset(cube, 0, sizeof *cube);
    sh->params[0] = is_cube ? 0.0f : (float)f->max_band;
    sh->params[1] = sh->params[3] = 1.0f;
    cube->params[0] = (float)f->max_band;
    cube->params[1] = cube->params[3] = 1.0f;
    double fit[18];
    if (is_cube) {
        memcpy(fit, acc, sizeof fit);
    } else {
        for (uint32_t k = 0; k < nc; ++k)
            for (int c = 0; c < 3; ++c) sh->sh[k][c] = (float)acc[3 * k + c];
        pb_error err = {0};
        if (pb_ambient_cube_from_sh(f->max_band, acc, PB_AMBIENT_CUBE_LEAST_SQUARES, fit, &err) != PB_SUCCESS)
            memset(fit, 0, sizeof fit);
    }
    for (int j = 0; j < 6; ++j)
        for (int c = 0; c < 3; ++c) cube->faces[j][c] = (float)fit[3 * j + c];
}

uint32_t sv_probes_assign(sv_probes *P, sv_scene *scene)
{
    uint32_t n = 0;
    bool any_v3 = false;
    for (uint32_t g = 0; g < P->grid_count; ++g) any_v3 = any_v3 || P->grids[g].tree || P->grids[g].tetra;
    if (any_v3 && P->slot_count != scene->object_count) {
        free(P->slot_sh);
        free(P->slot_cube);
        free(P->slot_weights);
        uint32_t c = scene->object_count ? scene->object_count : 1;
        P->slot_sh = calloc(c, sizeof *P->slot_sh);
        P->slot_cube = calloc(c, sizeof *P->slot_cube);
        P->slot_weights = calloc(c, sizeof *P->slot_weights);
        P->slot_count = P->slot_sh && P->slot_cube && P->slot_weights ? scene->object_count : 0;
        if (!P->slot_count) fprintf(stderr, "schnee-view: warning: out of memory for per-object probes\n");
    }
    double t0 = sv_now_ms();
    bool first = any_v3 && !P->vis && scene->object_count;
    if (first) P->vis = static_vis_create(scene);
    /* An object that left the static scene no longer blocks anyone's probes: re-query the others. */
    uint32_t movable = 0;
    for (uint32_t i = 0; i < scene->object_count; ++i) movable += scene->objects[i].movable;
    if (any_v3 && movable != P->movable_seen)
        for (uint32_t i = 0; i < scene->object_count; ++i) scene->objects[i].needs_probe = true;
    P->movable_seen = movable;
    for (uint32_t i = 0; i < scene->object_count; ++i) {
        sv_object *o = &scene->objects[i];
        if (!o->needs_probe) continue;
        o->needs_probe = false;
        n++;
        o->probe = 0;
        o->probe_flags = 0;
        uint32_t from = UINT32_MAX;
        if (i < P->slot_count) P->slot_weights[i].grid = UINT32_MAX, P->slot_weights[i].count = 0;
        if (o->aabb_min[0] > o->aabb_max[0]) continue; /* empty mesh: no bounds, no position */
        float c[3] = {0.5f * (o->aabb_min[0] + o->aabb_max[0]), 0.5f * (o->aabb_min[1] + o->aabb_max[1]),
                      0.5f * (o->aabb_min[2] + o->aabb_max[2])};
        for (uint32_t g = 0; g < P->grid_count && from == UINT32_MAX; ++g) {
            const sv_probe_grid *gr = &P->grids[g];
            const pb_shprobe *f = gr->file;
            if (!gr->tree && !gr->tetra) { /* dense grid: the cell holding the centre (DESIGN.md §7) */
                int32_t idx = pb_shprobe_lookup(f, c);
                if (idx < 0 || (uint32_t)idx >= f->probe_count) continue;
                o->probe = gr->base + (uint32_t)idx;
                from = g;
                continue;
            }
            if (i >= P->slot_count) continue;
            vis_query q = {P->vis, scene, i, f->positions};
            pb_interp_options opt = {.visible = probe_visible, .visible_user = &q, .validity = f->validity};
            double pd[3] = {c[0], c[1], c[2]};
            pb_interp_weights w;
            if (gr->tree)
                pb_interp_query_cotree(gr->tree, pd, &opt, &w);
            else
                pb_interp_query_tetra(gr->tetra, pd, &opt, &w);
            if (w.count == 0) continue; /* outside, or no probe sees the centre: the next grid */
            blend_slot(P, g, &w, &P->slot_sh[i], &P->slot_cube[i], &P->slot_weights[i]);
            P->slots_version++;
            o->probe = P->total + i;
            if (gr->tetra) o->probe_flags |= SV_DRAW_TETRA;
            from = g;
        }
        if (from != UINT32_MAX && P->grids[from].file->representation == PB_SHPROBE_AMBIENT_CUBE)
            o->probe_flags |= SV_DRAW_CUBE_ONLY;
        warn_mismatch(P, scene, o, from);
    }
    if (first)
        fprintf(stderr,
                "schnee-view: per-object probes from version 3 grids: %u object(s) queried in %.1f ms "
                "(static-scene Embree build included)\n",
                n, sv_now_ms() - t0);
    return n;
}

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

void sv_cell_centre(const pb_shprobe *f, int x, int y, int z, float out[3])
{
    const float *ax = f->grid_axes;
    float h = f->grid_spacing, l[3] = {((float)x + 0.5f) * h, ((float)y + 0.5f) * h, ((float)z + 0.5f) * h};
    for (int k = 0; k < 3; ++k)
        out[k] = f->grid_origin[k] + l[0] * ax[0 * 3 + k] + l[1] * ax[1 * 3 + k] + l[2] * ax[2 * 3 + k];
}

static bool segment_blocked(RTCScene rs, const float a[3], const float b[3])
{
    struct RTCRay ray = {0};
    ray.org_x = a[0], ray.org_y = a[1], ray.org_z = a[2];
    ray.dir_x = b[0] - a[0], ray.dir_y = b[1] - a[1], ray.dir_z = b[2] - a[2];
    ray.tnear = 1e-4f;
    ray.tfar = 1.0f - 1e-4f;
    ray.mask = 0xFFFFFFFFu;
    pb_rtc_occluded1(rs, &ray);
    return ray.tfar < 0.0f; /* occluded: -inf */
}

/* pb_segment_fn over the static scene: the first surface on a -> b as a fraction of its length (both
 * sides of every triangle), 1 when clear. The ends are left out by 1e-4 of the length, as in
 * segment_blocked: a probe on a floor modelled exactly on the lattice still sees along that floor. */
static double segment_first_hit(void *user, const double a[3], const double b[3])
{
    struct RTCRayHit rh = {0};
    rh.ray.org_x = (float)a[0], rh.ray.org_y = (float)a[1], rh.ray.org_z = (float)a[2];
    rh.ray.dir_x = (float)(b[0] - a[0]), rh.ray.dir_y = (float)(b[1] - a[1]), rh.ray.dir_z = (float)(b[2] - a[2]);
    rh.ray.tnear = 1e-4f;
    rh.ray.tfar = 1.0f - 1e-4f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    pb_rtc_intersect1((RTCScene)user, &rh);
    return rh.hit.geomID == RTC_INVALID_GEOMETRY_ID ? 1.0 : (double)rh.ray.tfar;
}

/* Neighbour visibility masks, one uint32 per cell in the layout of the concatenated dense cell grids
 * (n cells): bit (dx+1) + 3(dy+1) + 9(dz+1) (d in {-1,0,1}^3; bit 13 = the cell itself, always set) is
 * set when the segment between the centres of the cell and of its neighbour at offset d crosses no
 * triangle of the static scene (Embree occlusion ray, both sides). Empty cells, and cells whose
 * neighbour is empty or outside the grid, keep the bit set (no information, no change to the weights).
 * Then, in `leaf_vis` (leaf_count × 64 bytes, octree grids in order), each octree leaf's table of the
 * continuous visibility field (pb_cotree_pair_visibility, pb_interp.h): 56 segments between its corners. */
static uint32_t *visibility_masks(const sv_probes *probes, const sv_scene *scene, size_t n, uint8_t *leaf_vis,
                                  size_t leaf_count)
{
    uint32_t *masks = malloc((n ? n : 1) * sizeof(uint32_t));
    if (!masks) return NULL;
    for (size_t i = 0; i < n; ++i) masks[i] = (1u << 27) - 1u;
    memset(leaf_vis, PB_VIS_CLEAR, leaf_count * 64);
    if (!scene || !scene->object_count) return masks;
    double t0 = sv_now_ms();
    RTCDevice dev = new_embree_device();
    if (!dev) {
        fprintf(stderr, "schnee-view: warning: Embree device failed; per-pixel probes without visibility masks\n");
        return masks;
    }
    size_t tris = 0, rays = 0;
    /* The static scene only: an object that moved (--move, window) never blocks probes. */
    RTCScene rs = build_scene(dev, scene, true, RTC_SCENE_FLAG_NONE, &tris, NULL, NULL);
    size_t off = 0, loff = 0;
    for (uint32_t g = 0; g < probes->grid_count && tris; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        if (probes->grids[g].tree) {
            const pb_cotree *tree = probes->grids[g].tree;
            /* The tree was built from the file's leaves, which are in the same (Morton) order. */
            if (pb_cotree_leaf_count(tree) == f->element_count &&
                memcmp(pb_cotree_leaves(tree), f->leaves, 16u * (size_t)f->element_count) == 0) {
                (void)pb_cotree_pair_visibility(tree, segment_first_hit, rs, leaf_vis + 64u * loff, NULL);
                rays += 56u * (size_t)f->element_count;
            } else {
                fprintf(stderr,
                        "schnee-view: warning: grid %u: octree leaves out of file order; per pixel without "
                        "its visibility field\n",
                        g);
            }
            loff += f->element_count;
            continue;
        }
        if (!f->grid) continue;
        int X = (int)f->grid_dims[0], Y = (int)f->grid_dims[1], Z = (int)f->grid_dims[2];
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
                        ++rays;
                        if (segment_blocked(rs, a, b)) {
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
    size_t n = 0, leaves = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        if (probes->grids[g].tree)
            leaves += f->element_count;
        else if (f->grid)
            n += (size_t)f->grid_dims[0] * f->grid_dims[1] * f->grid_dims[2];
    }
    *grids_out = NULL;
    *cells_out = NULL;
    *cell_count = 0;
    size_t ints = 2 * n + (SV_LEAF_INTS + SV_LEAF_VIS_INTS) * leaves;
    if (ints > INT32_MAX) {
        fprintf(stderr, "schnee-view: error: probe grids have more than 2^31 cell and leaf entries in total\n");
        return false;
    }
    sv_gpu_grid *grids = calloc(probes->grid_count ? probes->grid_count : 1, sizeof(*grids));
    int32_t *cells = calloc(ints ? ints : 1, sizeof(int32_t));
    uint8_t *leaf_masks = malloc((leaves ? leaves : 1) * 64);
    uint32_t *masks = leaf_masks ? visibility_masks(probes, scene, n, leaf_masks, leaves) : NULL;
    if (!grids || !cells || !masks || !leaf_masks) {
        free(grids);
        free(cells);
        free(masks);
        free(leaf_masks);
        fprintf(stderr, "schnee-view: error: out of memory for the probe grids\n");
        return false;
    }
    size_t off = 0, loff = 0, leaf_base = 2 * n, mask_base = 2 * n + SV_LEAF_INTS * leaves;
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
            for (uint32_t i = 0; i < f->element_count; ++i) {
                const uint32_t *l = f->leaves + 4u * i;
                int32_t *o = cells + leaf_base + SV_LEAF_INTS * (loff + i);
                memcpy(o, l, 4 * sizeof(uint32_t)); /* x, y, z, level; ints 5..7 reserved (0) */
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

sv_gpu_cell *sv_probes_cells(const sv_probes *probes, uint32_t *sphere_count, uint32_t *cell_count)
{
    size_t n = 0;
    for (uint32_t g = 0; g < probes->grid_count; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        if (!f->grid) continue; /* octree, tetrahedra: spheres only, no cell outlines */
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
