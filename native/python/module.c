/* _schnee_native: the CPython face of the bake core (stable ABI, Py_LIMITED_API 3.11).
 *
 * The limited API has the buffer protocol but no numpy C API, so arrays come in as C-contiguous
 * buffers whose format and length are checked here (addon/schnee_probes/native.py makes them so
 * with numpy and gives them shapes), and go out as bytearrays that native.py wraps with
 * np.frombuffer (writable, no copy). Long core calls run with the GIL released; the placement
 * progress callback takes the GIL back to call Python. Core errors are raised as the class
 * registered with _set_error_class (native.SchneeError), default _schnee_native.Error, with the
 * core's message verbatim and `.code` = pb_result_string(code).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "schnee/pb_ambient_cube.h"
#include "schnee/pb_direct.h"
#include "schnee/pb_interp.h"
#include "schnee/pb_octree.h"
#include "schnee/pb_refine.h"
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"
#include "schnee/pb_sky_sun.h"
#ifdef SCHNEE_EMBREE_DYN
#include "pb_embree_dyn.h"
#endif

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct module_state {
    PyObject *error_class; /* raised for core errors */
} module_state;

static module_state *get_state(PyObject *module) { return (module_state *)PyModule_GetState(module); }

/* Raises the registered error class with the core's message and `.code`. Returns NULL. */
static PyObject *raise_core(PyObject *module, pb_result r, const pb_error *err)
{
    PyObject *cls = get_state(module)->error_class;
    const char *msg = err && err->message[0] ? err->message : pb_result_string(r);
    PyObject *exc = PyObject_CallFunction(cls, "s", msg);
    if (!exc) return NULL;
    PyObject *code = PyUnicode_FromString(pb_result_string(r));
    if (!code || PyObject_SetAttrString(exc, "code", code) < 0) {
        Py_XDECREF(code);
        Py_DECREF(exc);
        return NULL;
    }
    Py_DECREF(code);
    PyErr_SetObject(cls, exc);
    Py_DECREF(exc);
    return NULL;
}

/* ---- argument helpers ------------------------------------------------------------------------- */

/* A held buffer; `view.obj == NULL` means none. */
typedef struct held_buffer {
    Py_buffer view;
    Py_ssize_t count; /* number of items */
} held_buffer;

static void release(held_buffer *b)
{
    if (b->view.obj) PyBuffer_Release(&b->view);
    b->view.obj = NULL;
}

static const char *type_name(char code)
{
    switch (code) {
    case 'd': return "float64";
    case 'f': return "float32";
    case 'i': return "int32";
    case 'I': return "uint32";
    case 'B': return "uint8";
    }
    return "?";
}

/* Gets a C-contiguous buffer of `code` items ('d', 'f', 'i', 'I'; native byte order) from obj.
 * multiple > 0: the item count must be a multiple of it; expected >= 0: the count must equal it. */
static int get_buffer(PyObject *obj, const char *name, char code, Py_ssize_t multiple, Py_ssize_t expected,
                      held_buffer *out)
{
    memset(out, 0, sizeof *out);
    if (PyObject_GetBuffer(obj, &out->view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
        PyErr_Clear();
        out->view.obj = NULL;
        PyObject *tname = PyType_GetName(Py_TYPE(obj));
        PyErr_Format(PyExc_TypeError,
                     "%s must be a C-contiguous %s buffer (e.g. numpy.ascontiguousarray(x, "
                     "dtype=numpy.%s)), got %S",
                     name, type_name(code), type_name(code), tname ? tname : Py_None);
        Py_XDECREF(tname);
        return -1;
    }
    const char *fmt = out->view.format ? out->view.format : "B";
    if (*fmt == '@' || *fmt == '=' || (*fmt == '<' && PY_LITTLE_ENDIAN) || (*fmt == '>' && PY_BIG_ENDIAN)) fmt++;
    Py_ssize_t itemsize = code == 'd' ? 8 : (code == 'B' ? 1 : 4);
    bool ok = fmt[0] != '\0' && fmt[1] == '\0' && out->view.itemsize == itemsize &&
              (fmt[0] == code || (code == 'i' && fmt[0] == 'l') || (code == 'I' && fmt[0] == 'L'));
    if (!ok) {
        PyErr_Format(PyExc_TypeError, "%s must hold %s items, got buffer format '%s' (%zd bytes per item)", name,
                     type_name(code), out->view.format ? out->view.format : "B", out->view.itemsize);
        release(out);
        return -1;
    }
    out->count = out->view.len / itemsize;
    if (multiple > 0 && out->count % multiple != 0) {
        PyErr_Format(PyExc_ValueError, "%s has %zd items, not a multiple of %zd", name, out->count, multiple);
        release(out);
        return -1;
    }
    if (expected >= 0 && out->count != expected) {
        PyErr_Format(PyExc_ValueError, "%s has %zd items, expected %zd", name, out->count, expected);
        release(out);
        return -1;
    }
    return 0;
}

static int check_band(long band)
{
    if (band < 0 || band > PB_SH_MAX_BAND) {
        PyErr_Format(PyExc_ValueError, "max_band %ld is out of range 0..%d", band, PB_SH_MAX_BAND);
        return -1;
    }
    return 0;
}

static int check_u32(Py_ssize_t v, const char *name, uint32_t *out)
{
    if (v < 0 || (unsigned long long)v > UINT32_MAX) {
        PyErr_Format(PyExc_ValueError, "%s %zd is out of range 0..4294967295", name, v);
        return -1;
    }
    *out = (uint32_t)v;
    return 0;
}

/* a*b*c as Py_ssize_t, or -1 with ValueError when it overflows. */
static Py_ssize_t product3(Py_ssize_t a, Py_ssize_t b, Py_ssize_t c, const char *what)
{
    unsigned long long r = 0;
    if (a < 0 || b < 0 || c < 0 || __builtin_mul_overflow((unsigned long long)a, (unsigned long long)b, &r) ||
        __builtin_mul_overflow(r, (unsigned long long)c, &r) || r > (unsigned long long)PY_SSIZE_T_MAX) {
        PyErr_Format(PyExc_ValueError, "%s %zd x %zd x %zd is too large", what, a, b, c);
        return -1;
    }
    return (Py_ssize_t)r;
}

static PyObject *bytes_out(const void *data, size_t size)
{
    return PyByteArray_FromStringAndSize((const char *)data, (Py_ssize_t)size);
}

/* Optional 3x3 rotation: None or 9 float64. */
static int get_rotation(PyObject *obj, held_buffer *out)
{
    memset(out, 0, sizeof *out);
    if (obj == NULL || obj == Py_None) return 0;
    return get_buffer(obj, "rotation", 'd', 0, 9, out);
}

/* ---- SH --------------------------------------------------------------------------------------- */

static PyObject *py_sh_basis(PyObject *module, PyObject *args)
{
    PyObject *dirs_obj;
    long band;
    if (!PyArg_ParseTuple(args, "Ol:sh_basis", &dirs_obj, &band) || check_band(band) < 0) return NULL;
    held_buffer dirs;
    if (get_buffer(dirs_obj, "dirs", 'd', 3, -1, &dirs) < 0) return NULL;
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
    release(&dirs);
    return out;
}

static PyObject *py_min_panorama_size(PyObject *module, PyObject *args)
{
    long band;
    if (!PyArg_ParseTuple(args, "l:min_panorama_size", &band) || check_band(band) < 0) return NULL;
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
    if (check_band(band) < 0 || check_negative(negative) < 0 || check_u32(width, "width", &w) < 0 ||
        check_u32(height, "height", &h) < 0 || check_u32(channels, "channels", &c) < 0)
        return NULL;
    if (c < 3) return PyErr_Format(PyExc_ValueError, "channels %u: at least 3 (RGB first) are needed", c);
    held_buffer pix, rot;
    Py_ssize_t expected = product3(width, height, channels, "width x height x channels");
    if (expected < 0 || get_buffer(pix_obj, "pixels", 'f', 0, expected, &pix) < 0) return NULL;
    if (get_rotation(rot_obj, &rot) < 0) {
        release(&pix);
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
    Py_END_ALLOW_THREADS release(&pix);
    release(&rot);
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    return bytes_out(out, pb_sh_count((uint32_t)band) * 3 * sizeof(double));
}

static PyObject *py_project_file(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"path", "max_band", "rotation", "negative", NULL};
    PyObject *path = NULL, *rot_obj = Py_None;
    long band = 2, negative = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "O&|lOl:project_file", kwlist, PyUnicode_FSConverter, &path, &band,
                                     &rot_obj, &negative))
        return NULL;
    held_buffer rot;
    if (check_band(band) < 0 || check_negative(negative) < 0 || get_rotation(rot_obj, &rot) < 0) {
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
    Py_END_ALLOW_THREADS release(&rot);
    Py_DECREF(path);
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    return bytes_out(out, pb_sh_count((uint32_t)band) * 3 * sizeof(double));
}

