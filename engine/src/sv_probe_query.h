/* Per-object probe queries (DESIGN.md §7, docs/engine.md "Version 3 grids"): each object flagged
 * needs_probe gets the probe field at the centre of its world bounds: the blend of a grid's weighted
 * probes (visibility judged by sv_probe_vis.h) in its slot, or one probe's own entry.
 */
#ifndef SV_PROBE_QUERY_H
#define SV_PROBE_QUERY_H

#include <stdint.h>

#include "sv_probes.h"

/* Re-queries every object flagged needs_probe (centre of its world bounds); returns how many.
 * Dense grids (v1/v2, v3 structure 0): pb_grid_field_query at the centre (movable rule, no masks;
 * docs/grid-field.md "Per object"). Octree and tetrahedra grids: pb_interp_query_cotree / _tetra at the
 * centre with the file's validity. Both with one visibility judge: the segment probe (a dense grid's:
 * its cell's centre) -> centre through the static scene (objects never moved, without the queried object
 * itself) drops the probe. The weighted probes are blended into the object's slot; a dense grid's single
 * probe of weight 1 (at a cell centre) is given as its own buffer entry, unless probes->dense_slots. */
uint32_t sv_probes_assign(sv_probes *probes, sv_scene *scene);
/* The renderer left the file's probes off the GPU (docs/engine.md "Probe buffers"): from now on every object
 * on a dense grid reads its slot (a single probe of weight 1 too); re-queries those that named a file probe.
 * Returns how many. */
uint32_t sv_probes_use_slots(sv_probes *probes, sv_scene *scene);

#endif
