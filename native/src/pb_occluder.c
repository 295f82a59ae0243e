/* Occluders: one Embree device and triangle scene per handle (see pb_occluder.h). The only file of
 * the project that calls Embree; pb_embree_compat.h hides the differences between Embree 3 and 4,
 * and in the Python module every call goes through pb_embree_dyn.h's pointers. */
#include "schnee/pb_occluder.h"
#include "schnee/pb_octree.h"

#include "pb_embree_compat.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Embree errors met by one device: the first is kept for pb_*_error (queries run on many threads). */
typedef struct device_errors {
    pthread_mutex_t lock;
    bool lock_ok;
    bool failed;
    char message[256];
} device_errors;

static void device_error_fn(void *user, enum RTCError code, const char *str)
{
    device_errors *e = (device_errors *)user;
    if (code == RTC_ERROR_NONE) return;
    if (e->lock_ok) pthread_mutex_lock(&e->lock);
    if (!e->failed) {
        e->failed = true;
        snprintf(e->message, sizeof e->message, "Embree error %d: %s", (int)code, str ? str : "(no detail)");
    }
    if (e->lock_ok) pthread_mutex_unlock(&e->lock);
}

static pb_result device_errors_check(const device_errors *e, pb_error *err, const char *what)
{
    if (!e->failed) return PB_SUCCESS;
    return pb_error_set(err, PB_ERROR_EMBREE, "%s while %s", e->message, what);
}

/* A device whose BVH builds use at most `threads` threads, errors recorded in `e`. */
static RTCDevice new_device(uint32_t threads, device_errors *e, pb_error *err)
{
    e->lock_ok = pthread_mutex_init(&e->lock, NULL) == 0;
    char config[96];
    snprintf(config, sizeof config, "threads=%u,set_affinity=0,verbose=0", threads ? threads : 1u);
    RTCDevice device = rtcNewDevice(config);
    if (!device) {
        pb_error_set(err, PB_ERROR_EMBREE, "could not create an Embree device (error %d)",
                     (int)rtcGetDeviceError(NULL));
        return NULL;
    }
    rtcSetDeviceErrorFunction(device, device_error_fn, e);
    return device;
}

/* ---------------------------------------------------------------------------------------------- */
/* Triangle scenes                                                                                 */

struct pb_occluder {
    RTCDevice device;
    RTCScene scene; /* NULL without triangles */
    pb_occluder_mesh *meshes;
    uint32_t mesh_count;
    uint32_t *mesh_of_geom; /* Embree geometry id → mesh index */
    uint32_t geom_count;
    uint64_t triangle_count;
    double origin[3];
    device_errors errors;
};

static pb_result check_meshes(const pb_occluder_desc *d, const char *what, pb_error *err)
{
    for (uint32_t i = 0; i < d->mesh_count; i++) {
        const pb_occluder_mesh *m = &d->meshes[i];
        if (m->triangle_count == 0) continue;
        if (!m->indices || (!m->positions && !m->positions_f))
            return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "%s mesh %u has %u triangles but no %s array", what, i,
                                m->triangle_count, m->indices ? "position" : "index");
        for (size_t k = 0; k < 3 * (size_t)m->triangle_count; k++)
            if (m->indices[k] >= m->vertex_count)
                return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT,
                                    "%s mesh %u: triangle %zu uses vertex index %u, but the mesh has only %u vertices",
                                    what, i, k / 3, m->indices[k], m->vertex_count);
        for (size_t k = 0; k < 3 * (size_t)m->vertex_count; k++) {
            double x = m->positions ? m->positions[k] : (double)m->positions_f[k];
            if (!isfinite(x))
                return pb_error_set(err, PB_ERROR_NON_FINITE, "%s mesh %u: vertex %zu has a non-finite %c coordinate",
                                    what, i, k / 3, "xyz"[k % 3]);
        }
    }
    return PB_SUCCESS;
}

