/* `.shprobe` files (DESIGN.md §4; versions 2 and 3 in docs/shprobe-format.md): what every version
 * shares. The file image (create, destroy, lookup), the exact byte layout of each version computed from
 * the header with 64-bit overflow checks before anything is allocated (so a small malformed file can
 * never make the reader allocate or read more than the file holds), and the validation that the reader
 * and the writer both run. Version 3's structures: pb_shprobe_v3.c; reading: pb_shprobe_read.c;
 * writing: pb_shprobe_write.c; what they share: pb_shprobe_internal.h.
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_shprobe.h"

#include "schnee/pb_sh.h"

#include "pb_shprobe_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const char *const channel_names[3] = {"red", "green", "blue"};
const float pb_shprobe_identity_axes_[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

/* ---- sizes ------------------------------------------------------------------------------------ */

static bool mul_u64(uint64_t a, uint64_t b, uint64_t *out)
{
    if (b != 0 && a > UINT64_MAX / b) return false;
    *out = a * b;
    return true;
}

static bool add_u64(uint64_t a, uint64_t b, uint64_t *out)
{
    if (a > UINT64_MAX - b) return false;
    *out = a + b;
    return true;
}

const field_offsets pb_shprobe_v1_fields_ = {8, 0, 0, 12, 24, 36, 0, 40, 44};
const field_offsets pb_shprobe_v2_fields_ = {8, 12, 16, 20, 32, 44, 48, 84, 88};

static pb_result grid_cell_count(const uint32_t dims[3], uint64_t *cells, pb_error *err)
{
    static const char axis_names[3] = {'X', 'Y', 'Z'};
    for (int i = 0; i < 3; i++)
        if (dims[i] == 0)
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                "grid dim %c is 0; a grid has at least one cell per axis", axis_names[i]);
    uint64_t xy, xyz;
    if (!mul_u64(dims[0], dims[1], &xy) || !mul_u64(xy, dims[2], &xyz))
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "grid dims %u x %u x %u overflow 64 bits", dims[0], dims[1],
                            dims[2]);
    *cells = xyz;
    return PB_SUCCESS;
}

uint32_t pb_shprobe_colour_count(const pb_shprobe *p)
{
    if (!p) return 0;
    return p->representation == PB_SHPROBE_AMBIENT_CUBE ? 6u : pb_sh_count(p->max_band);
}

/* Indexed by pb_shprobe_structure; the same names as the add-on's native.STRUCTURES and the engine's
 * sv_ext_grid_structure_name (tests/python/test_structure_names.py compares them). */
static const char *const structure_names[] = {"grid", "octree", "tetrahedra"};
_Static_assert(sizeof structure_names / sizeof structure_names[0] == PB_SHPROBE_TETRA + 1,
               "one name per pb_shprobe_structure");

/* The kd corner tree (version 4 only) is named apart: the table above is the version 3 list. */
const char *pb_shprobe_structure_name_(uint32_t s)
{
    return s == PB_SHPROBE_KDTREE ? "kd corner tree" : s <= PB_SHPROBE_TETRA ? structure_names[s] : "grid";
}

/* Root cells of a kd corner tree: prod ceil(dims / 2^R), in 64 bits (at most 2^60). */
static uint64_t kd_root_cells(const uint32_t dims[3], uint32_t root_level)
{
    uint64_t g = 1;
    for (int k = 0; k < 3; k++) g *= ((uint64_t)dims[k] + ((uint64_t)1 << root_level) - 1u) >> root_level;
    return g;
}

/* Version 4 header fields of the kd corner tree (lattice extent already checked). */
static pb_result check_kd_header(const pb_shprobe *h, pb_result code, pb_error *err)
{
    if (h->root_level > V3_MAX_LEVEL)
        return pb_error_set(err, code, "root level %u at offset %u is out of range 0..%u", h->root_level, V4_ROOT_LEVEL,
                            V3_MAX_LEVEL);
    if (h->split_node_count > PB_SHPROBE_MAX_SPLIT_NODES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%u split-tree nodes (offset %u) are above the limit of %u",
                            h->split_node_count, V4_NODE_COUNT, PB_SHPROBE_MAX_SPLIT_NODES);
    uint64_t g = kd_root_cells(h->grid_dims, h->root_level);
    if (h->split_node_count < g)
        return pb_error_set(err, code,
                            "split-tree node count %u (offset %u) is below the %llu root cells of a %u x %u x %u "
                            "lattice at root level %u",
                            h->split_node_count, V4_NODE_COUNT, (unsigned long long)g, h->grid_dims[0], h->grid_dims[1],
                            h->grid_dims[2], h->root_level);
    return PB_SUCCESS;
}

