/* Probe visibility through the static scene (see sv_probe_vis.h). */
#include "sv_probe_vis.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "schnee/pb_occluder.h"
#include "sv_clock.h"
#include "sv_math.h"

struct sv_static_vis {
    pb_occluder *occluder; /* every object's triangles at load, one mesh per primitive */
    uint32_t *mesh_object; /* occluder mesh index -> object index */
    uint32_t mesh_count;
};

/* A bounded thread count for the occluders' BVH builds (docs/engine.md): at most
 * SV_EMBREE_MAX_THREADS, never more than the online CPUs. */
static uint32_t occluder_threads(void)
{
    long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    return cpus > 0 && cpus < SV_EMBREE_MAX_THREADS ? (uint32_t)cpus : SV_EMBREE_MAX_THREADS;
}

/* An occluder of the objects' triangles in world space (current transforms): every object, or
 * (static_only) those never moved; one mesh per primitive. mesh_object (optional) gets mesh index ->
 * object index. NULL on failure (message printed). */
static pb_occluder *build_occluder(const sv_scene *scene, bool static_only, uint32_t flags, uint32_t **mesh_object,
                                   uint32_t *mesh_count)
{
    const sv_gltf *g = scene->gltf;
    uint32_t n = 0;
    size_t floats = 0;
    for (uint32_t o = 0; o < scene->object_count; ++o) {
        const sv_object *obj = &scene->objects[o];
        if (static_only && obj->movable) continue;
        const sv_gltf_mesh *mesh = &g->meshes[obj->mesh];
        for (uint32_t p = 0; p < mesh->primitive_count; ++p) {
            const sv_gltf_primitive *pr = &mesh->primitives[p];
            if (pr->index_count < 3 || !pr->vertex_count) continue;
            n++;
            floats += 3 * (size_t)pr->vertex_count;
        }
    }
    pb_occluder_mesh *meshes = calloc(n + 1, sizeof *meshes);
    float *world = malloc((floats + 1) * sizeof(float));
    uint32_t *map = malloc((n + 1) * sizeof(uint32_t));
    pb_occluder *occ = NULL;
    if (meshes && world && map) {
        uint32_t k = 0;
        float *v = world;
        for (uint32_t o = 0; o < scene->object_count; ++o) {
            const sv_object *obj = &scene->objects[o];
            if (static_only && obj->movable) continue;
            const sv_gltf_mesh *mesh = &g->meshes[obj->mesh];
            for (uint32_t p = 0; p < mesh->primitive_count; ++p) {
                const sv_gltf_primitive *pr = &mesh->primitives[p];
                if (pr->index_count < 3 || !pr->vertex_count) continue;
                for (uint32_t i = 0; i < pr->vertex_count; ++i)
                    sv_mat4_point(obj->world, pr->positions + 3 * (size_t)i, v + 3 * (size_t)i);
                meshes[k].positions_f = v;
                meshes[k].indices = pr->indices;
                meshes[k].vertex_count = pr->vertex_count;
                meshes[k].triangle_count = pr->index_count / 3;
                map[k++] = o;
                v += 3 * (size_t)pr->vertex_count;
            }
        }
        pb_occluder_desc d = {0};
        d.meshes = meshes;
        d.mesh_count = n;
        d.thread_count = occluder_threads();
        d.flags = flags;
        d.what = "static scene";
        pb_error err = {0};
        if (pb_occluder_create(&d, &occ, &err) != PB_SUCCESS)
            fprintf(stderr, "schnee-view: warning: %s\n", err.message[0] ? err.message : pb_result_string(err.code));
    } else {
        fprintf(stderr, "schnee-view: warning: out of memory for the static scene\n");
    }
    free(meshes);
    free(world);
    if (occ && mesh_object) {
        *mesh_object = map;
        *mesh_count = n;
    } else {
        free(map);
    }
    return occ;
}

void sv_static_vis_destroy(sv_static_vis *v)
{
    if (!v) return;
    pb_occluder_destroy(v->occluder);
    free(v->mesh_object);
    free(v);
}

/* Every object's triangles; which ones occlude is decided per ray (skip_object): the static set. */
sv_static_vis *sv_static_vis_create(const sv_scene *scene)
{
    sv_static_vis *v = calloc(1, sizeof *v);
    if (!v) return NULL;
    v->occluder = build_occluder(scene, false, PB_OCCLUDER_FILTERABLE, &v->mesh_object, &v->mesh_count);
    if (!v->occluder) {
        fprintf(stderr, "schnee-view: warning: occluder failed; per-object probes without visibility\n");
        free(v);
        return NULL;
    }
    return v;
}

/* pb_occluder_skip_fn: hits on the queried object and on objects that have moved (not in the
 * static set) do not block. */
static bool skip_object(void *user, uint32_t mesh)
{
    const sv_vis_query *q = user;
    uint32_t o = mesh < q->vis->mesh_count ? q->vis->mesh_object[mesh] : UINT32_MAX;
    return o == q->self || (o < q->scene->object_count && q->scene->objects[o].movable);
}

