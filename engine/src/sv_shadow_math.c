/* The shadow maps' fitting math (docs/engine.md "Shadows"), pure functions with no Vulkan: see
 * sv_shadow_math.h. tests/engine/shadows/test_shadow_math.c checks them on the CPU. */
#include "sv_shadow_math.h"

#include <math.h>
#include <string.h>

/* Cascades (docs/engine.md "Shadows"): the practical split's weight of the logarithmic split against
 * the uniform one. 0.9 keeps the near cascade a few metres deep when the view spans hundreds. */
#define SV_CASCADE_LAMBDA 0.9f

/* An orthonormal light basis: f = unit dir (straight down when degenerate), x = normalize(f x up),
 * y = x x f, with up = +Y, or +X when |f.y| > 0.99. */
void sv_shadow_basis(const float dir[3], float x[3], float y[3], float f[3])
{
    memcpy(f, dir, 3 * sizeof(float));
    float fl = sqrtf(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    if (fl < 1e-12f) f[0] = 0, f[1] = -1, f[2] = 0, fl = 1;
    for (int k = 0; k < 3; ++k) f[k] /= fl;
    float up[3] = {0, 1, 0};
    if (fabsf(f[1]) > 0.99f) up[0] = 1, up[1] = 0;
    x[0] = f[1] * up[2] - f[2] * up[1], x[1] = f[2] * up[0] - f[0] * up[2], x[2] = f[0] * up[1] - f[1] * up[0];
    float xl = sqrtf(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
    for (int k = 0; k < 3; ++k) x[k] /= xl;
    y[0] = x[1] * f[2] - x[2] * f[1], y[1] = x[2] * f[0] - x[0] * f[2], y[2] = x[0] * f[1] - x[1] * f[0];
}

/* Corner c (bit 0: x, bit 1: y, bit 2: z at hi) of the box [lo, hi]. */
static void box_corner(const float lo[3], const float hi[3], int c, float p[3])
{
    for (int k = 0; k < 3; ++k) p[k] = (c >> k) & 1 ? hi[k] : lo[k];
}

/* The extent [mn, mx] of the world bounds [lo, hi] along each of the three light-space axes (the 8
 * corners projected), each padded by 1 % plus 1 mm so that surfaces on the bounds stay inside. */
static void light_space_bounds(const float *axes[3], const float lo[3], const float hi[3], float mn[3], float mx[3])
{
    for (int a = 0; a < 3; ++a) mn[a] = INFINITY, mx[a] = -INFINITY;
    for (int c = 0; c < 8; ++c) {
        float p[3];
        box_corner(lo, hi, c, p);
        for (int a = 0; a < 3; ++a) {
            float d = axes[a][0] * p[0] + axes[a][1] * p[1] + axes[a][2] * p[2];
            mn[a] = fminf(mn[a], d);
            mx[a] = fmaxf(mx[a], d);
        }
    }
    for (int a = 0; a < 3; ++a) {
        float pad = 0.01f * (mx[a] - mn[a]) + 1e-3f;
        mn[a] -= pad;
        mx[a] += pad;
    }
}

/* World -> light clip of an orthographic box along the basis `axes` (x, y, f): x, y in [-1, 1] over
 * centre c ± half extent h, z in [0, 1] over [zmin, zmax] along f (Vulkan); params[1..3] of
 * sv_gpu_frame.shadow_params (params[0], the texel size, is the caller's). */
static void ortho_light_projection(const float *axes[3], const float c[2], const float h[2], float zmin, float zmax,
                                   uint32_t res, float m[16], float params[4])
{
    memset(m, 0, 16 * sizeof(float));
    for (int k = 0; k < 3; ++k) {
        m[4 * k + 0] = axes[0][k] / h[0];
        m[4 * k + 1] = axes[1][k] / h[1];
        m[4 * k + 2] = axes[2][k] / (zmax - zmin);
    }
    m[12] = -c[0] / h[0];
    m[13] = -c[1] / h[1];
    m[14] = -zmin / (zmax - zmin);
    m[15] = 1.0f;
    params[1] = 1.0f / (zmax - zmin);
    params[2] = 1.0f / (float)res;
    params[3] = (float)SV_SHADOW_ORTHO;
}

/* The light-space projection of a directional light's layer: an orthographic box along `dir` fitted
 * to the 8 corners of the world bounds [lo, hi] (x, y extents and depth range, each padded by 1 %
 * plus 1 mm so that surfaces on the bounds stay inside), world -> clip with x, y in [-1, 1] and z in
 * [0, 1] (Vulkan), and its shadow_params (see sv_gpu_frame). */
void sv_shadow_fit_ortho(const float dir[3], const float lo[3], const float hi[3], uint32_t res, float m[16],
                         float params[4])
{
    float x[3], y[3], f[3];
    sv_shadow_basis(dir, x, y, f);
    const float *axes[3] = {x, y, f};
    float mn[3], mx[3];
    light_space_bounds(axes, lo, hi, mn, mx);
    float centre[2], half[2];
    for (int a = 0; a < 2; ++a) {
        centre[a] = 0.5f * (mn[a] + mx[a]);
        half[a] = 0.5f * (mx[a] - mn[a]);
    }
    ortho_light_projection(axes, centre, half, mn[2], mx[2], res, m, params);
    params[0] = 2.0f * fmaxf(half[0], half[1]) / (float)res;
}

/* near = max(znear, the nearest corner of [lo, hi] along the view), far = min(zfar, the farthest).
 * False when the scene lies wholly outside the camera's depth range (the cascades then all fall back
 * to the whole scene's fit). */
bool sv_cascade_view_fit(const sv_shadow_camera *v, float aspect, const float lo[3], const float hi[3],
                         sv_cascade_view *cv)
{
    for (int k = 0; k < 3; ++k) {
        cv->right[k] = v->view[4 * k + 0];
        cv->up[k] = v->view[4 * k + 1];
        cv->fwd[k] = -v->view[4 * k + 2];
        cv->eye[k] = v->camera_pos[k];
    }
    cv->perspective = v->yfov > 0.0f;
    cv->hy = cv->perspective ? tanf(0.5f * v->yfov) : v->ymag > 0 ? v->ymag : 1.0f;
    cv->hx = cv->hy * aspect;
    float dmin = INFINITY, dmax = -INFINITY;
    for (int c = 0; c < 8; ++c) {
        float p[3];
        box_corner(lo, hi, c, p);
        float d = 0.0f;
        for (int k = 0; k < 3; ++k) d += (p[k] - cv->eye[k]) * cv->fwd[k];
        dmin = fminf(dmin, d);
        dmax = fmaxf(dmax, d);
    }
    /* the camera's own far plane, as sv_view_projection sets it */
    float zfar =
        cv->perspective ? (v->zfar > 0.0f ? v->zfar : INFINITY) : (v->zfar > v->znear ? v->zfar : v->znear + 1000.0f);
    cv->near = fmaxf(dmin, v->znear);
    cv->far = fminf(dmax, zfar);
    return cv->far > cv->near;
}

/* Depth of split i of `count` (0 = near, count = far): the practical scheme
 * d_i = lambda * n * (f / n)^(i / C) + (1 - lambda) * (n + (f - n) * i / C) (uniform only when n <= 0,
 * an orthographic camera whose near plane is behind it). */
float sv_cascade_split(const sv_cascade_view *cv, uint32_t i, uint32_t count)
{
    if (i == 0) return cv->near;
    if (i >= count) return cv->far;
    float t = (float)i / (float)count, n = cv->near, f = cv->far;
    float uniform = n + (f - n) * t;
    if (n <= 0.0f) return uniform;
    return SV_CASCADE_LAMBDA * n * powf(f / n, t) + (1.0f - SV_CASCADE_LAMBDA) * uniform;
}

/* The light-space projection of cascade `cascade` of a directional light's `count`: an orthographic
 * box along `dir` whose depth range is the whole scene's (as shadow_projection_ortho: casters outside
 * the view still cast) and whose x, y square encloses the bounding sphere of the view slice's 8
 * corners (centre = their mean, on the view axis; radius = the farthest corner: it does not change as
 * the camera turns), its radius rounded up to a power of 2^(1/4) (the texel size does not change as
 * the split depths drift a little) plus room for SV_SHADOW_CASCADE_MARGIN + 1 texels, at most the
 * scene's own square, kept inside the scene's box where it fits, and its centre snapped to whole
 * texels (the texel grid stays put in light space as the camera moves: no shimmering). */
void sv_shadow_fit_cascade(const float dir[3], const float lo[3], const float hi[3], const sv_cascade_view *cv,
                           uint32_t cascade, uint32_t count, uint32_t res, float m[16], float params[4])
{
    float x[3], y[3], f[3];
    sv_shadow_basis(dir, x, y, f);
    const float *axes[3] = {x, y, f};
    float mn[3], mx[3];
    light_space_bounds(axes, lo, hi, mn, mx);
    /* the slice's corners, their mean and the bounding radius */
    float corner[8][3], centre[3] = {0, 0, 0};
    for (int c = 0; c < 8; ++c) {
        float d = sv_cascade_split(cv, cascade + (uint32_t)(c >> 2), count);
        float sx = (c & 1 ? 1.0f : -1.0f) * cv->hx * (cv->perspective ? d : 1.0f);
        float sy = (c & 2 ? 1.0f : -1.0f) * cv->hy * (cv->perspective ? d : 1.0f);
        for (int k = 0; k < 3; ++k) {
            corner[c][k] = cv->eye[k] + d * cv->fwd[k] + sx * cv->right[k] + sy * cv->up[k];
            centre[k] += corner[c][k] / 8.0f;
        }
    }
    float radius2 = 0.0f;
    for (int c = 0; c < 8; ++c) {
        float d2 = 0.0f;
        for (int k = 0; k < 3; ++k) d2 += (corner[c][k] - centre[k]) * (corner[c][k] - centre[k]);
        radius2 = fmaxf(radius2, d2);
    }
    float radius = exp2f(ceilf(4.0f * log2f(fmaxf(sqrtf(radius2), 1e-4f))) / 4.0f);
    float h = radius * (1.0f + 4.0f * (SV_SHADOW_CASCADE_MARGIN + 1.0f) / (float)res);
    h = fminf(h, 0.5f * fmaxf(mx[0] - mn[0], mx[1] - mn[1]));
    float texel = 2.0f * h / (float)res, c2[2];
    for (int a = 0; a < 2; ++a) {
        float c = axes[a][0] * centre[0] + axes[a][1] * centre[1] + axes[a][2] * centre[2];
        c = mn[a] + h <= mx[a] - h ? fminf(fmaxf(c, mn[a] + h), mx[a] - h) : 0.5f * (mn[a] + mx[a]);
        c2[a] = roundf(c / texel) * texel;
    }
    ortho_light_projection(axes, c2, (const float[2]){h, h}, mn[2], mx[2], res, m, params);
    params[0] = texel;
}

/* The projection of a spot light's layer or a point light's cube face: a perspective frustum from
 * the light's position along the layer's axis, tan(half fov) = layer->tan_half * (1 + 8 / res) (the
 * margin keeps the 3x3 filter of a fragment at the cone's edge, or at a cube face's edge, about 4
 * texels inside the map), far = the farthest corner of the world bounds [lo, hi] padded by 1 % plus
 * 1 mm, near = the bounds' distance from the light, at least far / 1000 (a float depth keeps about
 * 6e-5 of far there). Clip w = depth along the axis; z / w in [0, 1] between near and far. */
void sv_shadow_fit_perspective(const sv_shadow_layer *layer, const float lo[3], const float hi[3], uint32_t res,
                               float m[16], float params[4])
{
    float x[3], y[3], f[3];
    sv_shadow_basis(layer->dir, x, y, f);
    const float *pos = layer->pos;
    float far = 0.0f, near2 = 0.0f;
    for (int k = 0; k < 3; ++k) {
        float a = fabsf(lo[k] - pos[k]), b = fabsf(hi[k] - pos[k]), c = fmaxf(a, b);
        far += c * c;
        float outside = pos[k] < lo[k] ? lo[k] - pos[k] : pos[k] > hi[k] ? pos[k] - hi[k] : 0.0f;
        near2 += outside * outside;
    }
    far = sqrtf(far);
    far += 0.01f * far + 1e-3f;
    float near = fmaxf(0.99f * sqrtf(near2), far * 1e-3f);
    float t = layer->tan_half * (1.0f + 8.0f / (float)res);
    float a = far / (far - near), b = -near * far / (far - near);
    float xp = x[0] * pos[0] + x[1] * pos[1] + x[2] * pos[2];
    float yp = y[0] * pos[0] + y[1] * pos[1] + y[2] * pos[2];
    float fp = f[0] * pos[0] + f[1] * pos[1] + f[2] * pos[2];
    memset(m, 0, 16 * sizeof(float));
    for (int k = 0; k < 3; ++k) {
        m[4 * k + 0] = x[k] / t;
        m[4 * k + 1] = y[k] / t;
        m[4 * k + 2] = a * f[k];
        m[4 * k + 3] = f[k];
    }
    m[12] = -xp / t;
    m[13] = -yp / t;
    m[14] = -a * fp + b;
    m[15] = -fp;
    params[0] = 2.0f * t / (float)res;
    params[1] = 0.0f;
    params[2] = 1.0f / (float)res;
    params[3] = (float)layer->kind;
}

void sv_shadow_fit_layers(const sv_shadow_layer *layers, uint32_t count, uint32_t cascades,
                          const sv_shadow_camera *camera, float aspect, const float lo[3], const float hi[3],
                          uint32_t res, float m[][16], float params[][4])
{
    sv_cascade_view cv;
    memset(&cv, 0, sizeof(cv));
    bool sliced = cascades > 1 && sv_cascade_view_fit(camera, aspect, lo, hi, &cv);
    for (uint32_t k = 0; k < count; ++k) {
        const sv_shadow_layer *layer = &layers[k];
        if (layer->kind == SV_SHADOW_ORTHO && layer->cascades > 1 && sliced)
            sv_shadow_fit_cascade(layer->dir, lo, hi, &cv, layer->cascade, layer->cascades, res, m[k], params[k]);
        else if (layer->kind == SV_SHADOW_ORTHO)
            sv_shadow_fit_ortho(layer->dir, lo, hi, res, m[k], params[k]);
        else
            sv_shadow_fit_perspective(layer, lo, hi, res, m[k], params[k]);
    }
}
