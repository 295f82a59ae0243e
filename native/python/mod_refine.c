/* _schnee_native: error-driven refinement (pb_refine.h): the octree's test points (7 columns per
 * leaf) and the per-axis ones of boxes with per-axis levels (14 columns, docs/aniso-refinement.md
 * "Tests and the split rule"), their decisions, and the irradiance metric. The tree is mod_interp.c's
 * corner octree capsule; native.py wraps refine_tests / refine_decide, addon/schnee_probes/refine_axes.py
 * the per-axis pair. One binding per operation, the per-axis flag picking the core's function. */
#include "mod_common.h"

#include "schnee/pb_refine.h"
#include "schnee/pb_sh.h"

/* refine_tests[_axes](tree, active=None) -> dict: lattice uint32[T*3], positions float64[T*3], probe
 * int32[T], leaf_tests int32[L*7] (pb_refine_tests_create) or int32[L*14] (pb_refine_tests_create_axes). */
static PyObject *refine_tests(PyObject *module, PyObject *args, bool axes)
{
    PyObject *t_obj, *a_obj = Py_None;
    if (!PyArg_ParseTuple(args, axes ? "O|O:refine_tests_axes" : "O|O:refine_tests", &t_obj, &a_obj)) return NULL;
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t) return NULL;
    pb_py_buffer active = {0};
    if (a_obj != Py_None && _pb_py_get_buffer(a_obj, "active", 'B', 0, pb_cotree_leaf_count(t), &active) < 0)
        return NULL;
    const uint8_t *act = active.view.obj ? active.view.buf : NULL;
    pb_refine_tests *tests = NULL;
    pb_error err = {0};
    pb_result r =
        axes ? pb_refine_tests_create_axes(t, act, &tests, &err) : pb_refine_tests_create(t, act, &tests, &err);
    _pb_py_release(&active);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    size_t n = tests->point_count, L = tests->leaf_count;
    size_t per = axes ? PB_REFINE_AXIS_TESTS : PB_REFINE_TESTS_PER_LEAF;
    PyObject *d = PyDict_New();
    if (d && (_pb_py_dict_put(d, "lattice", _pb_py_bytes_out(tests->lattice, n * 12)) < 0 ||
              _pb_py_dict_put(d, "positions", _pb_py_bytes_out(tests->positions, n * 24)) < 0 ||
              _pb_py_dict_put(d, "probe", _pb_py_bytes_out(tests->probe, n * 4)) < 0 ||
              _pb_py_dict_put(d, "leaf_tests", _pb_py_bytes_out(tests->leaf_tests, L * per * 4)) < 0))
        Py_CLEAR(d);
    pb_refine_tests_destroy(tests);
    return d;
}

static PyObject *py_refine_tests(PyObject *module, PyObject *args) { return refine_tests(module, args, false); }
static PyObject *py_refine_tests_axes(PyObject *module, PyObject *args) { return refine_tests(module, args, true); }

/* Index ranges the core cannot check in a struct filled from Python buffers. */
static int check_indices(const int32_t *v, Py_ssize_t n, Py_ssize_t bound, const char *name, const char *what)
{
    for (Py_ssize_t i = 0; i < n; i++)
        if (v[i] < -1 || v[i] >= bound) {
            PyErr_Format(PyExc_ValueError, "%s[%zd] = %d is not a %s index", name, i, (int)v[i], what);
            return -1;
        }
    return 0;
}

/* refine_decide[_axes](tree, leaf_tests int32[L*7 or L*14], test_positions float64[T*3], test_probe
 * int32[T], max_band, probe_coeffs, test_coeffs, probe_noise=None, test_noise=None,
 * probe_validity=None, test_valid=None, tolerance=0, noise_k=0) -> (split uint8[L] (per axis: bit a
 * = split along axis a), error float64[L], threshold float64[L]) (pb_refine_decide /
 * pb_refine_decide_axes). */
