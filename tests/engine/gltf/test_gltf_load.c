/* glTF loader: every feature on generated inputs, values checked against hand-computed ones.
 * Runtime: well under a second. */
#include "gltf_testgen.h"
#include "sv_ext.h"
#include "sv_gpu.h"
#include "testutil.h"

#include <float.h>

#define PI 3.14159265358979323846

static sv_gltf *load_json(const char *tmpl, const char *const *kv, const sv_gltf_desc *desc)
{
    char *json = tg_json(tmpl, kv);
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    sv_gltf_result r = sv_gltf_load_memory(json, strlen(json), desc, &g, &err);
    if (r != SV_GLTF_SUCCESS) fprintf(stderr, "load failed: %s (%s)\n", err.message, sv_gltf_result_string(r));
    free(json);
    return g;
}

/* Column-major world matrix element (row r, col c). */
#define M(m, r, c) ((m)[(c)*4 + (r)])

/* One triangle spanning [-1,1]^3: (-1,-1,-1), (1,-1,1), (1,1,1). */
static tg_bin triangle_bin(void)
{
    tg_bin b = {0};
    const float p[9] = {-1, -1, -1, 1, -1, 1, 1, 1, 1};
    for (int i = 0; i < 9; i++) tg_f32(&b, p[i]);
    return b;
}

static void test_hierarchy_world_matrices(void)
{
    tg_bin b = triangle_bin();
    char *uri = tg_data_uri(b.data, b.size);
    const char *kv[] = {"URI", uri, NULL};
    /* Root: T(1,2,3) · R_y(90°) · S(2); child: T(1,0,0); grandchild: matrix = T(0,1,0).
     * By hand: R_y(90°) maps x → −z, so root·(1,0,0) origin = (1,2,3) + 2·(0,0,−1) = (1,2,1) and
     * the grandchild origin = (1,2,1) + R·S·(0,1,0) = (1,4,1). The child's linear part has columns
     * R·S·e_x = (0,0,−2), R·S·e_y = (0,2,0), R·S·e_z = (2,0,0). */
    sv_gltf *g = load_json(
        "{'asset':{'version':'2.0'},'scene':0,'scenes':[{'name':'S','nodes':[0]}],"
        "'nodes':[{'name':'root','translation':[1,2,3],'rotation':[0,0.70710678118654752,0,0.70710678118654752],"
        "'scale':[2,2,2],'children':[1]},"
        "{'name':'child','translation':[1,0,0],'mesh':0,'children':[2]},"
        "{'name':'grand','matrix':[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,1,0,1]},"
        "{'name':'orphan','mesh':0}],"
        "'meshes':[{'name':'tri','primitives':[{'attributes':{'POSITION':0}}]}],"
        "'accessors':[{'bufferView':0,'componentType':5126,'count':3,'type':'VEC3'}],"
        "'bufferViews':[{'buffer':0,'byteLength':36}],'buffers':[{'byteLength':36,'uri':'@URI@'}]}",
        kv, NULL);
    free(uri);
    free(b.data);
    TU_REQUIRE(g);
    TU_CHECK_EQ_INT(g->scene, 0);
    TU_CHECK(strcmp(g->scene_name, "S") == 0);
    TU_REQUIRE(g->node_count == 4);
    const sv_gltf_node *child = &g->nodes[1], *grand = &g->nodes[2];
    TU_CHECK_EQ_INT(child->parent, 0);
    TU_CHECK_EQ_INT(grand->parent, 1);
    TU_CHECK(grand->has_matrix && !child->has_matrix);
    const double tol = 1e-5; /* float products of unit-scale values */
    TU_CHECK_NEAR(M(child->world, 0, 3), 1, tol);
    TU_CHECK_NEAR(M(child->world, 1, 3), 2, tol);
    TU_CHECK_NEAR(M(child->world, 2, 3), 1, tol);
    const double expect_lin[3][3] = {{0, 0, -2}, {0, 2, 0}, {2, 0, 0}}; /* columns */
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < 3; r++) TU_CHECK_NEAR(M(child->world, r, c), expect_lin[c][r], tol);
    TU_CHECK_NEAR(M(grand->world, 0, 3), 1, tol);
    TU_CHECK_NEAR(M(grand->world, 1, 3), 4, tol);
    TU_CHECK_NEAR(M(grand->world, 2, 3), 1, tol);
    TU_CHECK(g->nodes[0].in_scene && grand->in_scene && !g->nodes[3].in_scene);
    /* The orphan node (not in the scene) gets no instance. */
    TU_REQUIRE(g->mesh_instance_count == 1);
    const sv_gltf_mesh_instance *mi = &g->mesh_instances[0];
    TU_CHECK_EQ_INT(mi->node, 1);
    TU_CHECK_EQ_INT(mi->mesh, 0);
    /* Local box [-1,1]^3 under the child's world: centre (1,2,1), half extent 2 on every axis. */
    const double wmin[3] = {-1, 0, -1}, wmax[3] = {3, 4, 3};
    for (int k = 0; k < 3; k++) {
        TU_CHECK_NEAR(mi->aabb_min[k], wmin[k], tol);
        TU_CHECK_NEAR(mi->aabb_max[k], wmax[k], tol);
        TU_CHECK_NEAR(g->scene_aabb_min[k], wmin[k], tol);
        TU_CHECK_NEAR(g->scene_aabb_max[k], wmax[k], tol);
        TU_CHECK_NEAR(g->meshes[0].aabb_min[k], -1, 0);
        TU_CHECK_NEAR(g->meshes[0].aabb_max[k], 1, 0);
    }
    sv_gltf_free(g);
}