/* Version 3 kind fields and structure counts: known values, limits, what each structure requires.
 * `code` is the result for a wrong value (format when reading, invalid argument when writing). */
pb_result pb_shprobe_check_v3_kind_(uint32_t version, const pb_shprobe *h, bool positions, pb_result code,
                                    pb_error *err)
{
    if (version == 4 && h->structure != PB_SHPROBE_KDTREE)
        return pb_error_set(err, code,
                            "structure %u at offset %u in a version 4 file; version 4 holds 3 = kd corner tree only "
                            "(the others are version 3)",
                            h->structure, V3_STRUCTURE);
    if (version != 4 && h->structure == PB_SHPROBE_KDTREE)
        return pb_error_set(err, code, "the kd corner tree (structure 3 at offset %u) needs version 4, not %u",
                            V3_STRUCTURE, version);
    if (h->representation > PB_SHPROBE_AMBIENT_CUBE)
        return pb_error_set(err, code,
                            "unknown representation %u at offset %u; this reader knows 0 = SH, 1 = ambient cube",
                            h->representation, V3_REPRESENTATION);
    if (h->storage > PB_SHPROBE_FLOAT16)
        return pb_error_set(err, code, "unknown storage %u at offset %u; this reader knows 0 = float32, 1 = binary16",
                            h->storage, V3_STORAGE);
    if (h->structure > PB_SHPROBE_TETRA && version != 4)
        return pb_error_set(err, code,
                            "unknown structure %u at offset %u; this reader knows 0 = grid, 1 = octree, 2 = tetrahedra",
                            h->structure, V3_STRUCTURE);
    if (h->structure == PB_SHPROBE_GRID) {
        if (h->element_count != 0 || h->hanging_count != 0)
            return pb_error_set(err, code, "a grid file has element and hanging counts 0 (offsets %u, %u), not %u, %u",
                                V3_ELEMENTS, V3_HANGING, h->element_count, h->hanging_count);
        return PB_SUCCESS;
    }
    if (!positions)
        return pb_error_set(err, code, "the %s structure needs probe positions (flag bit 0 at offset 16)",
                            pb_shprobe_structure_name_(h->structure));
    bool tets = h->structure == PB_SHPROBE_TETRA;
    uint32_t limit = tets ? PB_SHPROBE_MAX_TETS : PB_SHPROBE_MAX_LEAVES;
    if (h->element_count > limit)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%u %s (offset %u) are above the limit of %u", h->element_count,
                            tets ? "tetrahedra" : "leaves", V3_ELEMENTS, limit);
    if (h->element_count == 0)
        return pb_error_set(err, code, "the %s structure has no %s (offset %u)",
                            pb_shprobe_structure_name_(h->structure), tets ? "tetrahedra" : "leaves", V3_ELEMENTS);
    if (h->structure == PB_SHPROBE_TETRA) {
        if (h->hanging_count != 0)
            return pb_error_set(err, code, "tetrahedra have no hanging nodes; the count at offset %u is %u", V3_HANGING,
                                h->hanging_count);
        for (int i = 0; i < 3; i++)
            if (h->grid_dims[i] != 0)
                return pb_error_set(err, code, "tetrahedra have no lattice: dim %c at offset %u must be 0, not %u",
                                    "XYZ"[i], 20u + 4u * (uint32_t)i, h->grid_dims[i]);
        return PB_SUCCESS;
    }
    if (h->hanging_count > PB_SHPROBE_MAX_HANGING)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%u hanging nodes (offset %u) are above the limit of %u",
                            h->hanging_count, V3_HANGING, PB_SHPROBE_MAX_HANGING);
    for (int i = 0; i < 3; i++)
        if (h->grid_dims[i] == 0 || h->grid_dims[i] > PB_SHPROBE_MAX_LATTICE)
            return pb_error_set(err, h->grid_dims[i] ? PB_ERROR_TOO_LARGE : code,
                                "octree lattice extent %c at offset %u is %u; it must be 1..%u min cells", "XYZ"[i],
                                20u + 4u * (uint32_t)i, h->grid_dims[i], PB_SHPROBE_MAX_LATTICE);
    return h->structure == PB_SHPROBE_KDTREE ? check_kd_header(h, code, err) : PB_SUCCESS;
}