/* One Embree triangle geometry per mesh with triangles, attached in mesh order. */
static pb_result build_scene(pb_occluder *o, const pb_occluder_desc *d, const char *what, pb_error *err)
{
    o->scene = rtcNewScene(o->device);
    if (!o->scene) goto fail;
    enum RTCSceneFlags flags = RTC_SCENE_FLAG_NONE;
    if (d->flags & PB_OCCLUDER_FILTERABLE) flags = (enum RTCSceneFlags)(flags | PB_RTC_SCENE_FLAG_FILTER_IN_CALL);
    if (d->flags & PB_OCCLUDER_ROBUST) flags = (enum RTCSceneFlags)(flags | RTC_SCENE_FLAG_ROBUST);
    if (flags != RTC_SCENE_FLAG_NONE) rtcSetSceneFlags(o->scene, flags);
    if (d->flags & PB_OCCLUDER_BUILD_MEDIUM) rtcSetSceneBuildQuality(o->scene, RTC_BUILD_QUALITY_MEDIUM);
    for (uint32_t i = 0; i < d->mesh_count; i++) {
        const pb_occluder_mesh *m = &d->meshes[i];
        if (m->triangle_count == 0 || m->vertex_count == 0) continue;
        RTCGeometry g = rtcNewGeometry(o->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        if (!g) goto fail;
        float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                            m->vertex_count);
        unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                               m->triangle_count);
        if (!vb || !ib) {
            rtcReleaseGeometry(g);
            goto fail;
        }
        if (m->positions) {
            for (size_t v = 0; v < m->vertex_count; v++)
                for (int a = 0; a < 3; a++) vb[3 * v + a] = (float)(m->positions[3 * v + a] - d->origin[a]);
        } else {
            memcpy(vb, m->positions_f, 3 * sizeof(float) * (size_t)m->vertex_count);
        }
        memcpy(ib, m->indices, 3 * sizeof(unsigned) * (size_t)m->triangle_count);
        rtcCommitGeometry(g);
        unsigned id = rtcAttachGeometry(o->scene, g);
        rtcReleaseGeometry(g);
        if (id >= d->mesh_count) goto fail;
        o->mesh_of_geom[id] = i;
        if (id + 1 > o->geom_count) o->geom_count = id + 1;
        o->triangle_count += m->triangle_count;
    }
    rtcCommitScene(o->scene);
    if (o->errors.failed) goto fail;
    return PB_SUCCESS;
fail:;
    pb_result r = device_errors_check(&o->errors, err, "building the ray-tracing scene");
    return r ? r : pb_error_set(err, PB_ERROR_EMBREE, "Embree could not build the %s scene", what);
}

void pb_occluder_destroy(pb_occluder *o)
{
    if (!o) return;
    if (o->scene) rtcReleaseScene(o->scene);
    if (o->device) rtcReleaseDevice(o->device);
    if (o->errors.lock_ok) pthread_mutex_destroy(&o->errors.lock);
    free(o->meshes);
    free(o->mesh_of_geom);
    free(o);
}

pb_result pb_occluder_create(const pb_occluder_desc *desc, pb_occluder **out, pb_error *err)
{
    if (out) *out = NULL;
    if (!desc || !out)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_occluder_create: desc and out must not be NULL");
    const char *what = desc->what ? desc->what : "occluder";
    if (desc->mesh_count && !desc->meshes)
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_occluder_create: %u %s meshes but meshes is NULL",
                            desc->mesh_count, what);
    for (int a = 0; a < 3; a++)
        if (!isfinite(desc->origin[a]))
            return pb_error_set(err, PB_ERROR_NON_FINITE, "pb_occluder_create: the %s origin is not finite", what);
    pb_result r = check_meshes(desc, what, err);
    if (r) return r;
    uint64_t triangles = 0;
    for (uint32_t i = 0; i < desc->mesh_count; i++)
        if (desc->meshes[i].vertex_count) triangles += desc->meshes[i].triangle_count;

    pb_occluder *o = calloc(1, sizeof *o);
    if (!o) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory creating the %s", what);
    memcpy(o->origin, desc->origin, sizeof o->origin);
    o->mesh_count = desc->mesh_count;
    o->meshes = malloc(sizeof *o->meshes * ((size_t)desc->mesh_count + 1));
    o->mesh_of_geom = malloc(sizeof *o->mesh_of_geom * ((size_t)desc->mesh_count + 1));
    if (!o->meshes || !o->mesh_of_geom) {
        pb_occluder_destroy(o);
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory creating the %s", what);
    }
    if (desc->mesh_count) memcpy(o->meshes, desc->meshes, sizeof *o->meshes * desc->mesh_count);
    if (triangles == 0) { /* nothing occludes: no device at all */
        *out = o;
        return PB_SUCCESS;
    }
    o->device = new_device(desc->thread_count, &o->errors, err);
    if (!o->device) {
        pb_occluder_destroy(o);
        return PB_ERROR_EMBREE;
    }
    r = build_scene(o, desc, what, err);
    if (r) {
        pb_occluder_destroy(o);
        return r;
    }
    *out = o;
    return PB_SUCCESS;
}

