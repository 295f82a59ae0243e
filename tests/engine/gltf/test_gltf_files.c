/* Files a glTF references (issue 14), through sv_gltf_load_file and the engine's extension parser:
 * special files (FIFO, /dev/zero, a 2 GiB sparse file, a directory, a symlink loop) as the glTF
 * itself and as a buffer give a clear error quickly (each load is timed; the FIFO used to block
 * forever, the sparse file used to be read whole); references outside the glTF's folder tree are
 * refused unless allowed; a '%' that is no escape is taken literally with a warning. Runs under
 * ASan/UBSan in the sanitizer tree (label "native"). */
#define _DEFAULT_SOURCE /* mkfifo, symlink, truncate */
#include "gltf_testgen.h"
#include "sv_ext.h"
#include "testutil.h"

#include <errno.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static char *join(const char *dir, const char *name)
{
    char *p = malloc(strlen(dir) + strlen(name) + 2);
    if (!p) abort();
    sprintf(p, "%s/%s", dir, name);
    return p;
}

/* The special files, created inside dir under `name`. Returns the path to reference (malloc'ed). */
static char *make_special(const char *dir, const char *kind, const char *name)
{
    char *p = join(dir, name);
    if (strcmp(kind, "fifo") == 0) {
        if (mkfifo(p, 0600) != 0) abort();
    } else if (strcmp(kind, "dir") == 0) {
        if (mkdir(p, 0700) != 0) abort();
    } else if (strcmp(kind, "loop") == 0) {
        char *other = join(dir, "loop-other");
        if (symlink(name, other) != 0 && errno != EEXIST) abort();
        if (symlink("loop-other", p) != 0) abort();
        free(other);
    } else if (strcmp(kind, "sparse") == 0) {
        FILE *f = fopen(p, "wb");
        if (!f) abort();
        fclose(f);
        if (truncate(p, 2ll << 30) != 0) abort(); /* 2 GiB of holes: no disk used */
    } else {                                      /* "zero": the device itself (absolute path) */
        free(p);
        p = join("", "dev/zero");
    }
    return p;
}

static const char *KINDS[] = {"fifo", "zero", "sparse", "dir", "loop"};
static const char *EXPECT[] = {"is a FIFO", "is a character device", "", "is a directory",
                               "too many levels of symbolic links"};

/* The special file as the .gltf itself. */
static void test_gltf_path_is_special(void)
{
    char *dir = tg_tmpdir();
    for (size_t k = 0; k < sizeof KINDS / sizeof KINDS[0]; k++) {
        char name[32];
        snprintf(name, sizeof name, "scene-%s.gltf", KINDS[k]);
        char *path = make_special(dir, KINDS[k], name);
        sv_gltf *g = NULL;
        sv_gltf_error err = {0};
        double t0 = now_s();
        sv_gltf_result r = sv_gltf_load_file(path, NULL, &g, &err);
        double dt = now_s() - t0;
        TU_CHECK(r != SV_GLTF_SUCCESS && g == NULL);
        TU_CHECK(dt < 5.0);
        TU_CHECK_CONTAINS(err.message, path);
        /* The sparse file is a regular file: its first byte is no '{' and no GLB magic. */
        TU_CHECK_CONTAINS(err.message, EXPECT[k][0] ? EXPECT[k] : "is not a glTF file");
        if (r == SV_GLTF_SUCCESS) sv_gltf_free(g);
        if (strcmp(KINDS[k], "zero") != 0) unlink(path), rmdir(path);
        free(path);
    }
    tg_remove(dir, "loop-other");
    rmdir(dir);
    free(dir);
}

/* The special file as an external buffer (byteLength 12). /dev/zero lies outside the folder, so it
 * is reached with allow_outside_paths (the folder rule refuses it first otherwise). */
static void test_buffer_is_special(void)
{
    char *dir = tg_tmpdir();
    for (size_t k = 0; k < sizeof KINDS / sizeof KINDS[0]; k++) {
        char name[32];
        snprintf(name, sizeof name, "buf-%s.bin", KINDS[k]);
        char *target = make_special(dir, KINDS[k], name);
        const char *uri = strcmp(KINDS[k], "zero") == 0 ? target : name;
        char json[512];
        snprintf(json, sizeof json,
                 "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":12,\"uri\":\"%s\"}]}", uri);
        char *gltf = tg_write(dir, "scene.gltf", json, strlen(json));
        sv_gltf_desc desc = {.allow_outside_paths = strcmp(KINDS[k], "zero") == 0};
        sv_gltf *g = NULL;
        sv_gltf_error err = {0};
        double t0 = now_s();
        sv_gltf_result r = sv_gltf_load_file(gltf, &desc, &g, &err);
        double dt = now_s() - t0;
        TU_CHECK(dt < 5.0);
        if (strcmp(KINDS[k], "sparse") == 0) {
            /* A regular file with enough bytes loads: only byteLength (12) of its 2 GiB are read. */
            TU_CHECK_EQ_INT(r, SV_GLTF_SUCCESS);
        } else {
            TU_CHECK(r != SV_GLTF_SUCCESS && g == NULL);
            TU_CHECK_CONTAINS(err.message, "buffers[0]");
            TU_CHECK_CONTAINS(err.message, target);
            TU_CHECK_CONTAINS(err.message, EXPECT[k]);
        }
        if (r == SV_GLTF_SUCCESS) sv_gltf_free(g);
        if (strcmp(KINDS[k], "zero") != 0) unlink(target), rmdir(target);
        free(target);
        free(gltf);
    }
    tg_remove(dir, "loop-other");
    tg_remove(dir, "scene.gltf");
    rmdir(dir);
    free(dir);
}

