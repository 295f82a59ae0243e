/* _schnee_native: SH (pb_sh.h) and ambient cubes (pb_ambient_cube.h): basis, panorama projection, irradiance, ringing
 * window; native.py "SH" section. */
#include "mod_common.h"

#include "schnee/pb_ambient_cube.h"
#include "schnee/pb_sh.h"

#include <stdlib.h>
#include <string.h>

/* ---- SH --------------------------------------------------------------------------------------- */

static PyObject *py_sh_basis(PyObject *module, PyObject *args)
{
    PyObject *dirs_obj;
    long band;
    if (!PyArg_ParseTuple(args, "Ol:sh_basis", &dirs_obj, &band) || _pb_py_check_band(band) < 0) return NULL;
    pb_py_buffer dirs;
    if (_pb_py_get_buffer(dirs_obj, "dirs", 'd', 3, -1, &dirs) < 0) return NULL;
    Py_ssize_t n = dirs.count / 3;
    uint32_t count = pb_sh_count((uint32_t)band);
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * (Py_ssize_t)count * 8);
    if (out) {
        double *o = (double *)(void *)PyByteArray_AsString(out);
        const double *d = dirs.view.buf;
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < n; i++)
            pb_sh_eval_basis((uint32_t)band, d + 3 * i, o + count * i);
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&dirs);
    return out;
}

static PyObject *py_min_panorama_size(PyObject *module, PyObject *args)
{
    long band;
    if (!PyArg_ParseTuple(args, "l:min_panorama_size", &band) || _pb_py_check_band(band) < 0) return NULL;
    uint32_t w = 0, h = 0;
    pb_sh_min_panorama_size((uint32_t)band, &w, &h);
    return Py_BuildValue("(II)", w, h);
}

static int check_negative(long negative)
{
    if (negative < PB_NEGATIVE_ERROR || negative > PB_NEGATIVE_ALLOW) {
        PyErr_Format(PyExc_ValueError, "negative policy %ld is out of range 0..2", negative);
        return -1;
    }
    return 0;
}

static PyObject *py_project_equirect(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"pixels", "width", "height", "channels", "max_band", "rotation", "negative", NULL};
    PyObject *pix_obj, *rot_obj = Py_None;
    Py_ssize_t width, height, channels;
    long band = 2, negative = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "Onnn|lOl:project_equirect", kwlist, &pix_obj, &width, &height,
                                     &channels, &band, &rot_obj, &negative))
        return NULL;
    uint32_t w, h, c;
    if (_pb_py_check_band(band) < 0 || check_negative(negative) < 0 || _pb_py_check_u32(width, "width", &w) < 0 ||
        _pb_py_check_u32(height, "height", &h) < 0 || _pb_py_check_u32(channels, "channels", &c) < 0)
        return NULL;
    if (c < 3) return PyErr_Format(PyExc_ValueError, "channels %u: at least 3 (RGB first) are needed", c);
    pb_py_buffer pix, rot;
    Py_ssize_t expected = _pb_py_product3(width, height, channels, "width x height x channels");
    if (expected < 0 || _pb_py_get_buffer(pix_obj, "pixels", 'f', 0, expected, &pix) < 0) return NULL;
    if (_pb_py_get_rotation(rot_obj, &rot) < 0) {
        _pb_py_release(&pix);
        return NULL;
    }
    pb_sh_project_desc desc = {0};
    desc.pixels = pix.view.buf;
    desc.width = w;
    desc.height = h;
    desc.channels = c;
    desc.max_band = (uint32_t)band;
    desc.rotation = rot.view.obj ? rot.view.buf : NULL;
    desc.negative = (pb_negative_policy)negative;
    double out[PB_SH_MAX_COEFFS * 3] = {0};
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_sh_project_equirect(&desc, out, &err);
    Py_END_ALLOW_THREADS _pb_py_release(&pix);
    _pb_py_release(&rot);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return _pb_py_bytes_out(out, pb_sh_count((uint32_t)band) * 3 * sizeof(double));
}