uint64_t pb_occluder_triangle_count(const pb_occluder *o) { return o ? o->triangle_count : 0; }

pb_result pb_occluder_error(const pb_occluder *o, pb_error *err, const char *what)
{
    return o ? device_errors_check(&o->errors, err, what) : PB_SUCCESS;
}

static void ray_from(struct RTCRay *r, const pb_occluder_ray *ray)
{
    r->org_x = ray->org[0];
    r->org_y = ray->org[1];
    r->org_z = ray->org[2];
    r->dir_x = ray->dir[0];
    r->dir_y = ray->dir[1];
    r->dir_z = ray->dir[2];
    r->tnear = ray->tnear;
    r->tfar = ray->tfar;
    r->mask = 0xFFFFFFFFu;
}

bool pb_occluder_occluded(const pb_occluder *o, const pb_occluder_ray *ray)
{
    if (!o || !o->scene) return false;
    struct RTCRayHit rh;
    memset(&rh, 0, sizeof rh);
    ray_from(&rh.ray, ray);
    pb_rtc_occluded1(o->scene, &rh.ray);
    return rh.ray.tfar < 0.0f; /* Embree sets tfar = -inf on a hit */
}

typedef struct skip_ray_ctx {
    pb_rtc_context ctx; /* first member: Embree passes this pointer to the filter */
    const pb_occluder *o;
    pb_occluder_skip_fn skip;
    void *user;
} skip_ray_ctx;

static void skip_filter(const struct RTCFilterFunctionNArguments *args)
{
    const skip_ray_ctx *r = (const skip_ray_ctx *)args->context;
    for (unsigned i = 0; i < args->N; i++) {
        if (!args->valid[i]) continue;
        unsigned geom = ((const unsigned *)args->hit)[6 * args->N + i];
        if (geom < r->o->geom_count && r->skip(r->user, r->o->mesh_of_geom[geom])) args->valid[i] = 0;
    }
}

bool pb_occluder_first_hit(const pb_occluder *o, const pb_occluder_ray *ray, pb_occluder_skip_fn skip, void *skip_user,
                           float *t, uint32_t *mesh)
{
    if (!o || !o->scene) return false;
    struct RTCRayHit rh;
    memset(&rh, 0, sizeof rh);
    ray_from(&rh.ray, ray);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    if (skip) {
        skip_ray_ctx rc;
        memset(&rc, 0, sizeof rc);
        rc.o = o;
        rc.skip = skip;
        rc.user = skip_user;
        pb_rtc_intersect1_filtered(o->scene, &rc.ctx, skip_filter, &rh);
    } else {
        pb_rtc_intersect1(o->scene, &rh);
    }
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    if (t) *t = rh.ray.tfar;
    if (mesh) *mesh = o->mesh_of_geom[rh.hit.geomID];
    return true;
}

/* ---------------------------------------------------------------------------------------------- */
/* Geometry in double                                                                              */

static inline void sub3(double r[3], const double a[3], const double b[3])
{
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}

static inline void cross3(double r[3], const double a[3], const double b[3])
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