static PyObject *py_irradiance(PyObject *module, PyObject *args)
{
    PyObject *c_obj, *n_obj;
    long band;
    if (!PyArg_ParseTuple(args, "OlO:irradiance", &c_obj, &band, &n_obj) || check_band(band) < 0) return NULL;
    held_buffer coeffs, normals;
    if (get_buffer(c_obj, "coeffs", 'd', 0, (Py_ssize_t)pb_sh_count((uint32_t)band) * 3, &coeffs) < 0) return NULL;
    if (get_buffer(n_obj, "normals", 'd', 3, -1, &normals) < 0) {
        release(&coeffs);
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
    release(&coeffs);
    release(&normals);
    return out;
}

static PyObject *py_window(PyObject *module, PyObject *args)
{
    PyObject *c_obj;
    long band, kind;
    double strength;
    if (!PyArg_ParseTuple(args, "Olld:window", &c_obj, &band, &kind, &strength) || check_band(band) < 0) return NULL;
    if (kind < PB_SH_WINDOW_NONE || kind > PB_SH_WINDOW_LAPLACIAN)
        return PyErr_Format(PyExc_ValueError, "window kind %ld is out of range 0..2", kind);
    held_buffer coeffs;
    Py_ssize_t n = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    if (get_buffer(c_obj, "coeffs", 'd', 0, n, &coeffs) < 0) return NULL;
    double work[PB_SH_MAX_COEFFS * 3], min_e[3] = {0, 0, 0};
    memcpy(work, coeffs.view.buf, (size_t)n * sizeof(double));
    release(&coeffs);
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_sh_window((uint32_t)band, (pb_sh_window_kind)kind, strength, work, min_e, &err);
    Py_END_ALLOW_THREADS if (r != PB_SUCCESS) return raise_core(module, r, &err);
    PyObject *out = bytes_out(work, (size_t)n * sizeof(double));
    if (!out) return NULL;
    return Py_BuildValue("(N(ddd))", out, min_e[0], min_e[1], min_e[2]);
}

/* ---- placement -------------------------------------------------------------------------------- */

typedef struct mesh_list {
    Py_ssize_t count;
    pb_mesh_desc *desc;
    held_buffer *verts, *tris;
    PyObject **items; /* strong references to the (name, verts, tris) items, kept alive */
} mesh_list;

static void mesh_list_free(mesh_list *m)
{
    for (Py_ssize_t i = 0; i < m->count; i++) {
        if (m->verts) release(&m->verts[i]);
        if (m->tris) release(&m->tris[i]);
        if (m->items) Py_XDECREF(m->items[i]);
    }
    free(m->desc);
    free(m->verts);
    free(m->tris);
    free(m->items);
    memset(m, 0, sizeof *m);
}

static int mesh_list_get(PyObject *seq, const char *what, mesh_list *m)
{
    memset(m, 0, sizeof *m);
    Py_ssize_t n = PySequence_Size(seq);
    if (n < 0) {
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "%s must be a sequence of (name, vertices, triangles)", what);
        return -1;
    }
    if (n > UINT32_MAX) {
        PyErr_Format(PyExc_ValueError, "%s: too many meshes", what);
        return -1;
    }
    m->desc = calloc((size_t)n + 1, sizeof *m->desc);
    m->verts = calloc((size_t)n + 1, sizeof *m->verts);
    m->tris = calloc((size_t)n + 1, sizeof *m->tris);
    m->items = calloc((size_t)n + 1, sizeof *m->items);
    if (!m->desc || !m->verts || !m->tris || !m->items) {
        mesh_list_free(m);
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        m->count = i + 1;
        PyObject *item = PySequence_GetItem(seq, i);
        m->items[i] = item;
        if (!item) goto fail;
        PyObject *name = NULL, *v = NULL, *t = NULL;
        if (!PyArg_ParseTuple(item, "OOO", &name, &v, &t)) {
            PyErr_Format(PyExc_TypeError, "%s[%zd] must be a (name, vertices, triangles) tuple", what, i);
            goto fail;
        }
        if (name != Py_None) {
            m->desc[i].name = PyUnicode_AsUTF8AndSize(name, NULL);
            if (!m->desc[i].name) goto fail;
        }
        char label[96];
        snprintf(label, sizeof label, "%s[%zd] vertices", what, i);
        if (get_buffer(v, label, 'd', 3, -1, &m->verts[i]) < 0) goto fail;
        snprintf(label, sizeof label, "%s[%zd] triangles", what, i);
        if (get_buffer(t, label, 'I', 3, -1, &m->tris[i]) < 0) goto fail;
        if (m->verts[i].count / 3 > UINT32_MAX || m->tris[i].count / 3 > UINT32_MAX) {
            PyErr_Format(PyExc_ValueError, "%s[%zd]: too many vertices or triangles", what, i);
            goto fail;
        }
        m->desc[i].positions = m->verts[i].view.buf;
        m->desc[i].vertex_count = (uint32_t)(m->verts[i].count / 3);
        m->desc[i].indices = m->tris[i].view.buf;
        m->desc[i].triangle_count = (uint32_t)(m->tris[i].count / 3);
    }
    return 0;
fail:
    mesh_list_free(m);
    return -1;
}

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

static int dict_put(PyObject *d, const char *key, PyObject *value)
{
    if (!value) return -1;
    int r = PyDict_SetItemString(d, key, value);
    Py_DECREF(value);
    return r;
}

