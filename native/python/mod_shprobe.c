/* _schnee_native: .shprobe files (pb_shprobe.h): read (file, memory, header), write versions 1/2 and 3 (of an
 * interpolation handle), grid lookup, dense resampling; native.py ".shprobe" section. */
#include "mod_common.h"

#include "schnee/pb_interp.h"
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* ---- .shprobe --------------------------------------------------------------------------------- */

static int header_into_dict(PyObject *d, const pb_shprobe *p)
{
    const float *a = p->grid_axes;
    return (_pb_py_dict_put(d, "version", PyLong_FromUnsignedLong(p->version)) < 0 ||
            _pb_py_dict_put(d, "probe_count", PyLong_FromUnsignedLong(p->probe_count)) < 0 ||
            _pb_py_dict_put(d, "max_band", PyLong_FromUnsignedLong(p->max_band)) < 0 ||
            _pb_py_dict_put(d, "grid_dims", Py_BuildValue("(III)", p->grid_dims[0], p->grid_dims[1], p->grid_dims[2])) <
                0 ||
            _pb_py_dict_put(d, "grid_origin",
                            Py_BuildValue("(ddd)", (double)p->grid_origin[0], (double)p->grid_origin[1],
                                          (double)p->grid_origin[2])) < 0 ||
            _pb_py_dict_put(d, "grid_spacing", PyFloat_FromDouble(p->grid_spacing)) < 0 ||
            _pb_py_dict_put(d, "grid_axes",
                            Py_BuildValue("((ddd)(ddd)(ddd))", (double)a[0], (double)a[1], (double)a[2], (double)a[3],
                                          (double)a[4], (double)a[5], (double)a[6], (double)a[7], (double)a[8])) < 0 ||
            _pb_py_dict_put(d, "default_sh_scale", PyFloat_FromDouble(p->default_sh_scale)) < 0 ||
            _pb_py_dict_put(d, "default_ambient", PyFloat_FromDouble(p->default_ambient)) < 0)
               ? -1
               : 0;
}

/* Version 3 and 4 fields (versions 1/2 read back SH, float32, grid, no structure arrays; the kd corner
 * tree's leaves hold packed levels, its root level and split tree follow). */
static int v3_into_dict(PyObject *d, const pb_shprobe *p)
{
    size_t N = p->element_count, H = p->hanging_count, K = p->split_node_count;
    bool kd = p->structure == PB_SHPROBE_KDTREE, tet = p->structure == PB_SHPROBE_TETRA;
    bool oct = p->structure == PB_SHPROBE_OCTREE || kd;
    if (_pb_py_dict_put(d, "root_level", PyLong_FromUnsignedLong(p->root_level)) < 0 ||
        _pb_py_dict_put(d, "split_nodes", kd ? _pb_py_bytes_out(p->split_nodes, K * 4) : Py_NewRef(Py_None)) < 0)
        return -1;
    return (_pb_py_dict_put(d, "representation", PyLong_FromUnsignedLong(p->representation)) < 0 ||
            _pb_py_dict_put(d, "storage", PyLong_FromUnsignedLong(p->storage)) < 0 ||
            _pb_py_dict_put(d, "structure", PyLong_FromUnsignedLong(p->structure)) < 0 ||
            _pb_py_dict_put(d, "element_count", PyLong_FromUnsignedLong(p->element_count)) < 0 ||
            _pb_py_dict_put(d, "hanging_count", PyLong_FromUnsignedLong(p->hanging_count)) < 0 ||
            _pb_py_dict_put(d, "leaves", oct ? _pb_py_bytes_out(p->leaves, N * 16) : Py_NewRef(Py_None)) < 0 ||
            _pb_py_dict_put(d, "leaf_corners", oct ? _pb_py_bytes_out(p->leaf_corners, N * 32) : Py_NewRef(Py_None)) <
                0 ||
            _pb_py_dict_put(d, "hanging_sources",
                            oct ? _pb_py_bytes_out(p->hanging_sources, H * 16) : Py_NewRef(Py_None)) < 0 ||
            _pb_py_dict_put(d, "hanging_weights",
                            oct ? _pb_py_bytes_out(p->hanging_weights, H * 16) : Py_NewRef(Py_None)) < 0 ||
            _pb_py_dict_put(d, "tets", tet ? _pb_py_bytes_out(p->tets, N * 16) : Py_NewRef(Py_None)) < 0 ||
            _pb_py_dict_put(d, "tet_neighbours",
                            tet ? _pb_py_bytes_out(p->tet_neighbours, N * 16) : Py_NewRef(Py_None)) < 0)
               ? -1
               : 0;
}

