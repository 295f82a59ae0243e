/* Per-object probe queries (DESIGN.md §7, docs/engine.md "Version 3 grids"): each object flagged
 * needs_probe gets the probe at the centre of its world bounds: a dense grid's cell probe, or the
 * blend of a version 3 grid's interpolated probes (visibility judged by sv_probe_vis.h) in its slot.
 */
#ifndef SV_PROBE_QUERY_H
#define SV_PROBE_QUERY_H

#include <stdint.h>

#include "sv_probes.h"

/* Re-queries every object flagged needs_probe (centre of its world bounds); returns how many.
 * Dense grids (v1/v2, v3 structure 0): the probe of the cell holding the centre. Octree and
 * tetrahedra grids: pb_interp_query_cotree / _tetra at the centre with the file's validity and a
 * visibility judge that traces probe -> centre through the static scene (objects never moved,
 * without the queried object itself); the weighted probes are blended into the object's slot. */
uint32_t sv_probes_assign(sv_probes *probes, sv_scene *scene);

#endif