static PyObject *placement_dict(const pb_placement *p)
{
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    size_t n = p->probe_count;
    uint64_t cells = (uint64_t)p->grid_dims[0] * p->grid_dims[1] * p->grid_dims[2];
    if (dict_put(d, "probe_count", PyLong_FromUnsignedLong(p->probe_count)) < 0 ||
        dict_put(d, "positions", bytes_out(p->positions, n * 3 * sizeof(double))) < 0 ||
        dict_put(d, "cell_sizes", bytes_out(p->cell_sizes, n * sizeof(double))) < 0 ||
        dict_put(d, "backface_ratio", bytes_out(p->backface_ratio, n * sizeof(float))) < 0 ||
        dict_put(d, "grid", bytes_out(p->grid, (size_t)cells * sizeof(int32_t))) < 0 ||
        dict_put(d, "grid_dims", Py_BuildValue("(III)", p->grid_dims[0], p->grid_dims[1], p->grid_dims[2])) < 0 ||
        dict_put(d, "grid_origin", Py_BuildValue("(ddd)", p->grid_origin[0], p->grid_origin[1], p->grid_origin[2])) <
            0 ||
        dict_put(d, "grid_spacing", PyFloat_FromDouble(p->grid_spacing)) < 0 ||
        dict_put(d, "leaf_count", PyLong_FromUnsignedLongLong(p->leaf_count)) < 0 ||
        dict_put(d, "pruned_count", PyLong_FromUnsignedLongLong(p->pruned_count)) < 0) {
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
    if (check_u32(threads, "threads", &threads32) < 0 || check_u32(rays, "solid_ray_count", &rays32) < 0) return NULL;
    if (progress != Py_None && !PyCallable_Check(progress))
        return PyErr_Format(PyExc_TypeError, "progress must be callable(fraction, stage) or None");
    mesh_list vols, geo;
    if (mesh_list_get(vol_obj, "volumes", &vols) < 0) return NULL;
    if (mesh_list_get(geo_obj, "geometry", &geo) < 0) {
        mesh_list_free(&vols);
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
    Py_END_ALLOW_THREADS mesh_list_free(&vols);
    mesh_list_free(&geo);
    if (ctx.exc_type) { /* the callback raised: that exception wins over "cancelled" */
        pb_placement_destroy(placement);
        PyErr_Restore(ctx.exc_type, ctx.exc_value, ctx.exc_tb);
        return NULL;
    }
    if (r != PB_SUCCESS) {
        pb_placement_destroy(placement);
        return raise_core(module, r, &err);
    }
    PyObject *d = placement_dict(placement);
    pb_placement_destroy(placement);
    return d;
}

/* ---- .shprobe --------------------------------------------------------------------------------- */

static int header_into_dict(PyObject *d, const pb_shprobe *p)
{
    const float *a = p->grid_axes;
    return (dict_put(d, "version", PyLong_FromUnsignedLong(p->version)) < 0 ||
            dict_put(d, "probe_count", PyLong_FromUnsignedLong(p->probe_count)) < 0 ||
            dict_put(d, "max_band", PyLong_FromUnsignedLong(p->max_band)) < 0 ||
            dict_put(d, "grid_dims", Py_BuildValue("(III)", p->grid_dims[0], p->grid_dims[1], p->grid_dims[2])) < 0 ||
            dict_put(d, "grid_origin",
                     Py_BuildValue("(ddd)", (double)p->grid_origin[0], (double)p->grid_origin[1],
                                   (double)p->grid_origin[2])) < 0 ||
            dict_put(d, "grid_spacing", PyFloat_FromDouble(p->grid_spacing)) < 0 ||
            dict_put(d, "grid_axes",
                     Py_BuildValue("((ddd)(ddd)(ddd))", (double)a[0], (double)a[1], (double)a[2], (double)a[3],
                                   (double)a[4], (double)a[5], (double)a[6], (double)a[7], (double)a[8])) < 0 ||
            dict_put(d, "default_sh_scale", PyFloat_FromDouble(p->default_sh_scale)) < 0 ||
            dict_put(d, "default_ambient", PyFloat_FromDouble(p->default_ambient)) < 0)
               ? -1
               : 0;
}

/* Version 3 fields (versions 1/2 read back SH, float32, grid, no structure arrays). */
static int v3_into_dict(PyObject *d, const pb_shprobe *p)
{
    size_t N = p->element_count, H = p->hanging_count;
    bool oct = p->structure == PB_SHPROBE_OCTREE, tet = p->structure == PB_SHPROBE_TETRA;
    return (dict_put(d, "representation", PyLong_FromUnsignedLong(p->representation)) < 0 ||
            dict_put(d, "storage", PyLong_FromUnsignedLong(p->storage)) < 0 ||
            dict_put(d, "structure", PyLong_FromUnsignedLong(p->structure)) < 0 ||
            dict_put(d, "element_count", PyLong_FromUnsignedLong(p->element_count)) < 0 ||
            dict_put(d, "hanging_count", PyLong_FromUnsignedLong(p->hanging_count)) < 0 ||
            dict_put(d, "leaves", oct ? bytes_out(p->leaves, N * 16) : Py_NewRef(Py_None)) < 0 ||
            dict_put(d, "leaf_corners", oct ? bytes_out(p->leaf_corners, N * 32) : Py_NewRef(Py_None)) < 0 ||
            dict_put(d, "hanging_sources", oct ? bytes_out(p->hanging_sources, H * 16) : Py_NewRef(Py_None)) < 0 ||
            dict_put(d, "hanging_weights", oct ? bytes_out(p->hanging_weights, H * 16) : Py_NewRef(Py_None)) < 0 ||
            dict_put(d, "tets", tet ? bytes_out(p->tets, N * 16) : Py_NewRef(Py_None)) < 0 ||
            dict_put(d, "tet_neighbours", tet ? bytes_out(p->tet_neighbours, N * 16) : Py_NewRef(Py_None)) < 0)
               ? -1
               : 0;
}

static PyObject *shprobe_dict(const pb_shprobe *p)
{
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    size_t n = p->probe_count;
    size_t cells = p->grid ? (size_t)p->grid_dims[0] * p->grid_dims[1] * p->grid_dims[2] : 0;
    PyObject *positions = p->positions ? bytes_out(p->positions, n * 3 * sizeof(float)) : Py_NewRef(Py_None);
    if (header_into_dict(d, p) < 0 ||
        dict_put(d, "coeffs", bytes_out(p->coeffs, n * pb_shprobe_colour_count(p) * 3 * sizeof(float))) < 0 ||
        dict_put(d, "probe_scale", bytes_out(p->probe_scale, n * sizeof(float))) < 0 ||
        dict_put(d, "probe_ambient", bytes_out(p->probe_ambient, n * sizeof(float))) < 0 ||
        dict_put(d, "validity", bytes_out(p->validity, n * sizeof(float))) < 0 ||
        dict_put(d, "positions", positions) < 0 ||
        dict_put(d, "grid", p->grid ? bytes_out(p->grid, cells * sizeof(int32_t)) : Py_NewRef(Py_None)) < 0 ||
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
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    PyObject *d = shprobe_dict(p);
    pb_shprobe_destroy(p);
    return d;
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
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
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
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    PyObject *d = PyDict_New();
    if (d && header_into_dict(d, &h) < 0) Py_CLEAR(d);
    return d;
}

/* Optional per-probe float32 array of `n` items. */
static int get_optional(PyObject *obj, const char *name, Py_ssize_t n, held_buffer *out)
{
    memset(out, 0, sizeof *out);
    if (obj == NULL || obj == Py_None) return 0;
    return get_buffer(obj, name, 'f', 0, n, out);
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
    held_buffer coeffs = {0}, grid = {0}, pos = {0}, scale = {0}, amb = {0}, val = {0}, axes = {0};
    PyObject *result = NULL;
    if (check_band(band) < 0) goto done;
    if (version < 0 || version > 2) {
        PyErr_Format(PyExc_ValueError, "version %ld: expected 0 (auto), 1 or 2", version);
        goto done;
    }
    for (int i = 0; i < 3; i++)
        if (check_u32(dims[i], "grid_dims entry", &p.grid_dims[i]) < 0) goto done;
    Py_ssize_t per_probe = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    if (get_buffer(c_obj, "coeffs", 'f', per_probe, -1, &coeffs) < 0) goto done;
    Py_ssize_t n = coeffs.count / per_probe;
    if (n > UINT32_MAX) {
        PyErr_Format(PyExc_ValueError, "%zd probes exceed the file's uint32 probe count", n);
        goto done;
    }
    Py_ssize_t cells = product3(dims[0], dims[1], dims[2], "grid_dims");
    if (cells < 0 || get_buffer(g_obj, "grid", 'i', 0, cells, &grid) < 0) goto done;
    if (pos_obj != Py_None && get_buffer(pos_obj, "positions", 'f', 0, n * 3, &pos) < 0) goto done;
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
        Py_END_ALLOW_THREADS if (r != PB_SUCCESS) raise_core(module, r, &err);
        else result = PyLong_FromUnsignedLong(written.version);
    }
done:
    release(&coeffs);
    release(&grid);
    release(&pos);
    release(&scale);
    release(&amb);
    release(&val);
    release(&axes);
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
        if (check_u32(dims[i], "grid_dims entry", &p.grid_dims[i]) < 0) return NULL;
    if (check_u32(count, "probe_count", &p.probe_count) < 0) return NULL;
    held_buffer grid, pts, axes;
    Py_ssize_t cells = product3(dims[0], dims[1], dims[2], "grid_dims");
    if (cells < 0 || get_buffer(g_obj, "grid", 'i', 0, cells, &grid) < 0) return NULL;
    if (get_buffer(pts_obj, "points", 'f', 3, -1, &pts) < 0) {
        release(&grid);
        return NULL;
    }
    if (get_optional(axes_obj, "grid_axes", 9, &axes) < 0) {
        release(&grid);
        release(&pts);
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
    release(&grid);
    release(&pts);
    release(&axes);
    return out;
}

/* ---- interpolation and refinement (issue 12) ---------------------------------------------------- */

static const char CAP_COTREE[] = "schnee_probes.cotree";
static const char CAP_TETRA[] = "schnee_probes.tetra";

static void cotree_capsule_free(PyObject *cap) { pb_cotree_destroy(PyCapsule_GetPointer(cap, CAP_COTREE)); }
static void tetra_capsule_free(PyObject *cap) { pb_tetra_destroy(PyCapsule_GetPointer(cap, CAP_TETRA)); }

static pb_cotree *get_cotree(PyObject *o)
{
    if (!PyCapsule_IsValid(o, CAP_COTREE)) {
        PyErr_SetString(PyExc_TypeError, "expected a corner octree handle (from cotree_create)");
        return NULL;
    }
    return PyCapsule_GetPointer(o, CAP_COTREE);
}

static PyObject *cotree_capsule(pb_cotree *t)
{
    PyObject *cap = PyCapsule_New(t, CAP_COTREE, cotree_capsule_free);
    if (!cap) pb_cotree_destroy(t);
    return cap;
}

static PyObject *tetra_capsule(pb_tetra *t)
{
    PyObject *cap = PyCapsule_New(t, CAP_TETRA, tetra_capsule_free);
    if (!cap) pb_tetra_destroy(t);
    return cap;
}

static int get_dims(const Py_ssize_t in[3], uint32_t out[3])
{
    for (int i = 0; i < 3; i++)
        if (check_u32(in[i], "dims entry", &out[i]) < 0) return -1;
    return 0;
}

static PyObject *py_cotree_create(PyObject *module, PyObject *args)
{
    double origin[3], cell;
    Py_ssize_t level, dims_in[3];
    uint32_t dims[3], lv;
    if (!PyArg_ParseTuple(args, "(ddd)dn(nnn):cotree_create", &origin[0], &origin[1], &origin[2], &cell, &level,
                          &dims_in[0], &dims_in[1], &dims_in[2]) ||
        get_dims(dims_in, dims) < 0 || check_u32(level, "root_level", &lv) < 0)
        return NULL;
    pb_cotree *t = NULL;
    pb_error err = {0};
    pb_result r = pb_cotree_create(origin, cell, lv, dims, &t, &err);
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
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
    held_buffer leaves;
    if (get_buffer(l_obj, "leaves", 'I', 4, -1, &leaves) < 0) return NULL;
    pb_cotree *t = NULL;
    pb_error err = {0};
    pb_result r = leaves.count / 4 > UINT32_MAX ? PB_ERROR_TOO_LARGE : PB_SUCCESS;
    if (r == PB_SUCCESS)
        r = pb_cotree_create_leaves(origin, cell, dims, leaves.view.buf, (uint32_t)(leaves.count / 4), &t, &err);
    release(&leaves);
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    return cotree_capsule(t);
}

/* cotree_split / cotree_drop: flags = uint8[leaf_count]. */
static PyObject *cotree_flags_op(PyObject *module, PyObject *args, bool split)
{
    PyObject *t_obj, *f_obj;
    if (!PyArg_ParseTuple(args, "OO", &t_obj, &f_obj)) return NULL;
    pb_cotree *t = get_cotree(t_obj);
    if (!t) return NULL;
    held_buffer flags;
    if (get_buffer(f_obj, "flags", 'B', 0, pb_cotree_leaf_count(t), &flags) < 0) return NULL;
    pb_error err = {0};
    uint32_t n = 0;
    pb_result r = split ? pb_cotree_split(t, flags.view.buf, &n, &err) : pb_cotree_drop(t, flags.view.buf, &err);
    release(&flags);
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    return PyLong_FromUnsignedLong(n);
}

static PyObject *py_cotree_split(PyObject *module, PyObject *args) { return cotree_flags_op(module, args, true); }
static PyObject *py_cotree_drop(PyObject *module, PyObject *args) { return cotree_flags_op(module, args, false); }

static PyObject *py_cotree_finalize(PyObject *module, PyObject *t_obj)
{
    pb_cotree *t = get_cotree(t_obj);
    if (!t) return NULL;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_cotree_finalize(t, &err);
    Py_END_ALLOW_THREADS if (r != PB_SUCCESS) return raise_core(module, r, &err);
    Py_RETURN_NONE;
}

static PyObject *py_cotree_info(PyObject *module, PyObject *t_obj)
{
    pb_cotree *t = get_cotree(t_obj);
    if (!t) return NULL;
    double origin[3], cell;
    uint32_t dims[3];
    pb_cotree_frame(t, origin, &cell, dims);
    size_t L = pb_cotree_leaf_count(t), P = pb_cotree_probe_count(t), H = pb_cotree_hanging_count(t);
    bool fin = pb_cotree_probe_lattice(t) != NULL;
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    PyObject *pos = NULL, *corners = NULL, *src = NULL, *w = NULL;
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
    if (dict_put(d, "origin", Py_BuildValue("(ddd)", origin[0], origin[1], origin[2])) < 0 ||
        dict_put(d, "min_cell", PyFloat_FromDouble(cell)) < 0 ||
        dict_put(d, "dims", Py_BuildValue("(III)", dims[0], dims[1], dims[2])) < 0 ||
        dict_put(d, "finalized", PyBool_FromLong(fin)) < 0 ||
        dict_put(d, "leaves", bytes_out(pb_cotree_leaves(t), L * 4 * sizeof(uint32_t))) < 0 ||
        dict_put(d, "probe_count", PyLong_FromSize_t(P)) < 0 ||
        dict_put(d, "hanging_count", PyLong_FromSize_t(H)) < 0 ||
        dict_put(d, "probe_lattice",
                 fin ? bytes_out(pb_cotree_probe_lattice(t), P * 3 * sizeof(uint32_t)) : Py_NewRef(Py_None)) < 0 ||
        dict_put(d, "positions", pos) < 0 || dict_put(d, "leaf_corners", corners) < 0 ||
        dict_put(d, "hanging_sources", src) < 0 || dict_put(d, "hanging_weights", w) < 0) {
        Py_DECREF(d);
        return NULL;
    }
    return d;
}

static PyObject *py_tetra_create(PyObject *module, PyObject *args)
{
    PyObject *p_obj;
    if (!PyArg_ParseTuple(args, "O:tetra_create", &p_obj)) return NULL;
    held_buffer pos;
    if (get_buffer(p_obj, "positions", 'd', 3, -1, &pos) < 0) return NULL;
    pb_tetra *t = NULL;
    pb_error err = {0};
    pb_result r = pos.count / 3 > UINT32_MAX ? PB_ERROR_TOO_LARGE : PB_SUCCESS;
    if (r == PB_SUCCESS) {
        Py_BEGIN_ALLOW_THREADS r = pb_tetra_create(pos.view.buf, (uint32_t)(pos.count / 3), &t, &err);
        Py_END_ALLOW_THREADS
    }
    release(&pos);
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    return tetra_capsule(t);
}

static PyObject *py_tetra_info(PyObject *module, PyObject *t_obj)
{
    if (!PyCapsule_IsValid(t_obj, CAP_TETRA)) {
        PyErr_SetString(PyExc_TypeError, "expected a tetrahedra handle (from tetra_create)");
        return NULL;
    }
    pb_tetra *t = PyCapsule_GetPointer(t_obj, CAP_TETRA);
    size_t n = pb_tetra_count(t);
    PyObject *d = PyDict_New();
    if (!d) return NULL;
    if (dict_put(d, "tets", bytes_out(pb_tetra_tets(t), n * 16)) < 0 ||
        dict_put(d, "neighbours", bytes_out(pb_tetra_neighbours(t), n * 16)) < 0) {
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
    pb_cotree *tree = PyCapsule_IsValid(h_obj, CAP_COTREE) ? PyCapsule_GetPointer(h_obj, CAP_COTREE) : NULL;
    pb_tetra *tetra = PyCapsule_IsValid(h_obj, CAP_TETRA) ? PyCapsule_GetPointer(h_obj, CAP_TETRA) : NULL;
    if (!tree && !tetra) {
        PyErr_SetString(PyExc_TypeError, "expected a corner octree or tetrahedra handle");
        return NULL;
    }
    if (tree && !pb_cotree_probe_lattice(tree)) {
        PyErr_SetString(PyExc_ValueError, "the corner octree is not finalized (call cotree_finalize)");
        return NULL;
    }
    held_buffer pts, val = {0};
    if (get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    Py_ssize_t probe_count = tree ? (Py_ssize_t)pb_cotree_probe_count(tree) : (Py_ssize_t)pb_tetra_point_count(tetra);
    if (v_obj != Py_None && get_buffer(v_obj, "validity", 'f', 0, probe_count, &val) < 0) {
        release(&pts);
        return NULL;
    }
    held_buffer pvis = {0};
    if (pv_obj != Py_None) {
        if (!tree) {
            PyErr_SetString(PyExc_ValueError, "pair_visibility is for corner octrees only");
        } else {
            (void)get_buffer(pv_obj, "pair_visibility", 'B', 0, 64 * (Py_ssize_t)pb_cotree_leaf_count(tree), &pvis);
        }
        if (PyErr_Occurred()) {
            release(&pts);
            release(&val);
            return NULL;
        }
    }
    Py_ssize_t n = pts.count / 3;
    pb_interp_weights *w = malloc(((size_t)n + 1) * sizeof *w);
    if (!w) {
        release(&pts);
        release(&val);
        release(&pvis);
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
    Py_END_ALLOW_THREADS release(&pts);
    release(&val);
    release(&pvis);
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

static PyObject *py_refine_tests(PyObject *module, PyObject *args)
{
    PyObject *t_obj, *a_obj = Py_None;
    if (!PyArg_ParseTuple(args, "O|O:refine_tests", &t_obj, &a_obj)) return NULL;
    pb_cotree *t = get_cotree(t_obj);
    if (!t) return NULL;
    held_buffer active = {0};
    if (a_obj != Py_None && get_buffer(a_obj, "active", 'B', 0, pb_cotree_leaf_count(t), &active) < 0) return NULL;
    pb_refine_tests *tests = NULL;
    pb_error err = {0};
    pb_result r = pb_refine_tests_create(t, active.view.obj ? active.view.buf : NULL, &tests, &err);
    release(&active);
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    size_t n = tests->point_count, L = tests->leaf_count;
    PyObject *d = PyDict_New();
    if (d && (dict_put(d, "lattice", bytes_out(tests->lattice, n * 12)) < 0 ||
              dict_put(d, "positions", bytes_out(tests->positions, n * 24)) < 0 ||
              dict_put(d, "probe", bytes_out(tests->probe, n * 4)) < 0 ||
              dict_put(d, "leaf_tests", bytes_out(tests->leaf_tests, L * PB_REFINE_TESTS_PER_LEAF * 4)) < 0))
        Py_CLEAR(d);
    pb_refine_tests_destroy(tests);
    return d;
}

static PyObject *py_refine_decide(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"tree",         "leaf_tests",  "test_positions", "test_probe", "max_band",
                             "probe_coeffs", "test_coeffs", "probe_noise",    "test_noise", "probe_validity",
                             "test_valid",   "tolerance",   "noise_k",        NULL};
    PyObject *t_obj, *lt_obj, *tp_obj, *tpr_obj, *pc_obj, *tc_obj;
    PyObject *pn_obj = Py_None, *tn_obj = Py_None, *pv_obj = Py_None, *tv_obj = Py_None;
    long band;
    double tol = 0.0, k = 0.0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OOOOlOO|OOOOdd:refine_decide", kwlist, &t_obj, &lt_obj, &tp_obj,
                                     &tpr_obj, &band, &pc_obj, &tc_obj, &pn_obj, &tn_obj, &pv_obj, &tv_obj, &tol, &k))
        return NULL;
    pb_cotree *t = get_cotree(t_obj);
    if (!t || check_band(band) < 0) return NULL;
    Py_ssize_t L = pb_cotree_leaf_count(t), P = pb_cotree_probe_count(t), C = (Py_ssize_t)pb_sh_count((uint32_t)band);
    held_buffer lt = {0}, tp = {0}, tpr = {0}, pc = {0}, tc = {0}, pn = {0}, tn = {0}, pv = {0}, tv = {0};
    PyObject *result = NULL;
    if (get_buffer(lt_obj, "leaf_tests", 'i', 0, L * PB_REFINE_TESTS_PER_LEAF, &lt) < 0 ||
        get_buffer(tp_obj, "test_positions", 'd', 3, -1, &tp) < 0)
        goto done;
    Py_ssize_t T = tp.count / 3;
    if (get_buffer(tpr_obj, "test_probe", 'i', 0, T, &tpr) < 0 ||
        get_buffer(pc_obj, "probe_coeffs", 'd', 0, P * C * 3, &pc) < 0 ||
        get_buffer(tc_obj, "test_coeffs", 'd', 0, T * C * 3, &tc) < 0 ||
        (pn_obj != Py_None && get_buffer(pn_obj, "probe_noise", 'f', 0, P, &pn) < 0) ||
        (tn_obj != Py_None && get_buffer(tn_obj, "test_noise", 'f', 0, T, &tn) < 0) ||
        (pv_obj != Py_None && get_buffer(pv_obj, "probe_validity", 'f', 0, P, &pv) < 0) ||
        (tv_obj != Py_None && get_buffer(tv_obj, "test_valid", 'B', 0, T, &tv) < 0))
        goto done;
    {
        const int32_t *ltv = lt.view.buf, *tprv = tpr.view.buf;
        for (Py_ssize_t i = 0; i < L * PB_REFINE_TESTS_PER_LEAF; i++)
            if (ltv[i] < -1 || ltv[i] >= T) {
                PyErr_Format(PyExc_ValueError, "leaf_tests[%zd] = %d is not a test point index", i, (int)ltv[i]);
                goto done;
            }
        for (Py_ssize_t i = 0; i < T; i++)
            if (tprv[i] < -1 || tprv[i] >= P) {
                PyErr_Format(PyExc_ValueError, "test_probe[%zd] = %d is not a probe index", i, (int)tprv[i]);
                goto done;
            }
        pb_refine_tests tests = {.point_count = (uint32_t)T,
                                 .positions = tp.view.buf,
                                 .probe = tpr.view.buf,
                                 .leaf_count = (uint32_t)L,
                                 .leaf_tests = lt.view.buf};
        pb_refine_desc d = {.max_band = (uint32_t)band,
                            .probe_coeffs = pc.view.buf,
                            .test_coeffs = tc.view.buf,
                            .probe_noise = pn.view.obj ? pn.view.buf : NULL,
                            .test_noise = tn.view.obj ? tn.view.buf : NULL,
                            .probe_validity = pv.view.obj ? pv.view.buf : NULL,
                            .test_valid = tv.view.obj ? tv.view.buf : NULL,
                            .tolerance = tol,
                            .noise_k = k};
        PyObject *so = PyByteArray_FromStringAndSize(NULL, L);
        PyObject *eo = PyByteArray_FromStringAndSize(NULL, L * 8);
        PyObject *ho = PyByteArray_FromStringAndSize(NULL, L * 8);
        if (!so || !eo || !ho) {
            Py_XDECREF(so);
            Py_XDECREF(eo);
            Py_XDECREF(ho);
            goto done;
        }
        pb_error err = {0};
        pb_result r = pb_refine_decide(t, &tests, &d, (uint8_t *)PyByteArray_AsString(so),
                                       (double *)(void *)PyByteArray_AsString(eo),
                                       (double *)(void *)PyByteArray_AsString(ho), &err);
        if (r != PB_SUCCESS) {
            Py_DECREF(so);
            Py_DECREF(eo);
            Py_DECREF(ho);
            raise_core(module, r, &err);
            goto done;
        }
        result = Py_BuildValue("(NNN)", so, eo, ho);
    }
done:
    release(&lt);
    release(&tp);
    release(&tpr);
    release(&pc);
    release(&tc);
    release(&pn);
    release(&tn);
    release(&pv);
    release(&tv);
    return result;
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
    held_buffer coeffs = {0}, scale = {0}, amb = {0}, val = {0};
    pb_error err = {0};
    pb_result r = PB_SUCCESS;
    if (check_band(band) < 0) goto done;
    if (repr < 0 || repr > 1 || storage < 0 || storage > 1) {
        PyErr_Format(PyExc_ValueError, "representation %ld / storage %ld: expected 0 or 1", repr, storage);
        goto done;
    }
    if (PyCapsule_IsValid(h_obj, CAP_COTREE))
        r = pb_shprobe_from_cotree(PyCapsule_GetPointer(h_obj, CAP_COTREE), (uint32_t)repr, (uint32_t)band, &f, &err);
    else if (PyCapsule_IsValid(h_obj, CAP_TETRA))
        r = pb_shprobe_from_tetra(PyCapsule_GetPointer(h_obj, CAP_TETRA), NULL, (uint32_t)repr, (uint32_t)band, &f,
                                  &err);
    else {
        PyErr_SetString(PyExc_TypeError, "expected a corner octree or tetrahedra handle");
        goto done;
    }
    if (r != PB_SUCCESS) {
        raise_core(module, r, &err);
        goto done;
    }
    Py_ssize_t n = f->probe_count, per = (Py_ssize_t)pb_shprobe_colour_count(f) * 3;
    if (get_buffer(c_obj, "coeffs", 'f', 0, n * per, &coeffs) < 0 ||
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
        Py_END_ALLOW_THREADS if (r != PB_SUCCESS) raise_core(module, r, &err);
        else result = PyLong_FromSize_t((size_t)n);
    }
done:
    release(&coeffs);
    release(&scale);
    release(&amb);
    release(&val);
    pb_shprobe_destroy(f);
    Py_DECREF(path);
    return result;
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
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    return tree ? cotree_capsule(tree) : tetra_capsule(tetra);
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
    if (r != PB_SUCCESS) return raise_core(module, r, &err);
    PyObject *d = shprobe_dict(g);
    pb_shprobe_destroy(g);
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
    if (check_u32(threads, "threads", &threads32) < 0 || check_u32(rays, "solid_ray_count", &rays32) < 0) return NULL;
    held_buffer pts = {0}, bx = {0};
    if (p_obj != Py_None && get_buffer(p_obj, "points", 'd', 3, -1, &pts) < 0) return NULL;
    if (b_obj != Py_None && get_buffer(b_obj, "boxes", 'd', 4, -1, &bx) < 0) {
        release(&pts);
        return NULL;
    }
    Py_ssize_t n = pts.count / 3, m = bx.count / 4;
    PyObject *in_o = PyByteArray_FromStringAndSize(NULL, n), *ratio_o = PyByteArray_FromStringAndSize(NULL, n * 4);
    PyObject *cls_o = PyByteArray_FromStringAndSize(NULL, m);
    mesh_list vols = {0}, geo = {0};
    PyObject *result = NULL;
    if (!in_o || !ratio_o || !cls_o || n > UINT32_MAX || m > UINT32_MAX) {
        if (in_o && ratio_o && cls_o) PyErr_SetString(PyExc_ValueError, "too many points or boxes");
        goto done;
    }
    if (mesh_list_get(vol_obj, "volumes", &vols) < 0) goto done;
    if (mesh_list_get(geo_obj, "geometry", &geo) < 0) goto done;
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
        Py_END_ALLOW_THREADS if (r != PB_SUCCESS) raise_core(module, r, &err);
        else result = Py_BuildValue("(OOO)", in_o, ratio_o, cls_o);
    }
done:
    mesh_list_free(&vols);
    mesh_list_free(&geo);
    Py_XDECREF(in_o);
    Py_XDECREF(ratio_o);
    Py_XDECREF(cls_o);
    release(&pts);
    release(&bx);
    return result;
}

/* ---- module ----------------------------------------------------------------------------------- */

static PyObject *py_set_error_class(PyObject *module, PyObject *cls)
{
    if (!PyType_Check(cls) || !PyObject_IsSubclass(cls, PyExc_Exception))
        return PyErr_Format(PyExc_TypeError, "_set_error_class expects an Exception subclass");
    module_state *st = get_state(module);
    PyObject *old = st->error_class;
    st->error_class = Py_NewRef(cls);
    Py_XDECREF(old);
    Py_RETURN_NONE;
}

/* ---- ambient cube ----------------------------------------------------------------------------- */

static PyObject *py_ambient_cube_from_sh(PyObject *module, PyObject *args)
{
    PyObject *c_obj;
    long band, fit;
    if (!PyArg_ParseTuple(args, "Oll:ambient_cube_from_sh", &c_obj, &band, &fit) || check_band(band) < 0) return NULL;
    const Py_ssize_t per = (Py_ssize_t)pb_sh_count((uint32_t)band) * 3;
    held_buffer coeffs;
    if (get_buffer(c_obj, "coeffs", 'd', per, -1, &coeffs) < 0) return NULL;
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
    release(&coeffs);
    if (out && r != PB_SUCCESS) {
        Py_DECREF(out);
        return raise_core(module, r, &err);
    }
    return out;
}

static PyObject *py_ambient_cube_irradiance(PyObject *module, PyObject *args)
{
    PyObject *c_obj, *n_obj;
    if (!PyArg_ParseTuple(args, "OO:ambient_cube_irradiance", &c_obj, &n_obj)) return NULL;
    held_buffer cube, normals;
    if (get_buffer(c_obj, "cube", 'd', 0, 18, &cube) < 0) return NULL;
    if (get_buffer(n_obj, "normals", 'd', 3, -1, &normals) < 0) {
        release(&cube);
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
    release(&cube);
    release(&normals);
    return out;
}

static PyObject *py_result_string(PyObject *module, PyObject *args)
{
    int code;
    if (!PyArg_ParseTuple(args, "i:result_string", &code)) return NULL;
    return PyUnicode_FromString(pb_result_string((pb_result)code));
}

/* ---- direct light (issue 11, docs/direct-light.md) ---------------------------------------------- */

#define PB_LIGHT_RECORD 20 /* doubles per lamp record, layout in addon/schnee_probes/native.py */

static PyObject *py_direct_project(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"lights", "probes", "max_band", "samples", "geometry", "ray_offset", NULL};
    PyObject *lights_obj, *probes_obj, *geo_obj = Py_None;
    long band = 2;
    Py_ssize_t samples = 0;
    double offset = 0.0;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "OO|lnOd:direct_project", kwlist, &lights_obj, &probes_obj, &band,
                                     &samples, &geo_obj, &offset))
        return NULL;
    uint32_t samples32;
    if (check_band(band) < 0 || check_u32(samples, "samples", &samples32) < 0) return NULL;
    held_buffer lb, pb;
    if (get_buffer(lights_obj, "lights", 'd', PB_LIGHT_RECORD, -1, &lb) < 0) return NULL;
    if (get_buffer(probes_obj, "probes", 'd', 3, -1, &pb) < 0) {
        release(&lb);
        return NULL;
    }
    const Py_ssize_t nl = lb.count / PB_LIGHT_RECORD, np_ = pb.count / 3;
    pb_light *lights = calloc((size_t)nl + 1, sizeof *lights);
    if (!lights) {
        release(&lb);
        release(&pb);
        return PyErr_NoMemory();
    }
    const double *rec = lb.view.buf;
    for (Py_ssize_t i = 0; i < nl; i++, rec += PB_LIGHT_RECORD) {
        pb_light *l = &lights[i];
        if (!(rec[0] >= 0.0 && rec[0] < (double)PB_LIGHT_TYPE_COUNT_) || rec[0] != floor(rec[0])) {
            free(lights);
            release(&lb);
            release(&pb);
            return PyErr_Format(PyExc_ValueError, "lights[%zd]: unknown lamp type", i);
        }
        l->type = (pb_light_type)(int)rec[0];
        for (int k = 0; k < 3; k++) {
            l->position[k] = rec[1 + k];
            l->direction[k] = rec[4 + k];
            l->axis_u[k] = rec[7 + k];
            l->color[k] = rec[10 + k];
        }
        l->radius = rec[13];
        l->size_u = rec[14];
        l->size_v = rec[15];
        l->spot_size = rec[16];
        l->spot_blend = rec[17];
        l->legacy_point = rec[18] != 0.0;
        l->spot_cosine = rec[19] != 0.0;
    }
    mesh_list geo = {0};
    if (geo_obj != Py_None && mesh_list_get(geo_obj, "geometry", &geo) < 0) {
        free(lights);
        release(&lb);
        release(&pb);
        return NULL;
    }
    const uint32_t n = pb_sh_count((uint32_t)band);
    double *out = calloc((size_t)np_ * n * 3 + 1, sizeof(double));
    if (!out) {
        mesh_list_free(&geo);
        free(lights);
        release(&lb);
        release(&pb);
        return PyErr_NoMemory();
    }
    pb_error err = {0};
    pb_result r = PB_SUCCESS;
    Py_BEGIN_ALLOW_THREADS;
    pb_direct_scene *scene = NULL;
    if (geo.count) r = pb_direct_scene_create(geo.desc, (uint32_t)geo.count, &scene, &err);
    pb_direct_desc desc = {0};
    desc.max_band = (uint32_t)band;
    desc.samples = samples32;
    desc.ray_offset = offset;
    desc.scene = scene;
    const double *probes = pb.view.buf;
    for (Py_ssize_t p = 0; p < np_ && r == PB_SUCCESS; p++)
        r = pb_direct_project(&desc, lights, (uint32_t)nl, probes + 3 * p, out + (size_t)p * n * 3, &err);
    pb_direct_scene_destroy(scene);
    Py_END_ALLOW_THREADS;
    mesh_list_free(&geo);
    free(lights);
    release(&lb);
    release(&pb);
    if (r != PB_SUCCESS) {
        free(out);
        return raise_core(module, r, &err);
    }
    PyObject *res = bytes_out(out, (size_t)np_ * n * 3 * sizeof(double));
    free(out);
    return res;
}

static PyObject *py_sky_table(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"world",       "width",    "height",   "channels", "pano_width",
                             "pano_height", "max_band", "rotation", NULL};
    PyObject *world_obj, *rot_obj = Py_None;
    Py_ssize_t width, height, channels, pw, ph;
    long band = 2;
    if (!PyArg_ParseTupleAndKeywords(args, kw, "Onnnnn|lO:sky_table", kwlist, &world_obj, &width, &height, &channels,
                                     &pw, &ph, &band, &rot_obj))
        return NULL;
    uint32_t w, h, c, pw32, ph32;
    if (check_band(band) < 0 || check_u32(width, "width", &w) < 0 || check_u32(height, "height", &h) < 0 ||
        check_u32(channels, "channels", &c) < 0 || check_u32(pw, "pano_width", &pw32) < 0 ||
        check_u32(ph, "pano_height", &ph32) < 0)
        return NULL;
    if (c < 3) return PyErr_Format(PyExc_ValueError, "channels %u: at least 3 (RGB first) are needed", c);
    const uint32_t n = pb_sh_count((uint32_t)band);
    Py_ssize_t cells = product3(pw, ph, (Py_ssize_t)n * 3, "pano_width x pano_height x coefficients");
    Py_ssize_t expected = product3(width, height, channels, "width x height x channels");
    if (cells < 0 || expected < 0) return NULL;
    if (cells > ((Py_ssize_t)1 << 28)) return PyErr_Format(PyExc_ValueError, "the sky table would be too large");
    held_buffer world, rot;
    if (get_buffer(world_obj, "world", 'f', 0, expected, &world) < 0) return NULL;
    if (get_rotation(rot_obj, &rot) < 0) {
        release(&world);
        return NULL;
    }
    double *table = malloc(sizeof(double) * (size_t)cells + 1);
    if (!table) {
        release(&world);
        release(&rot);
        return PyErr_NoMemory();
    }
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_direct_sky_table(world.view.buf, w, h, c, pw32, ph32, (uint32_t)band,
                                                   rot.view.obj ? rot.view.buf : NULL, table, &err);
    Py_END_ALLOW_THREADS release(&world);
    release(&rot);
    if (r != PB_SUCCESS) {
        free(table);
        return raise_core(module, r, &err);
    }
    PyObject *res = bytes_out(table, (size_t)cells * sizeof(double));
    free(table);
    return res;
}

