/* `.shprobe` reader and writer: version 1 (DESIGN.md §4), versions 2 and 3 (docs/shprobe-format.md).
 *
 * Every byte is read and written through explicit little-endian helpers, never by casting the
 * buffer, so the code is independent of host byte order and alignment. The reader computes the
 * exact file size from the header with 64-bit overflow checks before it allocates anything, so a
 * small malformed file can never make it allocate or read more than the file holds.
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_shprobe.h"

#include "schnee/pb_sh.h"

#include "pb_file.h"
#include "pb_morton.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define V1_HEADER_SIZE    48u
#define V1_COEFFS         9u /* v1 always stores bands 0..2 */
#define V2_HEADER_SIZE    96u
#define V2_FLAG_POSITIONS 0x1u
#define V2_KNOWN_FLAGS    V2_FLAG_POSITIONS
#define AXIS_TOLERANCE    1e-4 /* orthonormality of the grid axes (float data, unit vectors) */
#define V3_HEADER_SIZE    128u
#define V3_REPRESENTATION 92u
#define V3_STORAGE        96u
#define V3_STRUCTURE      100u
#define V3_ELEMENTS       104u
#define V3_HANGING        108u
#define V3_LEAF_SIZE      48u /* x, y, z, level, 8 corner node indices */
#define V3_HANGING_SIZE   32u /* 4 source node indices, 4 float weights */
#define V3_TET_SIZE       32u /* 4 vertex indices, 4 neighbour indices */
#define V3_MAX_LEVEL      20u
#define HALF_MAX          65504.0f
#define HANGING_SUM_TOL   1e-5

static const char *const channel_names[3] = {"red", "green", "blue"};
static const float identity_axes[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};

/* ---- little-endian byte access ---------------------------------------------------------------- */

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static float get_f32(const uint8_t *p)
{
    uint32_t u = get_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static void put_f32(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    put_u32(p, u);
}

static uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

/* IEEE binary16 → float (exact; Inf/NaN stay Inf/NaN so the finite check rejects them). */
static float half_to_float(uint16_t h)
{
    uint32_t sign = (uint32_t)(h >> 15) << 31, exp = (h >> 10) & 0x1fu, man = h & 0x3ffu;
    float f;
    if (exp == 0) {
        f = ldexpf((float)man, -24); /* zero and subnormals */
        return sign ? -f : f;
    }
    uint32_t u = exp == 31 ? (sign | 0x7f800000u | man << 13) : (sign | (exp + 112u) << 23 | man << 13);
    memcpy(&f, &u, sizeof f);
    return f;
}

/* float → binary16, round to nearest even; |f| <= 65504 (checked by the writer). */
static uint16_t float_to_half(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    uint16_t sign = (uint16_t)((u >> 16) & 0x8000u);
    float a = fabsf(f);
    if (a < 6.103515625e-05f) {                /* subnormal half: multiples of 2^-24 */
        float q = nearbyintf(a * 16777216.0f); /* default rounding mode: to nearest even */
        return (uint16_t)(sign | (uint16_t)q);
    }
    uint32_t x = u & 0x7fffffffu;
    uint32_t mant = x & 0x7fffffu, exp = (x >> 23) - 112u; /* rebias 127 → 15 */
    uint32_t h = exp << 10 | mant >> 13, rest = mant & 0x1fffu;
    if (rest > 0x1000u || (rest == 0x1000u && (h & 1u))) h++; /* carries into the exponent correctly */
    return (uint16_t)(sign | h);
}

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

/* Where every field of one version lives; offsets are used for error messages too. */
typedef struct field_offsets {
    uint32_t count, band, flags, dims, origin, spacing, axes, scale, ambient;
} field_offsets;

static const field_offsets v1_fields = {8, 0, 0, 12, 24, 36, 0, 40, 44};
static const field_offsets v2_fields = {8, 12, 16, 20, 32, 44, 48, 84, 88};

typedef struct layout {
    uint32_t version;
    uint32_t disk_coeffs;  /* coefficient vec4s (colours) per probe record */
    uint32_t colour_bytes; /* 16 (float32 vec4) or 8 (binary16 ×4) */
    uint32_t structure;
    uint64_t hanging_offset; /* octree: after the leaves */
    bool positions;
    const field_offsets *fields;
    uint64_t grid_cells;
    uint64_t record_size; /* bytes per probe record */
    uint64_t records_offset;
    uint64_t positions_offset;
    uint64_t grid_offset;
    uint64_t total_size;
} layout;

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

static const char *structure_name(uint32_t s) { return s <= PB_SHPROBE_TETRA ? structure_names[s] : "grid"; }

/* Version 3 kind fields and structure counts: known values, limits, what each structure requires.
 * `code` is the result for a wrong value (format when reading, invalid argument when writing). */
static pb_result check_v3_kind(const pb_shprobe *h, bool positions, pb_result code, pb_error *err)
{
    if (h->representation > PB_SHPROBE_AMBIENT_CUBE)
        return pb_error_set(err, code,
                            "unknown representation %u at offset %u; this reader knows 0 = SH, 1 = ambient cube",
                            h->representation, V3_REPRESENTATION);
    if (h->storage > PB_SHPROBE_FLOAT16)
        return pb_error_set(err, code, "unknown storage %u at offset %u; this reader knows 0 = float32, 1 = binary16",
                            h->storage, V3_STORAGE);
    if (h->structure > PB_SHPROBE_TETRA)
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
                            structure_name(h->structure));
    uint32_t limit = h->structure == PB_SHPROBE_OCTREE ? PB_SHPROBE_MAX_LEAVES : PB_SHPROBE_MAX_TETS;
    if (h->element_count > limit)
        return pb_error_set(err, PB_ERROR_TOO_LARGE, "%u %s (offset %u) are above the limit of %u", h->element_count,
                            h->structure == PB_SHPROBE_OCTREE ? "leaves" : "tetrahedra", V3_ELEMENTS, limit);
    if (h->element_count == 0)
        return pb_error_set(err, code, "the %s structure has no %s (offset %u)", structure_name(h->structure),
                            h->structure == PB_SHPROBE_OCTREE ? "leaves" : "tetrahedra", V3_ELEMENTS);
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
    return PB_SUCCESS;
}