/* A buffer whose URI leaves the folder: '..', an absolute path, a symlink leading out. Each is
 * refused with SV_GLTF_ERROR_OUTSIDE naming the path, and loads with allow_outside_paths. A
 * probe grid's URI (the engine's extension parser) follows the same rule. */
static void test_outside_paths(void)
{
    char *top = tg_tmpdir();
    char *scene_dir = join(top, "scene");
    TU_REQUIRE(mkdir(scene_dir, 0700) == 0);
    uint8_t twelve[12] = {0};
    char *outside = tg_write(top, "outside.bin", twelve, sizeof twelve);
    char *link = join(scene_dir, "link.bin");
    TU_REQUIRE(symlink(outside, link) == 0);
    char abs_uri[600];
    snprintf(abs_uri, sizeof abs_uri, "%s", outside);
    const char *uris[] = {"../outside.bin", abs_uri, "link.bin", "../scene/../outside.bin"};
    const char *why[] = {"is outside the glTF's folder", "is an absolute path outside", "leads to",
                         "is outside the glTF's folder"};
    for (int i = 0; i < 4; i++) {
        char json[900];
        snprintf(json, sizeof json,
                 "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":12,\"uri\":\"%s\"}]}", uris[i]);
        char *gltf = tg_write(scene_dir, "scene.gltf", json, strlen(json));
        sv_gltf *g = NULL;
        sv_gltf_error err = {0};
        TU_CHECK_EQ_INT(sv_gltf_load_file(gltf, NULL, &g, &err), SV_GLTF_ERROR_OUTSIDE);
        TU_CHECK_CONTAINS(err.message, "buffers[0]");
        TU_CHECK_CONTAINS(err.message, why[i]);
        TU_CHECK_CONTAINS(err.message, i == 2 ? "link.bin" : uris[i]);
        TU_CHECK_CONTAINS(err.message, "--allow-outside-paths");
        sv_gltf_desc allow = {.allow_outside_paths = true};
        TU_CHECK_EQ_INT(sv_gltf_load_file(gltf, &allow, &g, &err), SV_GLTF_SUCCESS);
        sv_gltf_free(g);
        free(gltf);
    }
    /* A probe grid entry pointing out of the folder: the extension parser refuses it too. */
    const char *grid =
        "{\"asset\":{\"version\":\"2.0\"},\"scenes\":[{\"extensions\":{\"VULKAN_SCHNEE_engine_properties\":"
        "{\"shProbeGrids\":[{\"uri\":\"../outside.bin\",\"probeCount\":1,\"maxBand\":2,"
        "\"gridOrigin\":[0,0,0],\"gridDims\":[1,1,1],\"gridSpacing\":1}]}}}]}";
    char *gltf = tg_write(scene_dir, "scene.gltf", grid, strlen(grid));
    sv_gltf_desc desc = {.app_extensions = sv_ext_names, .app_extension_count = SV_EXT_NAME_COUNT};
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    TU_REQUIRE(sv_gltf_load_file(gltf, &desc, &g, &err) == SV_GLTF_SUCCESS);
    sv_ext ext;
    TU_CHECK_EQ_INT(sv_ext_parse(g, &ext, &err), SV_GLTF_ERROR_OUTSIDE);
    TU_CHECK_CONTAINS(err.message, "shProbeGrids[0]: '../outside.bin' is outside the glTF's folder");
    sv_gltf_free(g);
    free(gltf);
    tg_remove(scene_dir, "scene.gltf");
    unlink(link);
    rmdir(scene_dir);
    unlink(outside);
    rmdir(top);
    free(link);
    free(outside);
    free(scene_dir);
    free(top);
}

/* Blender's exporter writes buffer names unencoded ("scène #1 100% ü.bin"): a '%' that is no
 * %XX escape is taken literally with a warning; a valid escape still decodes. */
static void test_literal_percent(void)
{
    char *dir = tg_tmpdir();
    uint8_t twelve[12] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
    char *a = tg_write(dir, "sc\xc3\xa8ne #1 100% \xc3\xbc.bin", twelve, sizeof twelve);
    char *b = tg_write(dir, "two words.bin", twelve, sizeof twelve);
    const char *json =
        "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"byteLength\":12,\"uri\":\"sc\xc3\xa8ne #1 100% "
        "\xc3\xbc.bin\"},{\"byteLength\":12,\"uri\":\"two%20words.bin\"}]}";
    char *gltf = tg_write(dir, "scene.gltf", json, strlen(json));
    sv_gltf *g = NULL;
    sv_gltf_error err = {0};
    TU_REQUIRE(sv_gltf_load_file(gltf, NULL, &g, &err) == SV_GLTF_SUCCESS);
    TU_REQUIRE(g->warning_count == 1);
    TU_CHECK_CONTAINS(g->warnings[0], "buffers[0]: URI 'sc\xc3\xa8ne #1 100% \xc3\xbc.bin' has a '%' that is not a %XX "
                                      "escape; taken literally");
    sv_gltf_free(g);
    unlink(a);
    unlink(b);
    unlink(gltf);
    rmdir(dir);
    free(a);
    free(b);
    free(gltf);
    free(dir);
}

int main(void)
{
    TU_RUN(test_gltf_path_is_special);
    TU_RUN(test_buffer_is_special);
    TU_RUN(test_outside_paths);
    TU_RUN(test_literal_percent);
    return TU_EXIT();
}
