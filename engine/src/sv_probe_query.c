/* Per-object probe queries (see sv_probe_query.h): the interpolated and visibility-judged blend of a
 * grid's probes at the object's centre in the object's slot: a dense grid's field (pb_grid_field), a
 * version 3 tree's or tetrahedra's weights (pb_interp), the same segment test through the static scene. */
#include "sv_probe_query.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "schnee/pb_ambient_cube.h"
#include "schnee/pb_sh.h"
#include "sv_clock.h"
#include "sv_probe_vis.h"

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
        uint32_t mode, rep; /* the object's own (VULKAN_SCHNEE_node) over its material's */
        sv_object_probe_mode(o, em, P->probe_mode_override, P->probe_rep_override, &mode, &rep);
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

/* Grid g's field for per object (pb_grid_field over the file's colours, validity, scale and axes; no
 * masks: per object judges each probe by its segment instead), built at its first query; NULL (with a
 * warning, once) when it cannot be built. */
static const pb_grid_field *dense_field(sv_probes *P, uint32_t g)
{
    if (!P->fields) P->fields = calloc(P->grid_count, sizeof *P->fields);
    if (!P->fields) return NULL;
    if (P->fields[g]) return P->fields[g];
    const sv_probe_grid *gr = &P->grids[g];
    pb_error err = {0};
    pb_result rc = sv_grid_field_build(gr->file, &P->fields[g], &err);
    if (rc != PB_SUCCESS) {
        P->fields[g] = NULL;
        fprintf(stderr,
                "schnee-view: warning: shProbeGrids[%u] '%s': %s; per object takes the cell holding the centre\n", g,
                gr->name, err.message[0] ? err.message : pb_result_string(rc));
    }
    return P->fields[g];
}

/* Per object on dense grid g (docs/grid-field.md "Per object"): pb_grid_field_query at the centre c with
 * the movable rule (no normal: no back faces, home = the cell of c) and no masks; each weighted corner's
 * probe is judged by the segment from its cell's centre to c through the static scene (sv_probe_visible,
 * the trees' per-object test), hidden ones dropped, the rest renormalised (corners clamped onto one cell
 * merged); when the kept raw weight is <= 1e-6, the field's step 5: its plain trilinear x validity weights
 * (without the segment test). False when the grid gives no value (outside, or no valid corner: the next
 * grid). Without a field (build failure): the cell holding c, as before. */
static bool dense_weights(sv_probes *P, uint32_t g, const sv_scene *scene, uint32_t self, const double c[3],
                          pb_interp_weights *out)
{
    const pb_shprobe *f = P->grids[g].file;
    out->count = 0;
    const pb_grid_field *fld = dense_field(P, g);
    if (!fld) {
        float cf[3] = {(float)c[0], (float)c[1], (float)c[2]};
        int32_t idx = pb_shprobe_lookup(f, cf);
        if (idx < 0 || (uint32_t)idx >= f->probe_count) return false;
        out->count = 1, out->probe[0] = (uint32_t)idx, out->weight[0] = 1.0;
        return true;
    }
    pb_grid_field_weights w;
    pb_grid_field_status st = pb_grid_field_query(fld, c, NULL, NULL, &w);
    if (st == PB_GRID_FIELD_OUTSIDE || st == PB_GRID_FIELD_NONE) return false;
    float centres[8 * 3];
    sv_vis_query q = {P->vis, scene, self, centres};
    /* Pass 0: the weighted corners the segment test keeps. Pass 1, step 5 (pass 0 kept <= 1e-6, or the field's
     * own step 5): the field's weights without the segment test (the plain trilinear x validity here: no
     * masks, no back faces). */
    for (int pass = st == PB_GRID_FIELD_WEIGHTS ? 0 : 1; pass < 2; ++pass) {
        double sum = 0.0;
        out->count = 0;
        for (int k = 0; k < 8; ++k) {
            double wk = pass == 0 ? w.raw[k] : w.weight[k];
            if (!(wk > 0.0) || w.probe[k] < 0) continue;
            if (pass == 0) {
                sv_cell_centre(f, (int)w.cell[k][0], (int)w.cell[k][1], (int)w.cell[k][2], centres + 3 * k);
                if (!sv_probe_visible(&q, (uint32_t)k, c)) continue;
            }
            uint32_t j = 0;
            while (j < out->count && out->probe[j] != (uint32_t)w.probe[k]) ++j;
            if (j == out->count) out->probe[out->count++] = (uint32_t)w.probe[k], out->weight[j] = 0.0;
            out->weight[j] += wk;
            sum += wk;
        }
        if (sum > (pass == 0 ? PB_GRID_FIELD_MIN_WEIGHT : 0.0)) {
            for (uint32_t j = 0; j < out->count; ++j) out->weight[j] /= sum;
            return true;
        }
    }
    out->count = 0;
    return false;
}

uint32_t sv_probes_assign(sv_probes *P, sv_scene *scene)
{
    uint32_t n = 0;
    /* Every grid blends probes per object (dense grids too, since issue 30 item 3): slots and the static
     * scene's occluder whenever the scene has a grid. */
    bool any_grid = P->grid_count > 0;
    if (any_grid && P->slot_count != scene->object_count) {
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
    bool first = any_grid && !P->vis && scene->object_count;
    if (first) P->vis = sv_static_vis_create(scene);
    /* An object that left the static scene no longer blocks anyone's probes: re-query the others. */
    uint32_t movable = 0;
    for (uint32_t i = 0; i < scene->object_count; ++i) movable += scene->objects[i].movable;
    if (any_grid && movable != P->movable_seen)
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
            double pd[3] = {c[0], c[1], c[2]};
            pb_interp_weights w;
            if (!gr->tree && !gr->tetra) { /* dense grid: its field at the centre (docs/grid-field.md) */
                if (!dense_weights(P, g, scene, i, pd, &w)) continue;
                /* One probe (or no slot): its own entry, where the file's probes are on the GPU. */
                if ((w.count == 1 && !P->dense_slots) || i >= P->slot_count) {
                    uint32_t best = 0;
                    for (uint32_t k = 1; k < w.count; ++k) best = w.weight[k] > w.weight[best] ? k : best;
                    o->probe = gr->base + w.probe[best];
                    from = g;
                    continue;
                }
            } else {
                if (i >= P->slot_count) continue;
                sv_vis_query q = {P->vis, scene, i, f->positions};
                pb_interp_options opt = {.visible = sv_probe_visible, .visible_user = &q, .validity = f->validity};
                if (gr->tree)
                    pb_interp_query_cotree(gr->tree, pd, &opt, &w);
                else
                    pb_interp_query_tetra(gr->tetra, pd, &opt, &w);
                if (w.count == 0) continue; /* outside, or no probe sees the centre: the next grid */
            }
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
                "schnee-view: per-object probes: %u object(s) queried in %.1f ms "
                "(static-scene Embree build included)\n",
                n, sv_now_ms() - t0);
    return n;
}

uint32_t sv_probes_use_slots(sv_probes *P, sv_scene *scene)
{
    if (P->dense_slots) return 0;
    P->dense_slots = true;
    uint32_t n = 0;
    for (uint32_t i = 0; i < scene->object_count; ++i) {
        sv_object *o = &scene->objects[i];
        bool file_probe = o->probe > 0 && o->probe < P->total;
        o->needs_probe = o->needs_probe || file_probe;
        n += file_probe;
    }
    return n ? sv_probes_assign(P, scene) : 0;
}