static inline double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* A vertex in the occluder's frame, in double. */
static inline void vertex_rel(const pb_occluder *o, const pb_occluder_mesh *m, uint32_t v, double out[3])
{
    for (int a = 0; a < 3; a++)
        out[a] =
            m->positions ? m->positions[3 * (size_t)v + a] - o->origin[a] : (double)m->positions_f[3 * (size_t)v + a];
}

/* Projection of the triangle (v0, v1, v2, relative to the box centre) and of the box (half size h)
 * on axis a; returns true when they are separated. */
static inline bool sat_separated(const double a[3], const double v0[3], const double v1[3], const double v2[3],
                                 double h)
{
    double p0 = dot3(a, v0), p1 = dot3(a, v1), p2 = dot3(a, v2);
    double mn = fmin(p0, fmin(p1, p2)), mx = fmax(p0, fmax(p1, p2));
    double r = h * (fabs(a[0]) + fabs(a[1]) + fabs(a[2]));
    return mn > r || mx < -r;
}

/* Closed overlap of the cube (centre bc, half edge h) and triangle (t0, t1, t2): Akenine-Möller's
 * separating-axis test. */
static bool tri_box_overlap(const double bc[3], double h, const double t0[3], const double t1[3], const double t2[3])
{
    double v0[3], v1[3], v2[3];
    sub3(v0, t0, bc);
    sub3(v1, t1, bc);
    sub3(v2, t2, bc);
    /* 1. the box's face normals (= the triangle's bounding box against the box) */
    for (int k = 0; k < 3; k++) {
        double mn = fmin(v0[k], fmin(v1[k], v2[k])), mx = fmax(v0[k], fmax(v1[k], v2[k]));
        if (mn > h || mx < -h) return false;
    }
    double e[3][3];
    sub3(e[0], v1, v0);
    sub3(e[1], v2, v1);
    sub3(e[2], v0, v2);
    /* 2. the triangle's plane */
    double n[3];
    cross3(n, e[0], e[1]);
    if (sat_separated(n, v0, v0, v0, h)) return false;
    /* 3. the nine edge × box-axis cross products */
    for (int i = 0; i < 3; i++) {
        for (int k = 0; k < 3; k++) {
            double axis[3] = {0, 0, 0}, a[3];
            axis[k] = 1.0;
            cross3(a, e[i], axis);
            if (a[0] == 0 && a[1] == 0 && a[2] == 0) continue;
            if (sat_separated(a, v0, v1, v2, h)) return false;
        }
    }
    return true;
}

/* ---------------------------------------------------------------------------------------------- */
/* The solid test's fan                                                                            */

/* Rays go out in packets of 16 from the same origin (Embree's packet traversal is ~1.5× faster
 * than single rays here). */
void pb_occluder_backface_count(const pb_occluder *o, const double origin[3], const float (*dirs)[3], uint32_t count,
                                uint32_t *hits_out, uint32_t *back_out)
{
    uint32_t hits = 0, back = 0;
    if (o && o->scene) {
        struct RTCRayHit16 rh;
        _Alignas(64) int valid[16]; /* Embree requires the 16-wide valid mask 64-byte aligned */
        for (uint32_t k0 = 0; k0 < count; k0 += 16) {
            for (uint32_t l = 0; l < 16; l++) {
                uint32_t k = k0 + l;
                valid[l] = k < count ? -1 : 0;
                rh.ray.org_x[l] = (float)origin[0];
                rh.ray.org_y[l] = (float)origin[1];
                rh.ray.org_z[l] = (float)origin[2];
                rh.ray.dir_x[l] = valid[l] ? dirs[k][0] : 0.0f;
                rh.ray.dir_y[l] = valid[l] ? dirs[k][1] : 0.0f;
                rh.ray.dir_z[l] = valid[l] ? dirs[k][2] : 1.0f;
                rh.ray.tnear[l] = 0.0f;
                rh.ray.tfar[l] = INFINITY;
                rh.ray.time[l] = 0.0f;
                rh.ray.mask[l] = 0xFFFFFFFFu;
                rh.ray.id[l] = l;
                rh.ray.flags[l] = 0;
                rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
            }
            pb_rtc_intersect16(valid, o->scene, &rh);
            for (uint32_t l = 0; l < 16; l++) {
                if (!valid[l] || rh.hit.geomID[l] == RTC_INVALID_GEOMETRY_ID) continue;
                uint32_t k = k0 + l;
                hits++;
                /* The counter-clockwise normal in double from the input rather than Embree's float one. */
                const pb_occluder_mesh *m = &o->meshes[o->mesh_of_geom[rh.hit.geomID[l]]];
                const uint32_t *tri = &m->indices[3 * (size_t)rh.hit.primID[l]];
                double a[3], b[3], e1[3], e2[3], n[3];
                double dir[3] = {dirs[k][0], dirs[k][1], dirs[k][2]};
                vertex_rel(o, m, tri[0], a);
                vertex_rel(o, m, tri[1], b);
                sub3(e1, b, a);
                vertex_rel(o, m, tri[2], b);
                sub3(e2, b, a);
                cross3(n, e1, e2);
                if (dot3(n, dir) > 0) back++;
            }
        }
    }
    *hits_out = hits;
    *back_out = back;
}

