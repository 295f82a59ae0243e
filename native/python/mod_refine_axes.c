/* _schnee_native: per-axis refinement of boxes with per-axis levels (pb_refine.h "per-axis refinement",
 * docs/aniso-refinement.md "Tests and the split rule"): test points in 14 columns per leaf and axis
 * masks. The tree is mod_interp.c's corner octree capsule; addon/schnee_probes/refine_axes.py wraps
 * these as native.py wraps refine_tests / refine_decide. */
#include "mod_common.h"

#include "schnee/pb_refine.h"
#include "schnee/pb_sh.h"

static pb_cotree *get_cotree(PyObject *o)
{
    if (!PyCapsule_IsValid(o, PB_PY_CAP_COTREE)) {
        PyErr_SetString(PyExc_TypeError, "expected a corner octree handle (from cotree_create)");
        return NULL;
    }
    return PyCapsule_GetPointer(o, PB_PY_CAP_COTREE);
}

/* refine_tests_axes(tree, active=None) -> dict: lattice uint32[T*3], positions float64[T*3], probe
 * int32[T], leaf_tests int32[L*14] (pb_refine_tests_create_axes). */
static PyObject *py_refine_tests_axes(PyObject *module, PyObject *args)
{
    PyObject *t_obj, *a_obj = Py_None;
    if (!PyArg_ParseTuple(args, "O|O:refine_tests_axes", &t_obj, &a_obj)) return NULL;
    pb_cotree *t = get_cotree(t_obj);
    if (!t) return NULL;
    pb_py_buffer active = {0};
    if (a_obj != Py_None && _pb_py_get_buffer(a_obj, "active", 'B', 0, pb_cotree_leaf_count(t), &active) < 0)
        return NULL;
    pb_refine_tests *tests = NULL;
    pb_error err = {0};
    pb_result r = pb_refine_tests_create_axes(t, active.view.obj ? active.view.buf : NULL, &tests, &err);
    _pb_py_release(&active);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    size_t n = tests->point_count, L = tests->leaf_count;
    PyObject *d = PyDict_New();
    if (d && (_pb_py_dict_put(d, "lattice", _pb_py_bytes_out(tests->lattice, n * 12)) < 0 ||
              _pb_py_dict_put(d, "positions", _pb_py_bytes_out(tests->positions, n * 24)) < 0 ||
              _pb_py_dict_put(d, "probe", _pb_py_bytes_out(tests->probe, n * 4)) < 0 ||
              _pb_py_dict_put(d, "leaf_tests", _pb_py_bytes_out(tests->leaf_tests, L * PB_REFINE_AXIS_TESTS * 4)) < 0))
        Py_CLEAR(d);
    pb_refine_tests_destroy(tests);
    return d;
}

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

/* refine_decide_axes(tree, leaf_tests int32[L*14], test_positions float64[T*3], test_probe int32[T],
 * max_band, probe_coeffs, test_coeffs, probe_noise=None, test_noise=None, probe_validity=None,
 * test_valid=None, tolerance=0, noise_k=0) -> (axes bytearray uint8[L], error float64[L], threshold
 * float64[L]) (pb_refine_decide_axes; arguments as refine_decide's). */