/* sky_sun_split(image, width, height, channels, peak_fraction=0, max_radius=0, min_share=0)
 * -> (dict, bytearray rest float32[H*W*C]); the dict always holds "found" and "verdict". */
static PyObject *py_sky_sun_split(PyObject *module, PyObject *args, PyObject *kw)
{
    static char *kwlist[] = {"image", "width", "height", "channels", "peak_fraction", "max_radius", "min_share", NULL};
    PyObject *image_obj;
    Py_ssize_t width, height, channels;
    pb_sky_sun_desc desc = {0};
    if (!PyArg_ParseTupleAndKeywords(args, kw, "Onnn|ddd:sky_sun_split", kwlist, &image_obj, &width, &height, &channels,
                                     &desc.peak_fraction, &desc.max_radius, &desc.min_share))
        return NULL;
    uint32_t w, h, c;
    if (check_u32(width, "width", &w) < 0 || check_u32(height, "height", &h) < 0 ||
        check_u32(channels, "channels", &c) < 0)
        return NULL;
    Py_ssize_t expected = product3(width, height, channels, "width x height x channels");
    if (expected < 0) return NULL;
    held_buffer image;
    if (get_buffer(image_obj, "image", 'f', 0, expected, &image) < 0) return NULL;
    PyObject *rest = PyByteArray_FromStringAndSize(NULL, expected * (Py_ssize_t)sizeof(float));
    if (!rest) {
        release(&image);
        return NULL;
    }
    float *rest_buf = (float *)PyByteArray_AsString(rest);
    pb_sky_sun sun;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_sky_sun_split(&desc, image.view.buf, w, h, c, rest_buf, &sun, &err);
    Py_END_ALLOW_THREADS release(&image);
    if (r != PB_SUCCESS) {
        Py_DECREF(rest);
        return raise_core(module, r, &err);
    }
    PyObject *d = Py_BuildValue("{s:O,s:s,s:(ddd),s:(ddd),s:d,s:d,s:(ddd),s:d,s:(II),s:I}", "found",
                                sun.found ? Py_True : Py_False, "verdict", pb_sky_sun_verdict_string(sun.verdict),
                                "direction", sun.direction[0], sun.direction[1], sun.direction[2], "irradiance",
                                sun.irradiance[0], sun.irradiance[1], sun.irradiance[2], "angle", sun.angle, "share",
                                sun.share, "background", sun.background[0], sun.background[1], sun.background[2],
                                "extent", sun.extent, "peak", sun.peak_col, sun.peak_row, "texels", sun.texels);
    if (!d) {
        Py_DECREF(rest);
        return NULL;
    }
    PyObject *res = Py_BuildValue("(NN)", d, rest);
    return res;
}

