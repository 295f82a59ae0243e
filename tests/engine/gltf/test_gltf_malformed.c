/* glTF loader: a table of malformed inputs, each expecting a specific result code and an error
 * message fragment that names the broken element. Runs under ASan/UBSan in the sanitizer build,
 * so "no crash, no out-of-bounds read, no leak on the error path" is checked too. Runtime: < 1 s.
 * A case that loads is then run through the engine's extension parser (sv_ext_parse), whose errors
 * (VULKAN_SCHNEE_*) the table expects the same way. */
#include "gltf_testgen.h"
#include "sv_ext.h"
#include "testutil.h"

/* Fragments substituted into the templates (' becomes " in the templates only). */
#define A   "'asset':{'version':'2.0'}"
#define Z12 "'buffers':[{'byteLength':12,'uri':'data:application/octet-stream;base64,AAAAAAAAAAAAAAAA'}]"
/* 12 bytes, the first is 5. */
#define B5 "'buffers':[{'byteLength':12,'uri':'data:application/octet-stream;base64,BQAAAAAAAAAAAAAA'}]"
/* 12 bytes: a float NaN (0x7fc00000) then zeros. */
#define BNAN "'buffers':[{'byteLength':12,'uri':'data:application/octet-stream;base64,AADAfwAAAAAAAAAA'}]"
#define V12  "'bufferViews':[{'buffer':0,'byteLength':12}]"
/* One POSITION accessor of 1 vertex reading zeros (no bufferView). */
#define POS1       "{'componentType':5126,'count':1,'type':'VEC3'}"
#define MESH(prim) "'meshes':[{'primitives':[" prim "]}]"

typedef struct bad_case {
    const char *json;
    sv_gltf_result code;
    const char *fragment;
    bool non_triangles_are_errors;
    const char *base_dir;
} bad_case;

