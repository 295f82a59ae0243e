/* _schnee_native: probe bricks (pb_bricks.h, docs/probe-bricks.md): build from a corner octree handle,
 * exact sampling, the arrays for an upload; handles are capsules; native.py "probe bricks" section. */
#include "mod_common.h"

#include "schnee/pb_bricks.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PB_PY_CAP_BRICKS "schnee_probes.bricks"

static void bricks_capsule_free(PyObject *cap) { pb_bricks_destroy(PyCapsule_GetPointer(cap, PB_PY_CAP_BRICKS)); }

static pb_bricks *get_bricks(PyObject *o)
{
    if (!PyCapsule_IsValid(o, PB_PY_CAP_BRICKS)) {
        PyErr_SetString(PyExc_TypeError, "expected a probe bricks handle (from bricks_build)");
        return NULL;
    }
    return PyCapsule_GetPointer(o, PB_PY_CAP_BRICKS);
}

/* The static scene of a test: infinite planes n·p = d (4 doubles each) and triangles (9 doubles each,
 * both sides): the first crossing of a -> b as a fraction of its length (pb_segment_fn). A segment that
 * only touches a plane is clear; a triangle counts for fractions in [1e-4, 1 − 1e-4] (the engine's
 * sv_segment_first_hit's tnear / tfar), Möller–Trumbore in double. */
typedef struct planes {
    const double *p;
    Py_ssize_t count;
    const double *tri;
    Py_ssize_t tri_count;
} planes;

static double tri_hit(const double *v, const double a[3], const double d[3])
{
    double e1[3], e2[3], pv[3], tv[3], qv[3];
    for (int k = 0; k < 3; k++) {
        e1[k] = v[3 + k] - v[k];
        e2[k] = v[6 + k] - v[k];
        tv[k] = a[k] - v[k];
    }
    pv[0] = d[1] * e2[2] - d[2] * e2[1];
    pv[1] = d[2] * e2[0] - d[0] * e2[2];
    pv[2] = d[0] * e2[1] - d[1] * e2[0];
    double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (det == 0.0) return 2.0;
    double su = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
    if (su < 0.0 || su > 1.0) return 2.0;
    qv[0] = tv[1] * e1[2] - tv[2] * e1[1];
    qv[1] = tv[2] * e1[0] - tv[0] * e1[2];
    qv[2] = tv[0] * e1[1] - tv[1] * e1[0];
    double sv = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
    if (sv < 0.0 || su + sv > 1.0) return 2.0;
    return (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
}

static double planes_segment(void *user, const double a[3], const double b[3])
{
    const planes *pl = user;
    double t = 1.0;
    for (Py_ssize_t i = 0; i < pl->count; i++) {
        const double *q = pl->p + 4 * i;
        double sa = q[0] * a[0] + q[1] * a[1] + q[2] * a[2] - q[3], sb = q[0] * b[0] + q[1] * b[1] + q[2] * b[2] - q[3];
        if (sa * sb < 0.0 && sa / (sa - sb) < t) t = sa / (sa - sb);
    }
    const double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    for (Py_ssize_t i = 0; i < pl->tri_count; i++) {
        double h = tri_hit(pl->tri + 9 * i, a, d);
        if (h >= 1e-4 && h <= 1.0 - 1e-4 && h < t) t = h;
    }
    return t;
}

/* The static scene argument pair (planes float64[K*4] | None, triangles float64[T*9] | None). */
static int get_scene(PyObject *p_obj, PyObject *t_obj, pb_py_buffer *pl, pb_py_buffer *tr, planes *scene)
{
    if (p_obj != Py_None && _pb_py_get_buffer(p_obj, "planes", 'd', 4, -1, pl) < 0) return -1;
    if (t_obj != Py_None && _pb_py_get_buffer(t_obj, "triangles", 'd', 9, -1, tr) < 0) {
        _pb_py_release(pl);
        return -1;
    }
    scene->p = pl->view.obj ? pl->view.buf : NULL;
    scene->count = pl->view.obj ? pl->count / 4 : 0;
    scene->tri = tr->view.obj ? tr->view.buf : NULL;
    scene->tri_count = tr->view.obj ? tr->count / 9 : 0;
    return (pl->view.obj || tr->view.obj) ? 1 : 0;
}

/* bricks_leaf_tables(tree, planes=None, triangles=None) -> bytearray leaf_count × 64: the leaves' pair
 * tables (pb_cotree_pair_visibility) through the test scene, for the query's pair_visibility. */
static PyObject *py_bricks_leaf_tables(PyObject *module, PyObject *args)
{
    PyObject *t_obj, *p_obj = Py_None, *tr_obj = Py_None;
    if (!PyArg_ParseTuple(args, "O|OO:bricks_leaf_tables", &t_obj, &p_obj, &tr_obj)) return NULL;
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    pb_py_buffer pl = {0}, tr = {0};
    planes scene = {0};
    if (get_scene(p_obj, tr_obj, &pl, &tr, &scene) < 0) return NULL;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)pb_cotree_leaf_count(t) * 64);
    pb_result r = PB_SUCCESS;
    pb_error err = {0};
    if (out) {
        Py_BEGIN_ALLOW_THREADS r =
            pb_cotree_pair_visibility(t, planes_segment, &scene, (uint8_t *)PyByteArray_AsString(out), &err);
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&pl);
    _pb_py_release(&tr);
    if (!out) return NULL;
    if (r != PB_SUCCESS) {
        Py_DECREF(out);
        return _pb_py_raise_core(module, r, &err);
    }
    return out;
}

