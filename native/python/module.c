/* _schnee_native: the CPython face of the bake core (stable ABI, Py_LIMITED_API 3.11).
 *
 * The limited API has the buffer protocol but no numpy C API, so arrays come in as C-contiguous
 * buffers whose format and length are checked here (addon/schnee_probes/native.py makes them so
 * with numpy and gives them shapes), and go out as bytearrays that native.py wraps with
 * np.frombuffer (writable, no copy). Long core calls run with the GIL released; the placement
 * progress callback takes the GIL back to call Python. Core errors are raised as the class
 * registered with _set_error_class (native.SchneeError), default _schnee_native.Error, with the
 * core's message verbatim and `.code` = pb_result_string(code).
 *
 * This file holds the module (state, error class, init) and the argument helpers of mod_common.h;
 * the functions live in one file per area of the core (mod_common.h lists them).
 */
#include "mod_common.h"

#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"
#ifdef SCHNEE_EMBREE_DYN
/* Opens the Embree the package carries and fills the occluder module's function pointers
 * (native/src/pb_embree_dyn.h, private to native/src with the Embree headers): 0 on success, else
 * the reason in msg. Declared here so that no Embree header reaches the module's files. */
int pb_embree_load(char *msg, size_t msg_size);
#endif

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct module_state {
    PyObject *error_class; /* raised for core errors */
} module_state;

static module_state *get_state(PyObject *module) { return (module_state *)PyModule_GetState(module); }

PyObject *_pb_py_raise_core(PyObject *module, pb_result r, const pb_error *err)
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

void _pb_py_release(pb_py_buffer *b)
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
int _pb_py_get_buffer(PyObject *obj, const char *name, char code, Py_ssize_t multiple, Py_ssize_t expected,
                      pb_py_buffer *out)
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
        _pb_py_release(out);
        return -1;
    }
    out->count = out->view.len / itemsize;
    if (multiple > 0 && out->count % multiple != 0) {
        PyErr_Format(PyExc_ValueError, "%s has %zd items, not a multiple of %zd", name, out->count, multiple);
        _pb_py_release(out);
        return -1;
    }
    if (expected >= 0 && out->count != expected) {
        PyErr_Format(PyExc_ValueError, "%s has %zd items, expected %zd", name, out->count, expected);
        _pb_py_release(out);
        return -1;
    }
    return 0;
}

int _pb_py_check_band(long band)
{
    if (band < 0 || band > PB_SH_MAX_BAND) {
        PyErr_Format(PyExc_ValueError, "max_band %ld is out of range 0..%d", band, PB_SH_MAX_BAND);
        return -1;
    }
    return 0;
}

int _pb_py_check_u32(Py_ssize_t v, const char *name, uint32_t *out)
{
    if (v < 0 || (unsigned long long)v > UINT32_MAX) {
        PyErr_Format(PyExc_ValueError, "%s %zd is out of range 0..4294967295", name, v);
        return -1;
    }
    *out = (uint32_t)v;
    return 0;
}

/* a*b*c as Py_ssize_t, or -1 with ValueError when it overflows. */
Py_ssize_t _pb_py_product3(Py_ssize_t a, Py_ssize_t b, Py_ssize_t c, const char *what)
{
    unsigned long long r = 0;
    if (a < 0 || b < 0 || c < 0 || __builtin_mul_overflow((unsigned long long)a, (unsigned long long)b, &r) ||
        __builtin_mul_overflow(r, (unsigned long long)c, &r) || r > (unsigned long long)PY_SSIZE_T_MAX) {
        PyErr_Format(PyExc_ValueError, "%s %zd x %zd x %zd is too large", what, a, b, c);
        return -1;
    }
    return (Py_ssize_t)r;
}

PyObject *_pb_py_bytes_out(const void *data, size_t size)
{
    return PyByteArray_FromStringAndSize((const char *)data, (Py_ssize_t)size);
}

/* Optional 3x3 rotation: None or 9 float64. */
int _pb_py_get_rotation(PyObject *obj, pb_py_buffer *out)
{
    memset(out, 0, sizeof *out);
    if (obj == NULL || obj == Py_None) return 0;
    return _pb_py_get_buffer(obj, "rotation", 'd', 0, 9, out);
}

void _pb_py_mesh_list_free(pb_py_meshes *m)
{
    for (Py_ssize_t i = 0; i < m->count; i++) {
        if (m->verts) _pb_py_release(&m->verts[i]);
        if (m->tris) _pb_py_release(&m->tris[i]);
        if (m->items) Py_XDECREF(m->items[i]);
    }
    free(m->desc);
    free(m->verts);
    free(m->tris);
    free(m->items);
    memset(m, 0, sizeof *m);
}

int _pb_py_mesh_list_get(PyObject *seq, const char *what, pb_py_meshes *m)
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
        _pb_py_mesh_list_free(m);
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
        if (_pb_py_get_buffer(v, label, 'd', 3, -1, &m->verts[i]) < 0) goto fail;
        snprintf(label, sizeof label, "%s[%zd] triangles", what, i);
        if (_pb_py_get_buffer(t, label, 'I', 3, -1, &m->tris[i]) < 0) goto fail;
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
    _pb_py_mesh_list_free(m);
    return -1;
}

int _pb_py_dict_put(PyObject *d, const char *key, PyObject *value)
{
    if (!value) return -1;
    int r = PyDict_SetItemString(d, key, value);
    Py_DECREF(value);
    return r;
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

static PyObject *py_result_string(PyObject *module, PyObject *args)
{
    int code;
    if (!PyArg_ParseTuple(args, "i:result_string", &code)) return NULL;
    return PyUnicode_FromString(pb_result_string((pb_result)code));
}

static PyMethodDef methods[] = {
    {"result_string", py_result_string, METH_VARARGS, "result_string(code) -> str"},
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
    PyMethodDef *areas[] = {_pb_py_sh_methods,     _pb_py_placement_methods, _pb_py_shprobe_methods,
                            _pb_py_interp_methods, _pb_py_direct_methods,    _pb_py_refine_methods,
                            _pb_py_bricks_methods, _pb_py_grid_field_methods};
    for (size_t i = 0; i < sizeof areas / sizeof areas[0]; i++)
        if (PyModule_AddFunctions(m, areas[i]) < 0) {
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
