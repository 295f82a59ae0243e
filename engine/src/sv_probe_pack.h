/* GPU packing of the probe grids (DESIGN.md §7, docs/ambient-cube.md, docs/engine.md "Per-pixel
 * probes"): the probe buffer (SH or ambient cubes, full or half storage), the per-pixel grids with
 * their visibility masks, and the debug spheres.
 */
#ifndef SV_PROBE_PACK_H
#define SV_PROBE_PACK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "sv_probes.h"

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
/* As sv_probes_pack_cubes for `probes->total` entries, with the entries of grids whose file holds
 * ambient cubes (v3 representation 1) taken from the file (hanging nodes resolved as for the SH). */
sv_gpu_cube *sv_probes_pack_all_cubes(const sv_probes *probes, const sv_gpu_probe *packed);
/* One entry in half storage (the layouts of sv_probes_pack_half / _cubes_half). */
void sv_probe_to_half(const sv_gpu_probe *in, sv_gpu_probe_half *out);
void sv_cube_to_half(const sv_gpu_cube *in, sv_gpu_cube_half *out);
/* True when some grid's file holds ambient cubes only. */
bool sv_probes_have_cube_grids(const sv_probes *probes);
/* The same cubes in half storage (packHalf2x16 layout of sv_gpu_cube_half). Caller frees. */
sv_gpu_cube_half *sv_probes_pack_cubes_half(const sv_gpu_cube *cubes, uint32_t count);
/* As sv_probes_fit_half for the cube colours (a cube colour can exceed the SH coefficients it came
 * from: C = 0.886 L0 + ...). */
bool sv_probes_cubes_fit_half(const sv_probes *probes, const sv_gpu_cube *cubes, char *msg, size_t cap);

/* Per-pixel sampling data: one sv_gpu_grid per grid and the concatenated occupancy grids (n
 * int32 cell -> probe indices) followed by one neighbour-visibility mask per cell (n uint32, grid
 * g's at base[1]; *cell_count = 2n). The masks come from occlusion rays (sv_probe_vis.h) between cell centres
 * through `scene`'s triangles at their current transforms (NULL: every neighbour visible); see
 * docs/engine.md "Per-pixel probes". Caller frees both. */
bool sv_probes_gpu_grids(const sv_probes *probes, const sv_scene *scene, sv_gpu_grid **grids, int32_t **cells,
                         uint32_t *cell_count);

/* One sphere per probe (at its v2 position, else the mean centre of the cells that map to it;
 * radius 0.1 x the grid spacing), then one outline per occupied cell (its centre) and per leaf of an
 * octree or kd tree grid (its box: centre, packed levels in probe.z). Caller frees. */
sv_gpu_cell *sv_probes_cells(const sv_probes *probes, uint32_t *sphere_count, uint32_t *cell_count);

#endif
