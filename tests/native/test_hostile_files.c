/* Issue 14: no input file makes a native reader hang, read or allocate far beyond what the header
 * implies, or echo the content of a file that is not ours; the .shprobe writer never replaces what is
 * not a .shprobe. Every special file is made here in a temp folder: a FIFO, a directory, a symbolic
 * link loop, a 2 GiB sparse file (`truncate -s 2G`), a socket, and /dev/zero (read only).
 *
 * Each hostile call runs under a watchdog (SIGALRM after WATCHDOG_S: the test fails, where the old
 * code blocked forever on a FIFO) and must return within MAX_CALL_S with a peak-RSS growth below
 * MAX_RSS_GROWTH_KB (the old code read a 2 GiB sparse .shprobe whole: +2 GiB). */
#define _DEFAULT_SOURCE
#include "schnee/pb_image.h"
#include "schnee/pb_sh.h"
#include "schnee/pb_shprobe.h"
#include "testutil.h"
#include "watchdog.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <unistd.h>

/* The file types every reader gets. */
typedef struct hostile {
    const char *label;
    char path[128];
    pb_result code;     /* expected result of every reader */
    const char *needle; /* expected in the message (after the path) */
} hostile;

static int make_hostiles(hostile *h)
{
    int n = 0;
    h[n] = (hostile){"FIFO", "", PB_ERROR_IO, "not a regular file (a FIFO (named pipe))"};
    join(h[n].path, sizeof h[n].path, "fifo.shprobe");
    if (mkfifo(h[n].path, 0644) != 0) return -1;
    n++;
    h[n] = (hostile){"/dev/zero", "/dev/zero", PB_ERROR_IO, "not a regular file (a character device)"};
    n++;
    h[n] = (hostile){"directory", "", PB_ERROR_IO, "not a regular file (a directory)"};
    join(h[n].path, sizeof h[n].path, "dir.shprobe");
    if (mkdir(h[n].path, 0755) != 0) return -1;
    n++;
    h[n] = (hostile){"symlink loop", "", PB_ERROR_IO, "a symbolic link loop"};
    char other[128];
    join(h[n].path, sizeof h[n].path, "loop_a.shprobe");
    join(other, sizeof other, "loop_b.shprobe");
    if (symlink(other, h[n].path) != 0 || symlink(h[n].path, other) != 0) return -1;
    n++;
    /* 2 GiB of zeros, sparse: its first bytes are not any magic; format error from the header. */
    h[n] = (hostile){"sparse 2 GiB", "", PB_ERROR_FORMAT, ""};
    join(h[n].path, sizeof h[n].path, "sparse.shprobe");
    int fd = open(h[n].path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0 || ftruncate(fd, (off_t)2 << 30) != 0) return -1;
    close(fd);
    n++;
    return n;
}

typedef enum reader { READ_SHPROBE, READ_HEADER, READ_IMAGE, PROJECT_FILE, READER_COUNT } reader;
static const char *const reader_names[] = {"pb_shprobe_read", "pb_shprobe_read_header", "pb_image_read",
                                           "pb_sh_project_file"};

/* Runs one reader on one file under the watchdog; returns its result, fills err, checks time/RSS. */
static pb_result run_reader(reader which, const char *path, pb_error *err)
{
    char label[256];
    snprintf(label, sizeof label, "%s(%s)", reader_names[which], path);
    wd_call call = wd_begin(label);
    pb_result r = PB_SUCCESS;
    memset(err, 0, sizeof *err);
    switch (which) {
    case READ_SHPROBE: {
        pb_shprobe *p = (pb_shprobe *)(uintptr_t)1;
        r = pb_shprobe_read(path, &p, err);
        TU_CHECK(p == NULL);
        pb_shprobe_destroy(r == PB_SUCCESS ? p : NULL);
        break;
    }
    case READ_HEADER: {
        pb_shprobe h;
        r = pb_shprobe_read_header(path, &h, err);
        break;
    }
    case READ_IMAGE: {
        pb_image img;
        r = pb_image_read(path, &img, err);
        TU_CHECK(img.pixels == NULL);
        pb_image_free(&img);
        break;
    }
    case PROJECT_FILE: {
        double out[PB_SH_MAX_COEFFS * 3];
        pb_sh_project_desc d = {0};
        d.max_band = 2;
        r = pb_sh_project_file(path, &d, out, err);
        break;
    }
    case READER_COUNT: break;
    }
    wd_end(&call);
    printf("  %-60s %.4f s, +%ld KiB: %s\n", label, call.seconds, call.grown_kb, err->message);
    return r;
}

