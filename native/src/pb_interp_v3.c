/* The interpolation structures in `.shprobe` version 3 and 4 files (pb_interp_v3.h): a file image from
 * a corner octree (version 4 when some leaf is a box, not a cube) or tetrahedra, the structure back from
 * a file with the file's numbering, and the resampling of such a field onto the seed's dense grid.
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_interp_v3.h"

#include "schnee/pb_sh.h"

#include "pb_interp_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A version 4 image of a tree with some box that is not a cube: leaves in pb_cotree_leaves() order with
 * their packed levels, the canonical split tree (pb_cotree_split_tree) whose leaf nodes index them. */
static pb_result kdtree_image(const pb_cotree *t, const uint32_t *levels, uint32_t representation, uint32_t max_band,
                              pb_shprobe **out, pb_error *err)
{
    uint32_t K = 0;
    pb_result r = pb_cotree_split_tree(t, NULL, 0, &K, err);
    if (r != PB_SUCCESS) return r;
    pb_shprobe *p;
    r = pb_shprobe_create_v4(t->probe_count, representation, max_band, t->dims, t->leaf_count, t->hanging_count,
                             pb_cotree_root_level(t), K, &p, err);
    if (r != PB_SUCCESS) return r;
    uint32_t got = 0;
    r = pb_cotree_split_tree(t, p->split_nodes, K, &got, err);
    if (r == PB_SUCCESS && got != K)
        r = pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the split tree has %u nodes, then %u", K, got);
    if (r != PB_SUCCESS) {
        pb_shprobe_destroy(p);
        return r;
    }
    for (uint32_t i = 0; i < t->leaf_count; i++) {
        memcpy(p->leaves + 4u * i, t->leaves + 4u * i, 3 * sizeof(uint32_t));
        p->leaves[4u * i + 3] = PB_LEVELS_PACK(levels[3u * i], levels[3u * i + 1], levels[3u * i + 2]);
    }
    *out = p;
    return PB_SUCCESS;
}