bool sv_probe_visible(void *user, uint32_t probe, const double point[3])
{
    const sv_vis_query *q = user;
    if (!q->vis || !q->positions) return true;
    const float *a = q->positions + 3 * (size_t)probe;
    pb_occluder_ray ray = {{a[0], a[1], a[2]},
                           {(float)(point[0] - a[0]), (float)(point[1] - a[1]), (float)(point[2] - a[2])},
                           1e-4f,
                           1.0f - 1e-4f};
    return !pb_occluder_first_hit(q->vis->occluder, &ray, skip_object, (void *)q, NULL, NULL);
}

/* ---- per pixel --------------------------------------------------------------------------------- */

static bool segment_blocked(const pb_occluder *occ, const float a[3], const float b[3])
{
    pb_occluder_ray ray = {{a[0], a[1], a[2]}, {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, 1e-4f, 1.0f - 1e-4f};
    return pb_occluder_occluded(occ, &ray);
}

/* pb_segment_fn over the static scene: the first surface on a -> b as a fraction of its length (both
 * sides of every triangle), 1 when clear. The ends are left out by 1e-4 of the length, as in
 * segment_blocked: a probe on a floor modelled exactly on the lattice still sees along that floor. */
double sv_segment_first_hit(void *user, const double a[3], const double b[3])
{
    pb_occluder_ray ray = {{(float)a[0], (float)a[1], (float)a[2]},
                           {(float)(b[0] - a[0]), (float)(b[1] - a[1]), (float)(b[2] - a[2])},
                           1e-4f,
                           1.0f - 1e-4f};
    float t = 1.0f;
    return pb_occluder_first_hit((const pb_occluder *)user, &ray, NULL, NULL, &t, NULL) ? (double)t : 1.0;
}

pb_occluder *sv_static_occluder(const sv_scene *scene)
{
    if (!scene || !scene->object_count) return NULL;
    pb_occluder *occ = build_occluder(scene, true, 0, NULL, NULL);
    if (occ && !pb_occluder_triangle_count(occ)) {
        pb_occluder_destroy(occ);
        return NULL;
    }
    return occ;
}

/* The tree's leaves are the file's, in its order: min corners equal (a kd tree's 4th word packs the
 * levels where the tree's holds the largest; pb_interp_from_shprobe compared the levels). */
static bool same_leaves(const uint32_t *tree_leaves, const pb_shprobe *f)
{
    if (f->structure != PB_SHPROBE_KDTREE) return memcmp(tree_leaves, f->leaves, 16u * (size_t)f->element_count) == 0;
    for (size_t i = 0; i < f->element_count; ++i)
        if (memcmp(tree_leaves + 4 * i, f->leaves + 4 * i, 3 * sizeof(uint32_t)) != 0) return false;
    return true;
}

uint32_t *sv_probe_visibility_masks(const sv_probes *probes, const sv_scene *scene, size_t n, uint8_t *leaf_vis,
                                    size_t leaf_count)
{
    uint32_t *masks = malloc((n ? n : 1) * sizeof(uint32_t));
    if (!masks) return NULL;
    for (size_t i = 0; i < n; ++i) masks[i] = (1u << 27) - 1u;
    memset(leaf_vis, PB_VIS_CLEAR, leaf_count * 64);
    if (!scene || !scene->object_count) return masks;
    double t0 = sv_now_ms();
    /* The static scene only: an object that moved (--move, window) never blocks probes. */
    pb_occluder *occ = build_occluder(scene, true, 0, NULL, NULL);
    if (!occ) {
        fprintf(stderr, "schnee-view: warning: occluder failed; per-pixel probes without visibility masks\n");
        return masks;
    }
    size_t tris = (size_t)pb_occluder_triangle_count(occ), rays = 0;
    size_t off = 0, loff = 0;
    for (uint32_t g = 0; g < probes->grid_count && tris; ++g) {
        const pb_shprobe *f = probes->grids[g].file;
        if (probes->grids[g].tree) {
            const pb_cotree *tree = probes->grids[g].tree;
            /* The tree was built from the file's leaves, which are in the same (Morton) order. */
            if (pb_cotree_leaf_count(tree) == f->element_count && same_leaves(pb_cotree_leaves(tree), f)) {
                (void)pb_cotree_pair_visibility(tree, sv_segment_first_hit, occ, leaf_vis + 64u * loff, NULL);
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
                        if (segment_blocked(occ, a, b)) {
                            masks[off + ci] &= ~(1u << k);
                            masks[off + cj] &= ~(1u << (26 - k)); /* the opposite offset */
                        }
                    }
                }
        off += (size_t)X * Y * Z;
    }
    pb_occluder_destroy(occ);
    fprintf(stderr, "schnee-view: probe visibility masks: %zu segment(s) against %zu triangle(s) in %.1f ms\n", rays,
            tris, sv_now_ms() - t0);
    return masks;
}
