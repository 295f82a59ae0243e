/* Probe grids of a scene (DESIGN.md §5, §7): each shProbeGrids entry read with the bake's own
 * reader (pb_shprobe_read), packed into one GPU buffer whose index 0 is the fallback probe and
 * whose grids follow in glTF order; and the per-object query (first grid holding the point with a
 * valid cell wins, else 0).
 */
#ifndef SV_PROBES_H
#define SV_PROBES_H

#include <stdbool.h>
#include <stdint.h>

#include "schnee/pb_shprobe.h"
#include "sv_gpu.h"
#include "sv_scene.h"

/* Fallback probe (index 0): a uniform environment of this radiance in every channel, so an object
 * outside every grid gets E(n) = pi * radiance, i.e. diffuse = albedo * (shScale * radiance +
 * ambientTerm). The value is a neutral mid-dark grey; --fallback-radiance overrides it. */
#define SV_FALLBACK_RADIANCE 0.2f

/* Threads of the Embree device that computes the per-pixel visibility masks at load
 * (rtcNewDevice "threads=N"): min(online CPUs, this). */
#define SV_EMBREE_MAX_THREADS 4u

/* A .shprobe file larger than this is refused before it is read (1 GiB: about 2.5 M probes at
 * L = 4 with a 256^3 grid). */
#define SV_MAX_PROBE_FILE_BYTES (1ull << 30)

typedef struct sv_probe_grid {
    pb_shprobe *file;
    uint32_t base;    /* buffer index of the grid's probe 0 */
    const char *name; /* entry name (owned by the glTF) */
} sv_probe_grid;

typedef struct sv_probes {
    sv_probe_grid *grids;
    uint32_t grid_count;
    uint32_t total; /* probes in the buffer, fallback included (>= 1) */
} sv_probes;

/* Reads every grid of the scene. A file that cannot be read or is malformed is an error (message
 * names the grid and the file); an entry that disagrees with its file header is a warning (the
 * file is trusted). */
bool sv_probes_load(const sv_ext *ext, sv_probes *out);
void sv_probes_destroy(sv_probes *probes);

/* World-space centre of cell (x, y, z) of a grid: origin + sum_i (c_i + 0.5) * spacing * axis_i
 * (the GLSL twin is cell_centre() in shaders/gpu_types.glsl). */
void sv_cell_centre(const pb_shprobe *file, int x, int y, int z, float out[3]);

/* Buffer index for a world-space point (DESIGN.md §7). */
uint32_t sv_probes_lookup(const sv_probes *probes, const float point[3]);

/* Re-queries every object flagged needs_probe (centre of its world bounds); returns how many. */
uint32_t sv_probes_assign(const sv_probes *probes, sv_scene *scene);

/* GPU buffer contents: total entries, caller frees. Probe 0 (the fallback) is `sky_sh` (band
 * `sky_band`, radiance SH) when sky_sh is not NULL, else uniform `fallback_radiance`. */
sv_gpu_probe *sv_probes_pack(const sv_probes *probes, float fallback_radiance, const float (*sky_sh)[3],
                             uint32_t sky_band);
/* The same entries in half storage (packHalf2x16 layout of sv_gpu_probe_half). Caller frees. */
sv_gpu_probe_half *sv_probes_pack_half(const sv_gpu_probe *packed, uint32_t count);
/* True when every coefficient and scale of the packed probes fits half floats (|v| <= 65504, the
 * largest finite binary16); else false with a message naming the first grid and probe that does
 * not (or the fallback probe, the sky's SH) and the value. */
#define SV_HALF_MAX 65504.0f
bool sv_probes_fit_half(const sv_probes *probes, const sv_gpu_probe *packed, char *msg, size_t cap);
/* IEEE 754 binary16 of a float (round to nearest even), as GLSL's packHalf2x16 stores it. */
uint16_t sv_half_from_float(float f);

/* Ambient cubes of the packed probes (docs/ambient-cube.md §5): each probe's SH fitted by
 * pb_ambient_cube_from_sh (PB_AMBIENT_CUBE_LEAST_SQUARES), params copied (band, scale, validity).
 * Same indexing as `packed` (0 = the fallback, from the sky's SH or the constant). Caller frees. */
sv_gpu_cube *sv_probes_pack_cubes(const sv_gpu_probe *packed, uint32_t count);
/* The same cubes in half storage (packHalf2x16 layout of sv_gpu_cube_half). Caller frees. */
sv_gpu_cube_half *sv_probes_pack_cubes_half(const sv_gpu_cube *cubes, uint32_t count);
/* As sv_probes_fit_half for the cube colours (a cube colour can exceed the SH coefficients it came
 * from: C = 0.886 L0 + ...). */
bool sv_probes_cubes_fit_half(const sv_probes *probes, const sv_gpu_cube *cubes, char *msg, size_t cap);

/* Per-pixel sampling data: one sv_gpu_grid per grid and the concatenated occupancy grids (n
 * int32 cell -> probe indices) followed by one neighbour-visibility mask per cell (n uint32, grid
 * g's at base[1]; *cell_count = 2n). The masks come from Embree occlusion rays between cell centres
 * through `scene`'s triangles at their current transforms (NULL: every neighbour visible); see
 * docs/engine.md "Per-pixel probes". Caller frees both. */
bool sv_probes_gpu_grids(const sv_probes *probes, const sv_scene *scene, sv_gpu_grid **grids, int32_t **cells,
                         uint32_t *cell_count);

/* One sphere per probe (at its v2 position, else the mean centre of the cells that map to it;
 * radius 0.1 x the grid spacing), then one entry per occupied cell (its centre, for the
 * outlines). Caller frees. */
sv_gpu_cell *sv_probes_cells(const sv_probes *probes, uint32_t *sphere_count, uint32_t *cell_count);

#endif
