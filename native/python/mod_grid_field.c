/* _schnee_native: the dense grid's field (pb_grid_field.h, docs/grid-field.md): build, the rule's weights,
 * the sample, the texture form; handles are capsules; native.py "dense grid field" section. */
#include "mod_common.h"

#include "schnee/pb_grid_field.h"

#include <stdlib.h>
#include <string.h>

#define PB_PY_CAP_GRID_FIELD "schnee_probes.grid_field"

static void field_capsule_free(PyObject *cap)
{
    pb_grid_field_destroy(PyCapsule_GetPointer(cap, PB_PY_CAP_GRID_FIELD));
}

static pb_grid_field *get_field(PyObject *o)
{
    if (!PyCapsule_IsValid(o, PB_PY_CAP_GRID_FIELD)) {
        PyErr_SetString(PyExc_TypeError, "expected a grid field handle (from grid_field_build)");
        return NULL;
    }
    return PyCapsule_GetPointer(o, PB_PY_CAP_GRID_FIELD);
}

/* grid_field_build((X, Y, Z), (ox, oy, oz), spacing, axes float64[9] | None, cells int32[X*Y*Z],
 * coeffs float64[P*C*3], coeff_count, validity float32[P] | None, scale float32[P] | None,
 * masks uint32[X*Y*Z] | None, max_bytes) -> handle. P = len(coeffs) / (3 C). */
static PyObject *py_grid_field_build(PyObject *module, PyObject *args)
{
    unsigned int X, Y, Z;
    double o[3], h;
    PyObject *ax_obj, *cells_obj, *c_obj, *v_obj, *s_obj, *m_obj;
    Py_ssize_t count_in, max_in;
    if (!PyArg_ParseTuple(args, "(III)(ddd)dOOOnOOOn:grid_field_build", &X, &Y, &Z, &o[0], &o[1], &o[2], &h, &ax_obj,
                          &cells_obj, &c_obj, &count_in, &v_obj, &s_obj, &m_obj, &max_in))
        return NULL;
    uint32_t C;
    if (_pb_py_check_u32(count_in, "coeff_count", &C) < 0) return NULL;
    if (C < 1 || C > PB_GRID_FIELD_MAX_COLOURS)
        return PyErr_Format(PyExc_ValueError, "coeff_count %u outside 1..25", C);
    if (max_in < 0) return PyErr_Format(PyExc_ValueError, "max_bytes %zd is negative", max_in);
    Py_ssize_t cells = _pb_py_product3((Py_ssize_t)X, (Py_ssize_t)Y, (Py_ssize_t)Z, "cells");
    if (cells < 0) return NULL;
    pb_py_buffer ax = {0}, ce = {0}, co = {0}, val = {0}, sc = {0}, mk = {0};
    PyObject *result = NULL;
    if ((ax_obj != Py_None && _pb_py_get_buffer(ax_obj, "axes", 'd', 0, 9, &ax) < 0) ||
        _pb_py_get_buffer(cells_obj, "cells", 'i', 0, cells, &ce) < 0 ||
        _pb_py_get_buffer(c_obj, "coeffs", 'd', 3 * (Py_ssize_t)C, -1, &co) < 0)
        goto done;
    Py_ssize_t P = co.count / (3 * (Py_ssize_t)C);
    if (P > (Py_ssize_t)UINT32_MAX) {
        PyErr_Format(PyExc_ValueError, "%zd probes exceed 2^32 - 1", P);
        goto done;
    }
    if ((v_obj != Py_None && _pb_py_get_buffer(v_obj, "validity", 'f', 0, P, &val) < 0) ||
        (s_obj != Py_None && _pb_py_get_buffer(s_obj, "scale", 'f', 0, P, &sc) < 0) ||
        (m_obj != Py_None && _pb_py_get_buffer(m_obj, "masks", 'I', 0, cells, &mk) < 0))
        goto done;
    pb_grid_field_desc d = {.dims = {X, Y, Z},
                            .origin = {o[0], o[1], o[2]},
                            .spacing = h,
                            .axes = ax.view.obj ? ax.view.buf : NULL,
                            .cells = ce.view.buf,
                            .probe_count = (uint32_t)P,
                            .coeff_count = C,
                            .coeffs = co.view.buf,
                            .validity = val.view.obj ? val.view.buf : NULL,
                            .scale = sc.view.obj ? sc.view.buf : NULL,
                            .masks = mk.view.obj ? mk.view.buf : NULL,
                            .max_bytes = (uint64_t)max_in};
    pb_grid_field *f = NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_grid_field_build(&d, &f, &err);
    Py_END_ALLOW_THREADS if (r != PB_SUCCESS)
    {
        _pb_py_raise_core(module, r, &err);
        goto done;
    }
    result = PyCapsule_New(f, PB_PY_CAP_GRID_FIELD, field_capsule_free);
    if (!result) pb_grid_field_destroy(f);
done:
    _pb_py_release(&ax), _pb_py_release(&ce), _pb_py_release(&co);
    _pb_py_release(&val), _pb_py_release(&sc), _pb_py_release(&mk);
    return result;
}