/* The exact byte layout of a file; fails (code `fail`) when a size overflows 64 bits or size_t.
 * Version 3 kind fields must have passed check_v3_kind. */
static pb_result layout_compute(uint32_t version, const pb_shprobe *h, bool positions, pb_result fail, layout *lay,
                                pb_error *err)
{
    uint32_t probe_count = h->probe_count;
    const uint32_t *dims = h->grid_dims;
    memset(lay, 0, sizeof *lay);
    lay->version = version;
    lay->positions = positions;
    lay->colour_bytes = 16u;
    lay->structure = version == 3 ? h->structure : PB_SHPROBE_GRID;
    uint64_t header;
    if (version == 1) {
        lay->fields = &v1_fields;
        lay->disk_coeffs = V1_COEFFS;
        header = V1_HEADER_SIZE;
    } else {
        lay->fields = &v2_fields; /* version 3 keeps version 2's offsets up to 92 */
        lay->disk_coeffs = pb_sh_count(h->max_band);
        header = V2_HEADER_SIZE;
        if (version == 3) {
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
    uint64_t records, pos_bytes = 0, grid_bytes = 0, hanging_bytes = 0, end;
    bool ok = mul_u64(probe_count, lay->record_size, &records);
    if (positions) ok = ok && mul_u64(probe_count, 16u, &pos_bytes);
    ok = ok && add_u64(header, records, &lay->positions_offset);
    ok = ok && add_u64(lay->positions_offset, pos_bytes, &lay->grid_offset);
    if (lay->structure == PB_SHPROBE_GRID) {
        ok = ok && mul_u64(lay->grid_cells, 4u, &grid_bytes);
    } else if (lay->structure == PB_SHPROBE_OCTREE) {
        ok = ok && mul_u64(h->element_count, V3_LEAF_SIZE, &grid_bytes);
        ok = ok && mul_u64(h->hanging_count, V3_HANGING_SIZE, &hanging_bytes);
    } else {
        ok = ok && mul_u64(h->element_count, V3_TET_SIZE, &grid_bytes);
    }
    ok = ok && add_u64(lay->grid_offset, grid_bytes, &lay->hanging_offset);
    ok = ok && add_u64(lay->hanging_offset, hanging_bytes, &end);
    if (!ok || end > (uint64_t)SIZE_MAX)
        return pb_error_set(err, fail, "file size overflows: %u probes, grid %u x %u x %u cells (version %u)",
                            probe_count, dims[0], dims[1], dims[2], version);
    lay->total_size = end;
    return PB_SUCCESS;
}

/* ---- validation shared by reader and writer --------------------------------------------------- */

static bool axes_are_zero(const float axes[9])
{
    for (int i = 0; i < 9; i++)
        if (axes[i] != 0.0f) return false;
    return true;
}

static bool axes_are_identity(const float axes[9])
{
    return axes_are_zero(axes) || memcmp(axes, identity_axes, sizeof identity_axes) == 0;
}

/* Header values: finite floats, positive spacing, orthonormal axes. `what` prefixes messages. */
static pb_result check_header_values(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
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
    if (lay->version >= 2 && !axes_are_zero(p->grid_axes)) {
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

/* Octree leaves, corner references and hanging rules; tetrahedra and neighbours. Leaves must be in
 * Morton order of their min corners (z most significant): aligned cubes in that order do not overlap
 * exactly when each one's Morton range ends before the next one starts, so one pass proves it. */
static pb_result check_structure(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    uint64_t nodes = (uint64_t)p->probe_count + p->hanging_count;
    if (lay->structure == PB_SHPROBE_OCTREE) {
        uint64_t prev_end = 0;
        for (uint32_t i = 0; i < p->element_count; i++) {
            const uint32_t *l = p->leaves + 4u * i;
            uint64_t off = lay->grid_offset + (uint64_t)V3_LEAF_SIZE * i;
            if (l[3] > V3_MAX_LEVEL)
                return pb_error_set(err, code, "leaf %u level %u (offset %llu) is above %u", i, l[3],
                                    (unsigned long long)(off + 12u), V3_MAX_LEVEL);
            uint32_t size = 1u << l[3];
            for (int k = 0; k < 3; k++)
                if (l[k] % size != 0 || (uint64_t)l[k] + size > p->grid_dims[k])
                    return pb_error_set(err, code,
                                        "leaf %u at (%u, %u, %u) level %u (offset %llu) is not aligned to its size or "
                                        "reaches past the lattice extent %u x %u x %u",
                                        i, l[0], l[1], l[2], l[3], (unsigned long long)off, p->grid_dims[0],
                                        p->grid_dims[1], p->grid_dims[2]);
            uint64_t start = pb_morton3_(l[0], l[1], l[2]);
            if (i > 0 && start < prev_end)
                return pb_error_set(err, code,
                                    "leaf %u at (%u, %u, %u) (offset %llu) overlaps the leaf before it or is out of "
                                    "Morton order",
                                    i, l[0], l[1], l[2], (unsigned long long)off);
            prev_end = start + ((uint64_t)1 << (3u * l[3]));
            for (int c = 0; c < 8; c++) {
                int32_t v = p->leaf_corners[8u * i + (uint32_t)c];
                if (v < 0 || (uint64_t)v >= nodes)
                    return pb_error_set(
                        err, code, "leaf %u corner %d (offset %llu) is %d; it must be a node index below %llu", i, c,
                        (unsigned long long)(off + 16u + 4u * (uint32_t)c), (int)v, (unsigned long long)nodes);
            }
        }
        for (uint32_t j = 0; j < p->hanging_count; j++) {
            uint64_t off = lay->hanging_offset + (uint64_t)V3_HANGING_SIZE * j;
            double sum = 0.0;
            for (int k = 0; k < 4; k++) {
                uint32_t src = p->hanging_sources[4u * j + (uint32_t)k];
                float w = p->hanging_weights[4u * j + (uint32_t)k];
                if (src >= (uint64_t)p->probe_count + j)
                    return pb_error_set(err, code,
                                        "hanging node %u source %d (offset %llu) is %u; it must be a probe or an "
                                        "earlier hanging node, below %llu",
                                        j, k, (unsigned long long)(off + 4u * (uint32_t)k), src,
                                        (unsigned long long)p->probe_count + j);
                if (!isfinite(w))
                    return pb_error_set(err, PB_ERROR_NON_FINITE, "hanging node %u weight %d is %g (offset %llu)", j, k,
                                        (double)w, (unsigned long long)(off + 16u + 4u * (uint32_t)k));
                if (w < 0.0f || w > 1.0f)
                    return pb_error_set(err, code,
                                        "hanging node %u weight %d is %g (offset %llu); it must be in [0, 1]", j, k,
                                        (double)w, (unsigned long long)(off + 16u + 4u * (uint32_t)k));
                sum += w;
            }
            if (fabs(sum - 1.0) > HANGING_SUM_TOL)
                return pb_error_set(err, code, "hanging node %u weights sum to %.9g (offset %llu); they must sum to 1",
                                    j, sum, (unsigned long long)(off + 16u));
        }
    } else if (lay->structure == PB_SHPROBE_TETRA) {
        for (uint32_t i = 0; i < p->element_count; i++) {
            uint64_t off = lay->grid_offset + (uint64_t)V3_TET_SIZE * i;
            const uint32_t *t = p->tets + 4u * i;
            for (int k = 0; k < 4; k++) {
                if (t[k] >= p->probe_count)
                    return pb_error_set(err, code,
                                        "tetrahedron %u vertex %d (offset %llu) is %u; it must be a probe index below "
                                        "%u",
                                        i, k, (unsigned long long)(off + 4u * (uint32_t)k), t[k], p->probe_count);
                for (int m = 0; m < k; m++)
                    if (t[m] == t[k])
                        return pb_error_set(err, code, "tetrahedron %u (offset %llu) repeats vertex %u", i,
                                            (unsigned long long)off, t[k]);
                int32_t nb = p->tet_neighbours[4u * i + (uint32_t)k];
                if (nb < -1 || (nb >= 0 && (uint32_t)nb >= p->element_count))
                    return pb_error_set(
                        err, code, "tetrahedron %u neighbour %d (offset %llu) is %d; it must be -1 or below %u", i, k,
                        (unsigned long long)(off + 16u + 4u * (uint32_t)k), (int)nb, p->element_count);
            }
        }
    }
    return PB_SUCCESS;
}

/* Per-probe values and grid entries. `code` is the result for a range error (format when reading,
 * invalid argument when writing); NaN/Inf is always PB_ERROR_NON_FINITE. */
static pb_result check_contents(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
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
    if (lay->structure != PB_SHPROBE_GRID) return check_structure(p, lay, code, err);
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
    memcpy(p->grid_axes, identity_axes, sizeof p->grid_axes);
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

pb_result pb_shprobe_create_v3(uint32_t probe_count, uint32_t representation, uint32_t max_band, uint32_t structure,
                               const uint32_t grid_dims[3], uint32_t element_count, uint32_t hanging_count,
                               pb_shprobe **out, pb_error *err)
{
    if (!out || !grid_dims) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_create_v3: NULL argument");
    *out = NULL;
    if (max_band > PB_SH_MAX_BAND)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "max band %u is out of range 0..%d", max_band,
                            PB_SH_MAX_BAND);
    pb_shprobe h;
    memset(&h, 0, sizeof h);
    h.probe_count = probe_count;
    h.max_band = max_band;
    h.representation = representation;
    h.structure = structure;
    h.element_count = element_count;
    h.hanging_count = hanging_count;
    if (structure != PB_SHPROBE_TETRA) memcpy(h.grid_dims, grid_dims, sizeof h.grid_dims);
    pb_result r = check_v3_kind(&h, true, PB_ERROR_INVALID_ARGUMENT, err);
    if (r != PB_SUCCESS) return r;
    layout lay;
    r = layout_compute(3, &h, true, PB_ERROR_TOO_LARGE, &lay, err);
    if (r != PB_SUCCESS) return r;
    pb_shprobe *p = calloc(1, sizeof *p);
    if (!p) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for .shprobe header");
    *p = h;
    p->version = 3;
    memcpy(p->grid_axes, identity_axes, sizeof p->grid_axes);
    p->default_sh_scale = 1.0f;
    p->default_ambient = 0.1f;
    size_t P = probe_count, N = element_count, H = hanging_count;
    p->coeffs = calloc(P * lay.disk_coeffs * 3u + 1u, sizeof(float));
    p->probe_scale = malloc((P + 1u) * sizeof(float));
    p->probe_ambient = malloc((P + 1u) * sizeof(float));
    p->validity = malloc((P + 1u) * sizeof(float));
    p->positions = calloc(P * 3u + 1u, sizeof(float));
    bool ok = p->coeffs && p->probe_scale && p->probe_ambient && p->validity && p->positions;
    if (structure == PB_SHPROBE_GRID) {
        p->grid = malloc((size_t)lay.grid_cells * sizeof(int32_t) + sizeof(int32_t));
        ok = ok && p->grid;
        for (uint64_t j = 0; ok && j < lay.grid_cells; j++) p->grid[j] = -1;
    } else if (structure == PB_SHPROBE_OCTREE) {
        p->leaves = calloc(N * 4u + 1u, sizeof(uint32_t));
        p->leaf_corners = calloc(N * 8u + 1u, sizeof(int32_t));
        p->hanging_sources = calloc(H * 4u + 1u, sizeof(uint32_t));
        p->hanging_weights = calloc(H * 4u + 1u, sizeof(float));
        ok = ok && p->leaves && p->leaf_corners && p->hanging_sources && p->hanging_weights;
    } else {
        p->tets = calloc(N * 4u + 1u, sizeof(uint32_t));
        p->tet_neighbours = calloc(N * 4u + 1u, sizeof(int32_t));
        ok = ok && p->tets && p->tet_neighbours;
    }
    if (!ok) {
        pb_shprobe_destroy(p);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory for %u probes and the %s structure",
                            probe_count, structure_name(structure));
    }
    for (size_t i = 0; i < P; i++) {
        p->probe_scale[i] = 1.0f;
        p->probe_ambient[i] = p->default_ambient;
        p->validity[i] = 1.0f;
    }
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
    free(probes);
}

/* ---- reading ---------------------------------------------------------------------------------- */

/* Parses and validates the header from `data` (`avail` bytes, at least the header when the file is
 * long enough) against the whole file's size. Fills the scalar fields of `h` and the layout. */
static pb_result parse_header(const uint8_t *data, size_t avail, uint64_t file_size, pb_shprobe *h, layout *lay,
                              pb_error *err)
{
    memset(h, 0, sizeof *h);
    if (file_size < 4 || avail < 4)
        return pb_error_set(err, PB_ERROR_FORMAT, "truncated: %llu bytes, the magic at offset 0 needs 4",
                            (unsigned long long)file_size);
    /* The value found is not quoted: it would echo 4 bytes of a file that is not ours. */
    if (get_u32(data) != PB_SHPROBE_MAGIC)
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "not a .shprobe file (bad magic: it does not start with \"SPHR\" = 0x%08X)",
                            PB_SHPROBE_MAGIC);
    if (file_size < 8 || avail < 8)
        return pb_error_set(err, PB_ERROR_FORMAT, "truncated: %llu bytes, the version at offset 4 needs 8",
                            (unsigned long long)file_size);
    uint32_t version = get_u32(data + 4);
    if (version < 1 || version > 3)
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "unknown version %u at offset 4; this reader knows versions 1, 2 and 3", version);
    uint32_t header_size = version == 1 ? V1_HEADER_SIZE : (version == 2 ? V2_HEADER_SIZE : V3_HEADER_SIZE);
    if (file_size < header_size || avail < header_size)
        return pb_error_set(err, PB_ERROR_FORMAT, "truncated: %llu bytes, the version %u header needs %u",
                            (unsigned long long)file_size, version, header_size);
    const field_offsets *f = version == 1 ? &v1_fields : &v2_fields;
    h->version = version;
    h->probe_count = get_u32(data + f->count);
    uint32_t flags = 0;
    if (version == 1) {
        h->max_band = 2;
        memcpy(h->grid_axes, identity_axes, sizeof h->grid_axes);
    } else {
        h->max_band = get_u32(data + f->band);
        if (h->max_band > PB_SH_MAX_BAND)
            return pb_error_set(err, PB_ERROR_FORMAT, "max band %u at offset %u is out of range 0..%d", h->max_band,
                                f->band, PB_SH_MAX_BAND);
        flags = get_u32(data + f->flags);
        if (flags & ~V2_KNOWN_FLAGS)
            return pb_error_set(err, PB_ERROR_FORMAT, "unknown flags 0x%X at offset %u (known: 0x%X = positions)",
                                flags, f->flags, V2_KNOWN_FLAGS);
        for (int i = 0; i < 9; i++) h->grid_axes[i] = get_f32(data + f->axes + 4 * i);
        if (axes_are_zero(h->grid_axes))
            return pb_error_set(err, PB_ERROR_FORMAT, "grid axes at offset %u are all zero", f->axes);
    }
    if (version == 3) {
        h->representation = get_u32(data + V3_REPRESENTATION);
        h->storage = get_u32(data + V3_STORAGE);
        h->structure = get_u32(data + V3_STRUCTURE);
        h->element_count = get_u32(data + V3_ELEMENTS);
        h->hanging_count = get_u32(data + V3_HANGING);
        for (int i = 0; i < 3; i++) h->grid_dims[i] = get_u32(data + f->dims + 4 * i);
        pb_result kr = check_v3_kind(h, (flags & V2_FLAG_POSITIONS) != 0, PB_ERROR_FORMAT, err);
        if (kr != PB_SUCCESS) return kr;
    }
    for (int i = 0; i < 3; i++) {
        h->grid_dims[i] = get_u32(data + f->dims + 4 * i);
        h->grid_origin[i] = get_f32(data + f->origin + 4 * i);
        if (h->grid_dims[i] == 0 && h->structure != PB_SHPROBE_TETRA)
            return pb_error_set(err, PB_ERROR_FORMAT,
                                "grid dim %c at offset %u is 0; a grid has at least one cell per axis", "XYZ"[i],
                                f -> dims + 4u * (uint32_t)i);
    }
    h->grid_spacing = get_f32(data + f->spacing);
    h->default_sh_scale = get_f32(data + f->scale);
    h->default_ambient = get_f32(data + f->ambient);

    pb_result r = layout_compute(version, h, (flags & V2_FLAG_POSITIONS) != 0, PB_ERROR_FORMAT, lay, err);
    if (r != PB_SUCCESS) return r;
    r = check_header_values(h, lay, PB_ERROR_FORMAT, err);
    if (r != PB_SUCCESS) return r;
    if (file_size < lay->total_size)
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "truncated: %llu bytes, but %u probes (max band %u%s) and a %u x %u x %u "
                            "%s need %llu",
                            (unsigned long long)file_size, h->probe_count, h->max_band,
                            lay->positions ? ", positions" : "", h->grid_dims[0], h->grid_dims[1], h->grid_dims[2],
                            structure_name(lay->structure), (unsigned long long)lay->total_size);
    if (file_size > lay->total_size)
        return pb_error_set(err, PB_ERROR_FORMAT, "%llu bytes of trailing data after the %s, which ends at offset %llu",
                            (unsigned long long)(file_size - lay->total_size), structure_name(lay->structure),
                            (unsigned long long)lay->total_size);
    return PB_SUCCESS;
}

