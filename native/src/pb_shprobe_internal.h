/* Internal (not installed): what the `.shprobe` sources share (pb_shprobe.c: sizes, layout and
 * validation; pb_shprobe_v3.c: version 3 structures; pb_shprobe_read.c; pb_shprobe_write.c).
 *
 * Every byte is read and written through explicit little-endian helpers, never by casting the
 * buffer, so the code is independent of host byte order and alignment. */
#ifndef SCHNEE_PB_SHPROBE_INTERNAL_H
#define SCHNEE_PB_SHPROBE_INTERNAL_H

#include "schnee/pb_shprobe.h"

#include <string.h>

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
#define V4_ROOT_LEVEL     112u /* version 4: root level R */
#define V4_NODE_COUNT     116u /* version 4: split-tree node count K */
#define V4_RESERVED       120u /* version 4: 8 bytes, must be 0 */
#define V4_NODE_SIZE      4u
#define HALF_MAX          65504.0f
#define HANGING_SUM_TOL   1e-5

/* ---- little-endian byte access ---------------------------------------------------------------- */

static inline uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline float get_f32(const uint8_t *p)
{
    uint32_t u = get_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static inline void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static inline void put_f32(uint8_t *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    put_u32(p, u);
}

static inline uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }

static inline void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

/* Where every field of one version lives; offsets are used for error messages too. */
typedef struct field_offsets {
    uint32_t count, band, flags, dims, origin, spacing, axes, scale, ambient;
} field_offsets;

/* Offsets of versions 1 and 2 (version 3 keeps version 2's offsets up to 92); pb_shprobe.c. */
extern const field_offsets pb_shprobe_v1_fields_;
extern const field_offsets pb_shprobe_v2_fields_;
/* Rows of the identity grid axes: what all-zero axes stand for. */
extern const float pb_shprobe_identity_axes_[9];

/* Where each part of one file lies, from its header (pb_shprobe_layout_compute_). */
typedef struct layout {
    uint32_t version;
    uint32_t disk_coeffs;  /* coefficient vec4s (colours) per probe record */
    uint32_t colour_bytes; /* 16 (float32 vec4) or 8 (binary16 ×4) */
    uint32_t structure;
    uint64_t hanging_offset; /* octree, kd tree: after the leaves */
    uint64_t split_offset;   /* kd tree: the split-tree nodes, after the hanging rules */
    bool positions;
    const field_offsets *fields;
    uint64_t grid_cells;
    uint64_t record_size; /* bytes per probe record */
    uint64_t records_offset;
    uint64_t positions_offset;
    uint64_t grid_offset;
    uint64_t total_size;
} layout;

/* Name of a pb_shprobe_structure for messages ("grid" for an unknown value). */
const char *pb_shprobe_structure_name_(uint32_t s);

/* Version 3 and 4 kind fields and structure counts: known values, limits, what each structure requires
 * (version 4 holds the kd corner tree only, version 3 never). `code` is the result for a wrong value
 * (format when reading, invalid argument when writing). */
pb_result pb_shprobe_check_v3_kind_(uint32_t version, const pb_shprobe *h, bool positions, pb_result code,
                                    pb_error *err);

/* The exact byte layout of a file; fails (code `fail`) when a size overflows 64 bits or size_t.
 * Version 3 kind fields must have passed pb_shprobe_check_v3_kind_. */
pb_result pb_shprobe_layout_compute_(uint32_t version, const pb_shprobe *h, bool positions, pb_result fail, layout *lay,
                                     pb_error *err);

/* All nine axis components zero: the file's frame is the identity. */
bool pb_shprobe_axes_are_zero_(const float axes[9]);
/* Header values: finite floats, positive spacing, orthonormal axes. `what` prefixes messages. */
pb_result pb_shprobe_check_header_values_(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err);
/* Per-probe values and grid entries. `code` is the result for a range error (format when reading,
 * invalid argument when writing); NaN/Inf is always PB_ERROR_NON_FINITE. */
pb_result pb_shprobe_check_contents_(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err);
/* Versions 3 and 4 (pb_shprobe_v3.c; called by pb_shprobe_check_contents_): octree leaves, corner
 * references and hanging rules; tetrahedra and neighbours; the kd corner tree's boxes and split tree.
 * Octree leaves must be in Morton order of their min corners (z most significant): aligned cubes in that
 * order do not overlap exactly when each one's Morton range ends before the next one starts, so one pass
 * proves it. The kd tree's split tree proves the same for boxes (docs/shprobe-format.md "Version 4"). */
pb_result pb_shprobe_check_structure_(const pb_shprobe *p, const layout *lay, pb_result code, pb_error *err);

#endif
