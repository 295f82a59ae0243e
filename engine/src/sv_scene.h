/* The scene schnee-view draws: the loaded glTF (sv_gltf, immutable) plus the mutable state the
 * viewer changes — node transforms and, per drawn object, its world matrix, world bounds and the
 * probe it was assigned (DESIGN.md §7). Shared by the headless and the windowed path.
 */
#ifndef SV_SCENE_H
#define SV_SCENE_H

#include <stdbool.h>
#include <stdint.h>

#include "sv_ext.h"
#include "sv_gltf.h"

/* One drawn object: a mesh instance of the default scene. */
typedef struct sv_object {
    uint32_t node;     /* index into gltf->nodes */
    uint32_t mesh;     /* index into gltf->meshes */
    const char *name;  /* the node's name (owned by the glTF handle) */
    float world[16];   /* current object -> world */
    float aabb_min[3]; /* current world-space bounds (8 corners of the mesh bounds transformed) */
    float aabb_max[3];
    uint32_t probe;       /* assigned index in the probe buffer (0 = fallback) */
    uint32_t probe_flags; /* SV_DRAW_CUBE_ONLY / SV_DRAW_TETRA of the grid the probe came from */
    /* The object's own probe mode / representation (its node's VULKAN_SCHNEE_node), which replace its
     * materials'; SV_PROBE_MODE_MATERIAL / SV_PROBE_REP_MATERIAL = as its materials say. */
    uint32_t probe_mode, probe_representation;
    bool needs_probe; /* moved since the last probe query */
    bool movable;     /* moved at least once (--move, window keys): not part of the static scene whose
                         triangles judge probe visibility (docs/engine.md "Static scene") */
} sv_object;

typedef struct sv_scene {
    sv_gltf *gltf;
    sv_ext ext;        /* the VULKAN_SCHNEE_* extensions of gltf (materials, light modes, probe grids, sky) */
    float *node_local; /* node_count * 16, current local transforms */
    float *node_world; /* node_count * 16, current world transforms */
    sv_object *objects;
    uint32_t object_count;
    float aabb_min[3]; /* union of the objects' current bounds (min > max when empty) */
    float aabb_max[3];
} sv_scene;

/* Loads the glTF at path and parses its Schnee extensions (prints the warnings of both). Files the
 * glTF references must lie inside its folder tree unless allow_outside_paths (trusted scenes). On
 * error prints a message naming the problem and returns false with nothing allocated. */
bool sv_scene_load(const char *path, bool allow_outside_paths, sv_scene *out);
void sv_scene_destroy(sv_scene *scene);

/* Index of the node named `name` (first match), or -1. */
int32_t sv_scene_find_node(const sv_scene *scene, const char *name);

/* The mode and representation object `o` shades material `m` (its ext entry, NULL = the glTF default
 * material) with: the command line's override (`mode_override` / `rep_override` below _MATERIAL),
 * else the object's own (its node's VULKAN_SCHNEE_node), else the material's (docs/export.md "Node"). */
void sv_object_probe_mode(const sv_object *o, const sv_ext_material *m, uint32_t mode_override, uint32_t rep_override,
                          uint32_t *mode, uint32_t *rep);

/* Whether any object's node asks for ambient cubes (the renderer then builds the cube buffer). */
bool sv_scene_nodes_want_cubes(const sv_scene *scene);

/* Moves a node: sets its local translation (keeps rotation/scale; a node given by "matrix" gets
 * its translation column replaced), recomputes the world transforms of its subtree and marks every
 * affected object as needing a new probe query and as movable. */
void sv_scene_set_translation(sv_scene *scene, uint32_t node, const float translation[3]);

#endif