static PyObject *py_project_file(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "max_band", "rotation", "negative", NULL};
    PyObject *path = NULL, *rot_obj = Py_None;
    long band = 2, negative = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&|lOl:project_file", kwlist, PyUnicode_FSConverter, &path, &band,
                                     &rot_obj, &negative))
        return NULL;
    pb_py_buffer rot;
    if (_pb_py_check_band(band) < 0 || check_negative(negative) < 0 || _pb_py_get_rotation(rot_obj, &rot) < 0) {
        Py_DECREF(path);
        return NULL;
    }
    pb_sh_project_desc desc = {0};
    desc.max_band = (uint32_t)band;
    desc.rotation = rot.view.obj ? rot.view.buf : NULL;
    desc.negative = (pb_negative_policy)negative;
    double out[PB_SH_MAX_COEFFS * 3] = {0};
    pb_error err = {0};
    pb_result r;
    const char *cpath = PyBytes_AsString(path);
    Py_BEGIN_ALLOW_THREADS r = pb_sh_project_file(cpath, &desc, out, &err);
    Py_END_ALLOW_THREADS _pb_py_release(&rot);
    Py_DECREF(path);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    return _pb_py_bytes_out(out, pb_sh_count((uint32_t)band) * 3 * sizeof(double));
}

static PyObject *py_irradiance(PyObject *module, PyObject *args)
{
    PyObject *c_obj, *n_obj;
    long band;
    if (!PyArg_ParseTuple(args, "OlO:irradiance", &c_obj, &band, &n_obj) || _pb_py_check_band(band) < 0) return NULL;
    pb_py_buffer coeffs, normals;
    if (_pb_py_get_buffer(c_obj, "coeffs", 'd', 0, (Py_ssize_t)pb_sh_count((uint32_t)band) * 3, &coeffs) < 0)
        return NULL;
    if (_pb_py_get_buffer(n_obj, "normals", 'd', 3, -1, &normals) < 0) {
        _pb_py_release(&coeffs);
        return NULL;
    }
    Py_ssize_t n = normals.count / 3;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * 3 * 8);
    if (out) {
        double *o = (double *)(void *)PyByteArray_AsString(out);
        const double *c = coeffs.view.buf, *nrm = normals.view.buf;
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < n; i++)
            pb_sh_irradiance((uint32_t)band, c, nrm + 3 * i, o + 3 * i);
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&coeffs);
    _pb_py_release(&normals);
    return out;
}

static PyObject *py_window(PyObject *module, PyObject *args)
{
    PyObject *c_obj;
    long band, kind;
    double strength;
    if (!PyArg_ParseTuple(args, "Olld:window", &c_obj, &band, &kind, &strength) || _pb_py_check_band(band) < 0)
        return NULL;
    if (kind < PB_SH_WINDOW_NONE || kind > PB_SH_WINDOW_LAPLACIAN)
        return PyErr_Format(PyExc_ValueError, "window kind %ld is out of range 0..2", kind);
    pb_py_buffer coeffs;
    Py_ssize_t n = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    if (_pb_py_get_buffer(c_obj, "coeffs", 'd', 0, n, &coeffs) < 0) return NULL;
    double work[PB_SH_MAX_COEFFS * 3], min_e[3] = {0, 0, 0};
    memcpy(work, coeffs.view.buf, (size_t)n * sizeof(double));
    _pb_py_release(&coeffs);
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_sh_window((uint32_t)band, (pb_sh_window_kind)kind, strength, work, min_e, &err);
    Py_END_ALLOW_THREADS if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    PyObject *out = _pb_py_bytes_out(work, (size_t)n * sizeof(double));
    if (!out) return NULL;
    return Py_BuildValue("(N(ddd))", out, min_e[0], min_e[1], min_e[2]);
}

/* ---- ambient cube ----------------------------------------------------------------------------- */

