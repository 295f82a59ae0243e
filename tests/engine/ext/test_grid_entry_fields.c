/* The shProbeGrids entry fields of .shprobe version 3 (docs/ambient-cube.md §4 "glTF",
 * docs/engine.md "Version 3 grids"): `representation`, `storage`, `structure` parse to the
 * pb_shprobe_* values, default to sh / float32 / grid when absent (what versions 1 and 2 hold), and any
 * other value makes the entry invalid (skipped with a warning naming the field and the value). The
 * name tables are the ones the warnings print. */
#include "sv_ext.h"
#include "testutil.h"

#include <stdlib.h>

/* The .shprobe v3 header values (native/include/schnee/pb_shprobe.h, docs/shprobe-format.md offsets
 * 92-100); sv_ext has no dependency on the core, so they are spelled out here. */
enum { SH = 0, AMBIENT_CUBE = 1, FLOAT32 = 0, FLOAT16 = 1, GRID = 0, OCTREE = 1, TETRA = 2 };

/* Parses a glTF whose only grid entry carries `fields` (JSON members, may be empty). Returns the
 * grid count; fills *out with the first entry and `warning` with the first warning. */
static uint32_t parse_entry(const char *fields, sv_ext_probe_grid *out, char *warning, size_t cap)
{
    char json[768];
    snprintf(json, sizeof json,
             "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[],\"extensions\":"
             "{\"VULKAN_SCHNEE_engine_properties\":{\"shProbeGrids\":[{\"name\":\"g\",\"uri\":\"g.shprobe\","
             "\"probeCount\":1,\"maxBand\":2,\"gridOrigin\":[0,0,0],\"gridDims\":[1,1,1],\"gridSpacing\":1%s%s}]}}}]}",
             fields[0] ? "," : "", fields);
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    warning[0] = '\0';
    if (sv_gltf_load_memory(json, strlen(json), NULL, &g, &err) != SV_GLTF_SUCCESS) return 99;
    sv_ext ext;
    uint32_t n = 99;
    if (sv_ext_parse(g, &ext, &err) == SV_GLTF_SUCCESS) {
        n = ext.probe_grid_count;
        if (n) {
            *out = ext.probe_grids[0];
            out->name = out->uri = out->path = NULL; /* freed below */
        }
        for (uint32_t i = 0; i < ext.warning_count; ++i)
            if (strstr(ext.warnings[i], "shProbeGrids")) snprintf(warning, cap, "%s", ext.warnings[i]);
        sv_ext_free(&ext);
    }
    sv_gltf_free(g);
    return n;
}

static void test_defaults_and_values(void)
{
    sv_ext_probe_grid e;
    char w[512];
    TU_REQUIRE(parse_entry("", &e, w, sizeof w) == 1);
    TU_CHECK_EQ_INT(e.representation, SH);
    TU_CHECK_EQ_INT(e.storage, FLOAT32);
    TU_CHECK_EQ_INT(e.structure, GRID);
    TU_REQUIRE(parse_entry("\"representation\":\"ambientCube\",\"storage\":\"float16\",\"structure\":\"octree\"", &e, w,
                           sizeof w) == 1);
    TU_CHECK_EQ_INT(e.representation, AMBIENT_CUBE);
    TU_CHECK_EQ_INT(e.storage, FLOAT16);
    TU_CHECK_EQ_INT(e.structure, OCTREE);
    TU_REQUIRE(parse_entry("\"structure\":\"tetrahedra\"", &e, w, sizeof w) == 1);
    TU_CHECK_EQ_INT(e.structure, TETRA);
}

static void test_refusals(void)
{
    sv_ext_probe_grid e;
    char w[512];
    static const char *const bad[][2] = {
        {"\"representation\":\"cube\"", "representation: 'cube' is not sh or ambientCube"},
        {"\"representation\":\"SH\"", "representation: 'SH' is not sh or ambientCube"},
        {"\"storage\":\"half\"", "storage: 'half' is not float32 or float16"},
        {"\"structure\":\"tree\"", "structure: 'tree' is not grid, octree, tetrahedra or kdtree"},
        {"\"structure\":1", "structure: expected a string, got a number"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        TU_CHECK_EQ_INT(parse_entry(bad[i][0], &e, w, sizeof w), 0);
        TU_CHECK_CONTAINS(w, "shProbeGrids[0]");
        TU_CHECK_CONTAINS(w, bad[i][1]);
        TU_CHECK_CONTAINS(w, "(shProbeGrids entry skipped)");
    }
}

static void test_name_tables(void)
{
    /* The values are the file header's, the names the strings the Python module and exporter use. */
    TU_CHECK(strcmp(sv_ext_grid_representation_name(SH), "sh") == 0);
    TU_CHECK(strcmp(sv_ext_grid_representation_name(AMBIENT_CUBE), "ambientCube") == 0);
    TU_CHECK(sv_ext_grid_representation_name(2) == NULL);
    TU_CHECK(strcmp(sv_ext_grid_storage_name(FLOAT32), "float32") == 0);
    TU_CHECK(strcmp(sv_ext_grid_storage_name(FLOAT16), "float16") == 0);
    TU_CHECK(sv_ext_grid_storage_name(2) == NULL);
    TU_CHECK(strcmp(sv_ext_grid_structure_name(GRID), "grid") == 0);
    TU_CHECK(strcmp(sv_ext_grid_structure_name(OCTREE), "octree") == 0);
    TU_CHECK(strcmp(sv_ext_grid_structure_name(TETRA), "tetrahedra") == 0);
    TU_CHECK(strcmp(sv_ext_grid_structure_name(3), "kdtree") == 0); /* version 4's structure 3 */
    TU_CHECK(sv_ext_grid_structure_name(4) == NULL);
}

int main(void)
{
    TU_RUN(test_defaults_and_values);
    TU_RUN(test_refusals);
    TU_RUN(test_name_tables);
    return TU_EXIT();
}