/* Most rows leave the trailing option fields at zero. */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
static const bad_case CASES[] = {
    /* JSON and top level */
    {"", SV_GLTF_ERROR_JSON, "invalid JSON near byte 0"},
    {"{'asset':", SV_GLTF_ERROR_JSON, "invalid JSON"},
    {"{" A "} trailing", SV_GLTF_ERROR_JSON, "trailing data after the JSON value"},
    {"[]", SV_GLTF_ERROR_FORMAT, "the JSON root is not an object"},
    {"{}", SV_GLTF_ERROR_FORMAT, "asset: missing"},
    {"{'asset':{}}", SV_GLTF_ERROR_FORMAT, "asset.version: missing"},
    {"{'asset':{'version':'1.0'}}", SV_GLTF_ERROR_UNSUPPORTED, "asset.version: '1.0' is not glTF 2.x"},
    {"{" A ",'extensionsRequired':['KHR_draco_mesh_compression']}", SV_GLTF_ERROR_UNSUPPORTED,
     "extensionsRequired: 'KHR_draco_mesh_compression' is not supported"},
    {"{" A ",'accessors':{}}", SV_GLTF_ERROR_FORMAT, "(root).accessors: expected an array, got an object"},
    {"{" A ",'nodes':[{},3]}", SV_GLTF_ERROR_FORMAT, "nodes[1]: expected an object, got a number"},
    /* buffers */
    {"{" A ",'buffers':[{'byteLength':100,'uri':'data:application/octet-stream;base64,AAAAAAAAAAAAAAAA'}]}",
     SV_GLTF_ERROR_FORMAT, "buffers[0]: data: URI holds 12 bytes, byteLength is 100"},
    {"{" A ",'buffers':[{'byteLength':3,'uri':'data:application/octet-stream;base64,@@@@'}]}", SV_GLTF_ERROR_FORMAT,
     "buffers[0]: invalid base64 in data: URI"},
    {"{" A ",'buffers':[{'byteLength':3,'uri':'data:text/plain,abc'}]}", SV_GLTF_ERROR_UNSUPPORTED,
     "buffers[0]: data: URI is not base64-encoded"},
    {"{" A ",'buffers':[{'byteLength':3}]}", SV_GLTF_ERROR_FORMAT,
     "buffers[0]: no uri and no GLB binary chunk to refer to"},
    {"{" A ",'buffers':[{'uri':'a.bin'}]}", SV_GLTF_ERROR_FORMAT, "buffers[0].byteLength: missing"},
    {"{" A ",'buffers':[{'byteLength':0,'uri':'a.bin'}]}", SV_GLTF_ERROR_FORMAT,
     "buffers[0].byteLength: 0 out of range"},
    {"{" A ",'buffers':[{'byteLength':4,'uri':'a.bin'}]}", SV_GLTF_ERROR_UNSUPPORTED,
     "buffers[0]: external URI 'a.bin' but no base directory was given"},
    {"{" A ",'buffers':[{'byteLength':4,'uri':'http://example.com/a.bin'}]}", SV_GLTF_ERROR_UNSUPPORTED,
     "buffers[0]: URI scheme 'http:' is not supported"},
    /* issue 14: a '%' that is no escape is taken literally (Blender writes names unencoded), so this
     * is now a missing file named with the '%'; %00 stays an error. */
    {"{" A ",'buffers':[{'byteLength':4,'uri':'bad%zz.bin'}]}", SV_GLTF_ERROR_IO,
     "buffers[0]: cannot open '/nonexistent/bad%zz.bin'", false, "/nonexistent"},
    {"{" A ",'buffers':[{'byteLength':4,'uri':'bad%00.bin'}]}", SV_GLTF_ERROR_FORMAT,
     "buffers[0]: URI 'bad%00.bin' encodes a NUL byte (%00)", false, "/nonexistent"},
    {"{" A ",'buffers':[{'byteLength':4,'uri':'../up.bin'}]}", SV_GLTF_ERROR_OUTSIDE,
     "buffers[0]: '../up.bin' is outside the glTF's folder '/nonexistent'", false, "/nonexistent"},
    {"{" A ",'buffers':[{'byteLength':4,'uri':'/etc/passwd'}]}", SV_GLTF_ERROR_OUTSIDE,
     "buffers[0]: '/etc/passwd' is an absolute path outside the glTF's folder", false, "/nonexistent"},
    {"{" A ",'buffers':[{'byteLength':4,'uri':'missing.bin'}]}", SV_GLTF_ERROR_IO,
     "buffers[0]: cannot open '/nonexistent/missing.bin'", false, "/nonexistent"},
    {"{" A ",'buffers':[{'byteLength':4,'uri':7}]}", SV_GLTF_ERROR_FORMAT,
     "buffers[0].uri: expected a string, got a number"},
    /* bufferViews */
    {"{" A "," Z12 ",'bufferViews':[{'buffer':1,'byteLength':4}]}", SV_GLTF_ERROR_FORMAT,
     "bufferViews[0]: buffer 1 out of range (1 buffers)"},
    {"{" A "," Z12 ",'bufferViews':[{'byteLength':4}]}", SV_GLTF_ERROR_FORMAT, "bufferViews[0]: buffer missing"},
    {"{" A "," Z12 ",'bufferViews':[{'buffer':0,'byteOffset':8,'byteLength':8}]}", SV_GLTF_ERROR_FORMAT,
     "bufferViews[0]: byteOffset 8 + byteLength 8 exceeds buffer 0 (12 bytes)"},
    {"{" A "," Z12 ",'bufferViews':[{'buffer':0,'byteOffset':18446744073709551615,'byteLength':8}]}",
     SV_GLTF_ERROR_FORMAT, "bufferViews[0].byteOffset: 1.8446744073709552e+19 out of range"},
    {"{" A "," Z12 ",'bufferViews':[{'buffer':0,'byteLength':12,'byteStride':6}]}", SV_GLTF_ERROR_FORMAT,
     "bufferViews[0].byteStride: 6 is not a multiple of 4"},
    {"{" A "," Z12 ",'bufferViews':[{'buffer':0,'byteLength':12,'byteStride':2}]}", SV_GLTF_ERROR_FORMAT,
     "bufferViews[0].byteStride: 2 out of range [4, 252]"},
    {"{" A "," Z12 ",'bufferViews':[{'buffer':-1,'byteLength':12}]}", SV_GLTF_ERROR_FORMAT,
     "bufferViews[0]: buffer -1 out of range (1 buffers)"},
    /* accessors */
    {"{" A "," Z12 "," V12 ",'accessors':[{'bufferView':7,'componentType':5126,'count':1,'type':'VEC3'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0]: bufferView 7 out of range (1 bufferViews)"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'bufferView':0,'componentType':5126,'count':2,'type':'VEC3'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0]: needs bytes [0, 24) of bufferView 0, which has 12 bytes"},
    {"{" A "," Z12 "," V12
     ",'accessors':[{'bufferView':0,'byteOffset':4,'componentType':5126,'count':1,'type':'VEC3'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0]: needs bytes [4, 16) of bufferView 0"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'bufferView':0,'componentType':5124,'count':1,'type':'SCALAR'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0].componentType: 5124 is not a glTF component type"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'bufferView':0,'componentType':5126,'count':1,'type':'VEC5'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0].type: 'VEC5' is not SCALAR, VEC2..4 or MAT2..4"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'bufferView':0,'componentType':5126,'count':1}]}", SV_GLTF_ERROR_FORMAT,
     "accessors[0].type: missing"},
    {"{" A "," Z12 "," V12
     ",'accessors':[{'bufferView':0,'componentType':5126,'normalized':true,'count':1,'type':'VEC3'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0]: normalized is not allowed with componentType 5126"},
    {"{" A "," Z12 "," V12
     ",'accessors':[{'bufferView':0,'byteOffset':2,'componentType':5126,'count':1,'type':'SCALAR'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0]: byteOffset 2 is not a multiple of the component size 4"},
    {"{" A "," Z12 ",'bufferViews':[{'buffer':0,'byteLength':12,'byteStride':4}],"
     "'accessors':[{'bufferView':0,'componentType':5126,'count':1,'type':'VEC3'}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0]: bufferView 0 byteStride 4 is smaller than the element (12 bytes)"},
    {"{" A ",'accessors':[{'componentType':5126,'count':1.5,'type':'VEC3'}]}", SV_GLTF_ERROR_FORMAT,
     "accessors[0].count: expected an integer, got a fraction"},
    {"{" A ",'accessors':[{'componentType':5126,'count':'3','type':'VEC3'}]}", SV_GLTF_ERROR_FORMAT,
     "accessors[0].count: expected an integer, got a string"},
    {"{" A ",'accessors':[{'componentType':5126,'count':0,'type':'VEC3'}]}", SV_GLTF_ERROR_FORMAT,
     "accessors[0].count: 0 out of range [1, 4294967295]"},
    {"{" A ",'accessors':[{'componentType':5126,'count':1,'type':'VEC3','byteOffset':4}]}", SV_GLTF_ERROR_FORMAT,
     "accessors[0]: byteOffset without bufferView"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'componentType':5126,'count':2,'type':'SCALAR','sparse':"
     "{'count':3,'indices':{'bufferView':0,'componentType':5121},'values':{'bufferView':0}}}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0].sparse.count: 3 out of range [1, 2]"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'componentType':5126,'count':4,'type':'VEC3','sparse':"
     "{'count':2,'indices':{'bufferView':0,'componentType':5121},'values':{'bufferView':0}}}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0].sparse.values: needs bytes [0, 24) of bufferView 0, which has 12 bytes"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'componentType':5126,'count':4,'type':'SCALAR','sparse':"
     "{'count':1,'indices':{'bufferView':0,'componentType':5126},'values':{'bufferView':0}}}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0].sparse.indices.componentType: 5126 is not 5121, 5123 or 5125"},
    {"{" A "," Z12 "," V12 ",'accessors':[{'componentType':5126,'count':4,'type':'SCALAR','sparse':"
     "{'count':1,'values':{'bufferView':0}}}]}",
     SV_GLTF_ERROR_FORMAT, "accessors[0].sparse: indices missing"},
    /* meshes */
    {"{" A "," B5 "," V12 ",'accessors':[{'componentType':5126,'count':1,'type':'VEC3','sparse':"
     "{'count':1,'indices':{'bufferView':0,'componentType':5121},'values':{'bufferView':0}}}]," MESH(
         "{'attributes':{'POSITION':0}}") "}",
     SV_GLTF_ERROR_FORMAT,
     "meshes[0].primitives[0].attributes.POSITION: accessors[0].sparse.indices[0] = 5 is out of range"},
    {"{" A "," B5 "," V12 ",'accessors':[" POS1
     ",{'bufferView':0,'componentType':5121,'count':3,'type':'SCALAR'}]," MESH(
         "{'attributes':{'POSITION':0},'indices':1}") "}",
     SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0].indices: index 5 at position 0 is out of range (1 vertices)"},
    {"{" A ",'accessors':[" POS1
     ",{'componentType':5126,'count':2,'type':'VEC3'}]," MESH("{'attributes':{'POSITION':0,'NORMAL':1}}") "}",
     SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0].attributes.NORMAL: accessor 1 has count 2, POSITION has 1"},
    {"{" A ",'accessors':[" POS1
     ",{'componentType':5126,'count':1,'type':'VEC2'}]," MESH("{'attributes':{'POSITION':0,'NORMAL':1}}") "}",
     SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0].attributes.NORMAL: accessor 1 has type VEC2, expected VEC3"},
    {"{" A ",'accessors':[" POS1 "]," MESH("{'attributes':{'POSITION':0,'NORMAL':4}}") "}", SV_GLTF_ERROR_FORMAT,
     "meshes[0].primitives[0].attributes: NORMAL 4 out of range (1 accessors)"},
    {"{" A ",'accessors':[" POS1
     ",{'componentType':5126,'count':3,'type':'SCALAR'}]," MESH("{'attributes':{'POSITION':0},'indices':1}") "}",
     SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0].indices: accessor 1 must be a SCALAR of unsigned byte/short/int"},
    {"{" A ",'accessors':[{'componentType':5126,'count':4,'type':'VEC3'}]," MESH("{'attributes':{'POSITION':0}}") "}",
     SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0]: 4 indices is not a multiple of 3 for TRIANGLES"},
    {"{" A ",'accessors':[" POS1 "]," MESH("{'attributes':{'POSITION':0},'mode':9}") "}", SV_GLTF_ERROR_FORMAT,
     "meshes[0].primitives[0].mode: 9 out of range [0, 6]"},
    {"{" A ",'accessors':[" POS1 "]," MESH("{'attributes':{'POSITION':0},'mode':1}") "}", SV_GLTF_ERROR_UNSUPPORTED,
     "meshes[0].primitives[0]: mode LINES is not supported (triangles only)", true},
    {"{" A ",'accessors':[" POS1 "]," MESH("{'attributes':{'POSITION':0},'material':0}") "}", SV_GLTF_ERROR_FORMAT,
     "meshes[0].primitives[0]: material 0 out of range (0 materials)"},
    {"{" A "," MESH("") "}", SV_GLTF_ERROR_FORMAT, "meshes[0].primitives: missing or empty"},
    {"{" A "," MESH("{}") "}", SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0].attributes: missing"},
    {"{" A "," MESH("7") "}", SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0]: expected an object, got a number"},
    {"{" A "," BNAN "," V12 ",'accessors':[{'bufferView':0,'componentType':5126,'count':1,'type':'VEC3'}]," MESH(
         "{'attributes':{'POSITION':0}}") "}",
     SV_GLTF_ERROR_FORMAT, "meshes[0].primitives[0].attributes.POSITION: accessor 0 element 0 is not finite"},
    /* nodes and scenes */
    {"{" A ",'nodes':[{'mesh':3}]}", SV_GLTF_ERROR_FORMAT, "nodes[0]: mesh 3 out of range (0 meshes)"},
    {"{" A ",'nodes':[{'camera':0}]}", SV_GLTF_ERROR_FORMAT, "nodes[0]: camera 0 out of range (0 cameras)"},
    {"{" A ",'nodes':[{'children':[1]},{'children':[0]}]}", SV_GLTF_ERROR_FORMAT,
     "nodes[0]: part of a cycle in the node hierarchy"},
    {"{" A ",'nodes':[{'children':[1]},{'children':[2]},{'children':[1]}]}", SV_GLTF_ERROR_FORMAT,
     "nodes[2].children: node 1 already has parent 0"},
    {"{" A ",'nodes':[{'children':[0]}]}", SV_GLTF_ERROR_FORMAT, "nodes[0].children: node 0 is its own child (cycle)"},
    {"{" A ",'nodes':[{'children':[5]}]}", SV_GLTF_ERROR_FORMAT, "nodes[0].children[0]: not a node index (1 nodes)"},
    {"{" A ",'nodes':[{'matrix':[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1],'translation':[1,2,3]}]}", SV_GLTF_ERROR_FORMAT,
     "nodes[0]: has both matrix and translation/rotation/scale"},
    {"{" A ",'nodes':[{'matrix':[1,0,0,0,0,1,0,0,0,0,1,0,0,0,0]}]}", SV_GLTF_ERROR_FORMAT,
     "nodes[0].matrix: expected an array of 16 numbers"},
    {"{" A ",'nodes':[{'rotation':[0,0,0,0]}]}", SV_GLTF_ERROR_FORMAT, "nodes[0].rotation: zero quaternion"},
    {"{" A ",'nodes':[{'translation':[1e999,0,0]}]}", SV_GLTF_ERROR_FORMAT,
     "nodes[0].translation[0]: expected a finite number, got a non-finite one"},
    {"{" A ",'nodes':[{'scale':[1,'2',1]}]}", SV_GLTF_ERROR_FORMAT,
     "nodes[0].scale[1]: expected a finite number, got a string"},
    {"{" A ",'nodes':[{'extensions':{'KHR_lights_punctual':{'light':0}}}]}", SV_GLTF_ERROR_FORMAT,
     "nodes[0].extensions.KHR_lights_punctual: light 0 out of range (0 lights)"},
    {"{" A ",'nodes':[{'children':[1]},{}],'scenes':[{'nodes':[1]}]}", SV_GLTF_ERROR_FORMAT,
     "scenes[0].nodes[0]: node 1 is not a root node (it has a parent)"},
    {"{" A ",'nodes':[{}],'scenes':[{'nodes':[0,0]}]}", SV_GLTF_ERROR_FORMAT,
     "scenes[0].nodes[1]: node 0 is listed twice"},
    {"{" A ",'nodes':[{}],'scenes':[{'nodes':[0]}],'scene':2}", SV_GLTF_ERROR_FORMAT,
     "(root): scene 2 out of range (1 scenes)"},
    {"{" A ",'scenes':[{'nodes':[3]}]}", SV_GLTF_ERROR_FORMAT, "scenes[0].nodes[0]: not a node index (0 nodes)"},
    /* cameras and lights */
    {"{" A ",'cameras':[{'type':'perspective','perspective':{'znear':0.1}}]}", SV_GLTF_ERROR_FORMAT,
     "cameras[0].perspective.yfov: missing"},
    {"{" A ",'cameras':[{'type':'fisheye'}]}", SV_GLTF_ERROR_FORMAT,
     "cameras[0].type: 'fisheye' is not perspective or orthographic"},
    {"{" A ",'cameras':[{'type':'orthographic'}]}", SV_GLTF_ERROR_FORMAT,
     "cameras[0]: type orthographic but no 'orthographic' object"},
    {"{" A ",'cameras':[{'type':'perspective','perspective':{'yfov':1,'znear':2,'zfar':1}}]}", SV_GLTF_ERROR_FORMAT,
     "cameras[0].perspective: zfar 1 is not greater than znear 2"},
    {"{" A ",'cameras':[{'type':'orthographic','orthographic':{'xmag':0,'ymag':1,'znear':0,'zfar':1}}]}",
     SV_GLTF_ERROR_FORMAT, "cameras[0].orthographic: xmag and ymag must not be zero"},
    {"{" A ",'extensions':{'KHR_lights_punctual':{'lights':[{'type':'area'}]}}}", SV_GLTF_ERROR_FORMAT,
     "KHR_lights_punctual.lights[0].type: 'area' is not directional, point or spot"},
    {"{" A ",'extensions':{'KHR_lights_punctual':{'lights':[{'type':'point','name':'Fill',"
     "'extensions':{'VULKAN_SCHNEE_light':{'mode':'sometimes'}}}]}}}",
     SV_GLTF_ERROR_FORMAT, "'sometimes' is not baked, mixed or realtime"},
    {"{" A ",'extensions':{'KHR_lights_punctual':{'lights':[{'type':'point',"
     "'extensions':{'VULKAN_SCHNEE_light':{'mode':1}}}]}}}",
     SV_GLTF_ERROR_FORMAT, "VULKAN_SCHNEE_light.mode"},
    {"{" A
     ",'extensions':{'KHR_lights_punctual':{'lights':[{'type':'spot','spot':{'innerConeAngle':0.5,'outerConeAngle':0.4}}]}}}",
     SV_GLTF_ERROR_FORMAT,
     "KHR_lights_punctual.lights[0].spot: innerConeAngle 0.5 is not less than outerConeAngle 0.4"},
    {"{" A ",'extensions':{'KHR_lights_punctual':{'lights':[{'type':'point','intensity':-1}]}}}", SV_GLTF_ERROR_FORMAT,
     "KHR_lights_punctual.lights[0].intensity: -1 out of range"},
    {"{" A ",'extensions':{'KHR_lights_punctual':{'lights':{}}}}", SV_GLTF_ERROR_FORMAT,
     "extensions.KHR_lights_punctual.lights: expected an array, got an object"},
    /* materials, textures, images, samplers */
    {"{" A ",'materials':[{'pbrMetallicRoughness':{'baseColorFactor':[1,1,1]}}]}", SV_GLTF_ERROR_FORMAT,
     "materials[0].pbrMetallicRoughness.baseColorFactor: expected an array of 4 numbers"},
    {"{" A ",'materials':[{'pbrMetallicRoughness':{'metallicFactor':2}}]}", SV_GLTF_ERROR_FORMAT,
     "materials[0].pbrMetallicRoughness.metallicFactor: 2 out of range [0, 1]"},
    {"{" A ",'materials':[{'alphaMode':'FOO'}]}", SV_GLTF_ERROR_FORMAT,
     "materials[0].alphaMode: 'FOO' is not OPAQUE, MASK or BLEND"},
    {"{" A ",'materials':[{'pbrMetallicRoughness':{'baseColorTexture':{'index':0}}}]}", SV_GLTF_ERROR_FORMAT,
     "materials[0].pbrMetallicRoughness.baseColorTexture: index 0 out of range (0 textures)"},
    {"{" A ",'materials':[{'emissiveTexture':{}}]}", SV_GLTF_ERROR_FORMAT,
     "materials[0].emissiveTexture: index missing"},
    {"{" A ",'materials':[{'extensions':{'VULKAN_SCHNEE_materials':{'shScale':'big'}}}]}", SV_GLTF_ERROR_FORMAT,
     "materials[0].extensions.VULKAN_SCHNEE_materials.shScale: expected a finite number, got a string"},
    {"{" A ",'materials':[{'extensions':{'VULKAN_SCHNEE_materials':[1]}}]}", SV_GLTF_ERROR_FORMAT,
     "materials[0].extensions.VULKAN_SCHNEE_materials: expected an object, got an array"},
    {"{" A ",'textures':[{'source':0}]}", SV_GLTF_ERROR_FORMAT, "textures[0]: source 0 out of range (0 images)"},
    {"{" A ",'textures':[{'sampler':1}]}", SV_GLTF_ERROR_FORMAT, "textures[0]: sampler 1 out of range (0 samplers)"},
    {"{" A "," Z12 "," V12 ",'images':[{'uri':'a.png','bufferView':0}]}", SV_GLTF_ERROR_FORMAT,
     "images[0]: needs exactly one of uri and bufferView"},
    {"{" A ",'images':[{}]}", SV_GLTF_ERROR_FORMAT, "images[0]: needs exactly one of uri and bufferView"},
    {"{" A ",'images':[{'uri':'http://example.com/a.png'}]}", SV_GLTF_ERROR_UNSUPPORTED,
     "images[0]: URI scheme 'http:' is not supported", false, "/data"},
    {"{" A ",'samplers':[{'wrapS':1}]}", SV_GLTF_ERROR_FORMAT, "samplers[0].wrapS: 1 is not 33071, 33648 or 10497"},
    {"{" A ",'samplers':[{'magFilter':9984}]}", SV_GLTF_ERROR_FORMAT,
     "samplers[0].magFilter: 9984 is not 9728 or 9729"},
    /* probe-grid extension: the container must have the right type (entries are only warned about) */
    {"{" A ",'scenes':[{'extensions':{'VULKAN_SCHNEE_engine_properties':{'shProbeGrids':{}}}}]}", SV_GLTF_ERROR_FORMAT,
     "scenes[0].extensions.VULKAN_SCHNEE_engine_properties.shProbeGrids: expected an array, got an object"},
};
#pragma GCC diagnostic pop