pb_result pb_shprobe_from_cotree(const pb_cotree *t, uint32_t representation, uint32_t max_band, pb_shprobe **out,
                                 pb_error *err)
{
    if (!t || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_from_cotree: NULL argument");
    *out = NULL;
    if (!t->finalized) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the corner octree is not finalized");
    uint32_t *levels = malloc(((size_t)t->leaf_count * 3 + 1) * sizeof(uint32_t));
    if (!levels) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u leaves", t->leaf_count);
    pb_cotree_leaf_levels(t, levels);
    bool cubes = true;
    for (uint32_t i = 0; i < t->leaf_count && cubes; i++)
        cubes = levels[3u * i] == levels[3u * i + 1] && levels[3u * i] == levels[3u * i + 2];
    pb_shprobe *p;
    /* A tree of cubes stays version 3 structure 1, byte for byte as before boxes existed. */
    pb_result r = cubes ? pb_shprobe_create_v3(t->probe_count, representation, max_band, PB_SHPROBE_OCTREE, t->dims,
                                               t->leaf_count, t->hanging_count, &p, err)
                        : kdtree_image(t, levels, representation, max_band, &p, err);
    free(levels);
    if (r != PB_SUCCESS) return r;
    for (int k = 0; k < 3; k++) p->grid_origin[k] = (float)t->origin[k];
    p->grid_spacing = (float)t->h;
    for (uint32_t i = 0; i < t->probe_count; i++)
        for (int k = 0; k < 3; k++)
            p->positions[3u * i + (uint32_t)k] = (float)(t->origin[k] + t->h * t->probe_lattice[3u * i + (uint32_t)k]);
    if (cubes) memcpy(p->leaves, t->leaves, (size_t)t->leaf_count * 4 * sizeof(uint32_t));
    memcpy(p->leaf_corners, t->corners, (size_t)t->leaf_count * 8 * sizeof(int32_t));
    memcpy(p->hanging_sources, t->hang_src, (size_t)t->hanging_count * 4 * sizeof(uint32_t));
    memcpy(p->hanging_weights, t->hang_w, (size_t)t->hanging_count * 4 * sizeof(float));
    *out = p;
    return PB_SUCCESS;
}

pb_result pb_shprobe_from_tetra(const pb_tetra *t, const double *positions, uint32_t representation, uint32_t max_band,
                                pb_shprobe **out, pb_error *err)
{
    if (!t || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_from_tetra: NULL argument");
    *out = NULL;
    const uint32_t zero[3] = {0, 0, 0};
    pb_shprobe *p;
    pb_result r = pb_shprobe_create_v3(t->point_count, representation, max_band, PB_SHPROBE_TETRA, zero, t->tet_count,
                                       0, &p, err);
    if (r != PB_SUCCESS) return r;
    const double *pos = positions ? positions : t->points;
    for (size_t i = 0; i < (size_t)t->point_count * 3; i++) p->positions[i] = (float)pos[i];
    p->grid_spacing = 1.0f; /* unused by tetrahedra */
    memcpy(p->tets, t->tets, (size_t)t->tet_count * 4 * sizeof(uint32_t));
    memcpy(p->tet_neighbours, t->nbr, (size_t)t->tet_count * 4 * sizeof(int32_t));
    *out = p;
    return PB_SUCCESS;
}

static pb_result identity_frame(const pb_shprobe *f, pb_error *err)
{
    static const float identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    bool zero = true;
    for (int i = 0; i < 9; i++) zero &= f->grid_axes[i] == 0.0f;
    if (!zero && memcmp(f->grid_axes, identity, sizeof identity) != 0)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "octree files with rotated axes are not interpolated by this version (identity only)");
    return PB_SUCCESS;
}

/* A tree with a file's numbering: leaves as stored (Morton order, so the indices survive the sort),
 * corners and hanging rules as stored, expansions recomputed. Version 4 (the kd corner tree): the tree
 * from the boxes (pb_cotree_create_boxes, its split tree built from the leaves), their per-axis levels
 * placing the corners; as for version 3 the file's numbering is kept (any numbering whose rules name
 * earlier sources), and the geometry of the rules is the writer's guarantee (docs/shprobe-format.md). */
static pb_result cotree_from_file(const pb_shprobe *f, pb_cotree **out, pb_error *err)
{
    pb_result r0 = identity_frame(f, err);
    if (r0 != PB_SUCCESS) return r0;
    double origin[3] = {f->grid_origin[0], f->grid_origin[1], f->grid_origin[2]};
    bool kd = f->structure == PB_SHPROBE_KDTREE;
    pb_cotree *t;
    pb_result r =
        kd ? pb_cotree_create_boxes(origin, f->grid_spacing, f->root_level, f->grid_dims, f->leaves, f->element_count,
                                    &t, err)
           : pb_cotree_create_leaves(origin, f->grid_spacing, f->grid_dims, f->leaves, f->element_count, &t, err);
    if (r != PB_SUCCESS) return r;
    uint32_t *levels = malloc(((size_t)f->element_count * 3 + 1) * sizeof(uint32_t));
    if (!levels) {
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the file's octree");
    }
    pb_cotree_leaf_levels(t, levels);
    bool same = pb_cotree_leaf_count(t) == f->element_count;
    for (uint32_t i = 0; same && i < f->element_count; i++) {
        const uint32_t *l = f->leaves + 4u * i, *lv = levels + 3u * i;
        same = memcmp(t->leaves + 4u * i, l, 3 * sizeof(uint32_t)) == 0 &&
               (kd ? PB_LEVELS_PACK(lv[0], lv[1], lv[2]) == l[3] : t->leaves[4u * i + 3] == l[3]);
    }
    if (!same) {
        free(levels);
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "the file's leaves are not in Morton order");
    }
    uint32_t P = f->probe_count, H = f->hanging_count, N = f->element_count;
    t->probe_count = P;
    t->hanging_count = H;
    t->probe_lattice = calloc((size_t)P * 3 + 1, sizeof(uint32_t));
    t->hang_lattice = calloc((size_t)H * 3 + 1, sizeof(uint32_t));
    t->hang_src = malloc(((size_t)H * 4 + 1) * sizeof(uint32_t));
    t->hang_w = malloc(((size_t)H * 4 + 1) * sizeof(float));
    t->exp_start = calloc((size_t)H + 2, sizeof(uint32_t));
    t->exp_probe = malloc(((size_t)H * HANG_MAX_EXPANDED + 1) * sizeof(uint32_t));
    t->exp_w = malloc(((size_t)H * HANG_MAX_EXPANDED + 1) * sizeof(double));
    t->corners = malloc(((size_t)N * 8 + 1) * sizeof(int32_t));
    bool ok = t->probe_lattice && t->hang_lattice && t->hang_src && t->hang_w && t->exp_start && t->exp_probe &&
              t->exp_w && t->corners && hmap_init(&t->node_map, (size_t)N * 8);
    if (!ok) {
        free(levels);
        pb_cotree_destroy(t);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for the file's octree");
    }
    memcpy(t->hang_src, f->hanging_sources, (size_t)H * 4 * sizeof(uint32_t));
    memcpy(t->hang_w, f->hanging_weights, (size_t)H * 4 * sizeof(float));
    memcpy(t->corners, f->leaf_corners, (size_t)N * 8 * sizeof(int32_t));
    for (uint32_t i = 0; i < N; i++) {
        const uint32_t *l = t->leaves + 4u * i, *lv = levels + 3u * i;
        for (uint32_t c = 0; c < 8; c++) {
            uint32_t pnt[3];
            for (int k = 0; k < 3; k++) pnt[k] = l[k] + ((c >> k) & 1u ? 1u << lv[k] : 0u);
            uint32_t node = (uint32_t)t->corners[8u * i + c];
            if (node >= P + H) {
                free(levels);
                pb_cotree_destroy(t);
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "leaf %u corner %u is not a node", i, c);
            }
            bool inserted;
            *hmap_put(&t->node_map, pack3(pnt[0], pnt[1], pnt[2]), &inserted) = node;
            memcpy(node < P ? t->probe_lattice + 3u * node : t->hang_lattice + 3u * (node - P), pnt, sizeof pnt);
        }
    }
    free(levels);
    uint32_t e = 0;
    for (uint32_t hI = 0; hI < H; hI++) {
        uint32_t cnt = 0;
        t->exp_start[hI] = e;
        bool fits = true;
        for (uint32_t k = 0; k < 4 && fits; k++) {
            uint32_t src = t->hang_src[4u * hI + k];
            double w = t->hang_w[4u * hI + k];
            if (!(w > 0.0)) continue;
            if (src >= P + hI) {
                fits = false;
                break;
            }
            if (src < P) {
                fits = merge_add(t->exp_probe + e, t->exp_w + e, &cnt, HANG_MAX_EXPANDED, src, w);
            } else {
                for (uint32_t q = t->exp_start[src - P]; q < t->exp_start[src - P + 1] && fits; q++)
                    fits = merge_add(t->exp_probe + e, t->exp_w + e, &cnt, HANG_MAX_EXPANDED, t->exp_probe[q],
                                     w * t->exp_w[q]);
            }
        }
        if (!fits) {
            pb_cotree_destroy(t);
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "hanging node %u has a source that is not earlier or depends on more than %u probes",
                                hI, HANG_MAX_EXPANDED);
        }
        e += cnt;
        t->exp_start[hI + 1] = e;
    }
    t->finalized = true;
    *out = t;
    return PB_SUCCESS;
}

