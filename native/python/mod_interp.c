/* _schnee_native: Interpolation on probe positions (pb_interp.h: corner octree, tetrahedra, queries) and error-driven
 * refinement's tree (its bindings: mod_refine.c); handles are capsules;
 * native.py "interpolation" section. */
#include "mod_common.h"

#include "schnee/pb_interp.h"
#include "schnee/pb_refine.h"
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"

#include <stdlib.h>
#include <string.h>

/* ---- interpolation and refinement (issue 12) ---------------------------------------------------- */

static void cotree_capsule_free(PyObject *cap) { pb_cotree_destroy(PyCapsule_GetPointer(cap, PB_PY_CAP_COTREE)); }
static void tetra_capsule_free(PyObject *cap) { pb_tetra_destroy(PyCapsule_GetPointer(cap, PB_PY_CAP_TETRA)); }

pb_cotree *_pb_py_get_cotree(PyObject *o)
{
    if (!PyCapsule_IsValid(o, PB_PY_CAP_COTREE)) {
        PyErr_SetString(PyExc_TypeError, "expected a corner octree handle (from cotree_create)");
        return NULL;
    }
    return PyCapsule_GetPointer(o, PB_PY_CAP_COTREE);
}

static PyObject *cotree_capsule(pb_cotree *t)
{
    PyObject *cap = PyCapsule_New(t, PB_PY_CAP_COTREE, cotree_capsule_free);
    if (!cap) pb_cotree_destroy(t);
    return cap;
}

static PyObject *tetra_capsule(pb_tetra *t)
{
    PyObject *cap = PyCapsule_New(t, PB_PY_CAP_TETRA, tetra_capsule_free);
    if (!cap) pb_tetra_destroy(t);
    return cap;
}

static int get_dims(const Py_ssize_t in[3], uint32_t out[3])
{
    for (int i = 0; i < 3; i++)
        if (_pb_py_check_u32(in[i], "dims entry", &out[i]) < 0) return -1;
    return 0;
}

static PyObject *py_cotree_create(PyObject *module, PyObject *args)
{
    double origin[3], cell;
    Py_ssize_t level, dims_in[3];
    uint32_t dims[3], lv;
    if (!PyArg_ParseTuple(args, "(ddd)dn(nnn):cotree_create", &origin[0], &origin[1], &origin[2], &cell, &level,
                          &dims_in[0], &dims_in[1], &dims_in[2]) ||
        get_dims(dims_in, dims) < 0 || _pb_py_check_u32(level, "root_level", &lv) < 0)
        return NULL;
    pb_cotree *t = NULL;
    pb_error err = {0};
    pb_result r = pb_cotree_create(origin, cell, lv, dims, &t, &err);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return cotree_capsule(t);
}

static PyObject *py_cotree_from_leaves(PyObject *module, PyObject *args)
{
    double origin[3], cell;
    Py_ssize_t dims_in[3];
    uint32_t dims[3];
    PyObject *l_obj;
    if (!PyArg_ParseTuple(args, "(ddd)d(nnn)O:cotree_from_leaves", &origin[0], &origin[1], &origin[2], &cell,
                          &dims_in[0], &dims_in[1], &dims_in[2], &l_obj) ||
        get_dims(dims_in, dims) < 0)
        return NULL;
    pb_py_buffer leaves;
    if (_pb_py_get_buffer(l_obj, "leaves", 'I', 4, -1, &leaves) < 0) return NULL;
    pb_cotree *t = NULL;
    pb_error err = {0};
    pb_result r = leaves.count / 4 > UINT32_MAX ? PB_ERROR_TOO_LARGE : PB_SUCCESS;
    if (r == PB_SUCCESS)
        r = pb_cotree_create_leaves(origin, cell, dims, leaves.view.buf, (uint32_t)(leaves.count / 4), &t, &err);
    _pb_py_release(&leaves);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return cotree_capsule(t);
}