float pb_occluder_backface_ratio(const pb_occluder *o, const double origin[3], const float (*dirs)[3], uint32_t count)
{
    uint32_t hits = 0, back = 0;
    pb_occluder_backface_count(o, origin, dirs, count, &hits, &back);
    return hits ? (float)back / (float)hits : 0.0f;
}

/* ---------------------------------------------------------------------------------------------- */
/* Crossings (a filter passed with the call rejects each hit so traversal continues)               */

typedef struct crossing_ctx {
    pb_rtc_context ctx; /* first member: Embree passes this pointer to the filter */
    uint32_t capacity, count;
    bool overflow;
    uint32_t *geom; /* Embree geometry ids until the end of the ray */
    uint32_t *prim;
} crossing_ctx;

static void crossing_filter(const struct RTCFilterFunctionNArguments *args)
{
    crossing_ctx *r = (crossing_ctx *)args->context;
    for (unsigned i = 0; i < args->N; i++) {
        if (!args->valid[i]) continue;
        unsigned prim = ((unsigned *)args->hit)[5 * args->N + i];
        unsigned geom = ((unsigned *)args->hit)[6 * args->N + i];
        bool dup = false;
        /* A primitive referenced from two BVH leaves may be reported twice: count it once. */
        for (uint32_t k = 0; k < r->count; k++) {
            if (r->geom[k] == geom && r->prim[k] == prim) {
                dup = true;
                break;
            }
        }
        if (!dup) {
            if (r->count < r->capacity) {
                r->geom[r->count] = geom;
                r->prim[r->count] = prim;
                r->count++;
            } else {
                r->overflow = true;
            }
        }
        args->valid[i] = 0; /* reject: keep traversing to see every crossing */
    }
}

bool pb_occluder_crossings(const pb_occluder *o, const double org[3], const double dir[3], uint32_t capacity,
                           uint32_t *mesh, uint32_t *triangle, uint32_t *count)
{
    *count = 0;
    if (!o || !o->scene) return true;
    crossing_ctx r;
    memset(&r, 0, sizeof r);
    r.capacity = capacity;
    r.geom = mesh;
    r.prim = triangle;
    struct RTCRayHit rh;
    memset(&rh, 0, sizeof rh);
    rh.ray.org_x = (float)org[0];
    rh.ray.org_y = (float)org[1];
    rh.ray.org_z = (float)org[2];
    rh.ray.dir_x = (float)dir[0];
    rh.ray.dir_y = (float)dir[1];
    rh.ray.dir_z = (float)dir[2];
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = INFINITY;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    pb_rtc_intersect1_filtered(o->scene, &r.ctx, crossing_filter, &rh);
    for (uint32_t k = 0; k < r.count; k++) mesh[k] = o->mesh_of_geom[mesh[k]];
    *count = r.count;
    return !r.overflow;
}

