/* Image I/O through OpenImageIO: float round trips, 8-bit quantisation, atomic writes, errors, and the
 * in-memory reader (the same bytes from memory and from a file give the same pixels). */
#include "schnee/pb_image.h"
#include "testutil.h"

#include <dirent.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

static char g_dir[64];

static void join(char *out, size_t n, const char *name) { snprintf(out, n, "%s/%s", g_dir, name); }

/* Number of entries (other than . and ..) in a folder, and whether any is a leftover temp file. */
static int count_entries(const char *dir, int *temps)
{
    DIR *d = opendir(dir);
    int n = 0;
    *temps = 0;
    if (!d) return -1;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        n++;
        if (strstr(e->d_name, ".tmp-")) (*temps)++;
    }
    closedir(d);
    return n;
}

static float pattern(uint32_t x, uint32_t y, uint32_t c) { return (float)(x * 0.25 + y * 10.0 + c * 1000.0) - 3.5f; }

/* EXR keeps 32-bit floats bit for bit (negatives, large values) for 1..5 channels; dimensions and
 * row order (row 0 first in memory, first in the file) survive. */
static void test_exr_round_trip(void)
{
    const uint32_t w = 37, h = 11;
    for (uint32_t ch = 1; ch <= 5; ch++) {
        float *px = malloc(sizeof(float) * w * h * ch);
        TU_REQUIRE(px);
        for (uint32_t y = 0; y < h; y++)
            for (uint32_t x = 0; x < w; x++)
                for (uint32_t c = 0; c < ch; c++) px[((size_t)y * w + x) * ch + c] = pattern(x, y, c);
        px[0] = 1e30f;
        char path[128];
        join(path, sizeof path, "rt.exr");
        pb_error err = {0};
        TU_CHECK_EQ_INT(pb_image_write(path, w, h, ch, px, &err), PB_SUCCESS);
        pb_image img = {0};
        TU_CHECK_EQ_INT(pb_image_read(path, &img, &err), PB_SUCCESS);
        TU_CHECK_EQ_INT(img.width, w);
        TU_CHECK_EQ_INT(img.height, h);
        TU_CHECK_EQ_INT(img.channels, ch);
        if (img.pixels && img.width == w && img.height == h && img.channels == ch)
            TU_CHECK(memcmp(img.pixels, px, sizeof(float) * w * h * ch) == 0);
        pb_image_free(&img);
        TU_CHECK(img.pixels == NULL && img.width == 0);
        pb_image_free(&img); /* idempotent */
        free(px);
        if (err.code) fprintf(stderr, "  %s\n", err.message);
    }
}

/* 8-bit formats: values are clamped to [0, 1] and quantised to k/255 (OpenImageIO rounds to nearest),
 * so a read gives back round(clamp(v)·255)/255 within float rounding (1e-6). */
static void test_png_quantisation(void)
{
    const uint32_t w = 16, h = 4, ch = 3;
    float px[16 * 4 * 3];
    for (uint32_t q = 0; q < w * h * ch; q++) px[q] = -0.2f + 1.4f * (float)q / (w * h * ch - 1);
    char path[128];
    join(path, sizeof path, "q.png");
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_image_write(path, w, h, ch, px, &err), PB_SUCCESS);
    pb_image img = {0};
    TU_CHECK_EQ_INT(pb_image_read(path, &img, &err), PB_SUCCESS);
    TU_REQUIRE(img.pixels && img.width == w && img.height == h && img.channels == ch);
    for (uint32_t q = 0; q < w * h * ch; q++) {
        const double v = fmin(1.0, fmax(0.0, px[q]));
        TU_CHECK_NEAR(img.pixels[q], floor(v * 255.0 + 0.5) / 255.0, 1e-6);
    }
    pb_image_free(&img);
    struct stat st;
    TU_CHECK(stat(path, &st) == 0 && (st.st_mode & 0777) == 0644);
}

/* Atomic replacement: an existing file is replaced, and no temporary file is left behind, neither on
 * success nor when the final rename fails (target is a non-empty folder). */