static PyObject *refine_decide(PyObject *module, PyObject *args, PyObject *kw, bool axes)
{
    static char *kwlist[] = {"tree",         "leaf_tests",  "test_positions", "test_probe", "max_band",
                             "probe_coeffs", "test_coeffs", "probe_noise",    "test_noise", "probe_validity",
                             "test_valid",   "tolerance",   "noise_k",        NULL};
    PyObject *t_obj, *lt_obj, *tp_obj, *tpr_obj, *pc_obj, *tc_obj;
    PyObject *pn_obj = Py_None, *tn_obj = Py_None, *pv_obj = Py_None, *tv_obj = Py_None;
    long band;
    double tol = 0.0, k = 0.0;
    if (!PyArg_ParseTupleAndKeywords(
            args, kw, axes ? "OOOOlOO|OOOOdd:refine_decide_axes" : "OOOOlOO|OOOOdd:refine_decide", kwlist, &t_obj,
            &lt_obj, &tp_obj, &tpr_obj, &band, &pc_obj, &tc_obj, &pn_obj, &tn_obj, &pv_obj, &tv_obj, &tol, &k))
        return NULL;
    pb_cotree *t = _pb_py_get_cotree(t_obj);
    if (!t || _pb_py_check_band(band) < 0) return NULL;
    Py_ssize_t per = axes ? PB_REFINE_AXIS_TESTS : PB_REFINE_TESTS_PER_LEAF;
    Py_ssize_t L = pb_cotree_leaf_count(t), P = pb_cotree_probe_count(t), C = (Py_ssize_t)pb_sh_count((uint32_t)band);
    pb_py_buffer lt = {0}, tp = {0}, tpr = {0}, pc = {0}, tc = {0}, pn = {0}, tn = {0}, pv = {0}, tv = {0};
    PyObject *result = NULL, *so = NULL, *eo = NULL, *ho = NULL;
    if (_pb_py_get_buffer(lt_obj, "leaf_tests", 'i', 0, L * per, &lt) < 0 ||
        _pb_py_get_buffer(tp_obj, "test_positions", 'd', 3, -1, &tp) < 0)
        goto done;
    Py_ssize_t T = tp.count / 3;
    if (_pb_py_get_buffer(tpr_obj, "test_probe", 'i', 0, T, &tpr) < 0 ||
        _pb_py_get_buffer(pc_obj, "probe_coeffs", 'd', 0, P * C * 3, &pc) < 0 ||
        _pb_py_get_buffer(tc_obj, "test_coeffs", 'd', 0, T * C * 3, &tc) < 0 ||
        (pn_obj != Py_None && _pb_py_get_buffer(pn_obj, "probe_noise", 'f', 0, P, &pn) < 0) ||
        (tn_obj != Py_None && _pb_py_get_buffer(tn_obj, "test_noise", 'f', 0, T, &tn) < 0) ||
        (pv_obj != Py_None && _pb_py_get_buffer(pv_obj, "probe_validity", 'f', 0, P, &pv) < 0) ||
        (tv_obj != Py_None && _pb_py_get_buffer(tv_obj, "test_valid", 'B', 0, T, &tv) < 0))
        goto done;
    if (check_indices(lt.view.buf, L * per, T, "leaf_tests", "test point") < 0 ||
        check_indices(tpr.view.buf, T, P, "test_probe", "probe") < 0)
        goto done;
    pb_refine_tests tests = {.point_count = (uint32_t)T,
                             .positions = tp.view.buf,
                             .probe = tpr.view.buf,
                             .leaf_count = (uint32_t)L,
                             .leaf_tests = lt.view.buf,
                             .per_leaf = (uint32_t)per};
    pb_refine_desc d = {.max_band = (uint32_t)band,
                        .probe_coeffs = pc.view.buf,
                        .test_coeffs = tc.view.buf,
                        .probe_noise = pn.view.obj ? pn.view.buf : NULL,
                        .test_noise = tn.view.obj ? tn.view.buf : NULL,
                        .probe_validity = pv.view.obj ? pv.view.buf : NULL,
                        .test_valid = tv.view.obj ? tv.view.buf : NULL,
                        .tolerance = tol,
                        .noise_k = k};
    so = PyByteArray_FromStringAndSize(NULL, L);
    eo = PyByteArray_FromStringAndSize(NULL, L * 8);
    ho = PyByteArray_FromStringAndSize(NULL, L * 8);
    if (!so || !eo || !ho) goto done;
    uint8_t *split = (uint8_t *)PyByteArray_AsString(so);
    double *error = (double *)(void *)PyByteArray_AsString(eo), *threshold = (double *)(void *)PyByteArray_AsString(ho);
    pb_error err = {0};
    pb_result r = axes ? pb_refine_decide_axes(t, &tests, &d, split, error, threshold, &err)
                       : pb_refine_decide(t, &tests, &d, split, error, threshold, &err);
    if (r != PB_SUCCESS) {
        _pb_py_raise_core(module, r, &err);
        goto done;
    }
    result = Py_BuildValue("(OOO)", so, eo, ho);
done:
    Py_XDECREF(so);
    Py_XDECREF(eo);
    Py_XDECREF(ho);
    pb_py_buffer *bufs[] = {&lt, &tp, &tpr, &pc, &tc, &pn, &tn, &pv, &tv};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++) _pb_py_release(bufs[i]);
    return result;
}

