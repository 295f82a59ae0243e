/* _schnee_native's private header: what the module's files share (not installed, not exported).
 *
 * The module is one file per area of the core, each adding its functions with
 * PyModule_AddFunctions (module.c) and mirrored by one section of addon/schnee_probes/native.py:
 *
 *   module.c         the module (state, error class, init) and the argument helpers below
 *   mod_sh.c         pb_sh.h, pb_ambient_cube.h: basis, projection, irradiance, window, ambient cube
 *   mod_placement.c  pb_octree.h: place_probes, placement_classify
 *   mod_shprobe.c    pb_shprobe.h: .shprobe read, write (versions 1–3), lookup, dense resampling
 *   mod_interp.c     pb_interp.h, pb_refine.h: corner octree, tetrahedra, queries, refinement, metric
 *   mod_direct.c     pb_direct.h, pb_sky_sun.h: direct light of lamps, sky table, the sky's sun
 *   mod_bricks.c     pb_bricks.h: probe bricks (build, exact sampling, pool arrays)
 *   mod_grid_field.c pb_grid_field.h: the dense grid's field (weights, sample, texture form)
 *
 * Who checks what (validated once): native.py converts arguments (numpy dtype, C order) and checks
 * the shapes the C cannot see (a flat buffer has no shape) and the names of choices ("clamp",
 * "sinc4"); the C checks everything else once — buffer formats and item counts (memory safety),
 * value ranges (max_band, uint32 sizes, lengths, versions) — and the core checks the data. Helpers
 * set a Python exception and return -1 (int) or NULL (pointers).
 */
#ifndef SCHNEE_MOD_COMMON_H
#define SCHNEE_MOD_COMMON_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "schnee/pb_cotree.h"
#include "schnee/pb_octree.h"

#include <stdbool.h>
#include <stdint.h>

/* Capsule names of the interpolation handles (mod_interp.c makes them, mod_shprobe.c writes them). */
#define PB_PY_CAP_COTREE "schnee_probes.cotree"
#define PB_PY_CAP_TETRA  "schnee_probes.tetra"

/* The corner octree of a capsule made by mod_interp.c; NULL with a TypeError for anything else. */
pb_cotree *_pb_py_get_cotree(PyObject *o);

/* The methods of each area (NULL-terminated), added to the module by PyInit__schnee_native. */
extern PyMethodDef _pb_py_sh_methods[];
extern PyMethodDef _pb_py_placement_methods[];
extern PyMethodDef _pb_py_shprobe_methods[];
extern PyMethodDef _pb_py_interp_methods[];
extern PyMethodDef _pb_py_refine_methods[]; /* mod_refine.c: pb_refine.h tests, decisions, metric */
extern PyMethodDef _pb_py_direct_methods[];
extern PyMethodDef _pb_py_bricks_methods[];
extern PyMethodDef _pb_py_grid_field_methods[];

/* Raises the registered error class (native.SchneeError) with the core's message and `.code`.
 * Returns NULL. */
PyObject *_pb_py_raise_core(PyObject *module, pb_result r, const pb_error *err);

/* A held buffer; `view.obj == NULL` means none. */
typedef struct pb_py_buffer {
    Py_buffer view;
    Py_ssize_t count; /* number of items */
} pb_py_buffer;

void _pb_py_release(pb_py_buffer *b);

/* Gets a C-contiguous buffer of `code` items ('d', 'f', 'i', 'I', 'B'; native byte order) from obj.
 * multiple > 0: the item count must be a multiple of it; expected >= 0: the count must equal it. */
int _pb_py_get_buffer(PyObject *obj, const char *name, char code, Py_ssize_t multiple, Py_ssize_t expected,
                      pb_py_buffer *out);

/* Optional 3x3 rotation: None (or NULL) or 9 float64. */
int _pb_py_get_rotation(PyObject *obj, pb_py_buffer *out);

/* max_band in 0..PB_SH_MAX_BAND ("max_band 5 is out of range 0..4"). */
int _pb_py_check_band(long band);

/* v in 0..UINT32_MAX ("<name> <v> is out of range 0..4294967295"). */
int _pb_py_check_u32(Py_ssize_t v, const char *name, uint32_t *out);

/* a*b*c as Py_ssize_t, or -1 with ValueError when it overflows. */
Py_ssize_t _pb_py_product3(Py_ssize_t a, Py_ssize_t b, Py_ssize_t c, const char *what);

/* A new bytearray holding a copy of `size` bytes (native.py wraps it with np.frombuffer). */
PyObject *_pb_py_bytes_out(const void *data, size_t size);

/* d[key] = value, stealing value (NULL value = the error already set). -1 on error. */
int _pb_py_dict_put(PyObject *d, const char *key, PyObject *value);

/* A sequence of (name, vertices float64[V*3], triangles uint32[T*3]) meshes as core descs, the
 * buffers held until _pb_py_mesh_list_free (placement and direct light take the same meshes). */
typedef struct pb_py_meshes {
    Py_ssize_t count;
    pb_mesh_desc *desc;
    pb_py_buffer *verts, *tris;
    PyObject **items; /* strong references to the (name, verts, tris) items, kept alive */
} pb_py_meshes;

int _pb_py_mesh_list_get(PyObject *seq, const char *what, pb_py_meshes *m);
void _pb_py_mesh_list_free(pb_py_meshes *m);

#endif