pb_result pb_shprobe_read_memory(const void *data, size_t size, pb_shprobe **out, pb_error *err)
{
    if (!out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_read_memory: NULL out");
    *out = NULL;
    if (!data && size > 0) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_read_memory: NULL data");
    const uint8_t *bytes = data;
    pb_shprobe h;
    layout lay;
    pb_result r = parse_header(bytes, size, size, &h, &lay, err);
    if (r != PB_SUCCESS) return r;

    pb_shprobe *p = NULL;
    if (h.version == 3)
        r = pb_shprobe_create_v3(h.probe_count, h.representation, h.max_band, h.structure, h.grid_dims, h.element_count,
                                 h.hanging_count, &p, err);
    else
        r = pb_shprobe_create(h.probe_count, h.max_band, h.grid_dims, lay.positions, &p, err);
    if (r != PB_SUCCESS) return r;
    p->version = h.version;
    p->storage = h.storage;
    if (h.version == 3 && !lay.positions) { /* a v3 grid without positions */
        free(p->positions);
        p->positions = NULL;
    }
    memcpy(p->grid_origin, h.grid_origin, sizeof p->grid_origin);
    memcpy(p->grid_axes, h.grid_axes, sizeof p->grid_axes);
    p->grid_spacing = h.grid_spacing;
    p->default_sh_scale = h.default_sh_scale;
    p->default_ambient = h.default_ambient;

    uint32_t count = pb_shprobe_colour_count(p); /* = disk_coeffs for every version (v1 reads back band 2) */
    bool half = lay.colour_bytes == 8u;
    for (uint32_t i = 0; i < h.probe_count; i++) {
        const uint8_t *rec = bytes + lay.records_offset + (size_t)i * lay.record_size;
        float *c = p->coeffs + (size_t)i * count * 3u;
        for (uint32_t k = 0; k < count; k++)
            for (uint32_t ch = 0; ch < 3; ch++)
                c[3 * k + ch] = half ? half_to_float(get_u16(rec + 8 * k + 2 * ch)) : get_f32(rec + 16 * k + 4 * ch);
        const uint8_t *tail = rec + (size_t)lay.colour_bytes * lay.disk_coeffs;
        p->probe_scale[i] = get_f32(tail);
        p->probe_ambient[i] = get_f32(tail + 4);
        /* v1 bytes 8..15 of the tail are padding (ignored, written as zero). */
        p->validity[i] = h.version >= 2 ? get_f32(tail + 8) : 1.0f;
        if (lay.positions) {
            const uint8_t *pos = bytes + lay.positions_offset + 16u * (size_t)i;
            for (int k = 0; k < 3; k++) p->positions[3u * i + (uint32_t)k] = get_f32(pos + 4 * k);
        }
    }
    const uint8_t *grid = bytes + lay.grid_offset;
    if (lay.structure == PB_SHPROBE_GRID) {
        for (uint64_t j = 0; j < lay.grid_cells; j++) p->grid[j] = (int32_t)get_u32(grid + 4 * j);
    } else if (lay.structure == PB_SHPROBE_OCTREE) {
        for (uint32_t i = 0; i < h.element_count; i++) {
            const uint8_t *l = grid + (size_t)V3_LEAF_SIZE * i;
            for (int k = 0; k < 4; k++) p->leaves[4u * i + (uint32_t)k] = get_u32(l + 4 * k);
            for (int k = 0; k < 8; k++) p->leaf_corners[8u * i + (uint32_t)k] = (int32_t)get_u32(l + 16 + 4 * k);
        }
        const uint8_t *hang = bytes + lay.hanging_offset;
        for (uint32_t j = 0; j < h.hanging_count; j++)
            for (int k = 0; k < 4; k++) {
                p->hanging_sources[4u * j + (uint32_t)k] = get_u32(hang + (size_t)V3_HANGING_SIZE * j + 4 * k);
                p->hanging_weights[4u * j + (uint32_t)k] = get_f32(hang + (size_t)V3_HANGING_SIZE * j + 16 + 4 * k);
            }
    } else {
        for (uint32_t i = 0; i < h.element_count; i++)
            for (int k = 0; k < 4; k++) {
                p->tets[4u * i + (uint32_t)k] = get_u32(grid + (size_t)V3_TET_SIZE * i + 4 * k);
                p->tet_neighbours[4u * i + (uint32_t)k] = (int32_t)get_u32(grid + (size_t)V3_TET_SIZE * i + 16 + 4 * k);
            }
    }

    r = check_contents(p, &lay, PB_ERROR_FORMAT, err);
    if (r != PB_SUCCESS) {
        pb_shprobe_destroy(p);
        return r;
    }
    *out = p;
    return PB_SUCCESS;
}

/* Re-reports a format/validation error with the file name in front. */
static pb_result prefix_path(pb_result r, const char *path, const pb_error *local, pb_error *err)
{
    return pb_error_set(err, r, "%s: %s", path, local->message);
}

/* Opens `path` (regular files only, never blocking), reads the header bytes and validates the header
 * against the file size. On success *fd is open and positioned after `*got` header bytes. */
static pb_result open_and_parse_header(const char *path, int *fd, uint8_t head[V3_HEADER_SIZE], size_t *got,
                                       pb_shprobe *h, layout *lay, pb_error *err)
{
    uint64_t size;
    pb_result r = pb_open_regular_(path, "a .shprobe file", fd, &size, err);
    if (r != PB_SUCCESS) return r;
    r = pb_read_full_(*fd, path, head, V3_HEADER_SIZE, got, err);
    if (r == PB_SUCCESS) {
        pb_error local = {0};
        r = parse_header(head, *got, size, h, lay, &local);
        if (r != PB_SUCCESS) prefix_path(r, path, &local, err);
    }
    if (r != PB_SUCCESS) {
        close(*fd);
        *fd = -1;
    }
    return r;
}

pb_result pb_shprobe_read(const char *path, pb_shprobe **out, pb_error *err)
{
    if (!path || !out) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_read: NULL argument");
    *out = NULL;
    int fd;
    uint8_t head[V3_HEADER_SIZE];
    size_t got = 0;
    pb_shprobe h;
    layout lay;
    pb_result r = open_and_parse_header(path, &fd, head, &got, &h, &lay, err);
    if (r != PB_SUCCESS) return r;
    /* The header matched the file size exactly and the limits, so this is what the data needs. */
    size_t total = (size_t)lay.total_size;
    uint8_t *buf = malloc(total > got ? total : got);
    if (!buf) {
        close(fd);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "%s: out of memory for %llu bytes", path,
                            (unsigned long long)lay.total_size);
    }
    memcpy(buf, head, got);
    size_t rest = 0;
    if (total > got) r = pb_read_full_(fd, path, buf + got, total - got, &rest, err);
    close(fd);
    if (r == PB_SUCCESS) {
        pb_error local = {0};
        r = pb_shprobe_read_memory(buf, got + rest, out, &local);
        if (r != PB_SUCCESS) prefix_path(r, path, &local, err);
    }
    free(buf);
    return r;
}