/* bricks_build(tree, coeffs float64[P*C*3], coeff_count, validity float32[P] | None, scale float32[P] | None,
 * max_bytes, planes float64[K*4] | None) -> handle. With planes: the build with visibility (the planes as
 * the static scene). */
static PyObject *py_bricks_build(PyObject *module, PyObject *args)
{
    PyObject *t_obj, *c_obj, *v_obj = Py_None, *s_obj = Py_None, *p_obj = Py_None, *tr_obj = Py_None;
    Py_ssize_t count_in, max_in = 0;
    if (!PyArg_ParseTuple(args, "OOn|OOnOO:bricks_build", &t_obj, &c_obj, &count_in, &v_obj, &s_obj, &max_in, &p_obj,
                          &tr_obj))
        return NULL;
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    if (!pb_cotree_probe_lattice(t)) {
        PyErr_SetString(PyExc_ValueError, "the corner octree is not finalized (call cotree_finalize)");
        return NULL;
    }
    uint32_t C;
    if (_pb_py_check_u32(count_in, "coeff_count", &C) < 0) return NULL;
    if (max_in < 0) return PyErr_Format(PyExc_ValueError, "max_bytes %zd is negative", max_in);
    Py_ssize_t P = (Py_ssize_t)pb_cotree_probe_count(t), want = _pb_py_product3(P, (Py_ssize_t)C, 3, "coeffs");
    if (want < 0) return NULL;
    pb_py_buffer co = {0}, val = {0}, sc = {0}, pl = {0}, tr = {0};
    planes scene = {0};
    int has_scene = 0;
    if (_pb_py_get_buffer(c_obj, "coeffs", 'd', 0, want, &co) < 0 ||
        (v_obj != Py_None && _pb_py_get_buffer(v_obj, "validity", 'f', 0, P, &val) < 0) ||
        (s_obj != Py_None && _pb_py_get_buffer(s_obj, "scale", 'f', 0, P, &sc) < 0) ||
        (has_scene = get_scene(p_obj, tr_obj, &pl, &tr, &scene)) < 0) {
        _pb_py_release(&co);
        _pb_py_release(&val);
        _pb_py_release(&sc);
        return NULL;
    }
    pb_bricks_desc d = {.tree = t,
                        .coeff_count = C,
                        .coeffs = co.view.buf,
                        .validity = val.view.obj ? val.view.buf : NULL,
                        .scale = sc.view.obj ? sc.view.buf : NULL,
                        .max_bytes = (uint64_t)max_in,
                        .segment = has_scene ? planes_segment : NULL,
                        .segment_user = &scene};
    pb_bricks *b = NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_bricks_build(&d, &b, &err);
    Py_END_ALLOW_THREADS _pb_py_release(&co);
    _pb_py_release(&val);
    _pb_py_release(&sc);
    _pb_py_release(&pl);
    _pb_py_release(&tr);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    PyObject *cap = PyCapsule_New(b, PB_PY_CAP_BRICKS, bricks_capsule_free);
    if (!cap) pb_bricks_destroy(b);
    return cap;
}