static PyObject *shprobe_dict(const pb_shprobe *p)
{
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    size_t n = p->probe_count;
    size_t cells = p->grid ? (size_t)p->grid_dims[0] * p->grid_dims[1] * p->grid_dims[2] : 0;
    PyObject *positions = p->positions ? _pb_py_bytes_out(p->positions, n * 3 * sizeof(float)) : Py_NewRef(Py_None);
    if (header_into_dict(d, p) < 0 ||
        _pb_py_dict_put(d, "coeffs", _pb_py_bytes_out(p->coeffs, n * pb_shprobe_colour_count(p) * 3 * sizeof(float))) <
            0 ||
        _pb_py_dict_put(d, "probe_scale", _pb_py_bytes_out(p->probe_scale, n * sizeof(float))) < 0 ||
        _pb_py_dict_put(d, "probe_ambient", _pb_py_bytes_out(p->probe_ambient, n * sizeof(float))) < 0 ||
        _pb_py_dict_put(d, "validity", _pb_py_bytes_out(p->validity, n * sizeof(float))) < 0 ||
        _pb_py_dict_put(d, "positions", positions) < 0 ||
        _pb_py_dict_put(d, "grid", p->grid ? _pb_py_bytes_out(p->grid, cells * sizeof(int32_t)) : Py_NewRef(Py_None)) <
            0 ||
        v3_into_dict(d, p) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

static PyObject *py_shprobe_read(PyObject *module, PyObject *args)
{
    PyObject *path = NULL;
    if (!PyArg_ParseTuple(args, "O&:shprobe_read", PyUnicode_FSConverter, &path)) return NULL;
    const char *cpath = PyBytes_AsString(path);
    pb_shprobe *p = NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_shprobe_read(cpath, &p, &err);
    Py_END_ALLOW_THREADS Py_DECREF(path);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    PyObject *d = shprobe_dict(p);
    pb_shprobe_destroy(p);
    return d;
}

/* A read on a thread of its own that runs no Python (the viewport overlay's background read,
 * overlay_data.Reader): Blender 3.4's main thread can take the GIL from a Python thread that holds it
 * (its BPY_thread_save), so a Python worker thread crashes it; this one parses the file in C only and
 * the caller turns the result into a dict on its own thread (shprobe_read_poll). The job is freed by
 * whichever of the thread and the capsule lets go last. */
typedef struct read_job {
    atomic_int refs;
    atomic_int done;
    char *path;
    pb_shprobe *probes;
    pb_result result;
    pb_error err;
} read_job;

static const char READ_JOB[] = "schnee.shprobe_read_job";

static void read_job_release(read_job *j)
{
    if (atomic_fetch_sub(&j->refs, 1) != 1) return;
    pb_shprobe_destroy(j->probes);
    free(j->path);
    free(j);
}

static void *read_job_run(void *arg)
{
    read_job *j = arg;
    j->result = pb_shprobe_read(j->path, &j->probes, &j->err);
    atomic_store(&j->done, 1);
    read_job_release(j);
    return NULL;
}

static void read_job_capsule_free(PyObject *capsule)
{
    read_job *j = PyCapsule_GetPointer(capsule, READ_JOB);
    if (j) read_job_release(j);
}

static PyObject *py_shprobe_read_start(PyObject *module, PyObject *args)
{
    (void)module;
    PyObject *path = NULL;
    if (!PyArg_ParseTuple(args, "O&:shprobe_read_start", PyUnicode_FSConverter, &path)) return NULL;
    read_job *j = calloc(1, sizeof *j);
    char *cpath = j ? strdup(PyBytes_AsString(path)) : NULL;
    Py_DECREF(path);
    if (!cpath) {
        free(j);
        return PyErr_NoMemory();
    }
    j->path = cpath;
    atomic_init(&j->refs, 2);
    atomic_init(&j->done, 0);
    PyObject *capsule = PyCapsule_New(j, READ_JOB, read_job_capsule_free);
    if (!capsule) {
        free(cpath);
        free(j);
        return NULL;
    }
    pthread_attr_t attr;
    pthread_t thread;
    int rc = pthread_attr_init(&attr);
    if (rc == 0) {
        pthread_attr_setdetachstate(&attr, PTHREAD_CREATE_DETACHED);
        rc = pthread_create(&thread, &attr, read_job_run, j);
        pthread_attr_destroy(&attr);
    }
    if (rc != 0) {
        atomic_store(&j->refs, 1); /* the capsule's reference only: freed with it */
        Py_DECREF(capsule);
        errno = rc;
        return PyErr_SetFromErrno(PyExc_OSError);
    }
    return capsule;
}

static PyObject *py_shprobe_read_poll(PyObject *module, PyObject *args)
{
    PyObject *capsule;
    if (!PyArg_ParseTuple(args, "O:shprobe_read_poll", &capsule)) return NULL;
    read_job *j = PyCapsule_GetPointer(capsule, READ_JOB);
    if (!j) return NULL;
    if (!atomic_load(&j->done)) Py_RETURN_NONE;
    if (j->result != PB_SUCCESS) return _pb_py_raise_core(module, j->result, &j->err);
    return shprobe_dict(j->probes);
}

static PyObject *py_shprobe_read_memory(PyObject *module, PyObject *args)
{
    PyObject *obj;
    if (!PyArg_ParseTuple(args, "O:shprobe_read_memory", &obj)) return NULL;
    Py_buffer view;
    if (PyObject_GetBuffer(obj, &view, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    pb_shprobe *p = NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_shprobe_read_memory(view.buf, (size_t)view.len, &p, &err);
    Py_END_ALLOW_THREADS PyBuffer_Release(&view);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    PyObject *d = shprobe_dict(p);
    pb_shprobe_destroy(p);
    return d;
}

static PyObject *py_shprobe_read_header(PyObject *module, PyObject *args)
{
    PyObject *path = NULL;
    if (!PyArg_ParseTuple(args, "O&:shprobe_read_header", PyUnicode_FSConverter, &path)) return NULL;
    const char *cpath = PyBytes_AsString(path);
    pb_shprobe h;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_shprobe_read_header(cpath, &h, &err);
    Py_END_ALLOW_THREADS Py_DECREF(path);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    PyObject *d = PyDict_New();
    if (d && header_into_dict(d, &h) < 0) Py_CLEAR(d);
    return d;
}

/* Optional per-probe float32 array of `n` items. */
static int get_optional(PyObject *obj, const char *name, Py_ssize_t n, pb_py_buffer *out)
{
    memset(out, 0, sizeof *out);
    if (obj == NULL || obj == Py_None) return 0;
    return _pb_py_get_buffer(obj, name, 'f', 0, n, out);
}

static PyObject *py_shprobe_write(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {
        "path",         "coeffs",           "max_band",        "grid",      "grid_dims",   "grid_origin",
        "grid_spacing", "default_sh_scale", "default_ambient", "positions", "probe_scale", "probe_ambient",
        "validity",     "grid_axes",        "version",         NULL};
    PyObject *path = NULL, *c_obj, *g_obj, *pos_obj = Py_None, *scale_obj = Py_None;
    PyObject *amb_obj = Py_None, *val_obj = Py_None, *axes_obj = Py_None;
    long band, version = 0;
    Py_ssize_t dims[3];
    float origin[3], spacing, def_scale = 1.0f, def_ambient = 0.1f;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&OlO(nnn)(fff)f|ffOOOOOl:shprobe_write", kwlist, PyUnicode_FSConverter,
                                     &path, &c_obj, &band, &g_obj, &dims[0], &dims[1], &dims[2], &origin[0], &origin[1],
                                     &origin[2], &spacing, &def_scale, &def_ambient, &pos_obj, &scale_obj, &amb_obj,
                                     &val_obj, &axes_obj, &version))
        return NULL;
    pb_shprobe p;
    memset(&p, 0, sizeof p);
    pb_py_buffer coeffs = {0}, grid = {0}, pos = {0}, scale = {0}, amb = {0}, val = {0}, axes = {0};
    PyObject *result = NULL;
    if (_pb_py_check_band(band) < 0) goto done;
    if (version < 0 || version > 2) {
        PyErr_Format(PyExc_ValueError, "version %ld: expected 0 (auto), 1 or 2", version);
        goto done;
    }
    for (int i = 0; i < 3; i++)
        if (_pb_py_check_u32(dims[i], "grid_dims entry", &p.grid_dims[i]) < 0) goto done;
    Py_ssize_t per_probe = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    if (_pb_py_get_buffer(c_obj, "coeffs", 'f', per_probe, -1, &coeffs) < 0) goto done;
    Py_ssize_t n = coeffs.count / per_probe;
    if (n > UINT32_MAX) {
        PyErr_Format(PyExc_ValueError, "%zd probes exceed the file's uint32 probe count", n);
        goto done;
    }
    Py_ssize_t cells = _pb_py_product3(dims[0], dims[1], dims[2], "grid_dims");
    if (cells < 0 || _pb_py_get_buffer(g_obj, "grid", 'i', 0, cells, &grid) < 0) goto done;
    if (pos_obj != Py_None && _pb_py_get_buffer(pos_obj, "positions", 'f', 0, n * 3, &pos) < 0) goto done;
    if (get_optional(scale_obj, "probe_scale", n, &scale) < 0 || get_optional(amb_obj, "probe_ambient", n, &amb) < 0 ||
        get_optional(val_obj, "validity", n, &val) < 0 || get_optional(axes_obj, "grid_axes", 9, &axes) < 0)
        goto done;
    p.version = (uint32_t)version;
    p.probe_count = (uint32_t)n;
    p.max_band = (uint32_t)band;
    memcpy(p.grid_origin, origin, sizeof origin);
    p.grid_spacing = spacing;
    p.default_sh_scale = def_scale;
    p.default_ambient = def_ambient;
    p.coeffs = coeffs.view.buf;
    p.grid = grid.view.buf;
    p.positions = pos.view.obj ? pos.view.buf : NULL;
    p.probe_scale = scale.view.obj ? scale.view.buf : NULL;
    p.probe_ambient = amb.view.obj ? amb.view.buf : NULL;
    p.validity = val.view.obj ? val.view.buf : NULL;
    if (axes.view.obj) memcpy(p.grid_axes, axes.view.buf, sizeof p.grid_axes);
    {
        const char *cpath = PyBytes_AsString(path);
        pb_error err = {0};
        pb_shprobe written;
        pb_result r;
        Py_BEGIN_ALLOW_THREADS r = pb_shprobe_write(cpath, &p, &err);
        /* Report the version actually chosen by reading back the header just written. */
        if (r == PB_SUCCESS) r = pb_shprobe_read_header(cpath, &written, &err);
        Py_END_ALLOW_THREADS if (r != PB_SUCCESS) _pb_py_raise_core(module, r, &err);
        else result = PyLong_FromUnsignedLong(written.version);
    }
done:
    _pb_py_release(&coeffs);
    _pb_py_release(&grid);
    _pb_py_release(&pos);
    _pb_py_release(&scale);
    _pb_py_release(&amb);
    _pb_py_release(&val);
    _pb_py_release(&axes);
    Py_DECREF(path);
    return result;
}

static PyObject *py_shprobe_lookup(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"grid",        "grid_dims", "grid_origin", "grid_spacing",
                             "probe_count", "points",    "grid_axes",   NULL};
    PyObject *g_obj, *pts_obj, *axes_obj = Py_None;
    Py_ssize_t dims[3], count;
    float origin[3], spacing;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O(nnn)(fff)fnO|O:shprobe_lookup", kwlist, &g_obj, &dims[0], &dims[1],
                                     &dims[2], &origin[0], &origin[1], &origin[2], &spacing, &count, &pts_obj,
                                     &axes_obj))
        return NULL;
    pb_shprobe p;
    memset(&p, 0, sizeof p);
    for (int i = 0; i < 3; i++)
        if (_pb_py_check_u32(dims[i], "grid_dims entry", &p.grid_dims[i]) < 0) return NULL;
    if (_pb_py_check_u32(count, "probe_count", &p.probe_count) < 0) return NULL;
    pb_py_buffer grid, pts, axes;
    Py_ssize_t cells = _pb_py_product3(dims[0], dims[1], dims[2], "grid_dims");
    if (cells < 0 || _pb_py_get_buffer(g_obj, "grid", 'i', 0, cells, &grid) < 0) return NULL;
    if (_pb_py_get_buffer(pts_obj, "points", 'f', 3, -1, &pts) < 0) {
        _pb_py_release(&grid);
        return NULL;
    }
    if (get_optional(axes_obj, "grid_axes", 9, &axes) < 0) {
        _pb_py_release(&grid);
        _pb_py_release(&pts);
        return NULL;
    }
    memcpy(p.grid_origin, origin, sizeof origin);
    p.grid_spacing = spacing;
    p.grid = grid.view.buf;
    if (axes.view.obj) memcpy(p.grid_axes, axes.view.buf, sizeof p.grid_axes);
    Py_ssize_t n = pts.count / 3;
    PyObject *out = PyByteArray_FromStringAndSize(NULL, n * 4);
    if (out) {
        int32_t *o = (int32_t *)(void *)PyByteArray_AsString(out);
        const float *pt = pts.view.buf;
        for (Py_ssize_t i = 0; i < n; i++) o[i] = pb_shprobe_lookup(&p, pt + 3 * i);
    }
    _pb_py_release(&grid);
    _pb_py_release(&pts);
    _pb_py_release(&axes);
    return out;
}

