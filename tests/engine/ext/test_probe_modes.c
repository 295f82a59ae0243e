/* One source for the probe-mode names: the engine's table (sv_probe_mode_name in shaders/sv_gpu.h,
 * used by the command line, the window title and the VULKAN_SCHNEE_materials parser) must list
 * exactly the add-on exporter's PROBE_MODES (addon/schnee_probes/gltf_export.py, parsed here from
 * the file's text), in the same order, plus the command line's "material" as the last value. And
 * the parser accepts every exported name and refuses anything else, naming all of them; the node
 * extension (VULKAN_SCHNEE_node) takes the same names and warns about anything else. */
#include "sv_ext.h"
#include "sv_gpu.h"
#include "testutil.h"

#include <stdlib.h>

#define MAX_MODES 16

/* The string literals of the tuple/list assigned to PROBE_MODES at the start of a line. */
static int exporter_modes(char names[MAX_MODES][32])
{
    const char *path = SCHNEE_SOURCE_DIR "/addon/schnee_probes/gltf_export.py";
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        return -1;
    }
    static char text[1 << 20];
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = '\0';
    const char *p = strstr(text, "\nPROBE_MODES = ");
    if (!p) return -1;
    p += strlen("\nPROBE_MODES = ");
    char open = *p, close = open == '(' ? ')' : open == '[' ? ']' : 0;
    if (!close) return -1;
    int count = 0;
    for (++p; *p && *p != close; ++p) {
        if (*p != '"' && *p != '\'') continue;
        char q = *p++;
        const char *end = strchr(p, q);
        if (!end || end - p >= 32 || count == MAX_MODES) return -1;
        memcpy(names[count], p, (size_t)(end - p));
        names[count][end - p] = '\0';
        count++;
        p = end;
    }
    return *p == close ? count : -1;
}

static void test_table_matches_exporter(void)
{
    char names[MAX_MODES][32];
    int n = exporter_modes(names);
    TU_REQUIRE(n > 0);
    TU_CHECK_EQ_INT(n, (int)SV_PROBE_MODE_MATERIAL);
    for (int i = 0; i < n; i++) {
        const char *engine = sv_probe_mode_name((uint32_t)i);
        TU_CHECK(engine && strcmp(engine, names[i]) == 0);
        if (engine && strcmp(engine, names[i]) != 0)
            fprintf(stderr, "  mode %d: engine '%s', exporter '%s'\n", i, engine, names[i]);
        TU_CHECK_EQ_INT(sv_probe_mode_from_name(names[i], 0), i);
    }
    TU_CHECK(strcmp(sv_probe_mode_name(SV_PROBE_MODE_MATERIAL), "material") == 0);
    TU_CHECK(sv_probe_mode_name(SV_PROBE_MODE_COUNT) == NULL);
    TU_CHECK_EQ_INT(sv_probe_mode_from_name("material", 0), -1);
    TU_CHECK_EQ_INT(sv_probe_mode_from_name("material", 1), (int)SV_PROBE_MODE_MATERIAL);
}

/* The glTF parser takes every exporter name and gives its value; another name is an error that
 * lists the exporter's names. */
static void test_parser_uses_the_table(void)
{
    char names[MAX_MODES][32];
    int n = exporter_modes(names);
    TU_REQUIRE(n > 0);
    for (int i = 0; i <= n; i++) {
        char json[256];
        snprintf(json, sizeof json,
                 "{\"asset\":{\"version\":\"2.0\"},\"materials\":[{\"extensions\":{\"VULKAN_SCHNEE_materials\":"
                 "{\"probeMode\":\"%.31s\"}}}]}",
                 i < n ? names[i] : "material");
        sv_gltf *g = NULL;
        sv_gltf_error err = {0};
        TU_REQUIRE(sv_gltf_load_memory(json, strlen(json), NULL, &g, &err) == SV_GLTF_SUCCESS);
        sv_ext ext;
        sv_gltf_result r = sv_ext_parse(g, &ext, &err);
        if (i < n) {
            TU_CHECK_EQ_INT(r, SV_GLTF_SUCCESS);
            if (r == SV_GLTF_SUCCESS) TU_CHECK_EQ_INT(ext.materials[0].probe_mode, i);
            if (r == SV_GLTF_SUCCESS) sv_ext_free(&ext);
        } else {
            TU_CHECK_EQ_INT(r, SV_GLTF_ERROR_FORMAT);
            char list[128];
            sv_probe_mode_list(list, sizeof list, 0);
            TU_CHECK_CONTAINS(err.message, "probeMode: 'material' is not ");
            TU_CHECK_CONTAINS(err.message, list);
            TU_CHECK_CONTAINS(err.message, names[n - 1]);
        }
        sv_gltf_free(g);
    }
}