pb_result pb_shprobe_read_header(const char *path, pb_shprobe *out_header, pb_error *err)
{
    if (!path || !out_header)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_read_header: NULL argument");
    memset(out_header, 0, sizeof *out_header);
    int fd;
    uint8_t head[V3_HEADER_SIZE];
    size_t got = 0;
    pb_shprobe h;
    layout lay;
    pb_result r = open_and_parse_header(path, &fd, head, &got, &h, &lay, err);
    if (r != PB_SUCCESS) return r;
    close(fd);
    *out_header = h;
    return PB_SUCCESS;
}

/* ---- writing ---------------------------------------------------------------------------------- */

static bool all_valid(const pb_shprobe *p)
{
    if (!p->validity) return true;
    for (uint32_t i = 0; i < p->probe_count; i++)
        if (p->validity[i] != 1.0f) return false;
    return true;
}

static pb_result choose_version(const pb_shprobe *p, uint32_t *version, pb_error *err)
{
    const char *needs3 = NULL;
    if (p->representation != PB_SHPROBE_SH)
        needs3 = "an ambient cube";
    else if (p->storage != PB_SHPROBE_FLOAT32)
        needs3 = "binary16 storage";
    else if (p->structure != PB_SHPROBE_GRID)
        needs3 = p->structure == PB_SHPROBE_OCTREE ? "an octree" : "tetrahedra";
    if (p->version == 0 && needs3) {
        *version = 3;
        return PB_SUCCESS;
    }
    if ((p->version == 1 || p->version == 2) && needs3)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "version %u cannot hold %s; write version 3 or 0 (auto), or resample to a dense grid "
                            "(pb_interp_resample_dense)",
                            p->version, needs3);
    if (p->version == 3) {
        *version = 3;
        return PB_SUCCESS;
    }
    const char *needs2 = NULL;
    if (p->max_band > 2)
        needs2 = "max band > 2";
    else if (p->positions)
        needs2 = "probe positions";
    else if (!axes_are_identity(p->grid_axes))
        needs2 = "non-identity grid axes";
    else if (!all_valid(p))
        needs2 = "validity below 1";
    if (p->version == 0) {
        *version = needs2 ? 2u : 1u;
        return PB_SUCCESS;
    }
    if (p->version == 1 && needs2)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "version 1 cannot hold %s (max band %u); write version 2 or 0 (auto)", needs2, p->max_band);
    if (p->version > 3)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "unknown version %u to write; known: 1, 2, 3 (0 = auto)",
                            p->version);
    *version = p->version;
    return PB_SUCCESS;
}