static void test_malformed_table(void)
{
    for (size_t i = 0; i < sizeof CASES / sizeof CASES[0]; i++) {
        const bad_case *bc = &CASES[i];
        char *json = tg_json(bc->json, NULL);
        sv_gltf_desc desc = {.non_triangles_are_errors = bc->non_triangles_are_errors, .base_dir = bc->base_dir};
        sv_gltf *g = (sv_gltf *)&desc; /* must be reset to NULL on failure */
        sv_gltf_error err = {0};
        sv_gltf_result r = sv_gltf_load_memory(json, strlen(json), &desc, &g, &err);
        if (r == SV_GLTF_SUCCESS) { /* the Schnee extensions are parsed by the engine's module */
            sv_ext ext;
            r = sv_ext_parse(g, &ext, &err);
            if (r == SV_GLTF_SUCCESS) {
                sv_ext_free(&ext);
            } else {
                sv_gltf_free(g);
                g = NULL;
            }
        }
        if (r != bc->code || !strstr(err.message, bc->fragment))
            fprintf(stderr, "case %zu: %s\n  -> %s: %s\n", i, json, sv_gltf_result_string(r), err.message);
        TU_CHECK_EQ_INT(r, bc->code);
        TU_CHECK_EQ_INT(err.code, bc->code);
        TU_CHECK_CONTAINS(err.message, bc->fragment);
        TU_CHECK(g == NULL);
        if (r == SV_GLTF_SUCCESS) sv_gltf_free(g);
        free(json);
    }
}