static PyObject *triple_u32(const uint32_t v[3]) { return Py_BuildValue("(III)", v[0], v[1], v[2]); }

/* bricks_info(handle) -> dict of pb_bricks_info, and the arrays: regions uint32[n*4], indirection
 * uint32[entries*4], texels float64[n*125*channels] (bytearrays). */
static PyObject *py_bricks_info(PyObject *module, PyObject *h)
{
    (void)module;
    pb_bricks *b = get_bricks(h);
    if (!b) return NULL;
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    PyObject *levels = PyTuple_New(PB_COTREE_MAX_LEVEL + 1), *d = PyDict_New();
    for (uint32_t L = 0; levels && L <= PB_COTREE_MAX_LEVEL; L++) {
        PyObject *v = PyLong_FromUnsignedLong(in.level_counts[L]);
        if (!v || PyTuple_SetItem(levels, L, v) < 0) Py_CLEAR(levels);
    }
    uint64_t ind = (uint64_t)in.indirection_dims[0] * in.indirection_dims[1] * in.indirection_dims[2];
    if (!d || !levels || _pb_py_dict_put(d, "level_counts", Py_NewRef(levels)) < 0 ||
        _pb_py_dict_put(d, "origin", Py_BuildValue("(ddd)", in.origin[0], in.origin[1], in.origin[2])) < 0 ||
        _pb_py_dict_put(d, "min_cell", PyFloat_FromDouble(in.min_cell)) < 0 ||
        _pb_py_dict_put(d, "dims", triple_u32(in.dims)) < 0 ||
        _pb_py_dict_put(d, "root_level", PyLong_FromUnsignedLong(in.root_level)) < 0 ||
        _pb_py_dict_put(d, "coeff_count", PyLong_FromUnsignedLong(in.coeff_count)) < 0 ||
        _pb_py_dict_put(d, "channels", PyLong_FromUnsignedLong(in.channels)) < 0 ||
        _pb_py_dict_put(d, "groups", PyLong_FromUnsignedLong(in.groups)) < 0 ||
        _pb_py_dict_put(d, "brick_count", PyLong_FromUnsignedLong(in.brick_count)) < 0 ||
        _pb_py_dict_put(d, "pool_bricks", triple_u32(in.pool_bricks)) < 0 ||
        _pb_py_dict_put(d, "pool_texels", triple_u32(in.pool_texels)) < 0 ||
        _pb_py_dict_put(d, "indirection_dims", triple_u32(in.indirection_dims)) < 0 ||
        _pb_py_dict_put(d, "texel_count", PyLong_FromUnsignedLongLong(in.texel_count)) < 0 ||
        _pb_py_dict_put(d, "indirection_bytes", PyLong_FromUnsignedLongLong(in.indirection_bytes)) < 0 ||
        _pb_py_dict_put(d, "pool_bytes_f16", PyLong_FromUnsignedLongLong(in.pool_bytes_f16)) < 0 ||
        _pb_py_dict_put(d, "pool_bytes_f32", PyLong_FromUnsignedLongLong(in.pool_bytes_f32)) < 0 ||
        _pb_py_dict_put(d, "blocked_leaves", PyLong_FromUnsignedLong(in.blocked_leaves)) < 0 ||
        _pb_py_dict_put(d, "traced_cells", PyLong_FromUnsignedLong(in.traced_cells)) < 0 ||
        _pb_py_dict_put(d, "vis_record_count", PyLong_FromUnsignedLong(in.vis_record_count)) < 0 ||
        _pb_py_dict_put(d, "table_bytes", PyLong_FromUnsignedLongLong(in.table_bytes)) < 0 ||
        _pb_py_dict_put(d, "vis_record_bytes", PyLong_FromUnsignedLongLong(in.vis_record_bytes)) < 0 ||
        _pb_py_dict_put(d, "table", _pb_py_bytes_out(pb_bricks_table(b), (size_t)in.table_bytes)) < 0 ||
        _pb_py_dict_put(d, "vis_records", _pb_py_bytes_out(pb_bricks_vis_records(b), (size_t)in.vis_record_bytes)) <
            0 ||
        _pb_py_dict_put(d, "regions", _pb_py_bytes_out(pb_bricks_regions(b), (size_t)in.brick_count * 16u)) < 0 ||
        _pb_py_dict_put(d, "indirection", _pb_py_bytes_out(pb_bricks_indirection(b), (size_t)ind * 16u)) < 0 ||
        _pb_py_dict_put(d, "texels", _pb_py_bytes_out(pb_bricks_texels(b), (size_t)in.texel_count * in.channels * 8u)) <
            0) {
        Py_XDECREF(levels);
        Py_XDECREF(d);
        return NULL;
    }
    Py_DECREF(levels);
    return d;
}