pb_result pb_interp_from_shprobe(const pb_shprobe *f, pb_cotree **tree, pb_tetra **tetra, pb_error *err)
{
    if (!f || !tree || !tetra) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_interp_from_shprobe: NULL");
    *tree = NULL;
    *tetra = NULL;
    if (f->structure == PB_SHPROBE_OCTREE || f->structure == PB_SHPROBE_KDTREE) return cotree_from_file(f, tree, err);
    if (f->structure != PB_SHPROBE_TETRA)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "the file holds a dense grid, not probe positions with an interpolation structure");
    double *pos = malloc(((size_t)f->probe_count * 3 + 1) * sizeof(double));
    if (!pos) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory");
    for (size_t i = 0; i < (size_t)f->probe_count * 3; i++) pos[i] = f->positions[i];
    pb_result r = pb_tetra_create_from(pos, f->probe_count, f->tets, f->element_count, tetra, err);
    free(pos);
    return r;
}

/* The interpolation weights at the centre of cell j of a dense grid (min corner lo, cell size
 * spacing, dims cells per axis; j in the version 1/2 grid order, x fastest, then y, then z). */
static void dense_cell_weights(const pb_cotree *tree, const pb_tetra *tetra, const pb_interp_options *opt,
                               const double lo[3], double spacing, const uint32_t dims[3], uint64_t j,
                               pb_interp_weights *w)
{
    const uint64_t cell[3] = {j % dims[0], (j / dims[0]) % dims[1], j / ((uint64_t)dims[0] * dims[1])};
    double p[3];
    for (int k = 0; k < 3; k++) p[k] = lo[k] + spacing * ((double)cell[k] + 0.5);
    if (tree)
        pb_interp_query_cotree(tree, p, opt, w);
    else
        pb_interp_query_tetra(tetra, p, opt, w);
}