/* GLB container errors. */
static void test_malformed_glb(void)
{
    const char *json = "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":8}]}";
    tg_bin bin = {0};
    for (int i = 0; i < 8; i++) tg_u8(&bin, (uint8_t)i);
    tg_bin good = tg_glb(json, &bin);
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(good.data, good.size, NULL, &g, &err), SV_GLTF_SUCCESS);
    sv_gltf_free(g);

    struct {
        size_t cut;      /* truncate to this many bytes (0 = keep) */
        size_t patch_at; /* overwrite one uint32 at this offset (0 = none) */
        uint32_t patch;
        sv_gltf_result code;
        const char *fragment;
    } cases[] = {
        {10, 0, 0, SV_GLTF_ERROR_FORMAT, "GLB: 10 bytes is too short"},
        {good.size - 4, 0, 0, SV_GLTF_ERROR_FORMAT, "GLB: header length"},
        {0, 4, 1, SV_GLTF_ERROR_UNSUPPORTED, "GLB: container version 1 is not 2"},
        {0, 16, 0x004E4942u, SV_GLTF_ERROR_FORMAT, "GLB: first chunk is not JSON"},
        {0, 12, 0xFFFFFFF0u, SV_GLTF_ERROR_FORMAT, "GLB: chunk 0 length 4294967280 exceeds the file"},
        {0, 8, 0xFFFFFFFFu, SV_GLTF_ERROR_FORMAT, "GLB: header length 4294967295 but the data has"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        tg_bin b = {0};
        tg_put(&b, good.data, good.size);
        if (cases[i].cut) b.size = cases[i].cut;
        if (cases[i].patch_at) memcpy(b.data + cases[i].patch_at, &cases[i].patch, 4);
        sv_gltf_error e = {0};
        g = NULL;
        sv_gltf_result r = sv_gltf_load_memory(b.data, b.size, NULL, &g, &e);
        if (r != cases[i].code) fprintf(stderr, "glb case %zu: %s\n", i, e.message);
        TU_CHECK_EQ_INT(r, cases[i].code);
        TU_CHECK_CONTAINS(e.message, cases[i].fragment);
        TU_CHECK(g == NULL);
        free(b.data);
    }
    /* BIN chunk length that does not match the buffer's byteLength, and a GLB without BIN chunk. */
    tg_bin small = {0};
    tg_put(&small, bin.data, 4);
    tg_bin g2 = tg_glb(json, &small);
    err = (sv_gltf_error){0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(g2.data, g2.size, NULL, &g, &err), SV_GLTF_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "buffers[0]: byteLength 8 does not match the GLB BIN chunk (4 bytes)");
    tg_bin g3 = tg_glb(json, NULL);
    err = (sv_gltf_error){0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(g3.data, g3.size, NULL, &g, &err), SV_GLTF_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "buffers[0]: no uri and no GLB binary chunk");
    /* Invalid JSON inside a GLB. */
    tg_bin g4 = tg_glb("{\"asset\":", NULL);
    err = (sv_gltf_error){0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(g4.data, g4.size, NULL, &g, &err), SV_GLTF_ERROR_JSON);
    TU_CHECK_CONTAINS(err.message, "GLB JSON chunk: invalid JSON");
    free(g2.data);
    free(g3.data);
    free(g4.data);
    free(small.data);
    free(good.data);
    free(bin.data);
}