/* The exact byte layout of a file; fails (code `fail`) when a size overflows 64 bits or size_t.
 * Version 3 kind fields must have passed pb_shprobe_check_v3_kind_. */
pb_result pb_shprobe_layout_compute_(uint32_t version, const pb_shprobe *h, bool positions, pb_result fail, layout *lay,
                                     pb_error *err)
{
    uint32_t probe_count = h->probe_count;
    const uint32_t *dims = h->grid_dims;
    memset(lay, 0, sizeof *lay);
    lay->version = version;
    lay->positions = positions;
    lay->colour_bytes = 16u;
    lay->structure = version >= 3 ? h->structure : PB_SHPROBE_GRID;
    uint64_t header;
    if (version == 1) {
        lay->fields = &pb_shprobe_v1_fields_;
        lay->disk_coeffs = V1_COEFFS;
        header = V1_HEADER_SIZE;
    } else {
        lay->fields = &pb_shprobe_v2_fields_; /* version 3 keeps version 2's offsets up to 92 */
        lay->disk_coeffs = pb_sh_count(h->max_band);
        header = V2_HEADER_SIZE;
        if (version >= 3) {
            header = V3_HEADER_SIZE;
            lay->disk_coeffs = pb_shprobe_colour_count(h);
            lay->colour_bytes = h->storage == PB_SHPROBE_FLOAT16 ? 8u : 16u;
        }
    }
    if (lay->structure == PB_SHPROBE_GRID) {
        pb_error local = {0};
        if (grid_cell_count(dims, &lay->grid_cells, &local) != PB_SUCCESS)
            return pb_error_set(err, local.code == PB_ERROR_TOO_LARGE ? fail : local.code, "%s", local.message);
    }
    /* Documented limits (pb_shprobe.h): checked before any size is used. */
    if (probe_count > PB_SHPROBE_MAX_PROBES)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "probe count %u (offset %u) is above the limit of %u probes",
                            probe_count, lay->fields->count, PB_SHPROBE_MAX_PROBES);
    if (lay->grid_cells > PB_SHPROBE_MAX_GRID_CELLS)
        return pb_error_set(err, PB_ERROR_TOO_LARGE,
                            "grid %u x %u x %u = %llu cells (offset %u) is above the limit of %llu cells", dims[0],
                            dims[1], dims[2], (unsigned long long)lay->grid_cells, lay->fields->dims,
                            (unsigned long long)PB_SHPROBE_MAX_GRID_CELLS);
    /* Coefficient vec4s plus one vec4 (scale, ambient, validity, 0). */
    lay->record_size = (uint64_t)lay->colour_bytes * lay->disk_coeffs + 16u;
    lay->records_offset = header;
    uint64_t records, pos_bytes = 0, grid_bytes = 0, hanging_bytes = 0, node_bytes = 0, end;
    bool ok = mul_u64(probe_count, lay->record_size, &records);
    if (positions) ok = ok && mul_u64(probe_count, 16u, &pos_bytes);
    ok = ok && add_u64(header, records, &lay->positions_offset);
    ok = ok && add_u64(lay->positions_offset, pos_bytes, &lay->grid_offset);
    if (lay->structure == PB_SHPROBE_GRID) {
        ok = ok && mul_u64(lay->grid_cells, 4u, &grid_bytes);
    } else if (lay->structure == PB_SHPROBE_OCTREE || lay->structure == PB_SHPROBE_KDTREE) {
        ok = ok && mul_u64(h->element_count, V3_LEAF_SIZE, &grid_bytes);
        ok = ok && mul_u64(h->hanging_count, V3_HANGING_SIZE, &hanging_bytes);
        if (lay->structure == PB_SHPROBE_KDTREE) ok = ok && mul_u64(h->split_node_count, V4_NODE_SIZE, &node_bytes);
    } else {
        ok = ok && mul_u64(h->element_count, V3_TET_SIZE, &grid_bytes);
    }
    ok = ok && add_u64(lay->grid_offset, grid_bytes, &lay->hanging_offset);
    ok = ok && add_u64(lay->hanging_offset, hanging_bytes, &lay->split_offset);
    ok = ok && add_u64(lay->split_offset, node_bytes, &end);
    if (!ok || end > (uint64_t)SIZE_MAX)
        return pb_error_set(err, fail, "file size overflows: %u probes, grid %u x %u x %u cells (version %u)",
                            probe_count, dims[0], dims[1], dims[2], version);
    lay->total_size = end;
    return PB_SUCCESS;
}