static PyObject *py_cotree_from_boxes(PyObject *module, PyObject *args)
{
    double origin[3], cell;
    Py_ssize_t level, dims_in[3];
    uint32_t dims[3], lv;
    PyObject *l_obj;
    if (!PyArg_ParseTuple(args, "(ddd)dn(nnn)O:cotree_from_boxes", &origin[0], &origin[1], &origin[2], &cell, &level,
                          &dims_in[0], &dims_in[1], &dims_in[2], &l_obj) ||
        get_dims(dims_in, dims) < 0 || _pb_py_check_u32(level, "root_level", &lv) < 0)
        return NULL;
    pb_py_buffer leaves;
    if (_pb_py_get_buffer(l_obj, "leaves", 'I', 4, -1, &leaves) < 0) return NULL;
    pb_cotree *t = NULL;
    pb_error err = {0};
    pb_result r = leaves.count / 4 > UINT32_MAX ? PB_ERROR_TOO_LARGE : PB_SUCCESS;
    if (r == PB_SUCCESS)
        r = pb_cotree_create_boxes(origin, cell, lv, dims, leaves.view.buf, (uint32_t)(leaves.count / 4), &t, &err);
    _pb_py_release(&leaves);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return cotree_capsule(t);
}

/* cotree_split / cotree_split_axes / cotree_drop: flags (axis masks) = uint8[leaf_count]. */
enum { FLAGS_SPLIT, FLAGS_SPLIT_AXES, FLAGS_DROP };
static PyObject *cotree_flags_op(PyObject *module, PyObject *args, int op)
{
    PyObject *t_obj, *f_obj;
    if (!PyArg_ParseTuple(args, "OO", &t_obj, &f_obj)) return NULL;
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    pb_py_buffer flags;
    if (_pb_py_get_buffer(f_obj, op == FLAGS_SPLIT_AXES ? "axes" : "flags", 'B', 0, pb_cotree_leaf_count(t), &flags) <
        0)
        return NULL;
    pb_error err = {0};
    uint32_t n = 0;
    pb_result r = op == FLAGS_SPLIT        ? pb_cotree_split(t, flags.view.buf, &n, &err)
                  : op == FLAGS_SPLIT_AXES ? pb_cotree_split_axes(t, flags.view.buf, &n, &err)
                                           : pb_cotree_drop(t, flags.view.buf, &err);
    _pb_py_release(&flags);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return PyLong_FromUnsignedLong(n);
}

static PyObject *py_cotree_split(PyObject *module, PyObject *args)
{
    return cotree_flags_op(module, args, FLAGS_SPLIT);
}
static PyObject *py_cotree_split_axes(PyObject *module, PyObject *args)
{
    return cotree_flags_op(module, args, FLAGS_SPLIT_AXES);
}
static PyObject *py_cotree_drop(PyObject *module, PyObject *args) { return cotree_flags_op(module, args, FLAGS_DROP); }

/* cotree_split_tree(tree) -> bytearray uint32[K]: the canonical split tree (pb_cotree_split_tree). */
static PyObject *py_cotree_split_tree(PyObject *module, PyObject *t_obj)
{
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    pb_error err = {0};
    uint32_t k = 0;
    pb_result r = pb_cotree_split_tree(t, NULL, 0, &k, &err);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    PyObject *out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)k * 4);
    if (!out) return NULL;
    r = pb_cotree_split_tree(t, (uint32_t *)(void *)PyByteArray_AsString(out), k, &k, &err);
    if (r != PB_SUCCESS) {
        Py_DECREF(out);
        return _pb_py_raise_core(module, r, &err);
    }
    return out;
}

/* cotree_locate(tree, points float64[N*3]) -> bytearray int32[N]: the leaf holding each point, −1 none. */
static PyObject *py_cotree_locate(PyObject *module, PyObject *args)
{
    PyObject *t_obj, *p_obj;
    if (!PyArg_ParseTuple(args, "OO:cotree_locate", &t_obj, &p_obj)) return NULL;
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    pb_py_buffer pts;
    if (_pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    Py_ssize_t n = pts.count / 3;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * 4);
    if (out) {
        int32_t *o = (int32_t *)(void *)PyByteArray_AsString(out);
        const double *pp = pts.view.buf;
        for (Py_ssize_t i = 0; i < n; i++) o[i] = pb_cotree_locate(t, pp + 3 * i);
    }
    _pb_py_release(&pts);
    return out;
}