static uint8_t *serialize(const pb_shprobe *p, const layout *lay)
{
    uint8_t *b = calloc((size_t)lay->total_size, 1);
    if (!b) return NULL;
    const field_offsets *f = lay->fields;
    put_u32(b, PB_SHPROBE_MAGIC);
    put_u32(b + 4, lay->version);
    put_u32(b + f->count, p->probe_count);
    if (lay->version == 3) {
        put_u32(b + V3_REPRESENTATION, p->representation);
        put_u32(b + V3_STORAGE, p->storage);
        put_u32(b + V3_STRUCTURE, p->structure);
        put_u32(b + V3_ELEMENTS, p->element_count);
        put_u32(b + V3_HANGING, p->hanging_count);
    }
    if (lay->version >= 2) {
        put_u32(b + f->band, p->max_band);
        put_u32(b + f->flags, lay->positions ? V2_FLAG_POSITIONS : 0u);
        const float *axes = axes_are_zero(p->grid_axes) ? identity_axes : p->grid_axes;
        for (int i = 0; i < 9; i++) put_f32(b + f->axes + 4 * i, axes[i]);
    }
    for (int i = 0; i < 3; i++) {
        put_u32(b + f->dims + 4 * i, lay->structure == PB_SHPROBE_TETRA ? 0u : p->grid_dims[i]);
        put_f32(b + f->origin + 4 * i, p->grid_origin[i]);
    }
    put_f32(b + f->spacing, p->grid_spacing);
    put_f32(b + f->scale, p->default_sh_scale);
    put_f32(b + f->ambient, p->default_ambient);

    uint32_t count = pb_shprobe_colour_count(p); /* <= disk_coeffs; v1 pads bands < 2 with zeros */
    bool half = lay->colour_bytes == 8u;
    for (uint32_t i = 0; i < p->probe_count; i++) {
        uint8_t *rec = b + lay->records_offset + (size_t)i * lay->record_size;
        const float *c = p->coeffs + (size_t)i * count * 3u;
        for (uint32_t k = 0; k < count; k++)
            for (uint32_t ch = 0; ch < 3; ch++) {
                if (half)
                    put_u16(rec + 8 * k + 2 * ch, float_to_half(c[3 * k + ch]));
                else
                    put_f32(rec + 16 * k + 4 * ch, c[3 * k + ch]);
            }
        uint8_t *tail = rec + (size_t)lay->colour_bytes * lay->disk_coeffs;
        put_f32(tail, p->probe_scale ? p->probe_scale[i] : 1.0f);
        put_f32(tail + 4, p->probe_ambient ? p->probe_ambient[i] : p->default_ambient);
        if (lay->version >= 2) put_f32(tail + 8, p->validity ? p->validity[i] : 1.0f);
        if (lay->positions) {
            uint8_t *pos = b + lay->positions_offset + 16u * (size_t)i;
            for (int k = 0; k < 3; k++) put_f32(pos + 4 * k, p->positions[3u * i + (uint32_t)k]);
        }
    }
    uint8_t *grid = b + lay->grid_offset;
    if (lay->structure == PB_SHPROBE_GRID) {
        for (uint64_t j = 0; j < lay->grid_cells; j++) put_u32(grid + 4 * j, (uint32_t)p->grid[j]);
    } else if (lay->structure == PB_SHPROBE_OCTREE) {
        for (uint32_t i = 0; i < p->element_count; i++) {
            uint8_t *l = grid + (size_t)V3_LEAF_SIZE * i;
            for (int k = 0; k < 4; k++) put_u32(l + 4 * k, p->leaves[4u * i + (uint32_t)k]);
            for (int k = 0; k < 8; k++) put_u32(l + 16 + 4 * k, (uint32_t)p->leaf_corners[8u * i + (uint32_t)k]);
        }
        uint8_t *hang = b + lay->hanging_offset;
        for (uint32_t j = 0; j < p->hanging_count; j++)
            for (int k = 0; k < 4; k++) {
                put_u32(hang + (size_t)V3_HANGING_SIZE * j + 4 * k, p->hanging_sources[4u * j + (uint32_t)k]);
                put_f32(hang + (size_t)V3_HANGING_SIZE * j + 16 + 4 * k, p->hanging_weights[4u * j + (uint32_t)k]);
            }
    } else {
        for (uint32_t i = 0; i < p->element_count; i++)
            for (int k = 0; k < 4; k++) {
                put_u32(grid + (size_t)V3_TET_SIZE * i + 4 * k, p->tets[4u * i + (uint32_t)k]);
                put_u32(grid + (size_t)V3_TET_SIZE * i + 16 + 4 * k, (uint32_t)p->tet_neighbours[4u * i + (uint32_t)k]);
            }
    }
    return b;
}

