/* `.shprobe` reader, versions 1 to 4: the header first (its exact size against the file's, limits
 * before anything is allocated), then the records and the structure, then the validation shared with
 * the writer (pb_shprobe.c). Files are opened without blocking, regular files only (pb_file.h).
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_shprobe.h"

#include "schnee/pb_sh.h"

#include "pb_file.h"
#include "pb_shprobe_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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
    if (version < 1 || version > 4)
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "unknown version %u at offset 4; this reader knows versions 1, 2, 3 and 4", version);
    uint32_t header_size = version == 1 ? V1_HEADER_SIZE : (version == 2 ? V2_HEADER_SIZE : V3_HEADER_SIZE);
    if (file_size < header_size || avail < header_size)
        return pb_error_set(err, PB_ERROR_FORMAT, "truncated: %llu bytes, the version %u header needs %u",
                            (unsigned long long)file_size, version, header_size);
    const field_offsets *f = version == 1 ? &pb_shprobe_v1_fields_ : &pb_shprobe_v2_fields_;
    h->version = version;
    h->probe_count = get_u32(data + f->count);
    uint32_t flags = 0;
    if (version == 1) {
        h->max_band = 2;
        memcpy(h->grid_axes, pb_shprobe_identity_axes_, sizeof h->grid_axes);
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
        if (pb_shprobe_axes_are_zero_(h->grid_axes))
            return pb_error_set(err, PB_ERROR_FORMAT, "grid axes at offset %u are all zero", f->axes);
    }
    if (version >= 3) {
        h->representation = get_u32(data + V3_REPRESENTATION);
        h->storage = get_u32(data + V3_STORAGE);
        h->structure = get_u32(data + V3_STRUCTURE);
        h->element_count = get_u32(data + V3_ELEMENTS);
        h->hanging_count = get_u32(data + V3_HANGING);
        for (int i = 0; i < 3; i++) h->grid_dims[i] = get_u32(data + f->dims + 4 * i);
        if (version == 4) {
            h->root_level = get_u32(data + V4_ROOT_LEVEL);
            h->split_node_count = get_u32(data + V4_NODE_COUNT);
            for (uint32_t k = 0; k < 2; k++)
                if (get_u32(data + V4_RESERVED + 4u * k) != 0)
                    return pb_error_set(err, PB_ERROR_FORMAT, "reserved word at offset %u is 0x%X; it must be 0",
                                        V4_RESERVED + 4u * k, get_u32(data + V4_RESERVED + 4u * k));
        }
        pb_result kr = pb_shprobe_check_v3_kind_(version, h, (flags & V2_FLAG_POSITIONS) != 0, PB_ERROR_FORMAT, err);
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

    pb_result r = pb_shprobe_layout_compute_(version, h, (flags & V2_FLAG_POSITIONS) != 0, PB_ERROR_FORMAT, lay, err);
    if (r != PB_SUCCESS) return r;
    r = pb_shprobe_check_header_values_(h, lay, PB_ERROR_FORMAT, err);
    if (r != PB_SUCCESS) return r;
    if (file_size < lay->total_size)
        return pb_error_set(err, PB_ERROR_FORMAT,
                            "truncated: %llu bytes, but %u probes (max band %u%s) and a %u x %u x %u "
                            "%s need %llu",
                            (unsigned long long)file_size, h->probe_count, h->max_band,
                            lay->positions ? ", positions" : "", h->grid_dims[0], h->grid_dims[1], h->grid_dims[2],
                            pb_shprobe_structure_name_(lay->structure), (unsigned long long)lay->total_size);
    if (file_size > lay->total_size)
        return pb_error_set(err, PB_ERROR_FORMAT, "%llu bytes of trailing data after the %s, which ends at offset %llu",
                            (unsigned long long)(file_size - lay->total_size),
                            pb_shprobe_structure_name_(lay->structure), (unsigned long long)lay->total_size);
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
    if (h.version == 4)
        r = pb_shprobe_create_v4(h.probe_count, h.representation, h.max_band, h.grid_dims, h.element_count,
                                 h.hanging_count, h.root_level, h.split_node_count, &p, err);
    else if (h.version == 3)
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
    } else if (lay.structure == PB_SHPROBE_OCTREE || lay.structure == PB_SHPROBE_KDTREE) {
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
        for (uint32_t j = 0; j < h.split_node_count; j++)
            p->split_nodes[j] = get_u32(bytes + lay.split_offset + (size_t)V4_NODE_SIZE * j);
    } else {
        for (uint32_t i = 0; i < h.element_count; i++)
            for (int k = 0; k < 4; k++) {
                p->tets[4u * i + (uint32_t)k] = get_u32(grid + (size_t)V3_TET_SIZE * i + 4 * k);
                p->tet_neighbours[4u * i + (uint32_t)k] = (int32_t)get_u32(grid + (size_t)V3_TET_SIZE * i + 16 + 4 * k);
            }
    }

    r = pb_shprobe_check_contents_(p, &lay, PB_ERROR_FORMAT, err);
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