/* grid_field_info(handle) -> dict of pb_grid_field_info and texels float64[X*Y*Z*channels] (bytearray). */
static PyObject *py_grid_field_info(PyObject *module, PyObject *hdl)
{
    (void)module;
    pb_grid_field *f = get_field(hdl);
    if (!f) return NULL;
    pb_grid_field_info in;
    pb_grid_field_get_info(f, &in);
    uint64_t n = (uint64_t)in.dims[0] * in.dims[1] * in.dims[2];
    PyObject *d = PyDict_New();
    if (!d || _pb_py_dict_put(d, "dims", Py_BuildValue("(III)", in.dims[0], in.dims[1], in.dims[2])) < 0 ||
        _pb_py_dict_put(d, "origin", Py_BuildValue("(ddd)", in.origin[0], in.origin[1], in.origin[2])) < 0 ||
        _pb_py_dict_put(d, "spacing", PyFloat_FromDouble(in.spacing)) < 0 ||
        _pb_py_dict_put(d, "probe_count", PyLong_FromUnsignedLong(in.probe_count)) < 0 ||
        _pb_py_dict_put(d, "coeff_count", PyLong_FromUnsignedLong(in.coeff_count)) < 0 ||
        _pb_py_dict_put(d, "channels", PyLong_FromUnsignedLong(in.channels)) < 0 ||
        _pb_py_dict_put(d, "groups", PyLong_FromUnsignedLong(in.groups)) < 0 ||
        _pb_py_dict_put(d, "texture_bytes_f16", PyLong_FromUnsignedLongLong(in.texture_bytes_f16)) < 0 ||
        _pb_py_dict_put(d, "texture_bytes_f32", PyLong_FromUnsignedLongLong(in.texture_bytes_f32)) < 0 ||
        _pb_py_dict_put(d, "texels", _pb_py_bytes_out(pb_grid_field_texels(f), (size_t)(n * in.channels * 8u))) < 0) {
        Py_XDECREF(d);
        return NULL;
    }
    return d;
}

/* grid_field_query(handle, points float64[N*3], normals float64[N*3] | None, static_surface, normal_bias)
 * -> (status uint8[N], probe int32[N*8], weight float64[N*8], coeffs float64[N*C*3], home uint32[N*3]). */
static PyObject *py_grid_field_query(PyObject *module, PyObject *args)
{
    (void)module;
    PyObject *hdl, *p_obj, *n_obj;
    int stat = 0;
    double bias = 0.0;
    if (!PyArg_ParseTuple(args, "OOOpd:grid_field_query", &hdl, &p_obj, &n_obj, &stat, &bias)) return NULL;
    pb_grid_field *f = get_field(hdl);
    if (!f) return NULL;
    pb_grid_field_info in;
    pb_grid_field_get_info(f, &in);
    pb_py_buffer pts = {0}, nrm = {0};
    if (_pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    if (n_obj != Py_None && _pb_py_get_buffer(n_obj, "normals", 'd', 0, pts.count, &nrm) < 0) {
        _pb_py_release(&pts);
        return NULL;
    }
    Py_ssize_t N = pts.count / 3, C3 = 3 * (Py_ssize_t)in.coeff_count;
    PyObject *st = PyByteArray_FromStringAndSize(NULL, N), *pr = PyByteArray_FromStringAndSize(NULL, N * 32),
             *wt = PyByteArray_FromStringAndSize(NULL, N * 64), *co = PyByteArray_FromStringAndSize(NULL, N * C3 * 8),
             *hm = PyByteArray_FromStringAndSize(NULL, N * 12);
    if (st && pr && wt && co && hm) {
        uint8_t *s = (uint8_t *)PyByteArray_AsString(st);
        int32_t *p = (int32_t *)(void *)PyByteArray_AsString(pr);
        double *w = (double *)(void *)PyByteArray_AsString(wt), *c = (double *)(void *)PyByteArray_AsString(co);
        uint32_t *home = (uint32_t *)(void *)PyByteArray_AsString(hm);
        const double *pp = pts.view.buf, *nn = nrm.view.obj ? nrm.view.buf : NULL;
        pb_grid_field_opts o = {.static_surface = stat != 0, .normal_bias = bias};
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < N; i++)
        {
            pb_grid_field_weights q;
            s[i] = (uint8_t)pb_grid_field_sample(f, pp + 3 * i, nn ? nn + 3 * i : NULL, &o, c + C3 * i);
            pb_grid_field_query(f, pp + 3 * i, nn ? nn + 3 * i : NULL, &o, &q);
            memcpy(p + 8 * i, q.probe, sizeof q.probe);
            memcpy(w + 8 * i, q.weight, sizeof q.weight);
            memcpy(home + 3 * i, q.home, sizeof q.home);
        }
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&pts);
    _pb_py_release(&nrm);
    if (!st || !pr || !wt || !co || !hm) {
        Py_XDECREF(st), Py_XDECREF(pr), Py_XDECREF(wt), Py_XDECREF(co), Py_XDECREF(hm);
        return NULL;
    }
    return Py_BuildValue("(NNNNN)", st, pr, wt, co, hm);
}