/* ---------------------------------------------------------------------------------------------- */
/* Box overlap: candidates from a point query with the box's bounding sphere, then exact SAT        */

typedef struct box_query {
    const pb_occluder *o;
    double centre[3];
    double h;
    bool found;
} box_query;

static bool box_query_fn(struct RTCPointQueryFunctionArguments *args)
{
    box_query *q = (box_query *)args->userPtr;
    if (q->found) return false;
    const pb_occluder_mesh *m = &q->o->meshes[q->o->mesh_of_geom[args->geomID]];
    const uint32_t *tri = &m->indices[3 * (size_t)args->primID];
    double t0[3], t1[3], t2[3];
    vertex_rel(q->o, m, tri[0], t0);
    vertex_rel(q->o, m, tri[1], t1);
    vertex_rel(q->o, m, tri[2], t2);
    if (!tri_box_overlap(q->centre, q->h, t0, t1, t2)) return false;
    q->found = true;
    args->query->radius = 0.0f; /* nothing more to find: shrink the query to stop early */
    return true;
}

bool pb_occluder_box_overlaps(const pb_occluder *o, const double centre[3], double h, double pad)
{
    if (!o || !o->scene || h <= 0) return false;
    box_query q;
    q.o = o;
    memcpy(q.centre, centre, sizeof q.centre);
    q.h = h;
    q.found = false;
    struct RTCPointQuery pq;
    pq.x = (float)centre[0];
    pq.y = (float)centre[1];
    pq.z = (float)centre[2];
    pq.time = 0.0f;
    /* Bounding sphere of the cube, widened for the float rounding of the centre and of Embree's
     * bounds (relative 1e-5 of the coordinates is far above float's 6e-8). */
    double mag = fmax(fabs(centre[0]), fmax(fabs(centre[1]), fabs(centre[2])));
    pq.radius = (float)(h * 1.7320508075688772 * (1.0 + 1e-5) + 1e-5 * mag + pad);
    struct RTCPointQueryContext pctx;
    rtcInitPointQueryContext(&pctx);
    rtcPointQuery(o->scene, &pq, &pctx, box_query_fn, &q);
    return q.found;
}

/* ---------------------------------------------------------------------------------------------- */
/* Nearest point: a user geometry of one box per point                                             */

struct pb_point_index {
    RTCDevice device;
    RTCScene scene;
    const double *points;
    uint32_t count;
    double pad;
    device_errors errors;
};

static void point_bounds_fn(const struct RTCBoundsFunctionArguments *args)
{
    const pb_point_index *ix = (const pb_point_index *)args->geometryUserPtr;
    const double *p = &ix->points[3 * (size_t)args->primID];
    double pad = ix->pad + 1e-6 * fmax(fabs(p[0]), fmax(fabs(p[1]), fabs(p[2])));
    args->bounds_o->lower_x = (float)(p[0] - pad);
    args->bounds_o->lower_y = (float)(p[1] - pad);
    args->bounds_o->lower_z = (float)(p[2] - pad);
    args->bounds_o->upper_x = (float)(p[0] + pad);
    args->bounds_o->upper_y = (float)(p[1] + pad);
    args->bounds_o->upper_z = (float)(p[2] + pad);
}

void pb_point_index_destroy(pb_point_index *ix)
{
    if (!ix) return;
    if (ix->scene) rtcReleaseScene(ix->scene);
    if (ix->device) rtcReleaseDevice(ix->device);
    if (ix->errors.lock_ok) pthread_mutex_destroy(&ix->errors.lock);
    free(ix);
}

