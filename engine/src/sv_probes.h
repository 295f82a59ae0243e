/* Probe grids of a scene (DESIGN.md §5, §7): each shProbeGrids entry read with the bake's own
 * reader (pb_shprobe_read), packed into one GPU buffer whose index 0 is the fallback probe and
 * whose grids follow in glTF order; and the per-object query (first grid holding the point with a
 * valid cell wins, else 0).
 *
 * Files: sv_probes.c loading and lookup (this header), sv_probe_query.c the per-object queries,
 * sv_probe_vis.c the visibility through the static scene, sv_probe_pack.c the GPU packing.
 */
#ifndef SV_PROBES_H
#define SV_PROBES_H

#include <stdbool.h>
#include <stdint.h>

#include "schnee/pb_grid_field.h"
#include "schnee/pb_interp.h"
#include "schnee/pb_shprobe.h"
#include "sv_gpu.h"
#include "sv_scene.h"

/* Fallback probe (index 0): a uniform environment of this radiance in every channel, so an object
 * outside every grid gets E(n) = pi * radiance, i.e. diffuse = albedo * (shScale * radiance +
 * ambientTerm). The value is a neutral mid-dark grey; --fallback-radiance overrides it. */
#define SV_FALLBACK_RADIANCE 0.2f

/* Threads of the occluders' BVH builds (the static scene, the per-pixel visibility masks at load;
 * pb_occluder_desc.thread_count): min(online CPUs, this). */
#define SV_EMBREE_MAX_THREADS 4u

/* A .shprobe file larger than this is refused before it is read (1 GiB: about 2.5 M probes at
 * L = 4 with a 256^3 grid). */
#define SV_MAX_PROBE_FILE_BYTES (1ull << 30)

typedef struct sv_probe_grid {
    pb_shprobe *file;
    uint32_t base;    /* buffer index of the grid's probe 0 */
    uint32_t entries; /* buffer entries: the probes, then (octree) its hanging nodes resolved */
    const char *name; /* entry name (owned by the glTF) */
    pb_cotree *tree;  /* .shprobe v3 octree: the CPU interpolation (pb_interp_from_shprobe), else NULL */
    pb_tetra *tetra;  /* .shprobe v3 tetrahedra, else NULL */
} sv_probe_grid;

/* The last per-object query of an object whose probe came from a v3 grid (for --print-assignments). */
typedef struct sv_object_weights {
    uint32_t grid;                         /* grid index, UINT32_MAX = none */
    uint32_t count;                        /* probes with weight > 0 */
    uint32_t probe[PB_INTERP_MAX_WEIGHTS]; /* probe-buffer indices */
    float weight[PB_INTERP_MAX_WEIGHTS];
} sv_object_weights;

typedef struct sv_static_vis sv_static_vis;

typedef struct sv_probes {
    sv_probe_grid *grids;
    uint32_t grid_count;
    uint32_t total; /* fallback + every grid's entries (>= 1); the per-object slots follow */
    /* Per-object probes interpolated on the CPU from any grid (docs/engine.md "Version 3 grids"):
     * object o's slot is buffer entry total + o; allocated by the first sv_probes_assign. */
    uint32_t slot_count;
    sv_gpu_probe *slot_sh;  /* interpolated SH (scale folded in: params.y = 1, validity 1) */
    sv_gpu_cube *slot_cube; /* its ambient cube (fit of the SH, or blended cubes of a cube grid) */
    sv_object_weights *slot_weights;
    uint32_t slots_version; /* bumped whenever a slot changes (the renderer re-uploads) */
    /* For the §5 mismatch warning (docs/ambient-cube.md): the frame's overrides (SV_PROBE_MODE_MATERIAL
     * / SV_PROBE_REP_MATERIAL = each material's own) and which (material, grid) pairs were named. */
    uint32_t probe_mode_override, probe_rep_override;
    uint8_t *warned;        /* (material_count + 1) x grid_count */
    sv_static_vis *vis;     /* occluder of every object (sv_probe_vis.h), built at the first query;
                               hits on moved objects are ignored (docs/engine.md "Static scene") */
    uint32_t movable_seen;  /* movable objects at the last assignment (a change re-queries every object) */
    pb_grid_field **fields; /* per grid: a dense grid's field for per object (pb_grid_field, movable
                               rule, no masks), built at its first query; NULL elsewhere */
    bool dense_slots;       /* an object on a dense grid reads its slot even where one probe has all the
                               weight (the file's probes are not on the GPU: sv_probes_use_slots) */
} sv_probes;

/* Reads every grid of the scene. A file that cannot be read or is malformed is an error (message
 * names the grid and the file); an entry that disagrees with its file header is a warning (the
 * file is trusted). */
bool sv_probes_load(const sv_ext *ext, sv_probes *out);
void sv_probes_destroy(sv_probes *probes);

/* World-space centre of cell (x, y, z) of a grid: origin + sum_i (c_i + 0.5) * spacing * axis_i
 * (the GLSL twin is cell_centre() in shaders/gpu_types.glsl). */
void sv_cell_centre(const pb_shprobe *file, int x, int y, int z, float out[3]);
/* pb_grid_field_build on a dense grid file: its cells, coefficients (float64 copies, the file's colours),
 * validity, scale, origin, spacing and axes. Used by per object and by the per-pixel texture. */
pb_result sv_grid_field_build(const pb_shprobe *file, pb_grid_field **out, pb_error *err);

/* Buffer index for a world-space point (DESIGN.md §7). */
uint32_t sv_probes_lookup(const sv_probes *probes, const float point[3]);

/* The rest of the probe API, one header per concern (included here so that sv_probes.h still
 * declares all of it): */
#include "sv_probe_pack.h"  /* GPU buffers: SH, ambient cubes, half storage, per-pixel grids */
#include "sv_probe_query.h" /* per-object queries (sv_probes_assign) */
#include "sv_probe_vis.h"   /* visibility through the static scene (occluders of the core) */

#endif