static PyObject *py_refine_decide(PyObject *module, PyObject *args, PyObject *kw)
{
    return refine_decide(module, args, kw, false);
}

static PyObject *py_refine_decide_axes(PyObject *module, PyObject *args, PyObject *kw)
{
    return refine_decide(module, args, kw, true);
}

/* refine_error(a: float64[N*C*3], ref: float64[N*C*3], max_band) -> bytearray float64[N]: the
 * refinement's metric (pb_refine_irradiance_error) per point; refine_norm(c, max_band) -> float64[N]. */
static PyObject *py_refine_error(PyObject *module, PyObject *args)
{
    PyObject *a_obj, *r_obj;
    long band;
    if (!PyArg_ParseTuple(args, "OOl:refine_error", &a_obj, &r_obj, &band) || _pb_py_check_band(band) < 0) return NULL;
    Py_ssize_t per = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    pb_py_buffer a, ref;
    if (_pb_py_get_buffer(a_obj, "a", 'd', per, -1, &a) < 0) return NULL;
    if (_pb_py_get_buffer(r_obj, "ref", 'd', 0, a.count, &ref) < 0) {
        _pb_py_release(&a);
        return NULL;
    }
    Py_ssize_t n = a.count / per;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * 8);
    if (out)
        pb_refine_irradiance_error_many((uint32_t)band, (size_t)n, a.view.buf, ref.view.buf,
                                        (double *)(void *)PyByteArray_AsString(out));
    _pb_py_release(&a);
    _pb_py_release(&ref);
    return out;
}

static PyObject *py_refine_norm(PyObject *module, PyObject *args)
{
    PyObject *c_obj;
    long band;
    if (!PyArg_ParseTuple(args, "Ol:refine_norm", &c_obj, &band) || _pb_py_check_band(band) < 0) return NULL;
    Py_ssize_t per = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    pb_py_buffer c;
    if (_pb_py_get_buffer(c_obj, "c", 'd', per, -1, &c) < 0) return NULL;
    Py_ssize_t n = c.count / per;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * 8);
    if (out)
        pb_refine_irradiance_norm_many((uint32_t)band, (size_t)n, c.view.buf,
                                       (double *)(void *)PyByteArray_AsString(out));
    _pb_py_release(&c);
    return out;
}

PyMethodDef _pb_py_refine_methods[] = {
    {"refine_tests", py_refine_tests, METH_VARARGS, "refine_tests(tree, active=None) -> dict of test points"},
    {"refine_decide", (PyCFunction)(void (*)(void))py_refine_decide, METH_VARARGS | METH_KEYWORDS,
     "refine_decide(tree, leaf_tests, test_positions, test_probe, max_band, probe_coeffs, test_coeffs, ...) -> "
     "(split uint8[L], error float64[L], threshold float64[L])"},
    {"refine_error", py_refine_error, METH_VARARGS,
     "refine_error(a: float64[N*count*3], ref: float64[N*count*3], max_band) -> bytearray float64[N] "
     "(pb_refine_irradiance_error per point)"},
    {"refine_norm", py_refine_norm, METH_VARARGS,
     "refine_norm(c: float64[N*count*3], max_band) -> bytearray float64[N] (pb_refine_irradiance_norm_many)"},
    {"refine_tests_axes", py_refine_tests_axes, METH_VARARGS,
     "refine_tests_axes(tree, active=None) -> dict of test points, leaf_tests int32[L*14] (per-axis tests)"},
    {"refine_decide_axes", (PyCFunction)(void (*)(void))py_refine_decide_axes, METH_VARARGS | METH_KEYWORDS,
     "refine_decide_axes(tree, leaf_tests, test_positions, test_probe, max_band, probe_coeffs, test_coeffs, ...) "
     "-> (axes uint8[L]: bit a = split along axis a, error float64[L], threshold float64[L])"},
    {NULL, NULL, 0, NULL},
};