static void test_atomic_write(void)
{
    char sub[128], path[200], blocker[200], inner[260];
    join(sub, sizeof sub, "atomic");
    TU_REQUIRE(mkdir(sub, 0755) == 0);
    snprintf(path, sizeof path, "%s/a.exr", sub);
    float one[4] = {1, 2, 3, 4}, two[4] = {5, 6, 7, 8};
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_image_write(path, 2, 2, 1, one, &err), PB_SUCCESS);
    TU_CHECK_EQ_INT(pb_image_write(path, 2, 2, 1, two, &err), PB_SUCCESS);
    pb_image img = {0};
    TU_CHECK_EQ_INT(pb_image_read(path, &img, &err), PB_SUCCESS);
    TU_CHECK(img.pixels && img.pixels[3] == 8.0f);
    pb_image_free(&img);
    int temps = 0;
    TU_CHECK_EQ_INT(count_entries(sub, &temps), 1);
    TU_CHECK_EQ_INT(temps, 0);

    snprintf(blocker, sizeof blocker, "%s/b.exr", sub);
    TU_REQUIRE(mkdir(blocker, 0755) == 0);
    snprintf(inner, sizeof inner, "%s/keep", blocker);
    FILE *f = fopen(inner, "w");
    TU_REQUIRE(f);
    fclose(f);
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_write(blocker, 2, 2, 1, one, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "cannot rename");
    TU_CHECK_CONTAINS(err.message, "b.exr");
    TU_CHECK_EQ_INT(count_entries(sub, &temps), 2);
    TU_CHECK_EQ_INT(temps, 0);
    unlink(inner);
    rmdir(blocker);
    unlink(path);
    rmdir(sub);
}

static void test_errors(void)
{
    char path[128];
    pb_image img = {0};
    pb_error err = {0};
    float px[4] = {0};

    join(path, sizeof path, "missing.exr");
    TU_CHECK_EQ_INT(pb_image_read(path, &img, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "missing.exr");
    TU_CHECK(img.pixels == NULL);

    join(path, sizeof path, "garbage.exr");
    FILE *f = fopen(path, "w");
    TU_REQUIRE(f);
    fputs("this is not an image", f);
    fclose(f);
    err = (pb_error){0};
    TU_CHECK(pb_image_read(path, &img, &err) != PB_SUCCESS);
    TU_CHECK_CONTAINS(err.message, "garbage.exr");
    TU_CHECK(img.pixels == NULL);
    unlink(path);

    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_read(NULL, &img, &err), PB_ERROR_INVALID_ARGUMENT);
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_read("x.exr", NULL, &err), PB_ERROR_INVALID_ARGUMENT);

    join(path, sizeof path, "no/such/dir/x.exr");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_write(path, 2, 2, 1, px, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "no/such/dir/x.exr");

    join(path, sizeof path, "x.notaformat");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_write(path, 2, 2, 1, px, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, ".notaformat");

    join(path, sizeof path, "x.exr");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_write(path, 0, 2, 1, px, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "empty image");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_write(path, 2, 2, 1, NULL, &err), PB_ERROR_INVALID_ARGUMENT);
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_write(path, 0x80000000u, 2, 1, px, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "overflows");
    int temps = 0;
    /* nothing left by any failed call: only rt.exr and q.png from the earlier tests */
    TU_CHECK_EQ_INT(count_entries(g_dir, &temps), 2);
    TU_CHECK_EQ_INT(temps, 0);
}

/* The whole file at `path` in a malloc'ed buffer (*size bytes), or NULL. */
static unsigned char *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    unsigned char *buf = NULL;
    if (fseek(f, 0, SEEK_END) == 0) {
        long n = ftell(f);
        buf = n > 0 ? malloc((size_t)n) : NULL;
        if (buf && (fseek(f, 0, SEEK_SET) != 0 || fread(buf, 1, (size_t)n, f) != (size_t)n)) {
            free(buf);
            buf = NULL;
        }
        *size = buf ? (size_t)n : 0;
    }
    fclose(f);
    return buf;
}

/* pb_image_read_memory on a file's bytes gives pb_image_read's pixels bit for bit (EXR float, PNG
 * 8-bit); truncated bytes, garbage and nothing fail with the image's name in the message. */