pb_result pb_interp_resample_dense(const pb_shprobe *f, double spacing, pb_shprobe **out, pb_error *err)
{
    if (!f || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_interp_resample_dense: NULL argument");
    *out = NULL;
    if (f->representation != PB_SHPROBE_SH)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "a dense version 1/2 grid holds SH only; this file holds ambient cubes");
    pb_cotree *tree;
    pb_tetra *tetra;
    pb_result r = pb_interp_from_shprobe(f, &tree, &tetra, err);
    if (r != PB_SUCCESS) return r;
    double lo[3], hi[3];
    if (tree) {
        if (!(spacing > 0.0)) spacing = tree->h;
        for (int k = 0; k < 3; k++) lo[k] = tree->origin[k], hi[k] = tree->origin[k] + tree->h * tree->dims[k];
    } else {
        if (!(spacing > 0.0) || !isfinite(spacing)) {
            pb_tetra_destroy(tetra);
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "resampling tetrahedra needs a grid spacing > 0");
        }
        for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
        for (uint32_t i = 0; i < tetra->point_count; i++)
            for (int k = 0; k < 3; k++) {
                lo[k] = fmin(lo[k], tetra->points[3u * i + (uint32_t)k]);
                hi[k] = fmax(hi[k], tetra->points[3u * i + (uint32_t)k]);
            }
    }
    uint32_t dims[3];
    uint64_t cells = 1;
    for (int k = 0; k < 3; k++) {
        double d = ceil((hi[k] - lo[k]) / spacing - 1e-6);
        if (d < 1) d = 1;
        if (d > (double)PB_SHPROBE_MAX_GRID_CELLS) d = (double)PB_SHPROBE_MAX_GRID_CELLS + 1;
        dims[k] = (uint32_t)d;
        cells *= dims[k];
    }
    uint32_t C = pb_sh_count(f->max_band);
    int32_t *map = NULL;
    pb_shprobe *g = NULL;
    if (cells > PB_SHPROBE_MAX_GRID_CELLS) {
        r = pb_error_set(err, PB_ERROR_TOO_LARGE,
                         "the dense grid would have %u x %u x %u cells, above the limit of %llu; use a larger spacing",
                         dims[0], dims[1], dims[2], (unsigned long long)PB_SHPROBE_MAX_GRID_CELLS);
        goto done;
    }
    map = malloc((size_t)cells * sizeof(int32_t));
    if (!map) {
        r = pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %llu cells", (unsigned long long)cells);
        goto done;
    }
    pb_interp_options opt = {.validity = f->validity};
    uint32_t n = 0;
    for (uint64_t j = 0; j < cells; j++) {
        pb_interp_weights w;
        dense_cell_weights(tree, tetra, &opt, lo, spacing, dims, j, &w);
        map[j] = w.count ? (int32_t)n++ : -1;
    }
    if (n > PB_SHPROBE_MAX_PROBES) {
        r = pb_error_set(err, PB_ERROR_TOO_LARGE, "the dense grid would hold %u probes, above the limit of %u", n,
                         PB_SHPROBE_MAX_PROBES);
        goto done;
    }
    r = pb_shprobe_create(n, f->max_band, dims, false, &g, err);
    if (r != PB_SUCCESS) goto done;
    for (int k = 0; k < 3; k++) g->grid_origin[k] = (float)lo[k];
    g->grid_spacing = (float)spacing;
    g->default_sh_scale = f->default_sh_scale;
    g->default_ambient = f->default_ambient;
    for (uint64_t j = 0; j < cells; j++) {
        g->grid[j] = map[j];
        if (map[j] < 0) continue;
        pb_interp_weights w;
        dense_cell_weights(tree, tetra, &opt, lo, spacing, dims, j, &w);
        float *dst = g->coeffs + (size_t)map[j] * C * 3u;
        double acc[PB_SH_MAX_COEFFS * 3] = {0}, sc = 0.0, am = 0.0;
        for (uint32_t i = 0; i < w.count; i++) {
            const float *src = f->coeffs + (size_t)w.probe[i] * C * 3u;
            for (uint32_t k = 0; k < C * 3u; k++) acc[k] += w.weight[i] * src[k];
            sc += w.weight[i] * (f->probe_scale ? f->probe_scale[w.probe[i]] : 1.0f);
            am += w.weight[i] * (f->probe_ambient ? f->probe_ambient[w.probe[i]] : f->default_ambient);
        }
        for (uint32_t k = 0; k < C * 3u; k++) dst[k] = (float)acc[k];
        g->probe_scale[map[j]] = (float)sc;
        g->probe_ambient[map[j]] = (float)am;
    }
    *out = g;
    g = NULL;
done:
    free(map);
    pb_shprobe_destroy(g);
    pb_cotree_destroy(tree);
    pb_tetra_destroy(tetra);
    return r;
}

pb_result pb_shprobe_write_resampled(const char *path, const pb_shprobe *file, double spacing, uint32_t version,
                                     pb_error *err)
{
    if (version != 0 && version != 1 && version != 2)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "a dense grid is written as version 1, 2 or 0 (auto), not %u", version);
    pb_shprobe *dense = NULL;
    pb_result r = pb_interp_resample_dense(file, spacing, &dense, err);
    if (r != PB_SUCCESS) return r;
    dense->version = version;
    r = pb_shprobe_write(path, dense, err);
    pb_shprobe_destroy(dense);
    return r;
}