static PyObject *py_refine_decide_axes(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"tree",         "leaf_tests",  "test_positions", "test_probe", "max_band",
                             "probe_coeffs", "test_coeffs", "probe_noise",    "test_noise", "probe_validity",
                             "test_valid",   "tolerance",   "noise_k",        NULL};
    PyObject *t_obj, *lt_obj, *tp_obj, *tpr_obj, *pc_obj, *tc_obj;
    PyObject *pn_obj = Py_None, *tn_obj = Py_None, *pv_obj = Py_None, *tv_obj = Py_None;
    long band;
    double tol = 0.0, k = 0.0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOOOlOO|OOOOdd:refine_decide_axes", kwlist, &t_obj, &lt_obj, &tp_obj,
                                     &tpr_obj, &band, &pc_obj, &tc_obj, &pn_obj, &tn_obj, &pv_obj, &tv_obj, &tol, &k))
        return NULL;
    pb_cotree *t = get_cotree(t_obj);
    if (!t || _pb_py_check_band(band) < 0) return NULL;
    Py_ssize_t L = pb_cotree_leaf_count(t), P = pb_cotree_probe_count(t), C = (Py_ssize_t)pb_sh_count((uint32_t)band);
    pb_py_buffer lt = {0}, tp = {0}, tpr = {0}, pc = {0}, tc = {0}, pn = {0}, tn = {0}, pv = {0}, tv = {0};
    PyObject *result = NULL, *ao = NULL, *eo = NULL, *ho = NULL;
    if (_pb_py_get_buffer(lt_obj, "leaf_tests", 'i', 0, L * PB_REFINE_AXIS_TESTS, &lt) < 0 ||
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
    if (check_indices(lt.view.buf, L * PB_REFINE_AXIS_TESTS, T, "leaf_tests", "test point") < 0 ||
        check_indices(tpr.view.buf, T, P, "test_probe", "probe") < 0)
        goto done;
    pb_refine_tests tests = {.point_count = (uint32_t)T,
                             .positions = tp.view.buf,
                             .probe = tpr.view.buf,
                             .leaf_count = (uint32_t)L,
                             .leaf_tests = lt.view.buf,
                             .per_leaf = PB_REFINE_AXIS_TESTS};
    pb_refine_desc d = {.max_band = (uint32_t)band,
                        .probe_coeffs = pc.view.buf,
                        .test_coeffs = tc.view.buf,
                        .probe_noise = pn.view.obj ? pn.view.buf : NULL,
                        .test_noise = tn.view.obj ? tn.view.buf : NULL,
                        .probe_validity = pv.view.obj ? pv.view.buf : NULL,
                        .test_valid = tv.view.obj ? tv.view.buf : NULL,
                        .tolerance = tol,
                        .noise_k = k};
    ao = PyByteArray_FromStringAndSize(NULL, L);
    eo = PyByteArray_FromStringAndSize(NULL, L * 8);
    ho = PyByteArray_FromStringAndSize(NULL, L * 8);
    if (!ao || !eo || !ho) goto done;
    pb_error err = {0};
    pb_result r = pb_refine_decide_axes(t, &tests, &d, (uint8_t *)PyByteArray_AsString(ao),
                                        (double *)(void *)PyByteArray_AsString(eo),
                                        (double *)(void *)PyByteArray_AsString(ho), &err);
    if (r != PB_SUCCESS) {
        _pb_py_raise_core(module, r, &err);
        goto done;
    }
    result = Py_BuildValue("(OOO)", ao, eo, ho);
done:
    Py_XDECREF(ao);
    Py_XDECREF(eo);
    Py_XDECREF(ho);
    _pb_py_release(&lt);
    _pb_py_release(&tp);
    _pb_py_release(&tpr);
    _pb_py_release(&pc);
    _pb_py_release(&tc);
    _pb_py_release(&pn);
    _pb_py_release(&tn);
    _pb_py_release(&pv);
    _pb_py_release(&tv);
    return result;
}

PyMethodDef _pb_py_refine_axes_methods[] = {
    {"refine_tests_axes", py_refine_tests_axes, METH_VARARGS,
     "refine_tests_axes(tree, active=None) -> dict of test points, leaf_tests int32[L*14] (per-axis tests)"},
    {"refine_decide_axes", (PyCFunction)(void (*)(void))py_refine_decide_axes, METH_VARARGS | METH_KEYWORDS,
     "refine_decide_axes(tree, leaf_tests, test_positions, test_probe, max_band, probe_coeffs, test_coeffs, ...) "
     "-> (axes uint8[L]: bit a = split along axis a, error float64[L], threshold float64[L])"},
    {NULL, NULL, 0, NULL},
};
