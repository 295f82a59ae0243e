/* Schnee probes — `.shprobe` files (DESIGN.md §4; versions 2 to 4 in docs/shprobe-format.md).
 *
 * How to use it:
 *   writing: pb_shprobe_create() with the probe count, band and grid dims, fill the arrays,
 *            pb_shprobe_write() (atomic: temp file in the same folder + rename), pb_shprobe_destroy().
 *            Version 3 (probe positions + the sparse structure of the interpolation, SH or ambient
 *            cubes, float32 or binary16): pb_shprobe_create_v3(), fill, pb_shprobe_write().
 *   reading: pb_shprobe_read() (or _read_memory), use the fields, pb_shprobe_destroy().
 * The reader validates everything (magic 0x52485053, version, sizes and their overflow, truncation,
 * grid entries in [−1, probe_count), finite coefficients) and never crashes on malformed input.
 * The bake and the engine link this same code. All data is in engine space (Y-up).
 *
 * Layout: this header holds the file image (struct pb_shprobe, limits, create, lookup, destroy) and
 * includes the rest: pb_shprobe_read.h, pb_shprobe_write.h, pb_shprobe_v3.h. The sources follow the
 * same cut: native/src/pb_shprobe.c (layout and validation shared by every version), pb_shprobe_read.c,
 * pb_shprobe_write.c, pb_shprobe_v3.c (version 3's structures), pb_shprobe_internal.h (what they share).
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
/* Version 3 sparse structures (docs/shprobe-format.md, "Version 3"). */
#define PB_SHPROBE_MAX_LEAVES  (UINT32_C(1) << 26) /* octree leaves (48 B each) */
#define PB_SHPROBE_MAX_HANGING (UINT32_C(1) << 26) /* hanging nodes (32 B each) */
#define PB_SHPROBE_MAX_TETS    (UINT32_C(1) << 27) /* tetrahedra (32 B each) */
#define PB_SHPROBE_MAX_LATTICE (UINT32_C(1) << 20) /* octree lattice extent per axis, min cells */
/* Version 4 (structure 3, the kd corner tree): split-tree nodes (4 B each). */
#define PB_SHPROBE_MAX_SPLIT_NODES (UINT32_C(1) << 28)
#define PB_SHPROBE_SPLIT_EMPTY     ((UINT32_C(1) << 30) - 1u) /* a leaf node's index: no leaf (outside) */

typedef enum pb_shprobe_representation {
    PB_SHPROBE_SH = 0,           /* radiance SH of band max_band: pb_sh_count(max_band) colours per probe */
    PB_SHPROBE_AMBIENT_CUBE = 1, /* 6 irradiance colours +X, −X, +Y, −Y, +Z, −Z (docs/ambient-cube.md) */
} pb_shprobe_representation;

typedef enum pb_shprobe_storage {
    PB_SHPROBE_FLOAT32 = 0,
    PB_SHPROBE_FLOAT16 = 1, /* IEEE binary16 colours (version 3 only); scale/ambient/validity stay float32 */
} pb_shprobe_storage;

typedef enum pb_shprobe_structure {
    PB_SHPROBE_GRID = 0,   /* dense occupancy grid (versions 1, 2; 3 optional) */
    PB_SHPROBE_OCTREE = 1, /* corner octree: leaves with 8 corner nodes, hanging-node rules (version 3) */
    PB_SHPROBE_TETRA = 2,  /* Delaunay tetrahedra with neighbours (version 3) */
    PB_SHPROBE_KDTREE = 3, /* kd corner tree: boxes with per-axis levels and their split tree (version 4,
                              docs/aniso-refinement.md); a tree of cubes is written as OCTREE */
} pb_shprobe_structure;

typedef struct pb_shprobe {
    uint32_t version; /* version read, or to write: 0 = smallest that holds the data
                                (1 for max_band <= 2 without positions, identity axes and every
                                validity 1; 4 for the kd corner tree; 3 for an ambient cube, binary16
                                or another structure than the grid; else 2) */
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
    /* Added with version 3 (docs/shprobe-format.md). Versions 1/2 read back SH, float32, grid. For
     * the octree, grid_origin/grid_spacing/grid_axes are the lattice frame (spacing = min cell) and
     * grid_dims its extent in min cells; grid is NULL for the octree and tetrahedra. */
    uint32_t representation;   /* pb_shprobe_representation; coeffs holds pb_shprobe_colour_count()
                                 colours × RGB per probe */
    uint32_t storage;          /* pb_shprobe_storage (of the file; coeffs are float in memory) */
    uint32_t structure;        /* pb_shprobe_structure */
    uint32_t element_count;    /* octree leaves or tetrahedra */
    uint32_t hanging_count;    /* octree hanging nodes */
    uint32_t *leaves;          /* element_count × (x, y, z, level), Morton order of min corners; KDTREE:
                                  (x, y, z, levels packed lx | ly << 8 | lz << 16, PB_LEVELS_PACK) */
    int32_t *leaf_corners;     /* element_count × 8 node indices: [0, P) probes, [P, P+H) hanging nodes */
    uint32_t *hanging_sources; /* hanging_count × 4 node indices (probes or earlier hanging nodes) */
    float *hanging_weights;    /* hanging_count × 4, ≥ 0, sum 1 (unused sources: weight 0) */
    uint32_t *tets;            /* element_count × 4 probe indices */
    int32_t *tet_neighbours;   /* element_count × 4: neighbour opposite vertex i, or −1 */
    /* Added with version 4 (structure KDTREE; docs/shprobe-format.md "Version 4"). */
    uint32_t root_level;       /* R: Max Cell Size = 2^R min cells; the root grid is ceil(grid_dims / 2^R) */
    uint32_t split_node_count; /* K */
    uint32_t *split_nodes;     /* K nodes, 0..G-1 the root cells (x fastest). Bits 0-1: 0 leaf, 1/2/3 split
                                  along x/y/z; bits 2-31: the leaf's index (PB_SHPROBE_SPLIT_EMPTY: none)
                                  or the split's lower child (upper = lower + 1) */
} pb_shprobe;

/* Colours per probe record: pb_sh_count(max_band) for SH, 6 for an ambient cube. */
uint32_t pb_shprobe_colour_count(const pb_shprobe *probes);

/* Allocates a zeroed file image (grid filled with −1, scales 1, ambients = default 0.1, validity 1,
 * identity axes, positions allocated only if with_positions). grid_spacing is 0 and must be set
 * before writing. Free with pb_shprobe_destroy. */
pb_result pb_shprobe_create(uint32_t probe_count, uint32_t max_band, const uint32_t grid_dims[3], bool with_positions,
                            pb_shprobe **out, pb_error *err);

/* Probe index for an engine-space point: the grid cell holding it, −1 if outside or empty. */
int32_t pb_shprobe_lookup(const pb_shprobe *probes, const float point[3]);

void pb_shprobe_destroy(pb_shprobe *probes);

#ifdef __cplusplus
}
#endif

/* The rest of the API, one header per concern (pb_shprobe.h includes them all): */
#include "schnee/pb_shprobe_read.h"  /* pb_shprobe_read, _read_memory, _read_header */
#include "schnee/pb_shprobe_v3.h"    /* pb_shprobe_create_v3 */
#include "schnee/pb_shprobe_write.h" /* pb_shprobe_write */
#endif