static PyObject *py_cotree_finalize(PyObject *module, PyObject *t_obj)
{
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_cotree_finalize(t, &err);
    Py_END_ALLOW_THREADS if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    Py_RETURN_NONE;
}

static PyObject *py_cotree_info(PyObject *module, PyObject *t_obj)
{
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    double origin[3], cell;
    uint32_t dims[3];
    pb_cotree_frame(t, origin, &cell, dims);
    size_t L = pb_cotree_leaf_count(t), P = pb_cotree_probe_count(t), H = pb_cotree_hanging_count(t);
    bool fin = pb_cotree_probe_lattice(t) != NULL;
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    PyObject *pos = NULL, *corners = NULL, *src = NULL, *w = NULL;
    PyObject *levels = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(L * 3 * sizeof(uint32_t)));
    if (levels) pb_cotree_leaf_levels(t, (uint32_t *)(void *)PyByteArray_AsString(levels));
    if (fin) {
        pos = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(P * 3 * sizeof(double)));
        corners = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(L * 8 * sizeof(int32_t)));
        src = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(H * 4 * sizeof(uint32_t)));
        w = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(H * 4 * sizeof(float)));
        if (pos && corners && src && w) {
            pb_cotree_probe_positions(t, (double *)(void *)PyByteArray_AsString(pos));
            pb_cotree_leaf_corners(t, (int32_t *)(void *)PyByteArray_AsString(corners));
            pb_cotree_hanging_rules(t, (uint32_t *)(void *)PyByteArray_AsString(src),
                                    (float *)(void *)PyByteArray_AsString(w));
        }
    } else {
        pos = Py_NewRef(Py_None), corners = Py_NewRef(Py_None), src = Py_NewRef(Py_None), w = Py_NewRef(Py_None);
    }
    if (_pb_py_dict_put(d, "origin", Py_BuildValue("(ddd)", origin[0], origin[1], origin[2])) < 0 ||
        _pb_py_dict_put(d, "min_cell", PyFloat_FromDouble(cell)) < 0 ||
        _pb_py_dict_put(d, "dims", Py_BuildValue("(III)", dims[0], dims[1], dims[2])) < 0 ||
        _pb_py_dict_put(d, "finalized", PyBool_FromLong(fin)) < 0 ||
        _pb_py_dict_put(d, "leaves", _pb_py_bytes_out(pb_cotree_leaves(t), L * 4 * sizeof(uint32_t))) < 0 ||
        _pb_py_dict_put(d, "levels", levels) < 0 ||
        _pb_py_dict_put(d, "root_level", PyLong_FromUnsignedLong(pb_cotree_root_level(t))) < 0 ||
        _pb_py_dict_put(d, "forced_splits", PyLong_FromUnsignedLong(pb_cotree_forced_splits(t))) < 0 ||
        _pb_py_dict_put(d, "probe_count", PyLong_FromSize_t(P)) < 0 ||
        _pb_py_dict_put(d, "hanging_count", PyLong_FromSize_t(H)) < 0 ||
        _pb_py_dict_put(d, "probe_lattice",
                        fin ? _pb_py_bytes_out(pb_cotree_probe_lattice(t), P * 3 * sizeof(uint32_t))
                            : Py_NewRef(Py_None)) < 0 ||
        _pb_py_dict_put(d, "positions", pos) < 0 || _pb_py_dict_put(d, "leaf_corners", corners) < 0 ||
        _pb_py_dict_put(d, "hanging_sources", src) < 0 || _pb_py_dict_put(d, "hanging_weights", w) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

static PyObject *py_tetra_create(PyObject *module, PyObject *args)
{
    PyObject *p_obj;
    if (!PyArg_ParseTuple(args, "O:tetra_create", &p_obj)) return NULL;
    pb_py_buffer pos;
    if (_pb_py_get_buffer(p_obj, "positions", 'd', 3, -1, &pos) < 0) return NULL;
    pb_tetra *t = NULL;
    pb_error err = {0};
    pb_result r = pos.count / 3 > UINT32_MAX ? PB_ERROR_TOO_LARGE : PB_SUCCESS;
    if (r == PB_SUCCESS) {
        Py_BEGIN_ALLOW_THREADS r = pb_tetra_create(pos.view.buf, (uint32_t)(pos.count / 3), &t, &err);
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&pos);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return tetra_capsule(t);
}

static PyObject *py_tetra_info(PyObject *module, PyObject *t_obj)
{
    if (!PyCapsule_IsValid(t_obj, PB_PY_CAP_TETRA)) {
        PyErr_SetString(PyExc_TypeError, "expected a tetrahedra handle (from tetra_create)");
        return NULL;
    }
    pb_tetra *t = PyCapsule_GetPointer(t_obj, PB_PY_CAP_TETRA);
    size_t n = pb_tetra_count(t);
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    if (_pb_py_dict_put(d, "tets", _pb_py_bytes_out(pb_tetra_tets(t), n * 16)) < 0 ||
        _pb_py_dict_put(d, "neighbours", _pb_py_bytes_out(pb_tetra_neighbours(t), n * 16)) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

/* interp_query(handle, points float64[N*3], validity float32[P] or None) ->
 * (probes int32[N*K], weights float64[N*K], K): K = most weights any point got; unused: −1 / 0. */
static PyObject *py_interp_query(PyObject *module, PyObject *args)
{
    PyObject *h_obj, *p_obj, *v_obj = Py_None, *pv_obj = Py_None;
    if (!PyArg_ParseTuple(args, "OO|OO:interp_query", &h_obj, &p_obj, &v_obj, &pv_obj)) return NULL;
    pb_cotree *tree = PyCapsule_IsValid(h_obj, PB_PY_CAP_COTREE) ? PyCapsule_GetPointer(h_obj, PB_PY_CAP_COTREE) : NULL;
    pb_tetra *tetra = PyCapsule_IsValid(h_obj, PB_PY_CAP_TETRA) ? PyCapsule_GetPointer(h_obj, PB_PY_CAP_TETRA) : NULL;
    if (!tree && !tetra) {
        PyErr_SetString(PyExc_TypeError, "expected a corner octree or tetrahedra handle");
        return NULL;
    }
    if (tree && !pb_cotree_probe_lattice(tree)) {
        PyErr_SetString(PyExc_ValueError, "the corner octree is not finalized (call cotree_finalize)");
        return NULL;
    }
    pb_py_buffer pts, val = {0};
    if (_pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    Py_ssize_t probe_count = tree ? (Py_ssize_t)pb_cotree_probe_count(tree) : (Py_ssize_t)pb_tetra_point_count(tetra);
    if (v_obj != Py_None && _pb_py_get_buffer(v_obj, "validity", 'f', 0, probe_count, &val) < 0) {
        _pb_py_release(&pts);
        return NULL;
    }
    pb_py_buffer pvis = {0};
    if (pv_obj != Py_None) {
        if (!tree) {
            PyErr_SetString(PyExc_ValueError, "pair_visibility is for corner octrees only");
        } else {
            (void)_pb_py_get_buffer(pv_obj, "pair_visibility", 'B', 0, 64 * (Py_ssize_t)pb_cotree_leaf_count(tree),
                                    &pvis);
        }
        if (PyErr_Occurred()) {
            _pb_py_release(&pts);
            _pb_py_release(&val);
            return NULL;
        }
    }
    Py_ssize_t n = pts.count / 3;
    pb_interp_weights *w = malloc(((size_t)n + 1) * sizeof *w);
    if (!w) {
        _pb_py_release(&pts);
        _pb_py_release(&val);
        _pb_py_release(&pvis);
        return PyErr_NoMemory();
    }
    pb_interp_options opt = {.validity = val.view.obj ? val.view.buf : NULL,
                             .pair_visibility = pvis.view.obj ? pvis.view.buf : NULL};
    const double *pp = pts.view.buf;
    uint32_t K = 1;
    Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < n; i++)
    {
        if (tree)
            pb_interp_query_cotree(tree, pp + 3 * i, &opt, w + i);
        else
            pb_interp_query_tetra(tetra, pp + 3 * i, &opt, w + i);
        if (w[i].count > K) K = w[i].count;
    }
    Py_END_ALLOW_THREADS _pb_py_release(&pts);
    _pb_py_release(&val);
    _pb_py_release(&pvis);
    PyObject *po = PyByteArray_FromStringAndSize(NULL, n * (Py_ssize_t)K * 4);
    PyObject *wo = PyByteArray_FromStringAndSize(NULL, n * (Py_ssize_t)K * 8);
    if (!po || !wo) {
        free(w);
        Py_XDECREF(po);
        Py_XDECREF(wo);
        return NULL;
    }
    int32_t *pr = (int32_t *)(void *)PyByteArray_AsString(po);
    double *wt = (double *)(void *)PyByteArray_AsString(wo);
    for (Py_ssize_t i = 0; i < n; i++)
        for (uint32_t k = 0; k < K; k++) {
            bool used = k < w[i].count;
            pr[i * K + k] = used ? (int32_t)w[i].probe[k] : -1;
            wt[i * K + k] = used ? w[i].weight[k] : 0.0;
        }
    free(w);
    return Py_BuildValue("(NNI)", po, wo, K);
}

static PyObject *py_interp_from_file(PyObject *module, PyObject *args)
{
    PyObject *path = NULL;
    if (!PyArg_ParseTuple(args, "O&:interp_from_file", PyUnicode_FSConverter, &path)) return NULL;
    pb_shprobe *f = NULL;
    pb_error err = {0};
    pb_cotree *tree = NULL;
    pb_tetra *tetra = NULL;
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_shprobe_read(PyBytes_AsString(path), &f, &err);
    if (r == PB_SUCCESS) r = pb_interp_from_shprobe(f, &tree, &tetra, &err);
    Py_END_ALLOW_THREADS Py_DECREF(path);
    pb_shprobe_destroy(f);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return tree ? cotree_capsule(tree) : tetra_capsule(tetra);
}

PyMethodDef _pb_py_interp_methods[] = {
    {"cotree_create", py_cotree_create, METH_VARARGS,
     "cotree_create(origin, min_cell, root_level, root_dims) -> corner octree handle (not finalized)"},
    {"cotree_from_leaves", py_cotree_from_leaves, METH_VARARGS,
     "cotree_from_leaves(origin, min_cell, dims, leaves: uint32[N*4]) -> handle"},
    {"cotree_from_boxes", py_cotree_from_boxes, METH_VARARGS,
     "cotree_from_boxes(origin, min_cell, root_level, dims, leaves: uint32[N*4] (x, y, z, PB_LEVELS_PACK)) -> handle"},
    {"cotree_split", py_cotree_split, METH_VARARGS, "cotree_split(tree, flags: uint8[leaves]) -> leaves split"},
    {"cotree_split_axes", py_cotree_split_axes, METH_VARARGS,
     "cotree_split_axes(tree, axes: uint8[leaves], bit 0/1/2 = x/y/z) -> leaves split"},
    {"cotree_split_tree", py_cotree_split_tree, METH_O, "cotree_split_tree(tree) -> bytearray uint32[K]"},
    {"cotree_locate", py_cotree_locate, METH_VARARGS,
     "cotree_locate(tree, points: float64[N*3]) -> bytearray int32[N]"},
    {"cotree_drop", py_cotree_drop, METH_VARARGS, "cotree_drop(tree, flags: uint8[leaves]) -> 0"},
    {"cotree_finalize", py_cotree_finalize, METH_O, "cotree_finalize(tree): number probes, hanging rules"},
    {"cotree_info", py_cotree_info, METH_O, "cotree_info(tree) -> dict (leaves, probes, positions, rules)"},
    {"tetra_create", py_tetra_create, METH_VARARGS, "tetra_create(positions: float64[P*3]) -> tetrahedra handle"},
    {"tetra_info", py_tetra_info, METH_O, "tetra_info(tetra) -> dict (tets, neighbours)"},
    {"interp_query", py_interp_query, METH_VARARGS,
     "interp_query(handle, points: float64[N*3], validity=None, pair_visibility=None) -> (int32[N*K], float64[N*K], K)"},
    {"interp_from_file", py_interp_from_file, METH_VARARGS, "interp_from_file(path) -> handle of the file's structure"},
    {NULL, NULL, 0, NULL},
};