static void test_memory_matches_file(void)
{
    const char *names[2] = {"mem.exr", "mem.png"};
    const uint32_t w = 13, h = 7, ch = 4;
    float px[13 * 7 * 4];
    for (uint32_t i = 0; i < w * h * ch; i++) px[i] = (float)(i % 17) / 16.0f; /* in [0, 1] for the PNG */
    for (int k = 0; k < 2; k++) {
        char path[128];
        join(path, sizeof path, names[k]);
        pb_error err = {0};
        TU_REQUIRE(pb_image_write(path, w, h, ch, px, &err) == PB_SUCCESS);
        size_t size = 0;
        unsigned char *bytes = slurp(path, &size);
        TU_REQUIRE(bytes);
        pb_image from_file = {0}, from_memory = {0};
        TU_CHECK_EQ_INT(pb_image_read(path, &from_file, &err), PB_SUCCESS);
        TU_CHECK_EQ_INT(pb_image_read_memory(bytes, size, names[k], &from_memory, &err), PB_SUCCESS);
        if (err.code) fprintf(stderr, "  %s\n", err.message);
        TU_CHECK_EQ_INT(from_memory.width, w);
        TU_CHECK_EQ_INT(from_memory.height, h);
        TU_CHECK_EQ_INT(from_memory.channels, ch);
        TU_CHECK_EQ_INT(from_file.channels, ch);
        if (from_file.pixels && from_memory.pixels && from_memory.width == w && from_memory.height == h &&
            from_memory.channels == ch && from_file.channels == ch)
            TU_CHECK(memcmp(from_file.pixels, from_memory.pixels, sizeof(float) * w * h * ch) == 0);
        pb_image_free(&from_file);
        pb_image_free(&from_memory);
        /* the first half of the bytes: a clear error naming the image, no pixels */
        err = (pb_error){0};
        TU_CHECK(pb_image_read_memory(bytes, size / 2, "half.bin", &from_memory, &err) != PB_SUCCESS);
        TU_CHECK_CONTAINS(err.message, "half.bin");
        TU_CHECK(from_memory.pixels == NULL);
        free(bytes);
        unlink(path);
    }
    pb_image img = {0};
    pb_error err = {0};
    const char garbage[] = "this is not an image";
    TU_CHECK_EQ_INT(pb_image_read_memory(garbage, sizeof garbage, "garbage.png", &img, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "garbage.png");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_read_memory(garbage, sizeof garbage, NULL, &img, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "not a known image format");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_read_memory(garbage, 0, "empty.png", &img, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "empty");
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_read_memory(NULL, 4, "null.png", &img, &err), PB_ERROR_INVALID_ARGUMENT);
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_read_memory(garbage, sizeof garbage, "x.png", NULL, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK(img.pixels == NULL);
}

/* The size limits of pb_image.h hold for buffers as for files, checked before any pixel is
 * allocated: a PFM header announcing 100000 x 100000 (above PB_IMAGE_MAX_DIM) and a buffer above
 * PB_IMAGE_MAX_FILE_BYTES (its size alone is checked: not one byte of it is read) fail with
 * PB_ERROR_TOO_LARGE. */
static void test_memory_limits(void)
{
    const char pfm[] = "PF\n100000 100000\n-1.0\n\0\0\0\0\0\0\0\0\0\0\0\0";
    pb_image img = {0};
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_image_read_memory(pfm, sizeof pfm, "huge.pfm", &img, &err), PB_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "too large");
    TU_CHECK(img.pixels == NULL);
    err = (pb_error){0};
    TU_CHECK_EQ_INT(pb_image_read_memory(pfm, (size_t)PB_IMAGE_MAX_FILE_BYTES + 1, "huge.exr", &img, &err),
                    PB_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "huge.exr");
}

int main(void)
{
    snprintf(g_dir, sizeof g_dir, "/tmp/schnee_test_image_XXXXXX");
    if (!mkdtemp(g_dir)) {
        perror("mkdtemp");
        return 1;
    }
    TU_RUN(test_exr_round_trip);
    TU_RUN(test_png_quantisation);
    TU_RUN(test_atomic_write);
    TU_RUN(test_errors);
    TU_RUN(test_memory_matches_file);
    TU_RUN(test_memory_limits);
    char path[128];
    join(path, sizeof path, "rt.exr");
    unlink(path);
    join(path, sizeof path, "q.png");
    unlink(path);
    rmdir(g_dir);
    return TU_EXIT();
}
