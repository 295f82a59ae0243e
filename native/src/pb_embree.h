/* Schnee probes — which Embree: 3 (Debian 12, libembree3.so.3) or 4 (Debian 13 and later,
 * libembree4.so.4). CMake defines PB_EMBREE_MAJOR from the Embree it found (find_package(embree));
 * without it, Embree 3. Only the header and the library's soname differ here; the calls whose
 * signatures changed between 3 and 4 go through pb_embree_compat.h. */
#ifndef SCHNEE_PB_EMBREE_H
#define SCHNEE_PB_EMBREE_H

#if defined(PB_EMBREE_MAJOR) && PB_EMBREE_MAJOR >= 4
#include <embree4/rtcore.h>
#define PB_EMBREE_SONAME "libembree4.so.4"
#else
#include <embree3/rtcore.h>
#define PB_EMBREE_SONAME "libembree3.so.3"
#endif

#endif