/* bricks_sample(handle, points float64[N*3], subtexel_bits=0) -> (coeffs float64[N*C*3], d float64[N], has uint8[N],
 * brick int32[N] (−1 none), x float64[N*3] brick-local texel coordinates). */
static PyObject *py_bricks_sample(PyObject *module, PyObject *args)
{
    (void)module;
    PyObject *h, *p_obj;
    unsigned int bits = 0;
    if (!PyArg_ParseTuple(args, "OO|I:bricks_sample", &h, &p_obj, &bits)) return NULL;
    pb_bricks *b = get_bricks(h);
    if (!b) return NULL;
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    pb_py_buffer pts;
    if (_pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    Py_ssize_t n = pts.count / 3, C3 = 3 * (Py_ssize_t)in.coeff_count;
    PyObject *co = PyByteArray_FromStringAndSize(NULL, n * C3 * 8), *dd = PyByteArray_FromStringAndSize(NULL, n * 8),
             *has = PyByteArray_FromStringAndSize(NULL, n), *br = PyByteArray_FromStringAndSize(NULL, n * 4),
             *xo = PyByteArray_FromStringAndSize(NULL, n * 24);
    if (co && dd && has && br && xo) {
        double *c = (double *)(void *)PyByteArray_AsString(co), *d = (double *)(void *)PyByteArray_AsString(dd),
               *x = (double *)(void *)PyByteArray_AsString(xo);
        uint8_t *hv = (uint8_t *)PyByteArray_AsString(has);
        int32_t *bi = (int32_t *)(void *)PyByteArray_AsString(br);
        const double *pp = pts.view.buf;
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < n; i++)
        {
            uint32_t brick = 0;
            bool found = pb_bricks_locate(b, pp + 3 * i, &brick, x + 3 * i);
            bi[i] = found ? (int32_t)brick : -1;
            if (!found) x[3 * i] = x[3 * i + 1] = x[3 * i + 2] = 0.0;
            hv[i] = pb_bricks_sample_bits(b, pp + 3 * i, bits, c + C3 * i, d + i);
        }
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&pts);
    if (!co || !dd || !has || !br || !xo) {
        Py_XDECREF(co), Py_XDECREF(dd), Py_XDECREF(has), Py_XDECREF(br), Py_XDECREF(xo);
        return NULL;
    }
    return Py_BuildValue("(NNNNN)", co, dd, has, br, xo);
}

/* bricks_sample_surface(handle, points float64[N*3], surface float64[N*3] | None, normals float64[N*3] | None,
 * flags, subtexel_bits) -> (coeffs float64[N*C*3], d float64[N], has uint8[N]): pb_bricks_sample_surface per
 * point; the first refusal raises (its message names the point). */
