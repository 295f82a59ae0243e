/* _schnee_native: Probe placement (pb_octree.h): place_probes with a progress callback, placement_classify;
 * native.py "placement" section. */
#include "mod_common.h"

#include "schnee/pb_octree.h"

#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

/* ---- placement -------------------------------------------------------------------------------- */

typedef struct progress_ctx {
    PyObject *callable;
    PyObject *exc_type, *exc_value, *exc_tb; /* the callback's exception, re-raised afterwards */
} progress_ctx;

/* Called by the core with the GIL released, possibly from a worker thread. */
static bool progress_trampoline(void *user, double fraction, const char *stage)
{
    progress_ctx *ctx = user;
    PyGILState_STATE g = PyGILState_Ensure();
    bool keep_going = false;
    if (!ctx->exc_type) {
        PyObject *res = PyObject_CallFunction(ctx->callable, "ds", fraction, stage ? stage : "");
        if (!res) {
            PyErr_Fetch(&ctx->exc_type, &ctx->exc_value, &ctx->exc_tb);
        } else {
            /* None (a callback without return) continues; False or another falsy value cancels. */
            int truth = res == Py_None ? 1 : PyObject_IsTrue(res);
            Py_DECREF(res);
            if (truth < 0) PyErr_Fetch(&ctx->exc_type, &ctx->exc_value, &ctx->exc_tb);
            keep_going = truth > 0;
        }
    }
    PyGILState_Release(g);
    return keep_going;
}