static void test_interleaved_normalized_attributes(void)
{
    /* View 0 interleaved, stride 20: pos float3 | uv ushort2 normalized | colour ubyte4 normalized.
     * View 1: normals as normalized byte VEC3, stride 4. View 2: ubyte indices. */
    tg_bin b = {0};
    const uint16_t uv[3][2] = {{0, 65535}, {32768, 16384}, {65535, 0}};
    const uint8_t col[3][4] = {{255, 0, 51, 255}, {0, 255, 0, 128}, {0, 0, 255, 0}};
    for (int i = 0; i < 3; i++) {
        tg_f32(&b, (float)i);
        tg_f32(&b, 2.0f * i);
        tg_f32(&b, 3.0f * i);
        tg_u16(&b, uv[i][0]);
        tg_u16(&b, uv[i][1]);
        for (int k = 0; k < 4; k++) tg_u8(&b, col[i][k]);
    }
    const int8_t nrm[3][3] = {{127, 0, 0}, {-128, 0, 0}, {0, 127, 0}};
    for (int i = 0; i < 3; i++) {
        for (int k = 0; k < 3; k++) tg_u8(&b, (uint8_t)nrm[i][k]);
        tg_u8(&b, 0xEE); /* padding that must not be read */
    }
    tg_u8(&b, 2);
    tg_u8(&b, 1);
    tg_u8(&b, 0);
    char *uri = tg_data_uri(b.data, b.size);
    const char *kv[] = {"URI", uri, NULL};
    sv_gltf *g = load_json(
        "{'asset':{'version':'2.0'},'scenes':[{'nodes':[0]}],'nodes':[{'mesh':0}],"
        "'meshes':[{'primitives':[{'attributes':{'POSITION':0,'TEXCOORD_0':1,'COLOR_0':2,'NORMAL':3},'indices':4}]}],"
        "'accessors':["
        "{'bufferView':0,'componentType':5126,'count':3,'type':'VEC3','min':[0,0,0],'max':[2,4,6]},"
        "{'bufferView':0,'byteOffset':12,'componentType':5123,'normalized':true,'count':3,'type':'VEC2'},"
        "{'bufferView':0,'byteOffset':16,'componentType':5121,'normalized':true,'count':3,'type':'VEC4'},"
        "{'bufferView':1,'componentType':5120,'normalized':true,'count':3,'type':'VEC3'},"
        "{'bufferView':2,'componentType':5121,'count':3,'type':'SCALAR'}],"
        "'bufferViews':[{'buffer':0,'byteLength':60,'byteStride':20},{'buffer':0,'byteOffset':60,'byteLength':12,'byteStride':4},"
        "{'buffer':0,'byteOffset':72,'byteLength':3}],"
        "'buffers':[{'byteLength':75,'uri':'@URI@'}]}",
        kv, NULL);
    free(uri);
    free(b.data);
    TU_REQUIRE(g);
    TU_REQUIRE(g->mesh_count == 1 && g->meshes[0].primitive_count == 1);
    const sv_gltf_primitive *p = &g->meshes[0].primitives[0];
    TU_CHECK_EQ_INT(p->vertex_count, 3);
    TU_REQUIRE(p->positions && p->texcoords0 && p->colors0 && p->normals);
    TU_CHECK(!p->normals_generated && !p->tangents && !p->texcoords1);
    for (int i = 0; i < 3; i++) {
        TU_CHECK_NEAR(p->positions[i * 3 + 0], i, 0);
        TU_CHECK_NEAR(p->positions[i * 3 + 1], 2.0 * i, 0);
        TU_CHECK_NEAR(p->positions[i * 3 + 2], 3.0 * i, 0);
        /* glTF 2.0 §3.11: unsigned normalized f = c / (2^n − 1). */
        TU_CHECK_NEAR(p->texcoords0[i * 2 + 0], uv[i][0] / 65535.0, 1e-7);
        TU_CHECK_NEAR(p->texcoords0[i * 2 + 1], uv[i][1] / 65535.0, 1e-7);
        for (int k = 0; k < 4; k++) TU_CHECK_NEAR(p->colors0[i * 4 + k], col[i][k] / 255.0, 1e-7);
        /* Signed normalized f = max(c / 127, −1): −128 clamps to −1. */
        for (int k = 0; k < 3; k++) TU_CHECK_NEAR(p->normals[i * 3 + k], fmax(nrm[i][k] / 127.0, -1.0), 1e-7);
    }
    TU_CHECK_NEAR(p->texcoords0[2], 0.50000762951, 1e-7); /* 32768/65535 */
    TU_REQUIRE(p->index_count == 3);
    TU_CHECK_EQ_INT(p->indices[0], 2);
    TU_CHECK_EQ_INT(p->indices[1], 1);
    TU_CHECK_EQ_INT(p->indices[2], 0);
    TU_CHECK_EQ_INT(p->material, -1);
    sv_gltf_free(g);
}