static PyObject *py_bricks_sample_surface(PyObject *module, PyObject *args)
{
    PyObject *h, *p_obj, *s_obj = Py_None, *n_obj = Py_None;
    unsigned int flags = 0, bits = 0;
    if (!PyArg_ParseTuple(args, "OO|OOII:bricks_sample_surface", &h, &p_obj, &s_obj, &n_obj, &flags, &bits))
        return NULL;
    pb_bricks *b = get_bricks(h);
    if (!b) return NULL;
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    pb_py_buffer pts = {0}, sur = {0}, nor = {0};
    if (_pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    Py_ssize_t n = pts.count / 3, C3 = 3 * (Py_ssize_t)in.coeff_count;
    if ((s_obj != Py_None && _pb_py_get_buffer(s_obj, "surface", 'd', 0, 3 * n, &sur) < 0) ||
        (n_obj != Py_None && _pb_py_get_buffer(n_obj, "normals", 'd', 0, 3 * n, &nor) < 0)) {
        _pb_py_release(&pts);
        _pb_py_release(&sur);
        return NULL;
    }
    PyObject *co = PyByteArray_FromStringAndSize(NULL, n * C3 * 8), *dd = PyByteArray_FromStringAndSize(NULL, n * 8),
             *has = PyByteArray_FromStringAndSize(NULL, n);
    pb_error err = {0};
    pb_result r = PB_SUCCESS;
    Py_ssize_t bad = -1;
    if (co && dd && has) {
        double *c = (double *)(void *)PyByteArray_AsString(co), *d = (double *)(void *)PyByteArray_AsString(dd);
        uint8_t *hv = (uint8_t *)PyByteArray_AsString(has);
        const double *pp = pts.view.buf, *ps = sur.view.obj ? sur.view.buf : NULL,
                     *pn = nor.view.obj ? nor.view.buf : NULL;
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < n && r == PB_SUCCESS; i++)
        {
            bool v = false;
            r = pb_bricks_sample_surface(b, pp + 3 * i, ps ? ps + 3 * i : NULL, pn ? pn + 3 * i : NULL, flags, bits,
                                         c + C3 * i, d + i, &v, &err);
            hv[i] = v;
            if (r != PB_SUCCESS) bad = i;
        }
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&pts);
    _pb_py_release(&sur);
    _pb_py_release(&nor);
    if (!co || !dd || !has || r != PB_SUCCESS) {
        Py_XDECREF(co), Py_XDECREF(dd), Py_XDECREF(has);
        if (r != PB_SUCCESS) {
            pb_error at = {.code = r};
            snprintf(at.message, sizeof at.message, "point %zd: %.400s", bad, err.message);
            return _pb_py_raise_core(module, r, &at);
        }
        return NULL;
    }
    return Py_BuildValue("(NNN)", co, dd, has);
}

/* bricks_pool(handle, half) -> bytearray: the pool (pb_bricks_pool_f16 / _f32). */
static PyObject *py_bricks_pool(PyObject *module, PyObject *args)
{
    PyObject *h;
    int half = 0;
    if (!PyArg_ParseTuple(args, "Op:bricks_pool", &h, &half)) return NULL;
    pb_bricks *b = get_bricks(h);
    if (!b) return NULL;
    pb_bricks_info in;
    pb_bricks_get_info(b, &in);
    uint64_t n = (uint64_t)in.pool_texels[0] * in.pool_texels[1] * in.pool_texels[2] * in.groups * 4u;
    if (n > (uint64_t)PY_SSIZE_T_MAX / 4u) return PyErr_NoMemory();
    PyObject *out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n * (half ? 2u : 4u)));
    if (!out) return NULL;
    pb_error err = {0};
    void *buf = PyByteArray_AsString(out);
    pb_result r = half ? pb_bricks_pool_f16(b, buf, n, &err) : pb_bricks_pool_f32(b, buf, n, &err);
    if (r != PB_SUCCESS) {
        Py_DECREF(out);
        return _pb_py_raise_core(module, r, &err);
    }
    return out;
}

PyMethodDef _pb_py_bricks_methods[] = {
    {"bricks_build", py_bricks_build, METH_VARARGS,
     "bricks_build(tree, coeffs: float64[P*C*3], coeff_count, validity=None, scale=None, max_bytes=0, planes=None, "
     "triangles=None) -> handle"},
    {"bricks_leaf_tables", py_bricks_leaf_tables, METH_VARARGS,
     "bricks_leaf_tables(tree, planes=None, triangles=None) -> bytearray leaf_count * 64 (pair tables)"},
    {"bricks_info", py_bricks_info, METH_O, "bricks_info(handle) -> dict (sizes, regions, indirection, texels)"},
    {"bricks_sample", py_bricks_sample, METH_VARARGS,
     "bricks_sample(handle, points: float64[N*3], subtexel_bits=0) -> (coeffs, d, has_value, brick, x) bytearrays"},
    {"bricks_sample_surface", py_bricks_sample_surface, METH_VARARGS,
     "bricks_sample_surface(handle, points, surface=None, normals=None, flags=0, subtexel_bits=0) -> (coeffs, d, "
     "has_value) bytearrays"},
    {"bricks_pool", py_bricks_pool, METH_VARARGS, "bricks_pool(handle, half: bool) -> bytearray (RGBA16F / RGBA32F)"},
    {NULL, NULL, 0, NULL},
};