static PyObject *py_ambient_cube_from_sh(PyObject *module, PyObject *args)
{
    PyObject *c_obj;
    long band, fit;
    if (!PyArg_ParseTuple(args, "Oll:ambient_cube_from_sh", &c_obj, &band, &fit) || _pb_py_check_band(band) < 0)
        return NULL;
    const Py_ssize_t per = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    pb_py_buffer coeffs;
    if (_pb_py_get_buffer(c_obj, "coeffs", 'd', per, -1, &coeffs) < 0) return NULL;
    const Py_ssize_t n = coeffs.count / per;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * 18 * 8);
    pb_error err = {0};
    pb_result r = PB_SUCCESS;
    if (out) {
        double *o = (double *)(void *)PyByteArray_AsString(out);
        const double *c = coeffs.view.buf;
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < n && r == PB_SUCCESS; i++) r =
            pb_ambient_cube_from_sh((uint32_t)band, c + per * i, (pb_ambient_cube_fit)fit, o + 18 * i, &err);
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&coeffs);
    if (out && r != PB_SUCCESS) {
        Py_DECREF(out);
        return _pb_py_raise_core(module, r, &err);
    }
    return out;
}

static PyObject *py_ambient_cube_irradiance(PyObject *module, PyObject *args)
{
    PyObject *c_obj, *n_obj;
    if (!PyArg_ParseTuple(args, "OO:ambient_cube_irradiance", &c_obj, &n_obj)) return NULL;
    pb_py_buffer cube, normals;
    if (_pb_py_get_buffer(c_obj, "cube", 'd', 0, 18, &cube) < 0) return NULL;
    if (_pb_py_get_buffer(n_obj, "normals", 'd', 3, -1, &normals) < 0) {
        _pb_py_release(&cube);
        return NULL;
    }
    Py_ssize_t n = normals.count / 3;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * 3 * 8);
    if (out) {
        double *o = (double *)(void *)PyByteArray_AsString(out);
        const double *c = cube.view.buf, *nrm = normals.view.buf;
        Py_BEGIN_ALLOW_THREADS for (Py_ssize_t i = 0; i < n; i++) pb_ambient_cube_irradiance(c, nrm + 3 * i, o + 3 * i);
        Py_END_ALLOW_THREADS
    }
    _pb_py_release(&cube);
    _pb_py_release(&normals);
    return out;
}

PyMethodDef _pb_py_sh_methods[] = {
    {"sh_basis", py_sh_basis, METH_VARARGS, "sh_basis(dirs: float64[N*3], max_band) -> bytearray float64[N*count]"},
    {"min_panorama_size", py_min_panorama_size, METH_VARARGS, "min_panorama_size(max_band) -> (w, h)"},
    {"project_equirect", (PyCFunction)(void (*)(void))py_project_equirect, METH_VARARGS | METH_KEYWORDS,
     "project_equirect(pixels: float32[H*W*C], width, height, channels, max_band=2, rotation=None, "
     "negative=0) -> bytearray float64[count*3]"},
    {"project_file", (PyCFunction)(void (*)(void))py_project_file, METH_VARARGS | METH_KEYWORDS,
     "project_file(path, max_band=2, rotation=None, negative=0) -> bytearray float64[count*3]"},
    {"irradiance", py_irradiance, METH_VARARGS,
     "irradiance(coeffs: float64[count*3], max_band, normals: float64[N*3]) -> bytearray float64[N*3]"},
    {"window", py_window, METH_VARARGS,
     "window(coeffs: float64[count*3], max_band, kind, strength) -> (bytearray, (min_r, min_g, min_b))"},
    {"ambient_cube_from_sh", py_ambient_cube_from_sh, METH_VARARGS,
     "ambient_cube_from_sh(coeffs: float64[P*count*3], max_band, fit) -> bytearray float64[P*18]"},
    {"ambient_cube_irradiance", py_ambient_cube_irradiance, METH_VARARGS,
     "ambient_cube_irradiance(cube: float64[18], normals: float64[N*3]) -> bytearray float64[N*3]"},
    {NULL, NULL, 0, NULL},
};