/* nodes[i].extensions.VULKAN_SCHNEE_node (docs/export.md "Node"): every exporter name is taken as
 * the node's own mode; absent fields and nodes without the extension stay _MATERIAL; a bad value,
 * a bad type or a non-object extension is a warning naming the node and the field (not an error),
 * and that field stays _MATERIAL while the good one counts. */
static void test_node_fields(void)
{
    char names[MAX_MODES][32];
    int n = exporter_modes(names);
    TU_REQUIRE(n > 0);
    for (int i = 0; i < n; i++) {
        char json[512];
        snprintf(json, sizeof json,
                 "{\"asset\":{\"version\":\"2.0\"},\"nodes\":[{\"name\":\"Own\",\"extensions\":"
                 "{\"VULKAN_SCHNEE_node\":{\"probeMode\":\"%.31s\",\"probeRepresentation\":\"ambientCube\","
                 "\"later\":1}}},{\"name\":\"Plain\"},{\"extensions\":{\"VULKAN_SCHNEE_node\":{}}}]}",
                 names[i]);
        sv_gltf *g = NULL;
        sv_gltf_error err = {0};
        TU_REQUIRE(sv_gltf_load_memory(json, strlen(json), NULL, &g, &err) == SV_GLTF_SUCCESS);
        sv_ext ext;
        TU_REQUIRE(sv_ext_parse(g, &ext, &err) == SV_GLTF_SUCCESS);
        TU_CHECK_EQ_INT(ext.node_count, 3);
        TU_CHECK_EQ_INT(ext.nodes[0].probe_mode, i);
        TU_CHECK_EQ_INT(ext.nodes[0].probe_representation, SV_PROBE_REP_AMBIENT_CUBE);
        for (int k = 1; k < 3; k++) {
            TU_CHECK_EQ_INT(ext.nodes[k].probe_mode, SV_PROBE_MODE_MATERIAL);
            TU_CHECK_EQ_INT(ext.nodes[k].probe_representation, SV_PROBE_REP_MATERIAL);
        }
        TU_CHECK_EQ_INT(ext.warning_count, 0);
        sv_ext_free(&ext);
        sv_gltf_free(g);
    }
    const char *bad = "{\"asset\":{\"version\":\"2.0\"},\"nodes\":["
                      "{\"name\":\"A\",\"extensions\":{\"VULKAN_SCHNEE_node\":{\"probeMode\":\"material\","
                      "\"probeRepresentation\":\"sh\"}}},"
                      "{\"name\":\"B\",\"extensions\":{\"VULKAN_SCHNEE_node\":{\"probeMode\":\"pixel\","
                      "\"probeRepresentation\":true}}},"
                      "{\"name\":\"C\",\"extensions\":{\"VULKAN_SCHNEE_node\":\"pixel\"}}]}";
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    TU_REQUIRE(sv_gltf_load_memory(bad, strlen(bad), NULL, &g, &err) == SV_GLTF_SUCCESS);
    sv_ext ext;
    TU_REQUIRE(sv_ext_parse(g, &ext, &err) == SV_GLTF_SUCCESS);
    TU_CHECK_EQ_INT(ext.nodes[0].probe_mode, SV_PROBE_MODE_MATERIAL); /* "material" is the command line's only */
    TU_CHECK_EQ_INT(ext.nodes[0].probe_representation, SV_PROBE_REP_SH);
    TU_CHECK_EQ_INT(ext.nodes[1].probe_mode, SV_PROBE_MODE_PIXEL);
    TU_CHECK_EQ_INT(ext.nodes[1].probe_representation, SV_PROBE_REP_MATERIAL);
    TU_CHECK_EQ_INT(ext.nodes[2].probe_mode, SV_PROBE_MODE_MATERIAL);
    TU_REQUIRE(ext.warning_count == 3);
    char list[128];
    sv_probe_mode_list(list, sizeof list, 0);
    TU_CHECK_CONTAINS(ext.warnings[0], "nodes[0] ('A').extensions.VULKAN_SCHNEE_node.probeMode: 'material' is not ");
    TU_CHECK_CONTAINS(ext.warnings[0], list);
    TU_CHECK_CONTAINS(ext.warnings[0], "the node follows its materials");
    TU_CHECK_CONTAINS(ext.warnings[1], "nodes[1] ('B').extensions.VULKAN_SCHNEE_node.probeRepresentation: expected a "
                                       "string (sh or ambientCube), got a boolean");
    TU_CHECK_CONTAINS(ext.warnings[2],
                      "nodes[2] ('C').extensions.VULKAN_SCHNEE_node: expected an object, got a string");
    sv_ext_free(&ext);
    sv_gltf_free(g);
}

int main(void)
{
    TU_RUN(test_table_matches_exporter);
    TU_RUN(test_parser_uses_the_table);
    TU_RUN(test_node_fields);
    return TU_EXIT();
}