static void test_index_types_strips_fans_points(void)
{
    /* 4 vertices (a quad in the z=0 plane), then ushort and uint index lists. */
    tg_bin b = {0};
    const float quad[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    for (int i = 0; i < 12; i++) tg_f32(&b, quad[i]);
    const uint16_t us[6] = {0, 1, 2, 0, 2, 3};
    for (int i = 0; i < 6; i++) tg_u16(&b, us[i]);
    const uint32_t ui[4] = {3, 2, 1, 0};
    for (int i = 0; i < 4; i++) tg_u32(&b, ui[i]);
    char *uri = tg_data_uri(b.data, b.size);
    const char *kv[] = {"URI", uri, NULL};
    sv_gltf *g = load_json("{'asset':{'version':'2.0'},'scenes':[{'nodes':[0]}],'nodes':[{'mesh':0}],"
                           "'meshes':[{'primitives':["
                           "{'attributes':{'POSITION':0,'NORMAL':3},'indices':1},"
                           "{'attributes':{'POSITION':0,'NORMAL':3},'indices':2,'mode':5},"
                           "{'attributes':{'POSITION':0,'NORMAL':3},'mode':6},"
                           "{'attributes':{'POSITION':0},'mode':0},"
                           "{'attributes':{'POSITION':0,'NORMAL':3},'mode':1}]}],"
                           "'accessors':[{'bufferView':0,'componentType':5126,'count':4,'type':'VEC3'},"
                           "{'bufferView':1,'componentType':5123,'count':6,'type':'SCALAR'},"
                           "{'bufferView':2,'componentType':5125,'count':4,'type':'SCALAR'},"
                           "{'componentType':5126,'count':4,'type':'VEC3'}],"
                           "'bufferViews':[{'buffer':0,'byteLength':48},{'buffer':0,'byteOffset':48,'byteLength':12},"
                           "{'buffer':0,'byteOffset':60,'byteLength':16}],"
                           "'buffers':[{'byteLength':76,'uri':'@URI@'}]}",
                           kv, NULL);
    free(uri);
    free(b.data);
    TU_REQUIRE(g);
    /* POINTS and LINES are skipped with a warning each. */
    TU_REQUIRE(g->meshes[0].primitive_count == 3);
    TU_CHECK_EQ_INT(g->warning_count, 2);
    if (g->warning_count == 2) {
        TU_CHECK_CONTAINS(g->warnings[0], "meshes[0].primitives[3]: mode POINTS skipped");
        TU_CHECK_CONTAINS(g->warnings[1], "meshes[0].primitives[4]: mode LINES skipped");
    }
    const sv_gltf_primitive *list = &g->meshes[0].primitives[0], *strip = &g->meshes[0].primitives[1],
                            *fan = &g->meshes[0].primitives[2];
    TU_REQUIRE(list->index_count == 6);
    for (int i = 0; i < 6; i++) TU_CHECK_EQ_INT(list->indices[i], us[i]);
    /* Strip 3,2,1,0 → glTF §3.7.2.1 triangles {3,2,1}, {2,0,1} (odd one with the last two swapped). */
    const uint32_t strip_expect[6] = {3, 2, 1, 2, 0, 1};
    TU_REQUIRE(strip->index_count == 6);
    for (int i = 0; i < 6; i++) TU_CHECK_EQ_INT(strip->indices[i], strip_expect[i]);
    /* Fan over generated 0..3 → {1,2,0}, {2,3,0}. */
    const uint32_t fan_expect[6] = {1, 2, 0, 2, 3, 0};
    TU_REQUIRE(fan->index_count == 6);
    for (int i = 0; i < 6; i++) TU_CHECK_EQ_INT(fan->indices[i], fan_expect[i]);
    /* An accessor without bufferView reads as zeros. */
    for (int i = 0; i < 12; i++) TU_CHECK_NEAR(list->normals[i], 0, 0);
    sv_gltf_free(g);
}

static void test_sparse_and_flat_normals(void)
{
    /* POSITION: no bufferView (zeros) + sparse: vertices 1 and 2 set to (2,0,0) and (0,3,0).
     * Indices: ubyte zeros + sparse: positions 1 and 2 set to 1 and 2 → {0, 1, 2}.
     * No NORMAL → flat normals: e1 × e2 = (2,0,0) × (0,3,0) = (0,0,6) → (0,0,1). */
    tg_bin b = {0};
    tg_u16(&b, 1);
    tg_u16(&b, 2);
    const float vals[6] = {2, 0, 0, 0, 3, 0};
    for (int i = 0; i < 6; i++) tg_f32(&b, vals[i]);
    tg_u8(&b, 1);
    tg_u8(&b, 2);
    char *uri = tg_data_uri(b.data, b.size);
    const char *kv[] = {"URI", uri, NULL};
    sv_gltf *g = load_json("{'asset':{'version':'2.0'},'scenes':[{'nodes':[0]}],'nodes':[{'mesh':0}],"
                           "'meshes':[{'primitives':[{'attributes':{'POSITION':0},'indices':1}]}],"
                           "'accessors':[{'componentType':5126,'count':3,'type':'VEC3','sparse':{'count':2,"
                           "'indices':{'bufferView':0,'componentType':5123},'values':{'bufferView':1}}},"
                           "{'componentType':5121,'count':3,'type':'SCALAR','sparse':{'count':2,"
                           "'indices':{'bufferView':0,'componentType':5123},'values':{'bufferView':2}}}],"
                           "'bufferViews':[{'buffer':0,'byteLength':4},{'buffer':0,'byteOffset':4,'byteLength':24},"
                           "{'buffer':0,'byteOffset':28,'byteLength':2}],"
                           "'buffers':[{'byteLength':30,'uri':'@URI@'}]}",
                           kv, NULL);
    free(uri);
    free(b.data);
    TU_REQUIRE(g);
    const sv_gltf_primitive *p = &g->meshes[0].primitives[0];
    TU_REQUIRE(p->index_count == 3 && p->vertex_count == 3);
    for (int i = 0; i < 3; i++) TU_CHECK_EQ_INT(p->indices[i], i);
    const float expect_pos[9] = {0, 0, 0, 2, 0, 0, 0, 3, 0};
    for (int i = 0; i < 9; i++) TU_CHECK_NEAR(p->positions[i], expect_pos[i], 0);
    TU_REQUIRE(p->normals_generated);
    for (int v = 0; v < 3; v++) {
        TU_CHECK_NEAR(p->normals[v * 3 + 0], 0, 1e-7);
        TU_CHECK_NEAR(p->normals[v * 3 + 1], 0, 1e-7);
        TU_CHECK_NEAR(p->normals[v * 3 + 2], 1, 1e-7);
    }
    sv_gltf_free(g);

    /* keep_shared_normals: no normals generated. */
    tg_bin b3 = triangle_bin();
    uri = tg_data_uri(b3.data, b3.size);
    const char *kv3[] = {"URI", uri, NULL};
    sv_gltf_desc desc = {.keep_shared_normals = true};
    g = load_json("{'asset':{'version':'2.0'},'meshes':[{'primitives':[{'attributes':{'POSITION':0}}]}],"
                  "'accessors':[{'bufferView':0,'componentType':5126,'count':3,'type':'VEC3'}],"
                  "'bufferViews':[{'buffer':0,'byteLength':36}],'buffers':[{'byteLength':36,'uri':'@URI@'}]}",
                  kv3, &desc);
    free(uri);
    free(b3.data);
    TU_REQUIRE(g);
    TU_CHECK(g->meshes[0].primitives[0].normals == NULL && !g->meshes[0].primitives[0].normals_generated);
    TU_CHECK_EQ_INT(g->scene, -1); /* no scenes: nothing instanced */
    TU_CHECK_EQ_INT(g->mesh_instance_count, 0);
    TU_CHECK(g->scene_aabb_min[0] > g->scene_aabb_max[0]);
    sv_gltf_free(g);
}

static const char *MATERIAL_GLTF =
    "{'asset':{'version':'2.0'},"
    "'materials':[{'name':'full','pbrMetallicRoughness':{'baseColorFactor':[0.5,0.25,0.125,0.75],"
    "'baseColorTexture':{'index':0,'texCoord':1},'metallicFactor':0.3,'roughnessFactor':0.6,"
    "'metallicRoughnessTexture':{'index':1}},'normalTexture':{'index':2,'scale':0.5},"
    "'occlusionTexture':{'index':0,'strength':0.25},'emissiveFactor':[1,0.5,0],"
    "'emissiveTexture':{'index':1},'alphaMode':'MASK','alphaCutoff':0.3,'doubleSided':true,"
    "'extensions':{'VULKAN_SCHNEE_materials':{'shScale':2.5,'ambientTerm':0.05},"
    "'KHR_materials_emissive_strength':{'emissiveStrength':4}}},"
    "{'name':'defaults'},{'alphaMode':'BLEND','extensions':{'VULKAN_SCHNEE_materials':{}}}],"
    "'textures':[{'source':0,'sampler':0},{'source':1},{'source':2,'name':'tex2'}],"
    "'samplers':[{'magFilter':9728,'minFilter':9987,'wrapS':33071,'wrapT':33648}],"
    "'images':[{'uri':'tex/base%20color.png','name':'img0'},{'bufferView':0,'mimeType':'image/png'},"
    "{'uri':'data:image/jpeg;base64,/9j/'}],"
    "'bufferViews':[{'buffer':0,'byteOffset':4,'byteLength':8}],"
    "'buffers':[{'byteLength':12,'uri':'data:application/octet-stream;base64,AAECAwQFBgcICQoL'}]}";

static void test_materials_textures_images(void)
{
    sv_gltf_desc desc = {.base_dir = "/scenes/room"};
    sv_gltf *g = load_json(MATERIAL_GLTF, NULL, &desc);
    TU_REQUIRE(g);
    TU_REQUIRE(g->material_count == 3 && g->texture_count == 3 && g->image_count == 3 && g->sampler_count == 1);
    const sv_gltf_material *m = &g->materials[0];
    TU_CHECK(strcmp(m->name, "full") == 0);
    const float bc[4] = {0.5f, 0.25f, 0.125f, 0.75f};
    for (int k = 0; k < 4; k++) TU_CHECK_NEAR(m->base_color_factor[k], bc[k], 0);
    TU_CHECK_EQ_INT(m->base_color_texture.texture, 0);
    TU_CHECK_EQ_INT(m->base_color_texture.texcoord, 1);
    TU_CHECK_NEAR(m->metallic_factor, 0.3f, 0);
    TU_CHECK_NEAR(m->roughness_factor, 0.6f, 0);
    TU_CHECK_EQ_INT(m->metallic_roughness_texture.texture, 1);
    TU_CHECK_EQ_INT(m->normal_texture.texture, 2);
    TU_CHECK_NEAR(m->normal_texture.scale, 0.5, 0);
    TU_CHECK_NEAR(m->occlusion_texture.scale, 0.25, 0);
    TU_CHECK_NEAR(m->emissive_factor[0], 1, 0);
    TU_CHECK_NEAR(m->emissive_factor[1], 0.5, 0);
    TU_CHECK_NEAR(m->emissive_strength, 4, 0);
    TU_CHECK_EQ_INT(m->emissive_texture.texture, 1);
    TU_CHECK_EQ_INT(m->alpha_mode, SV_GLTF_ALPHA_MASK);
    TU_CHECK_NEAR(m->alpha_cutoff, 0.3f, 0);
    TU_CHECK(m->double_sided);
    /* VULKAN_SCHNEE_materials reaches the application as raw JSON (emissive strength is parsed). */
    TU_REQUIRE(m->extension_count == 1);
    TU_CHECK(strcmp(m->extensions[0].name, "VULKAN_SCHNEE_materials") == 0);
    TU_CHECK(strcmp(m->extensions[0].json, "{\"shScale\":2.5,\"ambientTerm\":0.05}") == 0);
    sv_ext ext;
    sv_gltf_error xerr = {0};
    TU_REQUIRE(sv_ext_parse(g, &ext, &xerr) == SV_GLTF_SUCCESS);
    TU_REQUIRE(ext.material_count == 3);
    TU_CHECK(ext.materials[0].present);
    TU_CHECK_NEAR(ext.materials[0].sh_scale, 2.5, 0);
    TU_CHECK_NEAR(ext.materials[0].ambient_term, 0.05f, 0);
    /* Defaults from the glTF 2.0 spec and DESIGN.md §5 (shScale 1, ambientTerm 0.1). */
    const sv_gltf_material *d = &g->materials[1];
    for (int k = 0; k < 4; k++) TU_CHECK_NEAR(d->base_color_factor[k], 1, 0);
    TU_CHECK_NEAR(d->metallic_factor, 1, 0);
    TU_CHECK_NEAR(d->roughness_factor, 1, 0);
    TU_CHECK_EQ_INT(d->base_color_texture.texture, -1);
    TU_CHECK_EQ_INT(d->normal_texture.texture, -1);
    TU_CHECK_NEAR(d->emissive_factor[0], 0, 0);
    TU_CHECK_NEAR(d->emissive_strength, 1, 0);
    TU_CHECK_EQ_INT(d->alpha_mode, SV_GLTF_ALPHA_OPAQUE);
    TU_CHECK_NEAR(d->alpha_cutoff, 0.5, 0);
    TU_CHECK(!d->double_sided && !ext.materials[1].present && d->extension_count == 0);
    TU_CHECK_NEAR(ext.materials[1].sh_scale, 1.0, 0);
    TU_CHECK_NEAR(ext.materials[1].ambient_term, 0.1f, 0);
    TU_CHECK_EQ_INT(ext.materials[1].probe_mode, SV_PROBE_MODE_OBJECT);
    TU_CHECK(ext.materials[2].present);
    TU_CHECK_NEAR(ext.materials[2].sh_scale, 1.0, 0);
    TU_CHECK_NEAR(ext.materials[2].ambient_term, 0.1f, 0);
    sv_ext_free(&ext);
    TU_CHECK_EQ_INT(g->materials[2].alpha_mode, SV_GLTF_ALPHA_BLEND);

    TU_CHECK_EQ_INT(g->textures[0].sampler, 0);
    TU_CHECK_EQ_INT(g->textures[1].sampler, -1);
    TU_CHECK_EQ_INT(g->textures[2].image, 2);
    TU_CHECK(strcmp(g->textures[2].name, "tex2") == 0);
    TU_CHECK_EQ_INT(g->samplers[0].mag_filter, 9728);
    TU_CHECK_EQ_INT(g->samplers[0].min_filter, 9987);
    TU_CHECK_EQ_INT(g->samplers[0].wrap_s, 33071);
    TU_CHECK_EQ_INT(g->samplers[0].wrap_t, 33648);
    /* External image: percent-decoded, resolved against the base dir, not read. */
    TU_CHECK(g->images[0].path && strcmp(g->images[0].path, "/scenes/room/tex/base color.png") == 0);
    TU_CHECK(g->images[0].data == NULL && strcmp(g->images[0].name, "img0") == 0);
    /* bufferView image: bytes 4..11 of the buffer (values 4..11). */
    TU_REQUIRE(g->images[1].data && g->images[1].size == 8);
    for (int i = 0; i < 8; i++) TU_CHECK_EQ_INT(g->images[1].data[i], 4 + i);
    TU_CHECK(strcmp(g->images[1].mime_type, "image/png") == 0 && g->images[1].path == NULL);
    /* data: URI image: "/9j/" = FF D8 FF (JPEG SOI), mime from the URI. */
    TU_REQUIRE(g->images[2].data && g->images[2].size == 3);
    TU_CHECK_EQ_INT(g->images[2].data[0], 0xFF);
    TU_CHECK_EQ_INT(g->images[2].data[1], 0xD8);
    TU_CHECK(strcmp(g->images[2].mime_type, "image/jpeg") == 0);
    sv_gltf_free(g);

    /* From memory without a base dir: external image paths stay NULL, with a warning. */
    g = load_json(MATERIAL_GLTF, NULL, NULL);
    TU_REQUIRE(g);
    TU_CHECK(g->images[0].path == NULL && g->images[0].data == NULL);
    TU_REQUIRE(g->warning_count == 1);
    TU_CHECK_CONTAINS(g->warnings[0],
                      "images[0]: external URI 'tex/base%20color.png' left unresolved (no base directory)");
    sv_gltf_free(g);
}

static void test_cameras_and_lights(void)
{
    /* Light node rotated −90° about X: its −Z axis points down, (0,−1,0) (R_x(θ)·(0,0,−1) with
     * θ = −90°: y' = sinθ = −1, z' = −cosθ = 0). Camera under a parent translated by (0,0,5). */
    const char *json =
        "{'asset':{'version':'2.0'},'scene':1,'scenes':[{'nodes':[]},{'nodes':[0,3]}],"
        "'nodes':[{'name':'rig','translation':[0,0,5],'children':[1,2]},"
        "{'name':'CamNode','camera':0,'translation':[0,1,0]},{'camera':1},"
        "{'name':'sun','rotation':[-0.70710678118654752,0,0,0.70710678118654752],'translation':[4,5,6],"
        "'extensions':{'KHR_lights_punctual':{'light':0}},'children':[4,5]},"
        "{'extensions':{'KHR_lights_punctual':{'light':1}}},{'extensions':{'KHR_lights_punctual':{'light':2}}}],"
        "'cameras':[{'name':'Persp','type':'perspective','perspective':{'yfov':0.8,'znear':0.1,'zfar':100,'aspectRatio':1.5}},"
        "{'type':'orthographic','orthographic':{'xmag':2,'ymag':1,'znear':0,'zfar':50}}],"
        "'extensionsUsed':['KHR_lights_punctual'],'extensionsRequired':['KHR_lights_punctual'],"
        "'extensions':{'KHR_lights_punctual':{'lights':["
        "{'name':'Sun','type':'directional','color':[1,0.9,0.8],'intensity':3,"
        "'extensions':{'VULKAN_SCHNEE_light':{'mode':'baked'}}},"
        "{'type':'point','range':10,'extensions':{'VULKAN_SCHNEE_light':{'mode':'realtime'}}},"
        "{'type':'spot','intensity':100,'spot':{'innerConeAngle':0.2,'outerConeAngle':0.5}}]}}}";
    sv_gltf *g = load_json(json, NULL, NULL);
    TU_REQUIRE(g);
    TU_CHECK_EQ_INT(g->scene, 1);
    TU_REQUIRE(g->camera_count == 2 && g->camera_instance_count == 2);
    const sv_gltf_camera *pc = &g->cameras[0], *oc = &g->cameras[1];
    TU_CHECK_EQ_INT(pc->type, SV_GLTF_CAMERA_PERSPECTIVE);
    TU_CHECK_NEAR(pc->yfov, 0.8f, 0);
    TU_CHECK_NEAR(pc->znear, 0.1f, 0);
    TU_CHECK_NEAR(pc->zfar, 100, 0);
    TU_CHECK_NEAR(pc->aspect_ratio, 1.5, 0);
    TU_CHECK_EQ_INT(oc->type, SV_GLTF_CAMERA_ORTHOGRAPHIC);
    TU_CHECK_NEAR(oc->xmag, 2, 0);
    TU_CHECK_NEAR(oc->ymag, 1, 0);
    TU_CHECK_NEAR(oc->zfar, 50, 0);
    /* Depth-first order: rig → CamNode → node 2. World origin of CamNode = (0,0,5) + (0,1,0). */
    TU_CHECK_EQ_INT(g->camera_instances[0].node, 1);
    TU_CHECK_NEAR(g->camera_instances[0].world[12], 0, 0);
    TU_CHECK_NEAR(g->camera_instances[0].world[13], 1, 0);
    TU_CHECK_NEAR(g->camera_instances[0].world[14], 5, 0);
    TU_CHECK_EQ_INT(g->camera_instances[1].camera, 1);
    TU_CHECK_EQ_INT(sv_gltf_find_camera(g, "CamNode"), 0);
    TU_CHECK_EQ_INT(sv_gltf_find_camera(g, "Persp"), 0);
    TU_CHECK_EQ_INT(sv_gltf_find_camera(g, "nope"), -1);

    TU_REQUIRE(g->light_count == 3 && g->light_instance_count == 3);
    const sv_gltf_light *sun = &g->lights[0], *pt = &g->lights[1], *spot = &g->lights[2];
    TU_CHECK_EQ_INT(sun->type, SV_GLTF_LIGHT_DIRECTIONAL);
    TU_CHECK(strcmp(sun->name, "Sun") == 0);
    TU_CHECK_NEAR(sun->color[2], 0.8f, 0);
    TU_CHECK_NEAR(sun->intensity, 3, 0);
    TU_CHECK_NEAR(sun->range, 0, 0); /* infinite */
    TU_CHECK_EQ_INT(pt->type, SV_GLTF_LIGHT_POINT);
    TU_CHECK_NEAR(pt->range, 10, 0);
    TU_CHECK_NEAR(pt->intensity, 1, 0);
    TU_CHECK_NEAR(pt->color[0], 1, 0);
    TU_CHECK_EQ_INT(spot->type, SV_GLTF_LIGHT_SPOT);
    TU_CHECK_NEAR(spot->inner_cone_angle, 0.2f, 0);
    TU_CHECK_NEAR(spot->outer_cone_angle, 0.5f, 0);
    TU_CHECK_NEAR(g->lights[0].outer_cone_angle, PI / 4, 1e-7); /* spec default */
    /* VULKAN_SCHNEE_light.mode as written; absent = realtime (docs/export.md). */
    sv_ext ext;
    sv_gltf_error xerr = {0};
    TU_REQUIRE(sv_ext_parse(g, &ext, &xerr) == SV_GLTF_SUCCESS);
    TU_REQUIRE(ext.light_count == 3);
    TU_CHECK_EQ_INT(ext.light_modes[0], SV_LIGHT_MODE_BAKED);
    TU_CHECK_EQ_INT(ext.light_modes[1], SV_LIGHT_MODE_REALTIME);
    TU_CHECK_EQ_INT(ext.light_modes[2], SV_LIGHT_MODE_REALTIME);
    TU_CHECK(spot->extension_count == 0 && sun->extension_count == 1);
    sv_ext_free(&ext);
    const sv_gltf_light_instance *li = &g->light_instances[0];
    TU_CHECK_EQ_INT(li->node, 3);
    TU_CHECK_NEAR(li->position[0], 4, 0);
    TU_CHECK_NEAR(li->position[1], 5, 0);
    TU_CHECK_NEAR(li->position[2], 6, 0);
    TU_CHECK_NEAR(li->direction[0], 0, 1e-6);
    TU_CHECK_NEAR(li->direction[1], -1, 1e-6);
    TU_CHECK_NEAR(li->direction[2], 0, 1e-6);
    /* Children inherit the rotation: same direction, same position. */
    TU_CHECK_NEAR(g->light_instances[2].direction[1], -1, 1e-6);
    TU_CHECK_NEAR(g->light_instances[2].position[2], 6, 1e-6);
    sv_gltf_free(g);
}

static void test_probe_grids(void)
{
    const char *json =
        "{'asset':{'version':'2.0'},'scenes':[{'nodes':[],'extensions':{'VULKAN_SCHNEE_engine_properties':{"
        "'shProbeGrids':["
        "{'name':'probes','uri':'sh_coeffs/probes.shprobe','probeCount':412,'maxBand':2,"
        "'gridOrigin':[-5,0,-5],'gridDims':[20,8,20],'gridSpacing':0.5,'gridAxes':[[1,0,0],[0,1,0],[0,0,1]]},"
        "{'name':'bad','uri':'sh_coeffs/bad.shprobe','probeCount':1,'maxBand':2,"
        "'gridOrigin':[0,0,0],'gridDims':'20x8x20','gridSpacing':0.5},"
        "{'name':'nouri','probeCount':1,'maxBand':2,'gridOrigin':[0,0,0],'gridDims':[1,1,1],'gridSpacing':1},"
        "{'uri':'two%20words.shprobe','probeCount':3,'maxBand':0,'gridOrigin':[1,2,3],'gridDims':[3,1,1],"
        "'gridSpacing':2,'gridAxes':[[0,0,1],[0,1,0],[-1,0,0]]}]}}}]}";
    sv_gltf_desc desc = {.base_dir = "/data/export"};
    sv_gltf *g = load_json(json, NULL, &desc);
    TU_REQUIRE(g);
    TU_REQUIRE(g->scene_extension_count == 1 && g->warning_count == 0);
    sv_ext ext;
    sv_gltf_error xerr = {0};
    TU_REQUIRE(sv_ext_parse(g, &ext, &xerr) == SV_GLTF_SUCCESS);
    TU_REQUIRE(ext.probe_grid_count == 2);
    const sv_ext_probe_grid *a = &ext.probe_grids[0], *b = &ext.probe_grids[1];
    TU_CHECK(strcmp(a->name, "probes") == 0);
    TU_CHECK(strcmp(a->uri, "sh_coeffs/probes.shprobe") == 0);
    TU_CHECK(strcmp(a->path, "/data/export/sh_coeffs/probes.shprobe") == 0);
    TU_CHECK_EQ_INT(a->probe_count, 412);
    TU_CHECK_EQ_INT(a->max_band, 2);
    TU_CHECK_NEAR(a->grid_origin[0], -5, 0);
    TU_CHECK_NEAR(a->grid_origin[2], -5, 0);
    TU_CHECK_EQ_INT(a->grid_dims[0], 20);
    TU_CHECK_EQ_INT(a->grid_dims[1], 8);
    TU_CHECK_NEAR(a->grid_spacing, 0.5, 0);
    TU_CHECK_NEAR(a->grid_axes[1][1], 1, 0);
    TU_CHECK(strcmp(b->name, "") == 0);
    TU_CHECK(strcmp(b->path, "/data/export/two words.shprobe") == 0);
    TU_CHECK_NEAR(b->grid_axes[0][2], 1, 0);
    TU_CHECK_NEAR(b->grid_axes[2][0], -1, 0);
    TU_CHECK_EQ_INT(b->max_band, 0);
    TU_REQUIRE(ext.warning_count == 2);
    TU_CHECK_CONTAINS(ext.warnings[0], "shProbeGrids[1].gridDims: expected an array of 3 numbers");
    TU_CHECK_CONTAINS(ext.warnings[0], "skipped");
    TU_CHECK_CONTAINS(ext.warnings[1], "shProbeGrids[2].uri: missing");
    sv_ext_free(&ext);
    sv_gltf_free(g);

    g = load_json(json, NULL, NULL);
    TU_REQUIRE(g);
    TU_REQUIRE(sv_ext_parse(g, &ext, &xerr) == SV_GLTF_SUCCESS);
    TU_REQUIRE(ext.probe_grid_count == 2);
    TU_CHECK(ext.probe_grids[0].path == NULL && strcmp(ext.probe_grids[0].uri, "sh_coeffs/probes.shprobe") == 0);
    TU_CHECK_EQ_INT(ext.warning_count, 4);
    sv_ext_free(&ext);
    sv_gltf_free(g);
}

/* The generic loader knows no VULKAN_SCHNEE_* extension: a file requiring one loads only when the
 * application declares it parses it (desc.app_extensions), and its JSON reaches it unparsed. */
static void test_app_extensions(void)
{
    const char *json = "{'asset':{'version':'2.0'},'extensionsRequired':['VULKAN_SCHNEE_materials'],"
                       "'extensions':{'X_root':{'a':[1,2]}},'materials':[{'extensions':{'VULKAN_SCHNEE_materials':"
                       "{'probeMode':'pixel'},'KHR_materials_emissive_strength':{'emissiveStrength':2}}}]}";
    char *text = tg_json(json, NULL);
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(text, strlen(text), NULL, &g, &err), SV_GLTF_ERROR_UNSUPPORTED);
    TU_CHECK_CONTAINS(err.message, "extensionsRequired: 'VULKAN_SCHNEE_materials' is not supported");
    sv_gltf_desc desc = {.app_extensions = sv_ext_names, .app_extension_count = SV_EXT_NAME_COUNT};
    TU_REQUIRE(sv_gltf_load_memory(text, strlen(text), &desc, &g, &err) == SV_GLTF_SUCCESS);
    TU_REQUIRE(g->material_count == 1 && g->materials[0].extension_count == 1);
    TU_CHECK_NEAR(g->materials[0].emissive_strength, 2, 0);
    TU_CHECK(strcmp(sv_gltf_find_extension(g->materials[0].extensions, 1, "VULKAN_SCHNEE_materials"),
                    "{\"probeMode\":\"pixel\"}") == 0);
    TU_CHECK(strcmp(sv_gltf_find_extension(g->extensions, g->extension_count, "X_root"), "{\"a\":[1,2]}") == 0);
    sv_ext ext;
    TU_REQUIRE(sv_ext_parse(g, &ext, &err) == SV_GLTF_SUCCESS);
    TU_CHECK_EQ_INT(ext.materials[0].probe_mode, SV_PROBE_MODE_PIXEL);
    sv_ext_free(&ext);
    sv_gltf_free(g);
    free(text);
}