static void test_readers_refuse_special_files(void)
{
    hostile h[8];
    int n = make_hostiles(h);
    TU_REQUIRE(n > 0);
    for (int i = 0; i < n; i++)
        for (int w = 0; w < READER_COUNT; w++) {
            pb_error err;
            pb_result r = run_reader((reader)w, h[i].path, &err);
            TU_CHECK_EQ_INT(r, h[i].code);
            TU_CHECK_CONTAINS(err.message, h[i].path); /* messages name the path */
            TU_CHECK_CONTAINS(err.message, h[i].needle);
        }
    /* The sparse file's messages say what it is not, per reader. */
    pb_error err;
    const char *sparse = h[4].path;
    TU_CHECK_EQ_INT(run_reader(READ_SHPROBE, sparse, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "not a .shprobe file (bad magic");
    TU_CHECK_EQ_INT(run_reader(READ_IMAGE, sparse, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "not a known image format");
    /* The same zeros named .exr: the EXR reader is asked (by extension) and fails on the header,
     * without OpenImageIO trying every other reader over 2 GiB (minutes before). */
    char exr[128];
    join(exr, sizeof exr, "sparse.exr");
    TU_REQUIRE(rename(sparse, exr) == 0);
    TU_CHECK_EQ_INT(run_reader(READ_IMAGE, exr, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "cannot read as exr");
    TU_CHECK_EQ_INT(run_reader(PROJECT_FILE, exr, &err), PB_ERROR_FORMAT);
    unlink(exr);
    /* A 2 GiB sparse file with a valid v1 header whose counts are above the limits: refused after the
     * header (TOO_LARGE), where a consistent size would otherwise make it read the rest. */
    char big[128];
    join(big, sizeof big, "big_header.shprobe");
    uint8_t hdr[48] = {0x53, 0x50, 0x48, 0x52, 1, 0, 0, 0};
    hdr[8 + 3] = 0x02; /* probe count 2^25 */
    for (int k = 0; k < 3; k++) hdr[12 + 4 * k] = 1;
    hdr[36 + 2] = 0x80, hdr[36 + 3] = 0x3f; /* spacing 1.0f */
    int fd = open(big, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    TU_REQUIRE(fd >= 0);
    TU_CHECK(write(fd, hdr, sizeof hdr) == (ssize_t)sizeof hdr);
    TU_CHECK(ftruncate(fd, (off_t)2 << 30) == 0);
    close(fd);
    TU_CHECK_EQ_INT(run_reader(READ_SHPROBE, big, &err), PB_ERROR_TOO_LARGE);
    TU_CHECK_CONTAINS(err.message, "probe count 33554432 (offset 8) is above the limit of 16777216 probes");
    TU_CHECK_EQ_INT(run_reader(READ_HEADER, big, &err), PB_ERROR_TOO_LARGE);
    unlink(big);
    for (int i = 0; i < n; i++) {
        if (i == 2)
            rmdir(h[i].path);
        else if (i != 1)
            unlink(h[i].path);
    }
    char other[128];
    join(other, sizeof other, "loop_b.shprobe");
    unlink(other);
}

/* A file that is not ours: the message says so without quoting its bytes (was "bad magic
 * 0x746F6F72", the "root" of /etc/passwd). */
static void test_no_content_in_messages(void)
{
    char path[128];
    join(path, sizeof path, "passwd");
    FILE *f = fopen(path, "wb");
    TU_REQUIRE(f);
    fputs("root:x:0:0:root:/root:/bin/bash\n", f);
    fclose(f);
    pb_error err;
    TU_CHECK_EQ_INT(run_reader(READ_SHPROBE, path, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "not a .shprobe file");
    TU_CHECK(strstr(err.message, "746F6F72") == NULL && strstr(err.message, "746f6f72") == NULL);
    TU_CHECK(strstr(err.message, "root") == NULL);
    TU_CHECK_EQ_INT(run_reader(READ_HEADER, path, &err), PB_ERROR_FORMAT);
    TU_CHECK(strstr(err.message, "746F6F72") == NULL && strstr(err.message, "root") == NULL);
    TU_CHECK_EQ_INT(run_reader(READ_IMAGE, path, &err), PB_ERROR_FORMAT);
    TU_CHECK(strstr(err.message, "root") == NULL);
    unlink(path);
}

/* Image headers beyond the documented limits are refused before any pixel is allocated or read: a
 * 16-byte PFM header that claims 65536 x 8193 x 3 floats (6 GiB) or 70000 pixels per side. */
static void test_image_limits(void)
{
    static const struct {
        const char *header;
        const char *needle;
    } cases[] = {
        {"PF\n65536 8193\n-1.0\n", "65536x8193 with 3 channel(s)"},
        {"Pf\n65536 8193\n-1.0\n", "65536x8193 with 1 channel(s)"}, /* 2^29 + 65536 values */
        {"PF\n70000 1\n-1.0\n", "70000x1 with 3 channel(s)"},
    };
    char path[128];
    join(path, sizeof path, "huge.pfm");
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        FILE *f = fopen(path, "wb");
        TU_REQUIRE(f);
        fputs(cases[i].header, f);
        fclose(f);
        pb_error err;
        TU_CHECK_EQ_INT(run_reader(READ_IMAGE, path, &err), PB_ERROR_TOO_LARGE);
        TU_CHECK_CONTAINS(err.message, cases[i].needle);
        TU_CHECK_CONTAINS(err.message, "the limits are 65536 pixels per side, 64 channels and 536870912 values");
    }
    /* Within the limits the same reader works (2 x 1 RGB, values read back exactly). */
    FILE *f = fopen(path, "wb");
    TU_REQUIRE(f);
    fputs("PF\n2 1\n-1.0\n", f);
    const float px[6] = {1.5f, 2.0f, -3.0f, 0.25f, 8.0f, 16.0f};
    TU_CHECK(fwrite(px, sizeof px, 1, f) == 1);
    fclose(f);
    pb_image img;
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_image_read(path, &img, &err), PB_SUCCESS);
    TU_CHECK(img.width == 2 && img.height == 1 && img.channels == 3);
    for (int k = 0; k < 6 && img.pixels; k++) TU_CHECK_NEAR(img.pixels[k], px[k], 0.0);
    pb_image_free(&img);
    /* An empty file. */
    f = fopen(path, "wb");
    fclose(f);
    TU_CHECK_EQ_INT(run_reader(READ_IMAGE, path, &err), PB_ERROR_FORMAT);
    TU_CHECK_CONTAINS(err.message, "empty file");
    unlink(path);
}

/* OpenEXR headers are walked before OpenEXR sees them (OpenEXR allocates an attribute's announced
 * size, and offset tables from the dataWindow and tiles, before reading): an attribute announcing
 * 270 MB in a tiny file (what the sky fuzzer found), sizes that disagree with their type, a 16384 x 16384 window of 1 x 1 tiles whose
 * offset table (2 GiB) cannot be in a 100-byte file, a window beyond the size limit, a deep file. */
static size_t exr_attr(unsigned char *p, const char *name, const char *type, int32_t size, const void *value,
                       size_t value_len)
{
    size_t n = 0;
    memcpy(p + n, name, strlen(name) + 1);
    n += strlen(name) + 1;
    memcpy(p + n, type, strlen(type) + 1);
    n += strlen(type) + 1;
    for (int i = 0; i < 4; i++) p[n++] = (unsigned char)((uint32_t)size >> (8 * i));
    memcpy(p + n, value, value_len);
    return n + value_len;
}

static void test_exr_header_announcements(void)
{
    const int32_t big_window[4] = {0, 0, 16383, 16383}, wide_window[4] = {0, 0, 69999, 0};
    const unsigned char tiles[9] = {1, 0, 0, 0, 1, 0, 0, 0, 0};
    static const struct {
        int kind;
        int code;
        const char *needle;
    } cases[] = {
        {0, PB_ERROR_FORMAT, "announces 270000000 bytes, past the end of the"},
        {1, PB_ERROR_FORMAT, "announces at least 268435456 chunks"},
        {2, PB_ERROR_TOO_LARGE, "70000x1"},
        {3, PB_ERROR_FORMAT, "deep image"},
        {4, PB_ERROR_FORMAT, "(type box2i, 11 bytes) is malformed: its size is not its type's size"},
        {5, PB_ERROR_FORMAT, "(type preview, 8 bytes) is malformed: its preview's size disagrees"},
        {6, PB_ERROR_FORMAT, "(type chlist, 20 bytes) is malformed: its channel list is not terminated"},
    };
    char path[128];
    join(path, sizeof path, "header.exr");
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        unsigned char buf[256] = {0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0};
        size_t n = 8;
        if (cases[i].kind == 0) n += exr_attr(buf + n, "comments", "string", 270000000, "hello", 5);
        if (cases[i].kind == 1) {
            buf[5] = 0x02; /* tiled */
            n += exr_attr(buf + n, "dataWindow", "box2i", 16, big_window, 16);
            n += exr_attr(buf + n, "tiles", "tiledesc", 9, tiles, 9);
        }
        if (cases[i].kind == 2) n += exr_attr(buf + n, "dataWindow", "box2i", 16, wide_window, 16);
        if (cases[i].kind == 3) buf[5] = 0x08; /* non-image (deep) */
        /* OpenEXR reads a box2i's 16 bytes whatever size is declared, a preview's 4 * w * h bytes,
         * a channel list up to its empty name: a disagreeing size desynchronises the walk. */
        if (cases[i].kind == 4) n += exr_attr(buf + n, "displayWindow", "box2i", 11, wide_window, 11);
        if (cases[i].kind == 5) n += exr_attr(buf + n, "preview", "preview", 8, "\0\0\1\0\0\0\1\0", 8);
        if (cases[i].kind == 6)
            n += exr_attr(buf + n, "channels", "chlist", 20, "R\0\1\0\0\0\0\0\0\0\1\0\0\0\1\0\0\0G\0", 20);
        buf[n++] = 0;
        FILE *f = fopen(path, "wb");
        TU_REQUIRE(f);
        TU_CHECK(fwrite(buf, 1, n + 16, f) == n + 16);
        fclose(f);
        pb_error err;
        TU_CHECK_EQ_INT(run_reader(READ_IMAGE, path, &err), cases[i].code);
        TU_CHECK_CONTAINS(err.message, cases[i].needle);
    }
    /* PNG: a chunk announcing 1.9 GB in a small file (the fuzzer's second finding: libpng allocates
     * the announced length first); a PNG without IEND. */
    {
        static const unsigned char png[] = {0x89, 'P',  'N', 'G', '\r', '\n', 0x1a, '\n', 0x71, 0x00,
                                            0x00, 0x0e, 't', 'E', 'X',  't',  'a',  'b',  'c',  'd'};
        FILE *f = fopen(path, "wb");
        TU_REQUIRE(f);
        TU_CHECK(fwrite(png, 1, sizeof png, f) == sizeof png);
        fclose(f);
        pb_error e;
        TU_CHECK_EQ_INT(run_reader(READ_IMAGE, path, &e), PB_ERROR_FORMAT);
        TU_CHECK_CONTAINS(e.message, "PNG chunk at offset 8 announces 1895825422 bytes, past the end of the 20-byte");
    }
    /* A real EXR (written by OpenImageIO, scan lines) still passes the walk and reads back. */
    const float px[6] = {1.5f, 2.0f, -3.0f, 0.25f, 8.0f, 16.0f};
    pb_error err = {0};
    TU_CHECK_EQ_INT(pb_image_write(path, 2, 1, 3, px, &err), PB_SUCCESS);
    pb_image img;
    TU_CHECK_EQ_INT(pb_image_read(path, &img, &err), PB_SUCCESS);
    TU_CHECK(img.width == 2 && img.height == 1 && img.channels == 3);
    for (int k = 0; k < 6 && img.pixels; k++) TU_CHECK_NEAR(img.pixels[k], px[k], 0.0);
    pb_image_free(&img);
    unlink(path);
}

/* ---- the writer never replaces what is not a .shprobe ------------------------------------------ */

static pb_shprobe *sample(void)
{
    const uint32_t dims[3] = {1, 1, 1};
    pb_shprobe *p = NULL;
    pb_error err = {0};
    if (pb_shprobe_create(1, 2, dims, false, &p, &err) != PB_SUCCESS) return NULL;
    p->grid_spacing = 1.0f;
    p->grid[0] = 0;
    p->coeffs[0] = 0.75f;
    return p;
}

static int count_temps(void)
{
    char cmd[160];
    snprintf(cmd, sizeof cmd, "ls -a '%s' | grep -c '\\.tmp\\.' > /dev/null", g_dir);
    return system(cmd) == 0; /* 1 when some temp file is left */
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

static void test_writer_refuses_foreign_destinations(void)
{
    pb_shprobe *p = sample();
    TU_REQUIRE(p != NULL);
    pb_error err;
    char path[128], target[128];
    struct stat st;

    /* A new path and an existing .shprobe: written (the second replaces the first atomically). */
    join(path, sizeof path, "ours.shprobe");
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_SUCCESS);
    p->coeffs[0] = 2.5f;
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_SUCCESS);
    pb_shprobe *back = NULL;
    TU_CHECK_EQ_INT(pb_shprobe_read(path, &back, &err), PB_SUCCESS);
    TU_CHECK(back && back->coeffs[0] == 2.5f);
    pb_shprobe_destroy(back);

    /* A regular file of another kind (the open .blend of issue 14) and an empty file: refused,
     * content untouched. */
    static const char blend[] = "BLENDER-v304 (not a probe file)";
    const char *names[] = {"scene.blend", "empty.shprobe"};
    const char *contents[] = {blend, ""};
    for (int i = 0; i < 2; i++) {
        join(path, sizeof path, names[i]);
        write_text(path, contents[i]);
        memset(&err, 0, sizeof err);
        TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_INVALID_ARGUMENT);
        TU_CHECK_CONTAINS(err.message, path);
        TU_CHECK_CONTAINS(err.message, "it exists and is not a .shprobe file");
        TU_CHECK(stat(path, &st) == 0 && (size_t)st.st_size == strlen(contents[i]));
        unlink(path);
    }

    /* Not regular files: a FIFO, a directory, a socket, and (as root) a character device node made
     * here like /dev/null (1, 3). Refused without being opened; each stays what it was. */
    join(path, sizeof path, "fifo.shprobe");
    TU_REQUIRE(mkfifo(path, 0644) == 0);
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "fifo.shprobe: it exists and is a FIFO (named pipe), not a .shprobe file");
    TU_CHECK(lstat(path, &st) == 0 && S_ISFIFO(st.st_mode));
    unlink(path);

    join(path, sizeof path, "sock.shprobe");
    int s = socket(AF_UNIX, SOCK_STREAM, 0);
    struct sockaddr_un addr = {0};
    addr.sun_family = AF_UNIX;
    TU_REQUIRE(strlen(path) < sizeof addr.sun_path);
    memcpy(addr.sun_path, path, strlen(path) + 1);
    TU_REQUIRE(s >= 0 && bind(s, (struct sockaddr *)&addr, sizeof addr) == 0);
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "is a socket, not a .shprobe file");
    TU_CHECK(lstat(path, &st) == 0 && S_ISSOCK(st.st_mode));
    close(s);
    unlink(path);

    join(path, sizeof path, "null");
    if (mknod(path, S_IFCHR | 0666, makedev(1, 3)) == 0) {
        memset(&err, 0, sizeof err);
        TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_INVALID_ARGUMENT);
        TU_CHECK_CONTAINS(err.message, "null: it exists and is a character device, not a .shprobe file");
        TU_CHECK(lstat(path, &st) == 0 && S_ISCHR(st.st_mode));
        unlink(path);
    } else {
        printf("  (mknod not permitted: %s; the character-device case runs as root only)\n", strerror(errno));
    }

    /* A symbolic link, even to one of our own files: refused (rename would replace the link). */
    join(target, sizeof target, "ours.shprobe");
    join(path, sizeof path, "link.shprobe");
    TU_REQUIRE(symlink(target, path) == 0);
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "link.shprobe: it is a symbolic link");
    TU_CHECK(lstat(path, &st) == 0 && S_ISLNK(st.st_mode));
    unlink(path);

    /* A symlink loop as the destination: refused the same way; a loop in the folder: I/O error. */
    char other[128];
    join(path, sizeof path, "wloop_a");
    join(other, sizeof other, "wloop_b");
    TU_REQUIRE(symlink(other, path) == 0 && symlink(path, other) == 0);
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(path, p, &err), PB_ERROR_INVALID_ARGUMENT);
    TU_CHECK_CONTAINS(err.message, "it is a symbolic link");
    char inside[160];
    snprintf(inside, sizeof inside, "%s/x.shprobe", path);
    memset(&err, 0, sizeof err);
    TU_CHECK_EQ_INT(pb_shprobe_write(inside, p, &err), PB_ERROR_IO);
    TU_CHECK_CONTAINS(err.message, "Too many levels of symbolic links");
    unlink(path);
    unlink(other);

    TU_CHECK(!count_temps());
    join(path, sizeof path, "ours.shprobe");
    unlink(path);
    pb_shprobe_destroy(p);
}

int main(void)
{
    if (!wd_setup("schnee_hostile")) return 2;
    TU_RUN(test_readers_refuse_special_files);
    TU_RUN(test_no_content_in_messages);
    TU_RUN(test_image_limits);
    TU_RUN(test_exr_header_announcements);
    TU_RUN(test_writer_refuses_foreign_destinations);
    wd_cleanup();
    return TU_EXIT();
}
