/* Schnee probes — loading Embree for the Python module (see pb_embree_dyn.h). */
#define _GNU_SOURCE
#define PB_EMBREE_DYN_IMPL
#include "pb_embree_dyn.h"

#include <dlfcn.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>

#define PB_EMBREE_DEFINE(name) __typeof__(&name) pb_dyn_##name;
PB_EMBREE_FUNCTIONS(PB_EMBREE_DEFINE)
#undef PB_EMBREE_DEFINE

static void *embree_handle;

/* The Embree to use (PB_EMBREE_SONAME: the major version built against), in order: one already in
 * the process under the same soname (Blender 3.x links Embree 3: sharing it avoids two copies), the one in lib/ next to this module (the add-on
 * package), the system's (a source build run from the tree). */
static void *open_embree(char *msg, size_t msg_size)
{
    void *h = dlopen(PB_EMBREE_SONAME, RTLD_NOW | RTLD_LOCAL | RTLD_NOLOAD);
    if (h) return h;
    Dl_info info;
    char path[PATH_MAX];
    const char *packaged_error = NULL;
    if (dladdr((void *)&pb_embree_load, &info) && info.dli_fname) {
        const char *slash = strrchr(info.dli_fname, '/');
        int dir_len = slash ? (int)(slash - info.dli_fname) : 1;
        const char *dir = slash ? info.dli_fname : ".";
        int n = snprintf(path, sizeof path, "%.*s/lib/" PB_EMBREE_SONAME, dir_len, dir);
        if (n > 0 && (size_t)n < sizeof path) {
            h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
            if (h) return h;
            packaged_error = dlerror();
        }
    }
    h = dlopen(PB_EMBREE_SONAME, RTLD_NOW | RTLD_LOCAL);
    if (h) return h;
    snprintf(msg, msg_size, "cannot load Embree (" PB_EMBREE_SONAME "): %s",
             packaged_error ? packaged_error : dlerror());
    return NULL;
}

int pb_embree_load(char *msg, size_t msg_size)
{
    if (embree_handle) return 0;
    void *h = open_embree(msg, msg_size);
    if (!h) return -1;
#define PB_EMBREE_RESOLVE(name)                                                                                        \
    *(void **)&pb_dyn_##name = dlsym(h, #name);                                                                        \
    if (!pb_dyn_##name) {                                                                                              \
        snprintf(msg, msg_size, "Embree (" PB_EMBREE_SONAME ") lacks %s", #name);                                      \
        return -1;                                                                                                     \
    }
    PB_EMBREE_FUNCTIONS(PB_EMBREE_RESOLVE)
#undef PB_EMBREE_RESOLVE
    embree_handle = h;
    return 0;
}