static PyMethodDef methods[] = {
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
    {"place_probes", (PyCFunction)(void (*)(void))py_place_probes, METH_VARARGS | METH_KEYWORDS,
     "place_probes(volumes, geometry, min_cell_size=None, max_cell_size=None, threads=0, progress=None, "
     "solid_ray_count=0, solid_backface_ratio=0, max_grid_cells=0) -> dict; sizes in metres, None = default "
     "(0, negative, NaN, Inf refused), max_grid_cells 0 = default limit (negative refused)"},
    {"shprobe_write", (PyCFunction)(void (*)(void))py_shprobe_write, METH_VARARGS | METH_KEYWORDS,
     "shprobe_write(path, coeffs, max_band, grid, grid_dims, grid_origin, grid_spacing, "
     "default_sh_scale=1, default_ambient=0.1, positions=None, probe_scale=None, probe_ambient=None, "
     "validity=None, grid_axes=None, version=0) -> version written"},
    {"shprobe_read", py_shprobe_read, METH_VARARGS, "shprobe_read(path) -> dict"},
    {"shprobe_read_memory", py_shprobe_read_memory, METH_VARARGS, "shprobe_read_memory(buffer) -> dict"},
    {"shprobe_read_header", py_shprobe_read_header, METH_VARARGS, "shprobe_read_header(path) -> dict"},
    {"shprobe_lookup", (PyCFunction)(void (*)(void))py_shprobe_lookup, METH_VARARGS | METH_KEYWORDS,
     "shprobe_lookup(grid, grid_dims, grid_origin, grid_spacing, probe_count, points: float32[N*3], "
     "grid_axes=None) -> bytearray int32[N]"},
    {"ambient_cube_from_sh", py_ambient_cube_from_sh, METH_VARARGS,
     "ambient_cube_from_sh(coeffs: float64[P*count*3], max_band, fit) -> bytearray float64[P*18]"},
    {"ambient_cube_irradiance", py_ambient_cube_irradiance, METH_VARARGS,
     "ambient_cube_irradiance(cube: float64[18], normals: float64[N*3]) -> bytearray float64[N*3]"},
    {"direct_project", (PyCFunction)(void (*)(void))py_direct_project, METH_VARARGS | METH_KEYWORDS,
     "direct_project(lights: float64[N*20], probes: float64[P*3], max_band=2, samples=0, geometry=None, "
     "ray_offset=0) -> bytearray float64[P*count*3] (docs/direct-light.md)"},
    {"sky_table", (PyCFunction)(void (*)(void))py_sky_table, METH_VARARGS | METH_KEYWORDS,
     "sky_table(world: float32[H*W*C], width, height, channels, pano_width, pano_height, max_band=2, "
     "rotation=None) -> bytearray float64[pano_h*pano_w*count*3]"},
    {"sky_sun_split", (PyCFunction)(void (*)(void))py_sky_sun_split, METH_VARARGS | METH_KEYWORDS,
     "sky_sun_split(image: float32[H*W*C], width, height, channels, peak_fraction=0, max_radius=0, min_share=0) "
     "-> (dict, bytearray float32 rest)"},
    {"result_string", py_result_string, METH_VARARGS, "result_string(code) -> str"},
    {"placement_classify", (PyCFunction)(void (*)(void))py_placement_classify, METH_VARARGS | METH_KEYWORDS,
     "placement_classify(volumes, geometry, points=None, boxes=None, ...) -> (inside, backface_ratio, box_class)"},
    {"cotree_create", py_cotree_create, METH_VARARGS,
     "cotree_create(origin, min_cell, root_level, root_dims) -> corner octree handle (not finalized)"},
    {"cotree_from_leaves", py_cotree_from_leaves, METH_VARARGS,
     "cotree_from_leaves(origin, min_cell, dims, leaves: uint32[N*4]) -> handle"},
    {"cotree_split", py_cotree_split, METH_VARARGS, "cotree_split(tree, flags: uint8[leaves]) -> leaves split"},
    {"cotree_drop", py_cotree_drop, METH_VARARGS, "cotree_drop(tree, flags: uint8[leaves]) -> 0"},
    {"cotree_finalize", py_cotree_finalize, METH_O, "cotree_finalize(tree): number probes, hanging rules"},
    {"cotree_info", py_cotree_info, METH_O, "cotree_info(tree) -> dict (leaves, probes, positions, rules)"},
    {"tetra_create", py_tetra_create, METH_VARARGS, "tetra_create(positions: float64[P*3]) -> tetrahedra handle"},
    {"tetra_info", py_tetra_info, METH_O, "tetra_info(tetra) -> dict (tets, neighbours)"},
    {"interp_query", py_interp_query, METH_VARARGS,
     "interp_query(handle, points: float64[N*3], validity=None, pair_visibility=None) -> (int32[N*K], float64[N*K], K)"},
    {"refine_tests", py_refine_tests, METH_VARARGS, "refine_tests(tree, active=None) -> dict of test points"},
    {"refine_decide", (PyCFunction)(void (*)(void))py_refine_decide, METH_VARARGS | METH_KEYWORDS,
     "refine_decide(tree, leaf_tests, test_positions, test_probe, max_band, probe_coeffs, test_coeffs, ...) -> "
     "(split uint8[L], error float64[L], threshold float64[L])"},
    {"shprobe_write_v3", (PyCFunction)(void (*)(void))py_shprobe_write_v3, METH_VARARGS | METH_KEYWORDS,
     "shprobe_write_v3(path, handle, coeffs, representation, max_band, storage=0, ...) -> probe count"},
    {"interp_from_file", py_interp_from_file, METH_VARARGS, "interp_from_file(path) -> handle of the file's structure"},
    {"shprobe_resample_dense", py_shprobe_resample_dense, METH_VARARGS,
     "shprobe_resample_dense(path, spacing=0) -> dict (a dense grid file image, SH only)"},
    {"_set_error_class", py_set_error_class, METH_O,
     "_set_error_class(cls): raise core errors as cls(message) with .code set"},
    {NULL, NULL, 0, NULL},
};