/* Whether `path` may be replaced: it does not exist, or it is a regular file (not a symbolic link)
 * that starts with the .shprobe magic. Anything else is refused without being opened (a device,
 * FIFO, socket or directory) or after reading its first 4 bytes only (a regular file). */
static pb_result check_destination(const char *path, pb_error *err)
{
    char why[128];
    struct stat st;
    if (lstat(path, &st) != 0) {
        if (errno == ENOENT) return PB_SUCCESS;
        pb_describe_errno_(errno, why, sizeof why);
        return pb_error_set(err, PB_ERROR_IO, "cannot write %s: cannot check what is there: %s", path, why);
    }
    if (S_ISLNK(st.st_mode))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "refusing to write %s: it is a symbolic link (writing would replace the link, not "
                            "the file it points to); write to the target path instead",
                            path);
    if (!S_ISREG(st.st_mode))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "refusing to write %s: it exists and is a %s, not a .shprobe file; only a new path "
                            "or an existing .shprobe file is written",
                            path, pb_file_kind_(st.st_mode));
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY | O_NOFOLLOW);
    if (fd < 0) {
        pb_describe_errno_(errno, why, sizeof why);
        return pb_error_set(err, PB_ERROR_IO,
                            "refusing to write %s: it exists and cannot be read to check that it is a .shprobe "
                            "file: %s",
                            path, why);
    }
    uint8_t magic[4] = {0};
    size_t got = 0;
    pb_error local = {0};
    bool regular = fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
    pb_result r = regular ? pb_read_full_(fd, path, magic, sizeof magic, &got, &local) : PB_ERROR_IO;
    close(fd);
    if (r != PB_SUCCESS || got < sizeof magic || get_u32(magic) != PB_SHPROBE_MAGIC)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            "refusing to replace %s: it exists and is not a .shprobe file (it does not start "
                            "with the .shprobe magic); remove it or choose another output path",
                            path);
    return PB_SUCCESS;
}

