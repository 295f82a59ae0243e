/* `.shprobe` reader and writer: version 1 (DESIGN.md §4) and version 2 (docs/shprobe-format.md).
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
    uint32_t disk_coeffs; /* coefficient vec4s per probe record */
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

/* The exact byte layout of a file; fails (code `fail`) when a size overflows 64 bits or size_t. */
static pb_result layout_compute(uint32_t version, uint32_t probe_count, uint32_t max_band, const uint32_t dims[3],
                                bool positions, pb_result fail, layout *lay, pb_error *err)
{
    memset(lay, 0, sizeof *lay);
    lay->version = version;
    lay->positions = positions;
    uint64_t header;
    if (version == 1) {
        lay->fields = &v1_fields;
        lay->disk_coeffs = V1_COEFFS;
        header = V1_HEADER_SIZE;
    } else {
        lay->fields = &v2_fields;
        lay->disk_coeffs = pb_sh_count(max_band);
        header = V2_HEADER_SIZE;
    }
    pb_error local = {0};
    if (grid_cell_count(dims, &lay->grid_cells, &local) != PB_SUCCESS)
        return pb_error_set(err, local.code == PB_ERROR_TOO_LARGE ? fail : local.code, "%s", local.message);
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
    lay->record_size = 16u * ((uint64_t)lay->disk_coeffs + 1u);
    lay->records_offset = header;
    uint64_t records, pos_bytes = 0, grid_bytes, end;
    bool ok = mul_u64(probe_count, lay->record_size, &records);
    if (positions) ok = ok && mul_u64(probe_count, 16u, &pos_bytes);
    ok = ok && add_u64(header, records, &lay->positions_offset);
    ok = ok && add_u64(lay->positions_offset, pos_bytes, &lay->grid_offset);
    ok = ok && mul_u64(lay->grid_cells, 4u, &grid_bytes);
    ok = ok && add_u64(lay->grid_offset, grid_bytes, &end);
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
    if (!(p->grid_spacing > 0.0f))
        return pb_error_set(err, code, "grid spacing is %g (offset %u); it must be > 0", (double)p->grid_spacing,
                            f->spacing);
    if (!isfinite(p->default_sh_scale))
        return pb_error_set(err, PB_ERROR_NON_FINITE, "default SH scale is %g (offset %u)", (double)p->default_sh_scale,
                            f->scale);
    if (!isfinite(p->default_ambient))
        return pb_error_set(err, PB_ERROR_NON_FINITE, "default ambient is %g (offset %u)", (double)p->default_ambient,
                            f->ambient);
    if (lay->version >= 2 && !axes_are_zero(p->grid_axes)) {
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
static pb_result check_contents(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err)
{
    uint32_t count = pb_sh_count(p->max_band);
    for (uint32_t i = 0; i < p->probe_count; i++) {
        uint64_t rec = lay->records_offset + (uint64_t)i * lay->record_size;
        const float *c = p->coeffs + (size_t)i * count * 3u;
        for (uint32_t k = 0; k < count * 3u; k++)
            if (!isfinite(c[k]))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "probe %u coefficient %u %s is %g (offset %llu)", i,
                                    k / 3u, channel_names[k % 3u], (double)c[k],
                                    (unsigned long long)(rec + 16u * (k / 3u) + 4u * (k % 3u)));
        uint64_t tail = rec + 16u * (uint64_t)lay->disk_coeffs;
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

void pb_shprobe_destroy(pb_shprobe *probes)
{
    if (!probes) return;
    free(probes->coeffs);
    free(probes->probe_scale);
    free(probes->probe_ambient);
    free(probes->validity);
    free(probes->positions);
    free(probes->grid);
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
    if (version != 1 && version != 2)
        return pb_error_set(err, PB_ERROR_FORMAT, "unknown version %u at offset 4; this reader knows versions 1 and 2",
                            version);
    uint32_t header_size = version == 1 ? V1_HEADER_SIZE : V2_HEADER_SIZE;
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
    for (int i = 0; i < 3; i++) {
        h->grid_dims[i] = get_u32(data + f->dims + 4 * i);
        h->grid_origin[i] = get_f32(data + f->origin + 4 * i);
        if (h->grid_dims[i] == 0)
            return pb_error_set(err, PB_ERROR_FORMAT,
                                "grid dim %c at offset %u is 0; a grid has at least one cell per axis", "XYZ"[i],
                                f -> dims + 4u * (uint32_t)i);
    }
    h->grid_spacing = get_f32(data + f->spacing);
    h->default_sh_scale = get_f32(data + f->scale);
    h->default_ambient = get_f32(data + f->ambient);

    pb_result r = layout_compute(version, h->probe_count, h->max_band, h->grid_dims, (flags & V2_FLAG_POSITIONS) != 0,
                                 PB_ERROR_FORMAT, lay, err);
    if (r != PB_SUCCESS) return r;
    r = check_header_values(h, lay, PB_ERROR_FORMAT, err);
    if (r != PB_SUCCESS) return r;
    if (file_size < lay->total_size)
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "truncated: %llu bytes, but %u probes (max band %u%s) and a %u x %u x %u "
                            "grid need %llu",
                            (unsigned long long)file_size, h->probe_count, h->max_band,
                            lay->positions ? ", positions" : "", h->grid_dims[0], h->grid_dims[1], h->grid_dims[2],
                            (unsigned long long)lay->total_size);
    if (file_size > lay->total_size)
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "%llu bytes of trailing data after the grid, which ends at offset %llu",
                            (unsigned long long)(file_size - lay->total_size), (unsigned long long)lay->total_size);
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
    r = pb_shprobe_create(h.probe_count, h.max_band, h.grid_dims, lay.positions, &p, err);
    if (r != PB_SUCCESS) return r;
    p->version = h.version;
    memcpy(p->grid_origin, h.grid_origin, sizeof p->grid_origin);
    memcpy(p->grid_axes, h.grid_axes, sizeof p->grid_axes);
    p->grid_spacing = h.grid_spacing;
    p->default_sh_scale = h.default_sh_scale;
    p->default_ambient = h.default_ambient;

    uint32_t count = pb_sh_count(h.max_band); /* = disk_coeffs for both versions */
    for (uint32_t i = 0; i < h.probe_count; i++) {
        const uint8_t *rec = bytes + lay.records_offset + (size_t)i * lay.record_size;
        float *c = p->coeffs + (size_t)i * count * 3u;
        for (uint32_t k = 0; k < count; k++)
            for (uint32_t ch = 0; ch < 3; ch++) c[3 * k + ch] = get_f32(rec + 16 * k + 4 * ch);
        const uint8_t *tail = rec + 16u * lay.disk_coeffs;
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
    for (uint64_t j = 0; j < lay.grid_cells; j++) p->grid[j] = (int32_t)get_u32(grid + 4 * j);

    r = check_contents(p, &lay, PB_ERROR_FORMAT, err);
    if (r != PB_SUCCESS) {
        pb_shprobe_destroy(p);
        return r;
    }
    *out = p;
    return PB_SUCCESS;
}

static void describe_errno(int e, char *buf, size_t n)
{
    if (strerror_r(e, buf, n) != 0) snprintf(buf, n, "errno %d", e);
}

/* Re-reports a format/validation error with the file name in front. */
static pb_result prefix_path(pb_result r, const char *path, const pb_error *local, pb_error *err)
{
    return pb_error_set(err, r, "%s: %s", path, local->message);
}

/* Opens `path` (regular files only, never blocking), reads the header bytes and validates the header
 * against the file size. On success *fd is open and positioned after `*got` header bytes. */
static pb_result open_and_parse_header(const char *path, int *fd, uint8_t head[V2_HEADER_SIZE], size_t *got,
                                       pb_shprobe *h, layout *lay, pb_error *err)
{
    uint64_t size;
    pb_result r = pb_open_regular_(path, "a .shprobe file", fd, &size, err);
    if (r != PB_SUCCESS) return r;
    r = pb_read_full_(*fd, path, head, V2_HEADER_SIZE, got, err);
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
    uint8_t head[V2_HEADER_SIZE];
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
    uint8_t head[V2_HEADER_SIZE];
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
    if (p->version > 2)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "unknown version %u to write; known: 1, 2 (0 = auto)",
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
    if (lay->version >= 2) {
        put_u32(b + f->band, p->max_band);
        put_u32(b + f->flags, lay->positions ? V2_FLAG_POSITIONS : 0u);
        const float *axes = axes_are_zero(p->grid_axes) ? identity_axes : p->grid_axes;
        for (int i = 0; i < 9; i++) put_f32(b + f->axes + 4 * i, axes[i]);
    }
    for (int i = 0; i < 3; i++) {
        put_u32(b + f->dims + 4 * i, p->grid_dims[i]);
        put_f32(b + f->origin + 4 * i, p->grid_origin[i]);
    }
    put_f32(b + f->spacing, p->grid_spacing);
    put_f32(b + f->scale, p->default_sh_scale);
    put_f32(b + f->ambient, p->default_ambient);

    uint32_t count = pb_sh_count(p->max_band); /* <= disk_coeffs; v1 pads bands < 2 with zeros */
    for (uint32_t i = 0; i < p->probe_count; i++) {
        uint8_t *rec = b + lay->records_offset + (size_t)i * lay->record_size;
        const float *c = p->coeffs + (size_t)i * count * 3u;
        for (uint32_t k = 0; k < count; k++)
            for (uint32_t ch = 0; ch < 3; ch++) put_f32(rec + 16 * k + 4 * ch, c[3 * k + ch]);
        uint8_t *tail = rec + 16u * lay->disk_coeffs;
        put_f32(tail, p->probe_scale ? p->probe_scale[i] : 1.0f);
        put_f32(tail + 4, p->probe_ambient ? p->probe_ambient[i] : p->default_ambient);
        if (lay->version >= 2) put_f32(tail + 8, p->validity ? p->validity[i] : 1.0f);
        if (lay->positions) {
            uint8_t *pos = b + lay->positions_offset + 16u * (size_t)i;
            for (int k = 0; k < 3; k++) put_f32(pos + 4 * k, p->positions[3u * i + (uint32_t)k]);
        }
    }
    uint8_t *grid = b + lay->grid_offset;
    for (uint64_t j = 0; j < lay->grid_cells; j++) put_u32(grid + 4 * j, (uint32_t)p->grid[j]);
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
        describe_errno(errno, why, sizeof why);
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
        describe_errno(errno, why, sizeof why);
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

/* Temp file in the same folder, write, fsync, rename; the temp is removed on any failure. */
static pb_result write_atomic(const char *path, const uint8_t *data, size_t size, pb_error *err)
{
    static const char suffix[] = ".tmp.XXXXXX";
    size_t n = strlen(path);
    char *tmp = malloc(n + sizeof suffix);
    if (!tmp) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    memcpy(tmp, path, n);
    memcpy(tmp + n, suffix, sizeof suffix);

    char why[128];
    const char *step = "create a temporary file";
    int fd = mkstemp(tmp);
    if (fd < 0) goto fail;
    step = "write";
    for (size_t done = 0; done < size;) {
        ssize_t k = write(fd, data + done, size - done);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0) goto fail;
        done += (size_t)k;
    }
    step = "set permissions of";
    if (fchmod(fd, 0644) != 0) goto fail;
    step = "fsync";
    if (fsync(fd) != 0) goto fail;
    step = "close";
    {
        int c = close(fd);
        fd = -1;
        if (c != 0) goto fail;
    }
    /* Checked again just before the rename: something may have appeared there while writing. */
    {
        pb_result again = check_destination(path, err);
        if (again != PB_SUCCESS) {
            unlink(tmp);
            free(tmp);
            return again;
        }
    }
    step = "rename the temporary file onto";
    if (rename(tmp, path) != 0) goto fail;
    free(tmp);

    /* Make the rename durable too (best effort: some filesystems refuse fsync on directories). */
    {
        const char *slash = strrchr(path, '/');
        char *dir = slash ? strndup(path, slash == path ? 1u : (size_t)(slash - path)) : strdup(".");
        if (dir) {
            int dfd = open(dir, O_RDONLY);
            if (dfd >= 0) {
                (void)fsync(dfd);
                close(dfd);
            }
            free(dir);
        }
    }
    return PB_SUCCESS;

fail:
    describe_errno(errno, why, sizeof why);
    if (fd >= 0) close(fd);
    if (strcmp(step, "create a temporary file") != 0) unlink(tmp);
    pb_error_set(err, PB_ERROR_IO, "%s: cannot %s %s: %s", path, step,
                 strcmp(step, "create a temporary file") == 0 ? "next to it" : "it", why);
    free(tmp);
    return PB_ERROR_IO;
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
    if (r == PB_SUCCESS)
        r = layout_compute(version, p->probe_count, p->max_band, p->grid_dims, p->positions != NULL, PB_ERROR_TOO_LARGE,
                           &lay, &local);
    if (r == PB_SUCCESS && ((p->probe_count > 0 && !p->coeffs) || !p->grid))
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "coeffs or grid is NULL");
    if (r == PB_SUCCESS) r = check_header_values(p, &lay, PB_ERROR_INVALID_ARGUMENT, &local);
    if (r == PB_SUCCESS) r = check_contents(p, &lay, PB_ERROR_INVALID_ARGUMENT, &local);
    if (r != PB_SUCCESS) return pb_error_set(err, r, "cannot write %s: %s", path, local.message);
    r = check_destination(path, err);
    if (r != PB_SUCCESS) return r;

    uint8_t *bytes = serialize(p, &lay);
    if (!bytes)
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "cannot write %s: out of memory for %llu bytes", path,
                            (unsigned long long)lay.total_size);
    r = write_atomic(path, bytes, (size_t)lay.total_size, err);
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
