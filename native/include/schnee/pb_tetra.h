/* Schnee probes — Delaunay tetrahedra of probe positions (qhull), barycentric inside each
 * tetrahedron; point location (pb_interp.h) through a uniform grid of tetrahedron bounds.
 *
 * How to use it: pb_tetra_create() from probe positions (or pb_tetra_create_from() a file's
 * tetrahedra), query with pb_interp_query_tetra() (pb_interp.h), pb_tetra_destroy().
 * Coordinates: engine space, metres, double.
 * Part of pb_interp.h (include either); source native/src/pb_tetra.c.
 */
#ifndef SCHNEE_PB_TETRA_H
#define SCHNEE_PB_TETRA_H

#include "schnee/pb_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- tetrahedra ----------------------------------------------------------------------------------- */

typedef struct pb_tetra pb_tetra;

/* Delaunay tetrahedralisation of `count` positions (count × 3) with qhull ("d Qt Qbb Qz"; lattice
 * points are cospherical, Qt triangulates and zero-volume tetrahedra are dropped from point location).
 * Fails with a message for fewer than 4 points or coplanar input. */
pb_result pb_tetra_create(const double *positions, uint32_t count, pb_tetra **out, pb_error *err);
/* A structure from explicit tetrahedra (a file's): 4 vertex indices each; neighbours are rebuilt. */
pb_result pb_tetra_create_from(const double *positions, uint32_t count, const uint32_t *tets, uint32_t tet_count,
                               pb_tetra **out, pb_error *err);
void pb_tetra_destroy(pb_tetra *tetra);
uint32_t pb_tetra_count(const pb_tetra *tetra);
uint32_t pb_tetra_point_count(const pb_tetra *tetra);      /* probes it was built from */
const uint32_t *pb_tetra_tets(const pb_tetra *tetra);      /* tet_count × 4 probe indices */
const int32_t *pb_tetra_neighbours(const pb_tetra *tetra); /* tet_count × 4: neighbour opposite vertex i, or −1 */
/* Tetrahedron holding the point, or −1 (outside the convex hull). */

#ifdef __cplusplus
}
#endif
#endif