static int module_traverse(PyObject *module, visitproc visit, void *arg)
{
    module_state *st = get_state(module);
    if (st) Py_VISIT(st->error_class);
    return 0;
}

static int module_clear(PyObject *module)
{
    module_state *st = get_state(module);
    if (st) Py_CLEAR(st->error_class);
    return 0;
}

static void module_free(void *module) { module_clear((PyObject *)module); }

static struct PyModuleDef schnee_module = {
    PyModuleDef_HEAD_INIT,
    "_schnee_native",
    "Schnee probes bake core (stable ABI). Use schnee_probes.native, which wraps this module.",
    sizeof(module_state),
    methods,
    NULL,
    module_traverse,
    module_clear,
    module_free,
};

PyMODINIT_FUNC PyInit__schnee_native(void)
{
#ifdef SCHNEE_EMBREE_DYN
    char embree_msg[512] = "";
    if (pb_embree_load(embree_msg, sizeof embree_msg) != 0) { /* Embree through dlsym: pb_embree_dyn.h */
        PyErr_SetString(PyExc_ImportError, embree_msg);
        return NULL;
    }
#endif
    PyObject *m = PyModule_Create(&schnee_module);
    if (!m) return NULL;
    PyObject *error = PyErr_NewExceptionWithDoc("_schnee_native.Error", "A core error; `.code` is the pb_result name.",
                                                PyExc_RuntimeError, NULL);
    if (!error) {
        Py_DECREF(m);
        return NULL;
    }
    get_state(m)->error_class = Py_NewRef(error);
    if (PyModule_AddObject(m, "Error", error) < 0) {
        Py_DECREF(error);
        Py_DECREF(m);
        return NULL;
    }
    if (PyModule_AddIntConstant(m, "SH_MAX_BAND", PB_SH_MAX_BAND) < 0 ||
        PyModule_AddIntConstant(m, "SHPROBE_MAGIC", (long)PB_SHPROBE_MAGIC) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
