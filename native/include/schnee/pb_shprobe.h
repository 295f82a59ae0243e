/* Schnee probes — `.shprobe` files (DESIGN.md §4; version 2 in docs/shprobe-format.md).
 *
 * How to use it:
 *   writing: pb_shprobe_create() with the probe count, band and grid dims, fill the arrays,
 *            pb_shprobe_write() (atomic: temp file in the same folder + rename), pb_shprobe_destroy().
 *   reading: pb_shprobe_read() (or _read_memory), use the fields, pb_shprobe_destroy().
 * The reader validates everything (magic 0x52485053, version, sizes and their overflow, truncation,
 * grid entries in [−1, probe_count), finite coefficients) and never crashes on malformed input.
 * The bake and the engine link this same code. All data is in engine space (Y-up).
 */
#ifndef SCHNEE_PB_SHPROBE_H
#define SCHNEE_PB_SHPROBE_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PB_SHPROBE_MAGIC 0x52485053u /* bytes on disk "SPHR" */

/* Documented limits (docs/shprobe-format.md, "Limits"): a header above them is refused with
 * PB_ERROR_TOO_LARGE after reading the header only (nothing allocated), and the writer refuses to
 * produce such a file. At the limits a band-4 file with positions is about 8.3 GB. */
#define PB_SHPROBE_MAX_PROBES     (UINT32_C(1) << 24) /* 16 777 216 probes */
#define PB_SHPROBE_MAX_GRID_CELLS (UINT64_C(1) << 28) /* 268 435 456 cells = 1 GiB of int32 */

typedef struct pb_shprobe {
    uint32_t version; /* version read, or to write: 0 = smallest that holds the data
                                (1 for max_band <= 2 without positions, identity axes and every
                                validity 1; else 2) */
    uint32_t probe_count;
    uint32_t max_band;      /* 0..4; version 1 files always read back as 2 (9 coefficients) */
    uint32_t grid_dims[3];  /* X, Y, Z */
    float grid_origin[3];   /* min corner of cell (0,0,0), engine space, metres */
    float grid_spacing;     /* metres */
    float default_sh_scale; /* header default, 1.0 in a fresh bake */
    float default_ambient;  /* header default, 0.1 in a fresh bake */
    float *coeffs;          /* probe_count * pb_sh_count(max_band) * 3: probe-major, then coeff, then RGB */
    float *probe_scale;     /* probe_count */
    float *probe_ambient;   /* probe_count */
    float *positions;       /* probe_count * 3, or NULL (version 1 has none) */
    int32_t *grid;          /* X*Y*Z, flat x + y*X + z*X*Y, probe index or −1 */
    /* Added with version 2 (docs/shprobe-format.md); version 1 reads back the defaults. */
    float grid_axes[9]; /* rows: unit X, Y, Z axes of the grid in engine space (orthonormal);
                                all zero = identity (a version 1 read fills the identity) */
    float *validity;    /* probe_count values in [0, 1] (1 − back-face ratio), or NULL = all 1 */
} pb_shprobe;

/* Allocates a zeroed file image (grid filled with −1, scales 1, ambients = default 0.1, validity 1,
 * identity axes, positions allocated only if with_positions). grid_spacing is 0 and must be set
 * before writing. Free with pb_shprobe_destroy. */
pb_result pb_shprobe_create(uint32_t probe_count, uint32_t max_band, const uint32_t grid_dims[3], bool with_positions,
                            pb_shprobe **out, pb_error *err);

/* Validates like the reader (finite values, grid entries in [−1, count), spacing > 0, ...), then
 * writes atomically. NULL probe_scale = all 1, NULL probe_ambient = all default_ambient.
 * Never replaces what is not a .shprobe: when `path` exists it must be a regular file whose first
 * 4 bytes are the magic; a directory, device, FIFO, socket, symbolic link (decided: refused, not
 * followed — rename would replace the link itself) or any other file is refused with
 * PB_ERROR_INVALID_ARGUMENT naming the path, and nothing is written. */
pb_result pb_shprobe_write(const char *path, const pb_shprobe *probes, pb_error *err);
pb_result pb_shprobe_read(const char *path, pb_shprobe **out, pb_error *err);
pb_result pb_shprobe_read_memory(const void *data, size_t size, pb_shprobe **out, pb_error *err);

/* The file readers open without blocking and read regular files only (a FIFO, device, directory or
 * symbolic-link loop fails at once with PB_ERROR_IO), check the header first and then read exactly
 * the size it implies (limits above). Errors never quote the content of a file that is not ours. */

/* Reads and validates only the header (for exporters): fills every scalar field, array pointers NULL. */
pb_result pb_shprobe_read_header(const char *path, pb_shprobe *out_header, pb_error *err);

/* Probe index for an engine-space point: the grid cell holding it, −1 if outside or empty. */
int32_t pb_shprobe_lookup(const pb_shprobe *probes, const float point[3]);

void pb_shprobe_destroy(pb_shprobe *probes);

#ifdef __cplusplus
}
#endif
#endif
