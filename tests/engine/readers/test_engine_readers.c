/* Issue 14, the engine's own readers without Vulkan: sv_probes_load (a shProbeGrids entry's file:
 * check_probe_file, then the core's pb_shprobe_read) and sv_sky_load (sv_image_file_check, then
 * pb_image_read) on the special files of the issue — a FIFO, /dev/zero, a 2 GiB sparse file, a
 * directory, a symbolic link loop — and on a file that is not ours (a passwd-like text). Built into
 * the sanitizer tree too (engine/CMakeLists.txt: sv_readers), so ASan/UBSan watch these paths; the
 * whole viewer is not (lavapipe under ASan is impractical, docs/engine.md). tests/engine/
 * test_engine_files.py runs the same files through the full schnee-view.
 *
 * Each call runs under a watchdog (SIGALRM after WATCHDOG_S fails the test: a FIFO opened for
 * reading without O_NONBLOCK blocks forever) and must return within MAX_CALL_S with a peak-RSS
 * growth below MAX_RSS_GROWTH_KB (a 2 GiB sparse file read whole would add 2 GiB). The message the
 * engine prints (stderr, captured) must name the file and say why, and never quote its bytes. A good
 * .shprobe and a good sky EXR load (the controls). */
#define _DEFAULT_SOURCE
#include "schnee/pb_image.h"
#include "schnee/pb_shprobe.h"
#include "sv_probes.h"
#include "sv_sky.h"
#include "testutil.h"
#include "watchdog.h"

#include <fcntl.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct special {
    const char *label;
    char path[128];
    const char *needle; /* in the engine's message, for both readers */
} special;

static int make_specials(special *s)
{
    int n = 0;
    s[n] = (special){"FIFO", "", "is a FIFO"};
    join(s[n].path, sizeof s[n].path, "fifo.dat");
    if (mkfifo(s[n].path, 0644) != 0) return -1;
    n++;
    s[n] = (special){"/dev/zero", "/dev/zero", "is a character device"};
    n++;
    s[n] = (special){"sparse 2 GiB", "", "has 2147483648 bytes, over the limit of 1073741824"};
    join(s[n].path, sizeof s[n].path, "sparse.dat");
    int fd = open(s[n].path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0 || ftruncate(fd, (off_t)2 << 30) != 0) return -1;
    close(fd);
    n++;
    s[n] = (special){"directory", "", "is a directory"};
    join(s[n].path, sizeof s[n].path, "dir.dat");
    if (mkdir(s[n].path, 0755) != 0) return -1;
    n++;
    s[n] = (special){"symlink loop", "", "too many levels of symbolic links"};
    char other[128];
    join(s[n].path, sizeof s[n].path, "loop_a.dat");
    join(other, sizeof other, "loop_b.dat");
    if (symlink(other, s[n].path) != 0 || symlink(s[n].path, other) != 0) return -1;
    n++;
    return n;
}

/* What one call printed on stderr (fd 2 redirected to a file meanwhile). */
static char g_msg[8192];

typedef enum which { PROBES, SKY } which;

/* Runs sv_probes_load or sv_sky_load on `path` under the watchdog; returns its result, the stderr
 * text in g_msg, and checks the time and the RSS growth. */
static bool run_reader(which w, const char *path, const char *label)
{
    char cur[256];
    snprintf(cur, sizeof cur, "%s(%s: %s)", w == PROBES ? "sv_probes_load" : "sv_sky_load", label, path);
    g_current = cur;
    char grid_path[128], name[] = "g", uri[] = "uri";
    snprintf(grid_path, sizeof grid_path, "%s", path);
    sv_ext_probe_grid entry = {.name = name, .uri = uri, .path = grid_path, .probe_count = 1, .max_band = 2};
    entry.grid_dims[0] = entry.grid_dims[1] = entry.grid_dims[2] = 1;
    entry.grid_spacing = 1.0f;
    for (int i = 0; i < 3; ++i) entry.grid_axes[i][i] = 1.0f;
    sv_ext ext = {0};
    if (w == PROBES) {
        ext.probe_grids = &entry;
        ext.probe_grid_count = 1;
    } else {
        ext.sky.present = true;
        ext.sky.uri = uri;
        ext.sky.path = grid_path;
        ext.sky.max_band = 2;
    }
    char log[160];
    join(log, sizeof log, "stderr.txt");
    fflush(stderr);
    int saved = dup(2);
    int lfd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(lfd, 2);
    close(lfd);

    wd_call call = wd_begin(cur);
    bool ok;
    if (w == PROBES) {
        sv_probes probes;
        ok = sv_probes_load(&ext, &probes);
        if (ok) sv_probes_destroy(&probes);
    } else {
        sv_sky sky;
        ok = sv_sky_load(&ext, &sky);
        if (ok) sv_sky_destroy(&sky);
    }
    wd_end(&call);

    fflush(stderr);
    dup2(saved, 2);
    close(saved);
    g_msg[0] = 0;
    FILE *f = fopen(log, "r");
    if (f) {
        size_t n = fread(g_msg, 1, sizeof g_msg - 1, f);
        g_msg[n] = 0;
        fclose(f);
    }
    fprintf(stderr, "  %s -> %s in %.3f s, +%ld KB: %s", cur, ok ? "true" : "false", call.seconds, call.grown_kb,
            g_msg[0] ? g_msg : "(no message)\n");
    return ok;
}