/* ---- validation shared by reader and writer --------------------------------------------------- */

bool pb_shprobe_axes_are_zero_(const float axes[9])
{
    for (int i = 0; i < 9; i++)
        if (axes[i] != 0.0f) return false;
    return true;
}

/* Header values: finite floats, positive spacing, orthonormal axes. `what` prefixes messages. */
pb_result pb_shprobe_check_header_values_(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    const field_offsets *f = lay->fields;
    for (int i = 0; i < 3; i++)
        if (!isfinite(p->grid_origin[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "grid origin[%d] is %g (offset %u)", i,
                                (double)p->grid_origin[i], f->origin + 4u * (uint32_t)i);
    if (!isfinite(p->grid_spacing))
        return pb_error_set(err, PB_ERROR_NON_FINITE, "grid spacing is %g (offset %u)", (double)p->grid_spacing,
                            f->spacing);
    if (!(p->grid_spacing > 0.0f) && lay->structure != PB_SHPROBE_TETRA)
        return pb_error_set(err, code, "grid spacing is %g (offset %u); it must be > 0", (double)p->grid_spacing,
                            f->spacing);
    if (!isfinite(p->default_sh_scale))
        return pb_error_set(err, PB_ERROR_NON_FINITE, "default SH scale is %g (offset %u)", (double)p->default_sh_scale,
                            f->scale);
    if (!isfinite(p->default_ambient))
        return pb_error_set(err, PB_ERROR_NON_FINITE, "default ambient is %g (offset %u)", (double)p->default_ambient,
                            f->ambient);
    if (lay->version >= 2 && !pb_shprobe_axes_are_zero_(p->grid_axes)) {
        /* (tetrahedra ignore the frame, but it is still checked: one rule for every version 3 file) */
        const float *a = p->grid_axes;
        for (int i = 0; i < 9; i++)
            if (!isfinite(a[i]))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "grid axes[%d] is %g (offset %u)", i, (double)a[i],
                                    f->axes + 4u * (uint32_t)i);
        for (int i = 0; i < 3; i++)
            for (int j = i; j < 3; j++) {
                double dot = (double)a[3 * i] * a[3 * j] + (double)a[3 * i + 1] * a[3 * j + 1] +
                             (double)a[3 * i + 2] * a[3 * j + 2];
                double want = i == j ? 1.0 : 0.0;
                if (fabs(dot - want) > AXIS_TOLERANCE)
                    return pb_error_set(err, code,
                                        "grid axes are not orthonormal: axis %d . axis %d = %.6g, "
                                        "expected %g (offset %u)",
                                        i, j, dot, want, f->axes);
            }
    }
    return PB_SUCCESS;
}

/* Per-probe values and grid entries. `code` is the result for a range error (format when reading,
 * invalid argument when writing); NaN/Inf is always PB_ERROR_NON_FINITE. */
pb_result pb_shprobe_check_contents_(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    uint32_t count = lay->disk_coeffs;
    if (lay->version == 1) count = pb_sh_count(p->max_band); /* v1 pads bands < 2 */
    uint32_t cb = lay->colour_bytes, chb = cb / 4u;
    bool half = cb == 8u;
    for (uint32_t i = 0; i < p->probe_count; i++) {
        uint64_t rec = lay->records_offset + (uint64_t)i * lay->record_size;
        const float *c = p->coeffs + (size_t)i * count * 3u;
        for (uint32_t k = 0; k < count * 3u; k++) {
            if (!isfinite(c[k]))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %u %s %u %s is %g (offset %llu)", i,
                                    p->representation == PB_SHPROBE_AMBIENT_CUBE ? "face" : "coefficient", k / 3u,
                                    channel_names[k % 3u], (double)c[k],
                                    (unsigned long long)(rec + cb * (k / 3u) + chb * (k % 3u)));
            if (half && fabsf(c[k]) > HALF_MAX)
                return pb_error_set(
                    err, code, "probe %u %s %u %s is %g (offset %llu); binary16 storage holds at most 65504", i,
                    p->representation == PB_SHPROBE_AMBIENT_CUBE ? "face" : "coefficient", k / 3u,
                    channel_names[k % 3u], (double)c[k], (unsigned long long)(rec + cb * (k / 3u) + chb * (k % 3u)));
        }
        uint64_t tail = rec + (uint64_t)cb * lay->disk_coeffs;
        if (p->probe_scale && !isfinite(p->probe_scale[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %u scale is %g (offset %llu)", i,
                                (double)p->probe_scale[i], (unsigned long long)tail);
        if (p->probe_ambient && !isfinite(p->probe_ambient[i]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %u ambient is %g (offset %llu)", i,
                                (double)p->probe_ambient[i], (unsigned long long)(tail + 4u));
        if (p->validity && lay->version >= 2) {
            float v = p->validity[i];
            if (!isfinite(v))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %u validity is %g (offset %llu)", i, (double)v,
                                    (unsigned long long)(tail + 8u));
            if (v < 0.0f || v > 1.0f)
                return pb_error_set(err, code, "probe %u validity is %g (offset %llu); it must be in [0, 1]", i,
                                    (double)v, (unsigned long long)(tail + 8u));
        }
        if (p->positions && lay->positions) {
            uint64_t off = lay->positions_offset + 16u * (uint64_t)i;
            for (int k = 0; k < 3; k++)
                if (!isfinite(p->positions[3u * i + (uint32_t)k]))
                    return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %u position[%d] is %g (offset %llu)", i, k,
                                        (double)p->positions[3u * i + (uint32_t)k],
                                        (unsigned long long)(off + 4u * (uint64_t)k));
        }
    }
    if (lay->structure != PB_SHPROBE_GRID) return pb_shprobe_check_structure_(p, lay, code, err);
    uint64_t xdim = p->grid_dims[0], xy = (uint64_t)p->grid_dims[0] * p->grid_dims[1];
    for (uint64_t j = 0; j < lay->grid_cells; j++) {
        int32_t v = p->grid[j];
        if (v < -1 || (v >= 0 && (uint32_t)v >= p->probe_count))
            return pb_error_set(err, code,
                                "grid cell (%llu, %llu, %llu) holds %d (offset %llu); entries must "
                                "be -1 or a probe index below the probe count %u",
                                (unsigned long long)(j % xdim), (unsigned long long)((j / xdim) % p->grid_dims[1]),
                                (unsigned long long)(j / xy), (int)v, (unsigned long long)(lay->grid_offset + 4u * j),
                                p->probe_count);
    }
    return PB_SUCCESS;
}

/* ---- create / destroy ------------------------------------------------------------------------- */

pb_result pb_shprobe_create(uint32_t probe_count, uint32_t max_band, const uint32_t grid_dims[3], bool with_positions,
                            pb_shprobe **out, pb_error *err)
{
    if (!out || !grid_dims) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_create: NULL argument");
    *out = NULL;
    if (max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "max band %u is out of range 0..%d", max_band,
                            PB_SH_MAX_BAND);
    uint64_t cells;
    pb_result r = grid_cell_count(grid_dims, &cells, err);
    if (r != PB_SUCCESS) return r;
    uint64_t coeff_count = (uint64_t)probe_count * pb_sh_count(max_band) * 3u;
    if (cells > SIZE_MAX / sizeof(int32_t) || coeff_count > SIZE_MAX / sizeof(float))
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%u probes / %llu grid cells do not fit memory", probe_count,
                            (unsigned long long)cells);

    pb_shprobe *p = calloc(1, sizeof *p);
    if (!p) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for .shprobe header");
    p->probe_count = probe_count;
    p->max_band = max_band;
    memcpy(p->grid_dims, grid_dims, sizeof p->grid_dims);
    memcpy(p->grid_axes, pb_shprobe_identity_axes_, sizeof p->grid_axes);
    p->default_sh_scale = 1.0f;
    p->default_ambient = 0.1f;
    /* +1 so that zero probes still give non-NULL arrays (calloc(0) may return NULL). */
    p->coeffs = calloc((size_t)coeff_count + 1u, sizeof(float));
    p->probe_scale = malloc(((size_t)probe_count + 1u) * sizeof(float));
    p->probe_ambient = malloc(((size_t)probe_count + 1u) * sizeof(float));
    p->validity = malloc(((size_t)probe_count + 1u) * sizeof(float));
    p->grid = malloc((size_t)cells * sizeof(int32_t));
    if (with_positions) p->positions = calloc((size_t)probe_count * 3u + 1u, sizeof(float));
    if (!p->coeffs || !p->probe_scale || !p->probe_ambient || !p->validity || !p->grid ||
        (with_positions && !p->positions)) {
        pb_shprobe_destroy(p);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes and %llu grid cells", probe_count,
                            (unsigned long long)cells);
    }
    for (uint32_t i = 0; i < probe_count; i++) {
        p->probe_scale[i] = 1.0f;
        p->probe_ambient[i] = p->default_ambient;
        p->validity[i] = 1.0f;
    }
    for (uint64_t j = 0; j < cells; j++) p->grid[j] = -1;
    *out = p;
    return PB_SUCCESS;
}