static PyObject *placement_dict(const pb_placement *p)
{
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    size_t n = p->probe_count;
    uint64_t cells = (uint64_t)p->grid_dims[0] * p->grid_dims[1] * p->grid_dims[2];
    if (_pb_py_dict_put(d, "probe_count", PyLong_FromUnsignedLong(p->probe_count)) < 0 ||
        _pb_py_dict_put(d, "positions", _pb_py_bytes_out(p->positions, n * 3 * sizeof(double))) < 0 ||
        _pb_py_dict_put(d, "cell_sizes", _pb_py_bytes_out(p->cell_sizes, n * sizeof(double))) < 0 ||
        _pb_py_dict_put(d, "backface_ratio", _pb_py_bytes_out(p->backface_ratio, n * sizeof(float))) < 0 ||
        _pb_py_dict_put(d, "grid", _pb_py_bytes_out(p->grid, (size_t)cells * sizeof(int32_t))) < 0 ||
        _pb_py_dict_put(d, "grid_dims", Py_BuildValue("(III)", p->grid_dims[0], p->grid_dims[1], p->grid_dims[2])) <
            0 ||
        _pb_py_dict_put(d, "grid_origin",
                        Py_BuildValue("(ddd)", p->grid_origin[0], p->grid_origin[1], p->grid_origin[2])) < 0 ||
        _pb_py_dict_put(d, "grid_spacing", PyFloat_FromDouble(p->grid_spacing)) < 0 ||
        _pb_py_dict_put(d, "leaf_count", PyLong_FromUnsignedLongLong(p->leaf_count)) < 0 ||
        _pb_py_dict_put(d, "pruned_count", PyLong_FromUnsignedLongLong(p->pruned_count)) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

/* An optional length in metres: omitted or None = the core default (0 in the desc); given, it must
 * be a positive finite number (0 is refused here: in Python it is a mistake, not "default"). */
static int get_length(PyObject *obj, const char *name, double *out)
{
    *out = 0.0;
    if (!obj || obj == Py_None) return 0;
    double v = PyFloat_AsDouble(obj);
    if (v == -1.0 && PyErr_Occurred()) return -1;
    if (!(v > 0.0) || !isfinite(v)) {
        char text[64];
        if (isnan(v))
            snprintf(text, sizeof text, "nan");
        else
            snprintf(text, sizeof text, "%g", v);
        PyErr_Format(PyExc_ValueError,
                     "%s must be a positive finite length in metres, got %s (omit it for the default)", name, text);
        return -1;
    }
    *out = v;
    return 0;
}

static PyObject *py_place_probes(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"volumes",  "geometry",        "min_cell_size",        "max_cell_size",  "threads",
                             "progress", "solid_ray_count", "solid_backface_ratio", "max_grid_cells", NULL};
    PyObject *vol_obj, *geo_obj, *progress = Py_None, *min_obj = NULL, *max_obj = NULL;
    double min_cell = 0.0, max_cell = 0.0, backface = 0.0;
    Py_ssize_t threads = 0, rays = 0;
    long long max_cells = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO|OOnOndL:place_probes", kwlist, &vol_obj, &geo_obj, &min_obj,
                                     &max_obj, &threads, &progress, &rays, &backface, &max_cells))
        return NULL;
    if (get_length(min_obj, "min_cell_size", &min_cell) < 0 || get_length(max_obj, "max_cell_size", &max_cell) < 0)
        return NULL;
    if (max_cells < 0)
        return PyErr_Format(PyExc_ValueError,
                            "max_grid_cells must be 0 (the default limit) or a positive cell count, got %lld",
                            max_cells);
    uint32_t threads32, rays32;
    if (_pb_py_check_u32(threads, "threads", &threads32) < 0 || _pb_py_check_u32(rays, "solid_ray_count", &rays32) < 0)
        return NULL;
    if (progress != Py_None && !PyCallable_Check(progress))
        return PyErr_Format(PyExc_TypeError, "progress must be callable(fraction, stage) or None");
    pb_py_meshes vols, geo;
    if (_pb_py_mesh_list_get(vol_obj, "volumes", &vols) < 0) return NULL;
    if (_pb_py_mesh_list_get(geo_obj, "geometry", &geo) < 0) {
        _pb_py_mesh_list_free(&vols);
        return NULL;
    }
    progress_ctx ctx = {progress, NULL, NULL, NULL};
    pb_placement_desc desc = {0};
    desc.volumes = vols.desc;
    desc.volume_count = (uint32_t)vols.count;
    desc.geometry = geo.desc;
    desc.geometry_count = (uint32_t)geo.count;
    desc.min_cell_size = min_cell;
    desc.max_cell_size = max_cell;
    desc.solid_ray_count = rays32;
    desc.solid_backface_ratio = backface;
    desc.max_grid_cells = (uint64_t)max_cells;
    desc.thread_count = threads32;
    if (progress != Py_None) {
        desc.progress = progress_trampoline;
        desc.progress_user = &ctx;
    }
    pb_placement *placement = NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_placement_build(&desc, &placement, &err);
    Py_END_ALLOW_THREADS _pb_py_mesh_list_free(&vols);
    _pb_py_mesh_list_free(&geo);
    if (ctx.exc_type) { /* the callback raised: that exception wins over "cancelled" */
        pb_placement_destroy(placement);
        PyErr_Restore(ctx.exc_type, ctx.exc_value, ctx.exc_tb);
        return NULL;
    }
    if (r != PB_SUCCESS) {
        pb_placement_destroy(placement);
        return _pb_py_raise_core(module, r, &err);
    }
    PyObject *d = placement_dict(placement);
    pb_placement_destroy(placement);
    return d;
}

/* placement_classify(volumes, geometry, points float64[N*3] or None, boxes float64[M*4] or None,
 * min_cell_size=0, max_cell_size=0, threads=0, solid_ray_count=0, solid_backface_ratio=0) ->
 * (inside uint8[N], backface_ratio float32[N], box_class uint8[M]) */