static void test_special_files_are_refused_at_once(void)
{
    special s[8];
    int n = make_specials(s);
    TU_REQUIRE(n == 5);
    for (int i = 0; i < n; ++i) {
        for (int w = PROBES; w <= SKY; ++w) {
            bool ok = run_reader((which)w, s[i].path, s[i].label);
            TU_CHECK(!ok);
            TU_CHECK(strstr(g_msg, "schnee-view: error: ") == g_msg);
            TU_CHECK(strstr(g_msg, w == PROBES ? "shProbeGrids[0] 'g'" : "sky") != NULL);
            TU_CHECK(strstr(g_msg, s[i].path) != NULL); /* names the file */
            if (!strstr(g_msg, s[i].needle)) TU_FAIL_("expected '%s' in: %s", s[i].needle, g_msg);
            TU_CHECK(strchr(g_msg, '\n') == g_msg + strlen(g_msg) - 1); /* one line */
        }
    }
}

static void test_a_file_not_ours_is_not_quoted(void)
{
    char path[128];
    join(path, sizeof path, "passwd");
    FILE *f = fopen(path, "w");
    TU_REQUIRE(f != NULL);
    fputs("root:x:0:0:root:/root:/bin/bash\n", f);
    fclose(f);
    TU_CHECK(!run_reader(PROBES, path, "text file"));
    TU_CHECK(strstr(g_msg, "(32 bytes) is not a .shprobe file (no \"SPHR\" magic)") != NULL);
    TU_CHECK(strstr(g_msg, "root:") == NULL && strstr(g_msg, "0x746F6F72") == NULL);
    TU_CHECK(!run_reader(SKY, path, "text file"));
    TU_CHECK(strstr(g_msg, "(32 bytes) does not start like an image file") != NULL);
    TU_CHECK(strstr(g_msg, "root:") == NULL);
}

static void test_good_files_load(void)
{
    /* A one-probe v1 grid (1 x 1 x 1) and an 8 x 4 sky of constant radiance 0.5. */
    char path[128];
    join(path, sizeof path, "good.shprobe");
    uint32_t dims[3] = {1, 1, 1};
    pb_shprobe *p = NULL;
    pb_error err = {0};
    TU_REQUIRE(pb_shprobe_create(1, 2, dims, false, &p, &err) == PB_SUCCESS);
    for (int k = 0; k < 27; ++k) p->coeffs[k] = k < 3 ? 1.0f : 0.0f;
    p->grid[0] = 0;
    p->grid_spacing = 1.0f;
    TU_REQUIRE(pb_shprobe_write(path, p, &err) == PB_SUCCESS);
    pb_shprobe_destroy(p);
    TU_CHECK(run_reader(PROBES, path, "good .shprobe"));
    TU_CHECK(g_msg[0] == 0); /* no error, and the entry agrees with the header: no warning */

    join(path, sizeof path, "sky.exr");
    float pixels[8 * 4 * 3];
    for (int k = 0; k < 8 * 4 * 3; ++k) pixels[k] = 0.5f;
    TU_REQUIRE(pb_image_write(path, 8, 4, 3, pixels, &err) == PB_SUCCESS);
    TU_CHECK(run_reader(SKY, path, "good sky"));
}

int main(void)
{
    if (!wd_setup("sv_readers")) return 1;
    TU_RUN(test_special_files_are_refused_at_once);
    TU_RUN(test_a_file_not_ours_is_not_quoted);
    TU_RUN(test_good_files_load);
    wd_cleanup();
    return TU_EXIT();
}