/* Bad arguments and the memory budget. */
static void test_arguments_and_budget(void)
{
    sv_gltf_error err = {0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(NULL, 4, NULL, NULL, &err), SV_GLTF_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "NULL argument");
    sv_gltf *g = NULL;
    TU_CHECK_EQ_INT(sv_gltf_load_file(NULL, NULL, &g, NULL), SV_GLTF_ERROR_INVALID_ARGUMENT);
    /* An accessor without bufferView costs nothing in the file but count * 12 bytes decoded:
     * 100 million vertices must hit the budget, not the allocator. */
    const char *json =
        "{'asset':{'version':'2.0'},'accessors':[{'componentType':5126,'count':100000000,'type':'VEC3'}],"
        "'meshes':[{'primitives':[{'attributes':{'POSITION':0}}]}]}";
    char *j = tg_json(json, NULL);
    sv_gltf_desc desc = {.max_decoded_bytes = 1 << 20};
    err = (sv_gltf_error){0};
    TU_CHECK_EQ_INT(sv_gltf_load_memory(j, strlen(j), &desc, &g, &err), SV_GLTF_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "meshes[0].primitives[0].attributes.POSITION: needs 1200000000 bytes");
    free(j);
    TU_CHECK(strcmp(sv_gltf_result_string(SV_GLTF_ERROR_FORMAT), "malformed glTF") == 0);
    TU_CHECK(strcmp(sv_gltf_result_string((sv_gltf_result)99), "unknown result") == 0);
}

int main(void)
{
    TU_RUN(test_malformed_table);
    TU_RUN(test_malformed_glb);
    TU_RUN(test_arguments_and_budget);
    return TU_EXIT();
}
