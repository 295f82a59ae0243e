/* _schnee_native: Direct light (pb_direct.h: lamps projected at probes, shadowed by meshes), the sky table and the
 * sky's sun (pb_sky_sun.h); native.py "direct light" and "the sky's sun" sections. */
#include "mod_common.h"

#include "schnee/pb_direct.h"
#include "schnee/pb_sh.h"
#include "schnee/pb_sky_sun.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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
    if (_pb_py_check_band(band) < 0 || _pb_py_check_u32(samples, "samples", &samples32) < 0) return NULL;
    pb_py_buffer lb, pb;
    if (_pb_py_get_buffer(lights_obj, "lights", 'd', PB_LIGHT_RECORD, -1, &lb) < 0) return NULL;
    if (_pb_py_get_buffer(probes_obj, "probes", 'd', 3, -1, &pb) < 0) {
        _pb_py_release(&lb);
        return NULL;
    }
    const Py_ssize_t nl = lb.count / PB_LIGHT_RECORD, np_ = pb.count / 3;
    pb_light *lights = calloc((size_t)nl + 1, sizeof *lights);
    if (!lights) {
        _pb_py_release(&lb);
        _pb_py_release(&pb);
        return PyErr_NoMemory();
    }
    const double *rec = lb.view.buf;
    for (Py_ssize_t i = 0; i < nl; i++, rec += PB_LIGHT_RECORD) {
        pb_light *l = &lights[i];
        if (!(rec[0] >= 0.0 && rec[0] < (double)PB_LIGHT_TYPE_COUNT_) || rec[0] != floor(rec[0])) {
            free(lights);
            _pb_py_release(&lb);
            _pb_py_release(&pb);
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
    pb_py_meshes geo = {0};
    if (geo_obj != Py_None && _pb_py_mesh_list_get(geo_obj, "geometry", &geo) < 0) {
        free(lights);
        _pb_py_release(&lb);
        _pb_py_release(&pb);
        return NULL;
    }
    const uint32_t n = pb_sh_count((uint32_t)band);
    double *out = calloc((size_t)np_ * n * 3 + 1, sizeof(double));
    if (!out) {
        _pb_py_mesh_list_free(&geo);
        free(lights);
        _pb_py_release(&lb);
        _pb_py_release(&pb);
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
    _pb_py_mesh_list_free(&geo);
    free(lights);
    _pb_py_release(&lb);
    _pb_py_release(&pb);
    if (r != PB_SUCCESS) {
        free(out);
        return _pb_py_raise_core(module, r, &err);
    }
    PyObject *res = _pb_py_bytes_out(out, (size_t)np_ * n * 3 * sizeof(double));
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
    if (_pb_py_check_band(band) < 0 || _pb_py_check_u32(width, "width", &w) < 0 ||
        _pb_py_check_u32(height, "height", &h) < 0 || _pb_py_check_u32(channels, "channels", &c) < 0 ||
        _pb_py_check_u32(pw, "pano_width", &pw32) < 0 || _pb_py_check_u32(ph, "pano_height", &ph32) < 0)
        return NULL;
    if (c < 3) return PyErr_Format(PyExc_ValueError, "channels %u: at least 3 (RGB first) are needed", c);
    const uint32_t n = pb_sh_count((uint32_t)band);
    Py_ssize_t cells = _pb_py_product3(pw, ph, (Py_ssize_t)n * 3, "pano_width x pano_height x coefficients");
    Py_ssize_t expected = _pb_py_product3(width, height, channels, "width x height x channels");
    if (cells < 0 || expected < 0) return NULL;
    if (cells > ((Py_ssize_t)1 << 28)) return PyErr_Format(PyExc_ValueError, "the sky table would be too large");
    pb_py_buffer world, rot;
    if (_pb_py_get_buffer(world_obj, "world", 'f', 0, expected, &world) < 0) return NULL;
    if (_pb_py_get_rotation(rot_obj, &rot) < 0) {
        _pb_py_release(&world);
        return NULL;
    }
    double *table = malloc(sizeof(double) * (size_t)cells + 1);
    if (!table) {
        _pb_py_release(&world);
        _pb_py_release(&rot);
        return PyErr_NoMemory();
    }
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_direct_sky_table(world.view.buf, w, h, c, pw32, ph32, (uint32_t)band,
                                                   rot.view.obj ? rot.view.buf : NULL, table, &err);
    Py_END_ALLOW_THREADS _pb_py_release(&world);
    _pb_py_release(&rot);
    if (r != PB_SUCCESS) {
        free(table);
        return _pb_py_raise_core(module, r, &err);
    }
    PyObject *res = _pb_py_bytes_out(table, (size_t)cells * sizeof(double));
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
    if (_pb_py_check_u32(width, "width", &w) < 0 || _pb_py_check_u32(height, "height", &h) < 0 ||
        _pb_py_check_u32(channels, "channels", &c) < 0)
        return NULL;
    Py_ssize_t expected = _pb_py_product3(width, height, channels, "width x height x channels");
    if (expected < 0) return NULL;
    pb_py_buffer image;
    if (_pb_py_get_buffer(image_obj, "image", 'f', 0, expected, &image) < 0) return NULL;
    PyObject *rest = PyByteArray_FromStringAndSize(NULL, expected * (Py_ssize_t)sizeof(float));
    if (!rest) {
        _pb_py_release(&image);
        return NULL;
    }
    float *rest_buf = (float *)PyByteArray_AsString(rest);
    pb_sky_sun sun;
    pb_error err = {0};
    pb_result r;
    Py_BEGIN_ALLOW_THREADS r = pb_sky_sun_split(&desc, image.view.buf, w, h, c, rest_buf, &sun, &err);
    Py_END_ALLOW_THREADS _pb_py_release(&image);
    if (r != PB_SUCCESS) {
        Py_DECREF(rest);
        return _pb_py_raise_core(module, r, &err);
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

PyMethodDef _pb_py_direct_methods[] = {
    {"direct_project", (PyCFunction)(void (*)(void))py_direct_project, METH_VARARGS | METH_KEYWORDS,
     "direct_project(lights: float64[N*20], probes: float64[P*3], max_band=2, samples=0, geometry=None, "
     "ray_offset=0) -> bytearray float64[P*count*3] (docs/direct-light.md)"},
    {"sky_table", (PyCFunction)(void (*)(void))py_sky_table, METH_VARARGS | METH_KEYWORDS,
     "sky_table(world: float32[H*W*C], width, height, channels, pano_width, pano_height, max_band=2, "
     "rotation=None) -> bytearray float64[pano_h*pano_w*count*3]"},
    {"sky_sun_split", (PyCFunction)(void (*)(void))py_sky_sun_split, METH_VARARGS | METH_KEYWORDS,
     "sky_sun_split(image: float32[H*W*C], width, height, channels, peak_fraction=0, max_radius=0, min_share=0) "
     "-> (dict, bytearray float32 rest)"},
    {NULL, NULL, 0, NULL},
};