/* grid_field_sample_texture(handle, points float64[N*3], subtexel_bits) -> (coeffs float64[N*C*3], d float64[N],
 * has uint8[N], t float64[N*3] texel coordinates (0 outside)). */
static PyObject *py_grid_field_sample_texture(PyObject *module, PyObject *args)
{
    (void)module;
    PyObject *hdl, *p_obj;
    unsigned int bits = 0;
    if (!PyArg_ParseTuple(args, "OO|I:grid_field_sample_texture", &hdl, &p_obj, &bits)) return NULL;
    pb_grid_field *f = get_field(hdl);
    if (!f) return NULL;
    pb_grid_field_info in;
    pb_grid_field_get_info(f, &in);
    pb_py_buffer pts;
    if (_pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    Py_ssize_t N = pts.count / 3, C3 = 3 * (Py_ssize_t)in.coeff_count;
    PyObject *co = PyByteArray_FromStringAndSize(NULL, N * C3 * 8), *dd = PyByteArray_FromStringAndSize(NULL, N * 8),
             *has = PyByteArray_FromStringAndSize(NULL, N), *to = PyByteArray_FromStringAndSize(NULL, N * 24);
    if (co && dd && has && to) {
        double *c = (double *)(void *)PyByteArray_AsString(co), *d = (double *)(void *)PyByteArray_AsString(dd),
               *t = (double *)(void *)PyByteArray_AsString(to);
        uint8_t *hv = (uint8_t *)PyByteArray_AsString(has);
        const double *pp = pts.view.buf;
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < N; i++)
        {
            if (!pb_grid_field_texel_coord(f, pp + 3 * i, t + 3 * i)) t[3 * i] = t[3 * i + 1] = t[3 * i + 2] = 0.0;
            hv[i] = pb_grid_field_sample_texture(f, pp + 3 * i, bits, NULL, c + C3 * i, d + i);
        }
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&pts);
    if (!co || !dd || !has || !to) {
        Py_XDECREF(co), Py_XDECREF(dd), Py_XDECREF(has), Py_XDECREF(to);
        return NULL;
    }
    return Py_BuildValue("(NNNN)", co, dd, has, to);
}

/* grid_field_sample_surface_texture(handle, points float64[N*3], normals float64[N*3] | None, static_surface,
 * normal_bias, subtexel_bits) -> (coeffs float64[N*C*3], d float64[N], has uint8[N], taps uint8[N] (1, 8; 0
 * outside)): pb_grid_field_sample_surface_texture per point. */