pb_result pb_shprobe_write(const char *path, const pb_shprobe *probes, pb_error *err)
{
    if (!path || !probes) return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_shprobe_write: NULL argument");
    const pb_shprobe *p = probes;
    pb_error local = {0};
    pb_result r = PB_SUCCESS;
    uint32_t version = 0;
    layout lay;
    if (p->max_band > PB_SH_MAX_BAND)
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "max band %u is out of range 0..%d", p->max_band,
                         PB_SH_MAX_BAND);
    if (r == PB_SUCCESS) r = choose_version(p, &version, &local);
    if (r == PB_SUCCESS && version == 3) r = check_v3_kind(p, p->positions != NULL, PB_ERROR_INVALID_ARGUMENT, &local);
    if (r == PB_SUCCESS) r = layout_compute(version, p, p->positions != NULL, PB_ERROR_TOO_LARGE, &lay, &local);
    if (r == PB_SUCCESS && p->probe_count > 0 && !p->coeffs)
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "coeffs is NULL");
    if (r == PB_SUCCESS && lay.structure == PB_SHPROBE_GRID && !p->grid)
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "grid is NULL");
    if (r == PB_SUCCESS && lay.structure == PB_SHPROBE_OCTREE &&
        (!p->leaves || !p->leaf_corners || (p->hanging_count && (!p->hanging_sources || !p->hanging_weights))))
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "octree leaves, corners or hanging rules are NULL");
    if (r == PB_SUCCESS && lay.structure == PB_SHPROBE_TETRA && (!p->tets || !p->tet_neighbours))
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "tetrahedra or neighbours are NULL");
    if (r == PB_SUCCESS) r = check_header_values(p, &lay, PB_ERROR_INVALID_ARGUMENT, &local);
    if (r == PB_SUCCESS) r = check_contents(p, &lay, PB_ERROR_INVALID_ARGUMENT, &local);
    if (r != PB_SUCCESS) return pb_error_set(err, r, "cannot write %s: %s", path, local.message);
    r = check_destination(path, err);
    if (r != PB_SUCCESS) return r;

    uint8_t *bytes = serialize(p, &lay);
    if (!bytes)
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "cannot write %s: out of memory for %llu bytes", path,
                            (unsigned long long)lay.total_size);
    r = pb_write_atomic_(path, bytes, (size_t)lay.total_size, check_destination, err);
    free(bytes);
    return r;
}

/* ---- lookup ----------------------------------------------------------------------------------- */

int32_t pb_shprobe_lookup(const pb_shprobe *probes, const float point[3])
{
    if (!probes || !point || !probes->grid || !(probes->grid_spacing > 0.0f) || !isfinite(probes->grid_spacing))
        return -1;
    const float *axes = axes_are_zero(probes->grid_axes) ? identity_axes : probes->grid_axes;
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
