/* Schnee probes — Embree reached through function pointers (the Python module only).
 *
 * Force-included (-include) into the Embree sources (embree_sources.cmake; pb_occluder.c is the only
 * one that calls Embree) when they are compiled for _schnee_native: every Embree
 * call becomes a call through a pointer that pb_embree_load() fills with dlsym() from the Embree
 * the add-on package carries (lib/libembree3.so.3 next to the module; libembree4.so.4 when built
 * against Embree 4, PB_EMBREE_SONAME), opened RTLD_LOCAL. The module then has no undefined rtc*
 * symbol at all, so nothing can bind its Embree calls to another Embree in the process: Blender
 * 4.x/5.x link Embree 4, which exports functions of the same names as Embree 3 with other
 * signatures. Symbol lookup of everything else (malloc, libstdc++) stays normal. */
#ifndef SCHNEE_PB_EMBREE_DYN_H
#define SCHNEE_PB_EMBREE_DYN_H

#include "pb_embree.h"
#include <stddef.h>

/* Every exported Embree function pb_occluder.c calls (the rtcInit* helpers are inline), in Embree 3
 * and 4 alike (pb_embree_compat.h). */
#define PB_EMBREE_FUNCTIONS(X)                                                                                         \
    X(rtcAttachGeometry)                                                                                               \
    X(rtcCommitGeometry)                                                                                               \
    X(rtcCommitScene)                                                                                                  \
    X(rtcGetDeviceError)                                                                                               \
    X(rtcIntersect1)                                                                                                   \
    X(rtcIntersect16)                                                                                                  \
    X(rtcNewDevice)                                                                                                    \
    X(rtcNewGeometry)                                                                                                  \
    X(rtcNewScene)                                                                                                     \
    X(rtcOccluded1)                                                                                                    \
    X(rtcPointQuery)                                                                                                   \
    X(rtcReleaseDevice)                                                                                                \
    X(rtcReleaseGeometry)                                                                                              \
    X(rtcReleaseScene)                                                                                                 \
    X(rtcSetDeviceErrorFunction)                                                                                       \
    X(rtcSetGeometryBoundsFunction)                                                                                    \
    X(rtcSetGeometryUserData)                                                                                          \
    X(rtcSetGeometryUserPrimitiveCount)                                                                                \
    X(rtcSetNewGeometryBuffer)                                                                                         \
    X(rtcSetSceneBuildQuality)                                                                                         \
    X(rtcSetSceneFlags)

#define PB_EMBREE_DECLARE(name) extern __typeof__(&name) pb_dyn_##name;
PB_EMBREE_FUNCTIONS(PB_EMBREE_DECLARE)
#undef PB_EMBREE_DECLARE

/* Opens Embree and resolves every function above; 0 on success, else -1 with a message in `msg`.
 * Idempotent. Called by the module's init before anything can reach the octree code. */
int pb_embree_load(char *msg, size_t msg_size);

#ifndef PB_EMBREE_DYN_IMPL
#define rtcAttachGeometry                pb_dyn_rtcAttachGeometry
#define rtcCommitGeometry                pb_dyn_rtcCommitGeometry
#define rtcCommitScene                   pb_dyn_rtcCommitScene
#define rtcGetDeviceError                pb_dyn_rtcGetDeviceError
#define rtcIntersect1                    pb_dyn_rtcIntersect1
#define rtcIntersect16                   pb_dyn_rtcIntersect16
#define rtcNewDevice                     pb_dyn_rtcNewDevice
#define rtcNewGeometry                   pb_dyn_rtcNewGeometry
#define rtcNewScene                      pb_dyn_rtcNewScene
#define rtcOccluded1                     pb_dyn_rtcOccluded1
#define rtcPointQuery                    pb_dyn_rtcPointQuery
#define rtcReleaseDevice                 pb_dyn_rtcReleaseDevice
#define rtcReleaseGeometry               pb_dyn_rtcReleaseGeometry
#define rtcReleaseScene                  pb_dyn_rtcReleaseScene
#define rtcSetDeviceErrorFunction        pb_dyn_rtcSetDeviceErrorFunction
#define rtcSetGeometryBoundsFunction     pb_dyn_rtcSetGeometryBoundsFunction
#define rtcSetGeometryUserData           pb_dyn_rtcSetGeometryUserData
#define rtcSetGeometryUserPrimitiveCount pb_dyn_rtcSetGeometryUserPrimitiveCount
#define rtcSetNewGeometryBuffer          pb_dyn_rtcSetNewGeometryBuffer
#define rtcSetSceneBuildQuality          pb_dyn_rtcSetSceneBuildQuality
#define rtcSetSceneFlags                 pb_dyn_rtcSetSceneFlags
#endif

#endif
