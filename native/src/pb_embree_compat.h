/* Schnee probes — the Embree calls whose form differs between Embree 3 and Embree 4.
 *
 * Embree 4 replaced the intersect context (RTCIntersectContext, rtcInitIntersectContext, the
 * context's filter member) by an optional RTCIntersectArguments (with an RTCRayQueryContext and the
 * filter), renamed RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION to RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS
 * and moved the context argument of rtcIntersect* to the end; an argument filter runs only where
 * RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER (or a per-geometry switch) asks for it. Point queries, buffers, user
 * geometries, RTC_SCENE_FLAG_ROBUST and the RTCHitN layout the filter reads are the same in both.
 *
 * Used by the occluders (native/src/pb_occluder.c), the only Embree caller; private to native/src.
 * Included after pb_embree_dyn.h when that is force-included (the Python module), so the calls
 * below go through its function pointers there as every other Embree call does. */
#ifndef SCHNEE_PB_EMBREE_COMPAT_H
#define SCHNEE_PB_EMBREE_COMPAT_H

#include "pb_embree.h"

#include <stddef.h>

#if RTC_VERSION_MAJOR >= 4
/* The per-ray context a filter function receives as args->context: embed it as the first member of
 * a larger struct to reach the caller's state from the filter. */
typedef struct RTCRayQueryContext pb_rtc_context;
#define PB_RTC_SCENE_FLAG_FILTER_IN_CALL RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS
#else
typedef struct RTCIntersectContext pb_rtc_context;
#define PB_RTC_SCENE_FLAG_FILTER_IN_CALL RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION
#endif

/* One ray against `scene` (made with PB_RTC_SCENE_FLAG_FILTER_IN_CALL) with `filter` called for
 * every candidate hit, its args->context being `ctx`. */
static inline void pb_rtc_intersect1_filtered(RTCScene scene, pb_rtc_context *ctx, RTCFilterFunctionN filter,
                                              struct RTCRayHit *rayhit)
{
#if RTC_VERSION_MAJOR >= 4
    rtcInitRayQueryContext(ctx);
    struct RTCIntersectArguments args;
    rtcInitIntersectArguments(&args);
    /* Embree 4 calls an argument filter only for geometries that enable it
     * (rtcSetGeometryEnableFilterFunctionFromArguments) or with this flag: for all of them. */
    args.flags = (enum RTCRayQueryFlags)(args.flags | RTC_RAY_QUERY_FLAG_INVOKE_ARGUMENT_FILTER);
    args.context = ctx;
    args.filter = filter;
    rtcIntersect1(scene, rayhit, &args);
#else
    rtcInitIntersectContext(ctx);
    ctx->filter = filter;
    rtcIntersect1(scene, ctx, rayhit);
#endif
}

/* A packet of 16 rays with the default (coherent-ray) settings. */
static inline void pb_rtc_intersect16(const int *valid, RTCScene scene, struct RTCRayHit16 *rayhit)
{
#if RTC_VERSION_MAJOR >= 4
    rtcIntersect16(valid, scene, rayhit, NULL);
#else
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcIntersect16(valid, scene, &ctx, rayhit);
#endif
}

/* One ray with the default settings: rayhit->ray.tfar becomes the nearest hit's distance. */
static inline void pb_rtc_intersect1(RTCScene scene, struct RTCRayHit *rayhit)
{
#if RTC_VERSION_MAJOR >= 4
    rtcIntersect1(scene, rayhit, NULL);
#else
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcIntersect1(scene, &ctx, rayhit);
#endif
}

/* One occlusion ray with the default settings; ray->tfar becomes -inf when something is hit. */
static inline void pb_rtc_occluded1(RTCScene scene, struct RTCRay *ray)
{
#if RTC_VERSION_MAJOR >= 4
    rtcOccluded1(scene, ray, NULL);
#else
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcOccluded1(scene, &ctx, ray);
#endif
}

#endif