static PyObject *py_shprobe_write_v3(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path",     "handle",           "coeffs",          "representation",
                             "max_band", "storage",          "probe_scale",     "probe_ambient",
                             "validity", "default_sh_scale", "default_ambient", NULL};
    PyObject *path = NULL, *h_obj, *c_obj, *scale_obj = Py_None, *amb_obj = Py_None, *val_obj = Py_None;
    long repr, band, storage = 0;
    float def_scale = 1.0f, def_ambient = 0.1f;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&OOll|lOOOff:shprobe_write_v3", kwlist, PyUnicode_FSConverter, &path,
                                     &h_obj, &c_obj, &repr, &band, &storage, &scale_obj, &amb_obj, &val_obj, &def_scale,
                                     &def_ambient))
        return NULL;
    PyObject *result = NULL;
    pb_shprobe *f = NULL;
    pb_py_buffer coeffs = {0}, scale = {0}, amb = {0}, val = {0};
    pb_error err = {0};
    pb_result r = PB_SUCCESS;
    if (_pb_py_check_band(band) < 0) goto done;
    if (repr < 0 || repr > 1 || storage < 0 || storage > 1) {
        PyErr_Format(PyExc_ValueError, "representation %ld / storage %ld: expected 0 or 1", repr, storage);
        goto done;
    }
    if (PyCapsule_IsValid(h_obj, PB_PY_CAP_COTREE))
        r = pb_shprobe_from_cotree(PyCapsule_GetPointer(h_obj, PB_PY_CAP_COTREE), (uint32_t)repr, (uint32_t)band, &f,
                                   &err);
    else if (PyCapsule_IsValid(h_obj, PB_PY_CAP_TETRA))
        r = pb_shprobe_from_tetra(PyCapsule_GetPointer(h_obj, PB_PY_CAP_TETRA), NULL, (uint32_t)repr, (uint32_t)band,
                                  &f, &err);
    else {
        PyErr_SetString(PyExc_TypeError, "expected a corner octree or tetrahedra handle");
        goto done;
    }
    if (r != PB_SUCCESS) {
        _pb_py_raise_core(module, r, &err);
        goto done;
    }
    Py_ssize_t n = f->probe_count, per = (Py_ssize_t)pb_shprobe_colour_count(f) * 3;
    if (_pb_py_get_buffer(c_obj, "coeffs", 'f', 0, n * per, &coeffs) < 0 ||
        get_optional(scale_obj, "probe_scale", n, &scale) < 0 || get_optional(amb_obj, "probe_ambient", n, &amb) < 0 ||
        get_optional(val_obj, "validity", n, &val) < 0)
        goto done;
    memcpy(f->coeffs, coeffs.view.buf, (size_t)(n * per) * sizeof(float));
    f->default_sh_scale = def_scale;
    f->default_ambient = def_ambient;
    for (Py_ssize_t i = 0; i < n; i++) {
        f->probe_scale[i] = scale.view.obj ? ((const float *)scale.view.buf)[i] : 1.0f;
        f->probe_ambient[i] = amb.view.obj ? ((const float *)amb.view.buf)[i] : def_ambient;
        f->validity[i] = val.view.obj ? ((const float *)val.view.buf)[i] : 1.0f;
    }
    f->storage = (uint32_t)storage;
    {
        const char *cpath = PyBytes_AsString(path);
        Py_BEGIN_ALLOW_THREADS r = pb_shprobe_write(cpath, f, &err);
        Py_END_ALLOW_THREADS if (r != PB_SUCCESS) _pb_py_raise_core(module, r, &err);
        else result = PyLong_FromSize_t((size_t)n);
    }
