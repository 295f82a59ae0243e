/* `.shprobe` writer, versions 1 to 4: the smallest version that holds the data (or the one asked
 * for), the validation shared with the reader (pb_shprobe.c), the bytes, and an atomic replace that
 * never overwrites anything but a .shprobe file (pb_file.h).
 */
#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_shprobe.h"

#include "schnee/pb_sh.h"

#include "pb_file.h"
#include "pb_shprobe_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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
static bool axes_are_identity(const float axes[9])
{
    return pb_shprobe_axes_are_zero_(axes) ||
           memcmp(axes, pb_shprobe_identity_axes_, sizeof pb_shprobe_identity_axes_) == 0;
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
    bool kd = p->structure == PB_SHPROBE_KDTREE;
    if (kd && (p->version == 0 || p->version == 4)) {
        *version = 4;
        return PB_SUCCESS;
    }
    if (kd || p->version == 4)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                            kd ? "version %u cannot hold a kd corner tree (structure 3); write version 4 or 0 (auto)"
                               : "version %u holds the kd corner tree (structure 3) only; write version 3 or 0 (auto)",
                            p->version);
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
    if (p->version > 4)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "unknown version %u to write; known: 1, 2, 3, 4 (0 = auto)",
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
    if (lay->version == 4) {
        put_u32(b + V4_ROOT_LEVEL, p->root_level);
        put_u32(b + V4_NODE_COUNT, p->split_node_count);
    }
    if (lay->version >= 3) {
        put_u32(b + V3_REPRESENTATION, p->representation);
        put_u32(b + V3_STORAGE, p->storage);
        put_u32(b + V3_STRUCTURE, p->structure);
        put_u32(b + V3_ELEMENTS, p->element_count);
        put_u32(b + V3_HANGING, p->hanging_count);
    }
    if (lay->version >= 2) {
        put_u32(b + f->band, p->max_band);
        put_u32(b + f->flags, lay->positions ? V2_FLAG_POSITIONS : 0u);
        const float *axes = pb_shprobe_axes_are_zero_(p->grid_axes) ? pb_shprobe_identity_axes_ : p->grid_axes;
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
    } else if (lay->structure == PB_SHPROBE_OCTREE || lay->structure == PB_SHPROBE_KDTREE) {
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
        for (uint32_t j = 0; lay->structure == PB_SHPROBE_KDTREE && j < p->split_node_count; j++)
            put_u32(b + lay->split_offset + (size_t)V4_NODE_SIZE * j, p->split_nodes[j]);
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
    if (r == PB_SUCCESS && version >= 3)
        r = pb_shprobe_check_v3_kind_(version, p, p->positions != NULL, PB_ERROR_INVALID_ARGUMENT, &local);
    if (r == PB_SUCCESS)
        r = pb_shprobe_layout_compute_(version, p, p->positions != NULL, PB_ERROR_TOO_LARGE, &lay, &local);
    if (r == PB_SUCCESS && p->probe_count > 0 && !p->coeffs)
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "coeffs is NULL");
    if (r == PB_SUCCESS && lay.structure == PB_SHPROBE_GRID && !p->grid)
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "grid is NULL");
    if (r == PB_SUCCESS && (lay.structure == PB_SHPROBE_OCTREE || lay.structure == PB_SHPROBE_KDTREE) &&
        (!p->leaves || !p->leaf_corners || (p->hanging_count && (!p->hanging_sources || !p->hanging_weights)) ||
         (lay.structure == PB_SHPROBE_KDTREE && !p->split_nodes)))
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "leaves, corners, hanging rules or split tree are NULL");
    if (r == PB_SUCCESS && lay.structure == PB_SHPROBE_TETRA && (!p->tets || !p->tet_neighbours))
        r = pb_error_set(&local, PB_ERROR_INVALID_ARGUMENT, "tetrahedra or neighbours are NULL");
    if (r == PB_SUCCESS) r = pb_shprobe_check_header_values_(p, &lay, PB_ERROR_INVALID_ARGUMENT, &local);
    if (r == PB_SUCCESS) r = pb_shprobe_check_contents_(p, &lay, PB_ERROR_INVALID_ARGUMENT, &local);
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