static PyObject *py_grid_field_sample_surface_texture(PyObject *module, PyObject *args)
{
    (void)module;
    PyObject *hdl, *p_obj, *n_obj;
    int stat = 0;
    double bias = 0.0;
    unsigned int bits = 0;
    if (!PyArg_ParseTuple(args, "OOOpd|I:grid_field_sample_surface_texture", &hdl, &p_obj, &n_obj, &stat, &bias, &bits))
        return NULL;
    pb_grid_field *f = get_field(hdl);
    if (!f) return NULL;
    pb_grid_field_info in;
    pb_grid_field_get_info(f, &in);
    pb_py_buffer pts, nrm = {0};
    if (_pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    if (n_obj != Py_None && _pb_py_get_buffer(n_obj, "normals", 'd', 0, pts.count, &nrm) < 0) {
        _pb_py_release(&pts);
        return NULL;
    }
    Py_ssize_t N = pts.count / 3, C3 = 3 * (Py_ssize_t)in.coeff_count;
    PyObject *co = PyByteArray_FromStringAndSize(NULL, N * C3 * 8), *dd = PyByteArray_FromStringAndSize(NULL, N * 8),
             *has = PyByteArray_FromStringAndSize(NULL, N), *tp = PyByteArray_FromStringAndSize(NULL, N);
    if (co && dd && has && tp) {
        double *c = (double *)(void *)PyByteArray_AsString(co), *d = (double *)(void *)PyByteArray_AsString(dd);
        uint8_t *hv = (uint8_t *)PyByteArray_AsString(has), *tv = (uint8_t *)PyByteArray_AsString(tp);
        const double *pp = pts.view.buf, *nn = n_obj != Py_None ? nrm.view.buf : NULL;
        pb_grid_field_opts o = {.static_surface = stat != 0, .normal_bias = bias};
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < N; i++)
        {
            uint32_t taps = 0;
            hv[i] = pb_grid_field_sample_surface_texture(f, pp + 3 * i, nn ? nn + 3 * i : NULL, &o, bits, c + C3 * i,
                                                         d + i, &taps);
            tv[i] = (uint8_t)taps;
        }
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&pts);
    if (n_obj != Py_None) _pb_py_release(&nrm);
    if (!co || !dd || !has || !tp) {
        Py_XDECREF(co), Py_XDECREF(dd), Py_XDECREF(has), Py_XDECREF(tp);
        return NULL;
    }
    return Py_BuildValue("(NNNN)", co, dd, has, tp);
}

/* grid_field_texture(handle, half) -> bytearray (pb_grid_field_texture_f16 / _f32). */
static PyObject *py_grid_field_texture(PyObject *module, PyObject *args)
{
    PyObject *hdl;
    int half = 0;
    if (!PyArg_ParseTuple(args, "Op:grid_field_texture", &hdl, &half)) return NULL;
    pb_grid_field *f = get_field(hdl);
    if (!f) return NULL;
    pb_grid_field_info in;
    pb_grid_field_get_info(f, &in);
    uint64_t n = (uint64_t)in.dims[0] * in.dims[1] * in.dims[2] * in.groups * 4u;
    if (n > (uint64_t)PY_SSIZE_T_MAX / 4u) return PyErr_NoMemory();
    PyObject *out = PyByteArray_FromStringAndSize(NULL, (Py_ssize_t)(n * (half ? 2u : 4u)));
    if (!out) return NULL;
    pb_error err = {0};
    void *buf = PyByteArray_AsString(out);
    pb_result r = half ? pb_grid_field_texture_f16(f, buf, n, &err) : pb_grid_field_texture_f32(f, buf, n, &err);
    if (r != PB_SUCCESS) {
        Py_DECREF(out);
        return _pb_py_raise_core(module, r, &err);
    }
    return out;
}

PyMethodDef _pb_py_grid_field_methods[] = {
    {"grid_field_build", py_grid_field_build, METH_VARARGS,
     "grid_field_build(dims, origin, spacing, axes, cells, coeffs, coeff_count, validity, scale, masks, max_bytes) -> "
     "handle"},
    {"grid_field_info", py_grid_field_info, METH_O, "grid_field_info(handle) -> dict (sizes, texels)"},
    {"grid_field_query", py_grid_field_query, METH_VARARGS,
     "grid_field_query(handle, points, normals, static_surface, normal_bias) -> (status, probe, weight, coeffs, home)"},
    {"grid_field_sample_texture", py_grid_field_sample_texture, METH_VARARGS,
     "grid_field_sample_texture(handle, points, subtexel_bits=0) -> (coeffs, d, has_value, t)"},
    {"grid_field_sample_surface_texture", py_grid_field_sample_surface_texture, METH_VARARGS,
     "grid_field_sample_surface_texture(handle, points, normals, static_surface, normal_bias, subtexel_bits=0) -> "
     "(coeffs, d, has_value, taps)"},
    {"grid_field_texture", py_grid_field_texture, METH_VARARGS,
     "grid_field_texture(handle, half: bool) -> bytearray (RGBA16F / RGBA32F groups)"},
    {NULL, NULL, 0, NULL},
};