static PyObject *py_placement_classify(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"volumes", "geometry",        "points",
                             "boxes",   "min_cell_size",   "max_cell_size",
                             "threads", "solid_ray_count", "solid_backface_ratio",
                             NULL};
    PyObject *vol_obj, *geo_obj, *p_obj = Py_None, *b_obj = Py_None;
    double min_cell = 0.0, max_cell = 0.0, backface = 0.0;
    Py_ssize_t threads = 0, rays = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO|OOddnnd:placement_classify", kwlist, &vol_obj, &geo_obj, &p_obj,
                                     &b_obj, &min_cell, &max_cell, &threads, &rays, &backface))
        return NULL;
    uint32_t threads32, rays32;
    if (_pb_py_check_u32(threads, "threads", &threads32) < 0 || _pb_py_check_u32(rays, "solid_ray_count", &rays32) < 0)
        return NULL;
    pb_py_buffer pts = {0}, bx = {0};
    if (p_obj != Py_None && _pb_py_get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    if (b_obj != Py_None && _pb_py_get_buffer(b_obj, "boxes", 'd', 4, -1, &bx) < 0) {
        _pb_py_release(&pts);
        return NULL;
    }
    Py_ssize_t n = pts.count / 3, m = bx.count / 4;
    PyObject *in_o = PyByteArray_FromStringAndSize(NULL, n), *ratio_o = PyByteArray_FromStringAndSize(NULL, n * 4);
    PyObject *cls_o = PyByteArray_FromStringAndSize(NULL, m);
    pb_py_meshes vols = {0}, geo = {0};
    PyObject *result = NULL;
    if (!in_o || !ratio_o || !cls_o || n > UINT32_MAX || m > UINT32_MAX) {
        if (in_o && ratio_o && cls_o) PyErr_SetString(PyExc_ValueError, "too many points or boxes");
        goto done;
    }
    if (_pb_py_mesh_list_get(vol_obj, "volumes", &vols) < 0) goto done;
    if (_pb_py_mesh_list_get(geo_obj, "geometry", &geo) < 0) goto done;
    {
        pb_placement_desc desc = {0};
        desc.volumes = vols.desc;
        desc.volume_count = (uint32_t)vols.count;
        desc.geometry = geo.desc;
        desc.geometry_count = (uint32_t)geo.count;
        desc.min_cell_size = min_cell;
        desc.max_cell_size = max_cell;
        desc.solid_ray_count = rays32;
        desc.solid_backface_ratio = backface;
        desc.thread_count = threads32;
        pb_classify_query q = {pts.view.obj ? pts.view.buf : NULL,    (uint32_t)n,
                               (uint8_t *)PyByteArray_AsString(in_o), (float *)(void *)PyByteArray_AsString(ratio_o),
                               bx.view.obj ? bx.view.buf : NULL,      (uint32_t)m,
                               (uint8_t *)PyByteArray_AsString(cls_o)};
        pb_error err = {0};
        pb_result r;
        Py_BEGIN_ALLOW_THREADS r = pb_placement_classify(&desc, &q, &err);
        Py_END_ALLOW_THREADS if (r != PB_SUCCESS) _pb_py_raise_core(module, r, &err);
        else result = Py_BuildValue("(OOO)", in_o, ratio_o, cls_o);
    }
done:
    _pb_py_mesh_list_free(&vols);
    _pb_py_mesh_list_free(&geo);
    Py_XDECREF(in_o);
    Py_XDECREF(ratio_o);
    Py_XDECREF(cls_o);
    _pb_py_release(&pts);
    _pb_py_release(&bx);
    return result;
}

PyMethodDef _pb_py_placement_methods[] = {
    {"place_probes", (PyCFunction)(void (*)(void))py_place_probes, METH_VARARGS | METH_KEYWORDS,
     "place_probes(volumes, geometry, min_cell_size=None, max_cell_size=None, threads=0, progress=None, "
     "solid_ray_count=0, solid_backface_ratio=0, max_grid_cells=0) -> dict; sizes in metres, None = default "
     "(0, negative, NaN, Inf refused), max_grid_cells 0 = default limit (negative refused)"},
    {"placement_classify", (PyCFunction)(void (*)(void))py_placement_classify, METH_VARARGS | METH_KEYWORDS,
     "placement_classify(volumes, geometry, points=None, boxes=None, ...) -> (inside, backface_ratio, box_class)"},
    {NULL, NULL, 0, NULL},
};