pb_result pb_point_index_create(const double *points, uint32_t count, double pad, uint32_t thread_count,
                                pb_point_index **out, pb_error *err)
{
    if (out) *out = NULL;
    if (!out || (count && !points))
        return pb_error_set(err, PB_ERROR_INVALID_ARGUMENT, "pb_point_index_create: NULL points or out");
    pb_point_index *ix = calloc(1, sizeof *ix);
    if (!ix) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory creating the probe index");
    ix->points = points;
    ix->count = count;
    ix->pad = pad;
    if (count == 0) {
        *out = ix;
        return PB_SUCCESS;
    }
    ix->device = new_device(thread_count, &ix->errors, err);
    if (!ix->device) {
        pb_point_index_destroy(ix);
        return PB_ERROR_EMBREE;
    }
    ix->scene = rtcNewScene(ix->device);
    RTCGeometry g = ix->scene ? rtcNewGeometry(ix->device, RTC_GEOMETRY_TYPE_USER) : NULL;
    if (g) {
        rtcSetGeometryUserPrimitiveCount(g, count);
        rtcSetGeometryUserData(g, ix);
        rtcSetGeometryBoundsFunction(g, point_bounds_fn, ix);
        rtcCommitGeometry(g);
        rtcAttachGeometry(ix->scene, g);
        rtcReleaseGeometry(g);
        rtcCommitScene(ix->scene);
    }
    pb_result r = device_errors_check(&ix->errors, err, "indexing the probes");
    if (!r && !g) r = pb_error_set(err, PB_ERROR_EMBREE, "could not create the probe index");
    if (r) {
        pb_point_index_destroy(ix);
        return r;
    }
    *out = ix;
    return PB_SUCCESS;
}

typedef struct nearest_query {
    const double *points;
    double p[3];
    double best_d2;
    int32_t best;
    double slack;
} nearest_query;

static bool nearest_fn(struct RTCPointQueryFunctionArguments *args)
{
    nearest_query *q = (nearest_query *)args->userPtr;
    const double *s = &q->points[3 * (size_t)args->primID];
    double d[3];
    sub3(d, s, q->p);
    double d2 = dot3(d, d);
    int32_t idx = (int32_t)args->primID;
    if (q->best < 0 || d2 < q->best_d2 || (d2 == q->best_d2 && idx < q->best)) {
        q->best = idx;
        q->best_d2 = d2;
        /* Keep a margin so points at the same distance are still visited (ties → smaller index). */
        args->query->radius = (float)(sqrt(d2) * (1.0 + 1e-5) + q->slack);
        return true;
    }
    return false;
}

int32_t pb_point_index_nearest(const pb_point_index *ix, const double p[3], double slack)
{
    if (!ix || !ix->scene) return -1;
    nearest_query q;
    memcpy(q.p, p, sizeof q.p);
    q.points = ix->points;
    q.best = -1;
    q.best_d2 = INFINITY;
    q.slack = slack;
    struct RTCPointQuery pq;
    pq.x = (float)p[0];
    pq.y = (float)p[1];
    pq.z = (float)p[2];
    pq.time = 0.0f;
    pq.radius = INFINITY;
    struct RTCPointQueryContext pctx;
    rtcInitPointQueryContext(&pctx);
    rtcPointQuery(ix->scene, &pq, &pctx, nearest_fn, &q);
    return q.best;
}

pb_result pb_point_index_error(const pb_point_index *ix, pb_error *err, const char *what)
{
    return ix ? device_errors_check(&ix->errors, err, what) : PB_SUCCESS;
}

pb_result pb_occluder_create_from_meshes(const pb_mesh_desc *meshes, uint32_t count, const double origin[3],
                                         uint32_t thread_count, uint32_t flags, const char *what, pb_occluder **out,
                                         pb_error *err)
{
    pb_occluder_mesh *om = calloc((size_t)count + 1, sizeof *om);
    if (!om)
        return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "out of memory creating the %s", what ? what : "occluder");
    for (uint32_t i = 0; i < count; i++) {
        om[i].positions = meshes[i].positions;
        om[i].indices = meshes[i].indices;
        om[i].vertex_count = meshes[i].vertex_count;
        om[i].triangle_count = meshes[i].triangle_count;
    }
    pb_occluder_desc d = {0};
    d.meshes = om;
    d.mesh_count = count;
    memcpy(d.origin, origin, sizeof d.origin);
    d.thread_count = thread_count;
    d.flags = flags;
    d.what = what;
    pb_result r = pb_occluder_create(&d, out, err);
    free(om);
    return r;
}