void pb_shprobe_destroy(pb_shprobe *probes)
{
    if (!probes) return;
    free(probes->coeffs);
    free(probes->probe_scale);
    free(probes->probe_ambient);
    free(probes->validity);
    free(probes->positions);
    free(probes->grid);
    free(probes->leaves);
    free(probes->leaf_corners);
    free(probes->hanging_sources);
    free(probes->hanging_weights);
    free(probes->tets);
    free(probes->tet_neighbours);
    free(probes->split_nodes);
    free(probes);
}
/* ---- lookup ----------------------------------------------------------------------------------- */

int32_t pb_shprobe_lookup(const pb_shprobe *probes, const float point[3])
{
    if (!probes || !point || !probes->grid || !(probes->grid_spacing > 0.0f) || !isfinite(probes->grid_spacing))
        return -1;
    const float *axes = pb_shprobe_axes_are_zero_(probes->grid_axes) ? pb_shprobe_identity_axes_ : probes->grid_axes;
    double d[3], spacing = probes->grid_spacing;
    for (int i = 0; i < 3; i++) d[i] = (double)point[i] - (double)probes->grid_origin[i];
    uint64_t cell[3];
    for (int i = 0; i < 3; i++) {
        const float *a = axes + 3 * i;
        double u = (d[0] * a[0] + d[1] * a[1] + d[2] * a[2]) / spacing;
        /* Cells are half-open [k, k+1): the max faces belong to no cell; NaN fails both tests. */
        if (!(u >= 0.0) || !(u < (double)probes->grid_dims[i])) return -1;
        cell[i] = (uint64_t)u;
        if (cell[i] >= probes->grid_dims[i]) return -1;
    }
    uint64_t x = probes->grid_dims[0], xy = x * probes->grid_dims[1];
    int32_t v = probes->grid[cell[0] + cell[1] * x + cell[2] * xy];
    return (v < 0 || (uint32_t)v >= probes->probe_count) ? -1 : v;
}
