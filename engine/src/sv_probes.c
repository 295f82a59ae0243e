/* Probe grids: loading, header checks, lookup (see sv_probes.h). The per-object queries are in
 * sv_probe_query.c, the static scene's visibility in sv_probe_vis.c, the GPU packing in sv_probe_pack.c. */
#include "sv_probes.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "schnee/pb_ambient_cube.h"
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
    /* A structure the glTF parser has no name for (the kd corner tree, version 4, until sv_ext.c lists
     * "kdtree") cannot be named in an entry: not compared. */
    int compared = sv_ext_grid_structure_name(f->structure) ? 3 : 2;
    for (int k = 0; k < compared; ++k)
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
        uint32_t entries = f->probe_count + (tree ? f->hanging_count : 0u);
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

void sv_probes_destroy(sv_probes *probes)
{
    for (uint32_t i = 0; i < probes->grid_count; ++i) {
        pb_shprobe_destroy(probes->grids[i].file);
        pb_cotree_destroy(probes->grids[i].tree);
        pb_tetra_destroy(probes->grids[i].tetra);
        if (probes->fields) pb_grid_field_destroy(probes->fields[i]);
    }
    free(probes->fields);
    free(probes->grids);
    free(probes->slot_sh);
    free(probes->slot_cube);
    free(probes->slot_weights);
    free(probes->warned);
    sv_static_vis_destroy(probes->vis);
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

void sv_cell_centre(const pb_shprobe *f, int x, int y, int z, float out[3])
{
    const float *ax = f->grid_axes;
    float h = f->grid_spacing, l[3] = {((float)x + 0.5f) * h, ((float)y + 0.5f) * h, ((float)z + 0.5f) * h};
    for (int k = 0; k < 3; ++k)
        out[k] = f->grid_origin[k] + l[0] * ax[0 * 3 + k] + l[1] * ax[1 * 3 + k] + l[2] * ax[2 * 3 + k];
}

pb_result sv_grid_field_build(const pb_shprobe *f, pb_grid_field **out, pb_error *err)
{
    uint32_t nc = pb_shprobe_colour_count(f);
    size_t n = (size_t)f->probe_count * nc * 3u;
    double *c = malloc((n ? n : 1) * sizeof(double)), axes[9];
    if (!c) return PB_ERROR_OUT_OF_MEMORY;
    for (size_t i = 0; i < n; ++i) c[i] = f->coeffs[i];
    for (int i = 0; i < 9; ++i) axes[i] = f->grid_axes[i];
    pb_grid_field_desc d = {.dims = {f->grid_dims[0], f->grid_dims[1], f->grid_dims[2]},
                            .origin = {f->grid_origin[0], f->grid_origin[1], f->grid_origin[2]},
                            .spacing = f->grid_spacing,
                            .axes = axes,
                            .cells = f->grid,
                            .probe_count = f->probe_count,
                            .coeff_count = nc,
                            .coeffs = c,
                            .validity = f->validity,
                            .scale = f->probe_scale};
    pb_result rc = pb_grid_field_build(&d, out, err);
    free(c);
    return rc;
}