done:
    _pb_py_release(&coeffs);
    _pb_py_release(&scale);
    _pb_py_release(&amb);
    _pb_py_release(&val);
    pb_shprobe_destroy(f);
    Py_DECREF(path);
    return result;
}

static PyObject *py_shprobe_resample_dense(PyObject *module, PyObject *args)
{
    PyObject *path = NULL;
    double spacing = 0.0;
    if (!PyArg_ParseTuple(args, "O&|d:shprobe_resample_dense", PyUnicode_FSConverter, &path, &spacing)) return NULL;
    pb_shprobe *f = NULL, *g = NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_shprobe_read(PyBytes_AsString(path), &f, &err);
    if (r == PB_SUCCESS) r = pb_interp_resample_dense(f, spacing, &g, &err);
    Py_END_ALLOW_THREADS Py_DECREF(path);
    pb_shprobe_destroy(f);
    if (r != PB_SUCCESS) return _pb_py_raise_core(module, r, &err);
    PyObject *d = shprobe_dict(g);
    pb_shprobe_destroy(g);
    return d;
}

PyMethodDef _pb_py_shprobe_methods[] = {
    {"shprobe_write", (PyCFunction)(void (*)(void))py_shprobe_write, METH_VARARGS | METH_KEYWORDS,
     "shprobe_write(path, coeffs, max_band, grid, grid_dims, grid_origin, grid_spacing, "
     "default_sh_scale=1, default_ambient=0.1, positions=None, probe_scale=None, probe_ambient=None, "
     "validity=None, grid_axes=None, version=0) -> version written"},
    {"shprobe_read", py_shprobe_read, METH_VARARGS, "shprobe_read(path) -> dict"},
    {"shprobe_read_start", py_shprobe_read_start, METH_VARARGS,
     "shprobe_read_start(path) -> job: shprobe_read on a thread that runs no Python"},
    {"shprobe_read_poll", py_shprobe_read_poll, METH_VARARGS,
     "shprobe_read_poll(job) -> None while reading, then shprobe_read's dict (or its error), each call"},
    {"shprobe_read_memory", py_shprobe_read_memory, METH_VARARGS, "shprobe_read_memory(buffer) -> dict"},
    {"shprobe_read_header", py_shprobe_read_header, METH_VARARGS, "shprobe_read_header(path) -> dict"},
    {"shprobe_lookup", (PyCFunction)(void (*)(void))py_shprobe_lookup, METH_VARARGS | METH_KEYWORDS,
     "shprobe_lookup(grid, grid_dims, grid_origin, grid_spacing, probe_count, points: float32[N*3], "
     "grid_axes=None) -> bytearray int32[N]"},
    {"shprobe_write_v3", (PyCFunction)(void (*)(void))py_shprobe_write_v3, METH_VARARGS | METH_KEYWORDS,
     "shprobe_write_v3(path, handle, coeffs, representation, max_band, storage=0, ...) -> probe count"},
    {"shprobe_resample_dense", py_shprobe_resample_dense, METH_VARARGS,
     "shprobe_resample_dense(path, spacing=0) -> dict (a dense grid file image, SH only)"},
    {NULL, NULL, 0, NULL},
};
