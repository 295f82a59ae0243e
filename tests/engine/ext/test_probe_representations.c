/* One source for the probe-representation names (docs/ambient-cube.md §4-§5): the engine's table
 * (sv_probe_representation_name in shaders/sv_gpu.h, used by --probe-representation and the
 * VULKAN_SCHNEE_materials parser) must list exactly the add-on exporter's PROBE_REPRESENTATIONS
 * (addon/schnee_probes/gltf_export.py, parsed from the file's text), in the same order, plus the
 * command line's "material" as the last value. The parser takes every exported name, defaults to
 * "sh" and refuses anything else (wrong case, "material", a non-string) naming the element. */
#include "sv_ext.h"
#include "sv_gpu.h"
#include "testutil.h"

#include <stdlib.h>

#define MAX_NAMES 16

/* The string literals of the tuple/list assigned to PROBE_REPRESENTATIONS at the start of a line. */
static int exporter_names(char names[MAX_NAMES][32])
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
    const char *key = "\nPROBE_REPRESENTATIONS = ";
    const char *p = strstr(text, key);
    if (!p) return -1;
    p += strlen(key);
    char open = *p, close = open == '(' ? ')' : open == '[' ? ']' : 0;
    if (!close) return -1;
    int count = 0;
    for (++p; *p && *p != close; ++p) {
        if (*p != '"' && *p != '\'') continue;
        char q = *p++;
        const char *end = strchr(p, q);
        if (!end || end - p >= 32 || count == MAX_NAMES) return -1;
        memcpy(names[count], p, (size_t)(end - p));
        names[count][end - p] = '\0';
        count++;
        p = end;
    }
    return *p == close ? count : -1;
}

static void test_table_matches_exporter(void)
{
    char names[MAX_NAMES][32];
    int n = exporter_names(names);
    TU_REQUIRE(n > 0);
    TU_CHECK_EQ_INT(n, (int)SV_PROBE_REP_MATERIAL);
    for (int i = 0; i < n; i++) {
        const char *engine = sv_probe_representation_name((uint32_t)i);
        TU_CHECK(engine && strcmp(engine, names[i]) == 0);
        TU_CHECK_EQ_INT(sv_probe_representation_from_name(names[i], 0), i);
    }
    TU_CHECK(strcmp(sv_probe_representation_name(SV_PROBE_REP_SH), "sh") == 0);
    TU_CHECK(strcmp(sv_probe_representation_name(SV_PROBE_REP_AMBIENT_CUBE), "ambientCube") == 0);
    TU_CHECK(strcmp(sv_probe_representation_name(SV_PROBE_REP_MATERIAL), "material") == 0);
    TU_CHECK(sv_probe_representation_name(SV_PROBE_REP_COUNT) == NULL);
    TU_CHECK_EQ_INT(sv_probe_representation_from_name("material", 0), -1);
    TU_CHECK_EQ_INT(sv_probe_representation_from_name("material", 1), (int)SV_PROBE_REP_MATERIAL);
}

/* Parses one material whose VULKAN_SCHNEE_materials is `ext_json`; returns the result. */
static sv_gltf_result parse_one(const char *ext_json, uint32_t *rep, uint32_t *mode, char *msg, size_t cap)
{
    char json[384];
    snprintf(json, sizeof json,
             "{\"asset\":{\"version\":\"2.0\"},\"materials\":[{},{\"extensions\":{\"VULKAN_SCHNEE_materials\":%s}}]}",
             ext_json);
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    if (sv_gltf_load_memory(json, strlen(json), NULL, &g, &err) != SV_GLTF_SUCCESS) return SV_GLTF_ERROR_IO;
    sv_ext ext;
    sv_gltf_result r = sv_ext_parse(g, &ext, &err);
    if (r == SV_GLTF_SUCCESS) {
        *rep = ext.materials[1].probe_representation;
        *mode = ext.materials[1].probe_mode;
        /* A material without the extension: the default. */
        TU_CHECK_EQ_INT(ext.materials[0].probe_representation, (int)SV_PROBE_REP_SH);
        sv_ext_free(&ext);
    }
    snprintf(msg, cap, "%s", err.message);
    sv_gltf_free(g);
    return r;
}

static void test_parser(void)
{
    uint32_t rep = 99, mode = 99;
    char msg[512];
    TU_CHECK_EQ_INT(
        parse_one("{\"probeRepresentation\":\"ambientCube\",\"probeMode\":\"pixel\"}", &rep, &mode, msg, sizeof msg),
        SV_GLTF_SUCCESS);
    TU_CHECK_EQ_INT(rep, (int)SV_PROBE_REP_AMBIENT_CUBE);
    TU_CHECK_EQ_INT(mode, (int)SV_PROBE_MODE_PIXEL); /* orthogonal to the mode */
    TU_CHECK_EQ_INT(parse_one("{\"probeRepresentation\":\"sh\"}", &rep, &mode, msg, sizeof msg), SV_GLTF_SUCCESS);
    TU_CHECK_EQ_INT(rep, (int)SV_PROBE_REP_SH);
    TU_CHECK_EQ_INT(parse_one("{\"shScale\":2}", &rep, &mode, msg, sizeof msg), SV_GLTF_SUCCESS);
    TU_CHECK_EQ_INT(rep, (int)SV_PROBE_REP_SH); /* absent = sh */
    static const char *const bad[][2] = {
        {"{\"probeRepresentation\":\"material\"}", "probeRepresentation: 'material' is not sh or ambientCube"},
        {"{\"probeRepresentation\":\"AmbientCube\"}", "probeRepresentation: 'AmbientCube' is not sh or ambientCube"},
        {"{\"probeRepresentation\":\"\"}", "probeRepresentation: '' is not sh or ambientCube"},
        {"{\"probeRepresentation\":true}", "probeRepresentation: expected a string, got a boolean"},
        {"{\"probeRepresentation\":[\"sh\"]}", "probeRepresentation: expected a string, got an array"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        TU_CHECK_EQ_INT(parse_one(bad[i][0], &rep, &mode, msg, sizeof msg), SV_GLTF_ERROR_FORMAT);
        TU_CHECK_CONTAINS(msg, "materials[1].extensions.VULKAN_SCHNEE_materials.");
        TU_CHECK_CONTAINS(msg, bad[i][1]);
    }
}

int main(void)
{
    TU_RUN(test_table_matches_exporter);
    TU_RUN(test_parser);
    return TU_EXIT();
}
