/* Probe bricks' anti-leak data (docs/probe-bricks.md "Back faces and visibility", step 5 of the sampling
 * rule; --probe-path bricks): the bricks of every octree / kd grid are built with the static scene's
 * tracer (sv_segment_first_hit over sv_static_occluder, the segment function of the leaves' tables), so
 * the core traces the leaves' pair tables, computes the visibility texels and one 64-B record per blocked
 * brick cell. This module uploads the core's brick tables and records as one storage buffer
 * (SV_BINDING_BRICK_VIS, uint[]):
 *   rows     4 uint per brick, the grids' bricks one after another (grid order): x = the uint offset in
 *            this buffer of the brick's first record, y / z = its blocked-cell bits (pb_bricks_table);
 *   records  16 uint per record (pb_bricks_vis_records: byte 8k + c, read with gpu pair_vis()).
 * Each indirection entry with a brick gets w = its brick's row (the core leaves w = 0, reserved), so the
 * shader finds the row without a per-grid offset. A storage buffer, not a texture: the data are read
 * unfiltered at computed offsets, one row and then at most one record per fragment, like the leaves'
 * tables the buffers path reads from the cell buffer. */
#ifndef SV_BRICKS_VIS_H
#define SV_BRICKS_VIS_H

#include "schnee/pb_bricks.h"
#include "sv_renderer.h"

typedef struct sv_bricks_vis {
    const sv_scene *scene;
    bool tried;        /* the tracer was asked for (the first tree grid's build) */
    pb_occluder *occ;  /* the static scene (NULL: no object, no triangle: plain bricks) */
    uint64_t segments; /* calls of the segment function so far (all grids) */
    double t0;         /* sv_now_ms() when the tracer was made */
    size_t triangles;
} sv_bricks_vis;

/* Remembers the scene; its tracer is made at the first sv_bricks_vis_desc (none without triangles). */
void sv_bricks_vis_begin(sv_bricks_vis *v, const sv_scene *scene);
/* Sets d->segment / segment_user to the tracer (left NULL without one), making it the first time. */
void sv_bricks_vis_desc(sv_bricks_vis *v, pb_bricks_desc *d);
/* Sets w of each entry of the combined indirection (index, dims: the grids' indirection grids along z,
 * bricked grids in order) to its brick's row, uploads the rows and records into r->brick_vis and prints
 * the record count and the build time (nothing printed without a bricked grid). b: grid_count entries,
 * NULL where the grid is not bricked. */
bool sv_bricks_vis_upload(sv_renderer *r, sv_bricks_vis *v, pb_bricks *const *b, uint32_t grid_count, uint32_t *index,
                          const uint32_t dims[3]);
/* A one-row stand-in (the binding must hold a buffer when the bricks are off). */
bool sv_bricks_vis_standin(sv_renderer *r);
void sv_bricks_vis_end(sv_bricks_vis *v);

#endif