/* Writes the same scene as .gltf + external .bin (name needing percent-decoding) and as .glb,
 * loads both from files and checks they decode identically. */
static void test_files_glb_and_external_bin(void)
{
    char *dir = tg_tmpdir();
    tg_bin b = triangle_bin();
    const char *body =
        "{'asset':{'version':'2.0','generator':'test'},'scenes':[{'nodes':[0]}],'nodes':[{'mesh':0,'name':'N'}],"
        "'meshes':[{'primitives':[{'attributes':{'POSITION':0}}]}],"
        "'accessors':[{'bufferView':0,'componentType':5126,'count':3,'type':'VEC3'}],"
        "'bufferViews':[{'buffer':0,'byteLength':36}],'buffers':[{'byteLength':36@URI@}]}";
    const char *kv_ext[] = {"URI", ",\"uri\":\"my%20mesh.bin\"", NULL};
    char *json_ext = tg_json(body, kv_ext);
    char *p_bin = tg_write(dir, "my mesh.bin", b.data, b.size);
    char *p_gltf = tg_write(dir, "scene.gltf", json_ext, strlen(json_ext));
    const char *kv_glb[] = {"URI", "", NULL};
    char *json_glb = tg_json(body, kv_glb);
    tg_bin glb = tg_glb(json_glb, &b);
    char *p_glb = tg_write(dir, "scene.glb", glb.data, glb.size);

    sv_gltf *g1 = NULL, *g2 = NULL;
    sv_gltf_error e1 = {0}, e2 = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_file(p_gltf, NULL, &g1, &e1), SV_GLTF_SUCCESS);
    TU_CHECK_EQ_INT(sv_gltf_load_file(p_glb, NULL, &g2, &e2), SV_GLTF_SUCCESS);
    if (e1.code) fprintf(stderr, "%s\n", e1.message);
    if (e2.code) fprintf(stderr, "%s\n", e2.message);
    if (g1 && g2) {
        TU_CHECK(strcmp(g1->base_dir, dir) == 0);
        const sv_gltf_primitive *a = &g1->meshes[0].primitives[0], *c = &g2->meshes[0].primitives[0];
        TU_CHECK_EQ_INT(a->vertex_count, 3); /* flat normals: still 3 (one triangle) */
        TU_CHECK(memcmp(a->positions, c->positions, 9 * sizeof(float)) == 0);
        TU_CHECK_NEAR(a->positions[3], 1, 0);
        TU_CHECK_NEAR(c->positions[8], 1, 0);
        TU_CHECK_EQ_INT(g2->mesh_instance_count, 1);
    }
    sv_gltf_free(g1);
    sv_gltf_free(g2);

    /* From memory: the .gltf needs a base dir for its .bin; the .glb does not. */
    sv_gltf *g3 = NULL;
    sv_gltf_error e3 = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(json_ext, strlen(json_ext), NULL, &g3, &e3), SV_GLTF_ERROR_UNSUPPORTED);
    TU_CHECK_CONTAINS(e3.message, "buffers[0]: external URI 'my%20mesh.bin' but no base directory");
    TU_CHECK(g3 == NULL);
    sv_gltf_desc desc = {.base_dir = dir};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(json_ext, strlen(json_ext), &desc, &g3, &e3), SV_GLTF_SUCCESS);
    sv_gltf_free(g3);
    g3 = NULL;
    TU_CHECK_EQ_INT(sv_gltf_load_memory(glb.data, glb.size, NULL, &g3, &e3), SV_GLTF_SUCCESS);
    sv_gltf_free(g3);

    /* Truncated external buffer file. */
    free(tg_write(dir, "my mesh.bin", b.data, 20));
    sv_gltf_error e4 = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_file(p_gltf, NULL, &g3, &e4), SV_GLTF_ERROR_FORMAT);
    TU_CHECK_CONTAINS(e4.message, "buffers[0]: file '");
    TU_CHECK_CONTAINS(e4.message, "has 20 bytes, byteLength is 36");
    /* Missing files. */
    tg_remove(dir, "my mesh.bin");
    sv_gltf_error e5 = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_file(p_gltf, NULL, &g3, &e5), SV_GLTF_ERROR_IO);
    TU_CHECK_CONTAINS(e5.message, "buffers[0]: cannot open '");
    sv_gltf_error e6 = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_file("/nonexistent/x.gltf", NULL, &g3, &e6), SV_GLTF_ERROR_IO);
    TU_CHECK_CONTAINS(e6.message, "cannot open '/nonexistent/x.gltf'");
    /* Budget: 36 bytes of buffer + the file itself do not fit in 64 bytes. */
    sv_gltf_desc small = {.max_decoded_bytes = 64};
    sv_gltf_error e7 = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_file(p_glb, &small, &g3, &e7), SV_GLTF_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(e7.message, "over the max_decoded_bytes limit (64)");
    TU_CHECK(g3 == NULL);

    tg_remove(dir, "scene.gltf");
    tg_remove(dir, "scene.glb");
    rmdir(dir);
    free(p_bin);
    free(p_gltf);
    free(p_glb);
    free(json_ext);
    free(json_glb);
    free(glb.data);
    free(b.data);
    free(dir);
}

int main(void)
{
    TU_RUN(test_hierarchy_world_matrices);
    TU_RUN(test_interleaved_normalized_attributes);
    TU_RUN(test_index_types_strips_fans_points);
    TU_RUN(test_sparse_and_flat_normals);
    TU_RUN(test_materials_textures_images);
    TU_RUN(test_cameras_and_lights);
    TU_RUN(test_probe_grids);
    TU_RUN(test_app_extensions);
    TU_RUN(test_files_glb_and_external_bin);
    return TU_EXIT();
}
