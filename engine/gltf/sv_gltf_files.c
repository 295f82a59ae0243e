/* Loader: the files a glTF references (docs/gltf-loader.md "Files"): URI resolution with the
 * folder-tree rule, and opening without blocking, regular files only, bounded reads. */
#define _DEFAULT_SOURCE /* realpath, O_CLOEXEC */
#include "sv_gltf_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *kind_of(mode_t m)
{
    if (S_ISDIR(m)) return "a directory";
    if (S_ISFIFO(m)) return "a FIFO";
    if (S_ISCHR(m)) return "a character device";
    if (S_ISBLK(m)) return "a block device";
    if (S_ISSOCK(m)) return "a socket";
    return "not a regular file";
}

int sv_gltf_open_regular(const char *path, const char *what, uint64_t max_bytes, uint64_t *size, sv_gltf_error *err)
{
    ctx_ c = {.err = err};
    if (size) *size = 0;
    if (!path || !what) {
        svg_fail(&c, SV_GLTF_ERROR_INVALID_ARGUMENT, "sv_gltf_open_regular: NULL argument");
        return -1;
    }
    /* O_NONBLOCK: opening a FIFO for reading must not wait for a writer; the type is checked on the
     * open descriptor (fstat), so nothing can be swapped in between. */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) {
        int e = errno;
        svg_fail(&c, SV_GLTF_ERROR_IO, "%s: cannot open '%s': %s", what, path,
                 e == ELOOP ? "too many levels of symbolic links (a symlink loop?)" : strerror(e));
        return -1;
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        svg_fail(&c, SV_GLTF_ERROR_IO, "%s: cannot stat '%s': %s", what, path, strerror(errno));
        close(fd);
        return -1;
    }
    if (!S_ISREG(st.st_mode)) {
        svg_fail(&c, SV_GLTF_ERROR_IO, "%s: '%s' is %s; only regular files are read", what, path, kind_of(st.st_mode));
        close(fd);
        return -1;
    }
    if (max_bytes && (uint64_t)st.st_size > max_bytes) {
        svg_fail(&c, SV_GLTF_ERROR_TOO_LARGE, "%s: '%s' has %llu bytes, over the limit of %llu", what, path,
                 (unsigned long long)st.st_size, (unsigned long long)max_bytes);
        close(fd);
        return -1;
    }
    if (size) *size = (uint64_t)st.st_size;
    return fd;
}

/* Reads exactly n bytes at the descriptor's position. */
static bool read_all(int fd, uint8_t *buf, uint64_t n)
{
    while (n) {
        size_t chunk = n > (1u << 30) ? (1u << 30) : (size_t)n;
        ssize_t r = read(fd, buf, chunk);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) return false;
        buf += r;
        n -= (uint64_t)r;
    }
    return true;
}

bool svg_read_file(ctx_ *c, const char *path, uint64_t want, const char *what, uint8_t **out, uint64_t *out_size)
{
    *out = NULL;
    uint64_t size;
    int fd = sv_gltf_open_regular(path, what, 0, &size, c->err);
    if (fd < 0) {
        c->result = c->err ? c->err->code : SV_GLTF_ERROR_IO;
        return false;
    }
    if (want && size < want) {
        close(fd);
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: file '%s' has %llu bytes, byteLength is %llu", what, path,
                 (unsigned long long)size, (unsigned long long)want);
        return false;
    }
    if (!want) {
        /* The glTF file itself: its header bounds the read. A GLB says its total length; JSON must
         * start with '{' (after whitespace) and stays under SV_GLTF_MAX_JSON_BYTES. */
        uint8_t head[12] = {0};
        uint64_t n = size < sizeof head ? size : sizeof head;
        if (!read_all(fd, head, n) || lseek(fd, 0, SEEK_SET) != 0) {
            close(fd);
            svg_fail(c, SV_GLTF_ERROR_IO, "%s: cannot read '%s'", what, path);
            return false;
        }
        uint32_t magic = (uint32_t)head[0] | (uint32_t)head[1] << 8 | (uint32_t)head[2] << 16 | (uint32_t)head[3] << 24;
        if (n >= 12 && magic == 0x46546C67u) {
            uint64_t length =
                (uint64_t)head[8] | (uint64_t)head[9] << 8 | (uint64_t)head[10] << 16 | (uint64_t)head[11] << 24;
            want = length < size ? length : size; /* parse_glb reports a header length past the end */
            if (want < 12) want = size;
        } else {
            uint64_t k = 0;
            while (k < n && (head[k] == ' ' || head[k] == '\t' || head[k] == '\r' || head[k] == '\n')) k++;
            if (k == n && n == size && size > 0) k = 0; /* only whitespace: the JSON parser says so */
            if (size && k < n && head[k] != '{') {
                close(fd);
                svg_fail(c, SV_GLTF_ERROR_FORMAT,
                         "%s: '%s' is not a glTF file (neither JSON starting with '{' nor the GLB magic)", what, path);
                return false;
            }
            if (size > SV_GLTF_MAX_JSON_BYTES) {
                close(fd);
                svg_fail(c, SV_GLTF_ERROR_TOO_LARGE, "%s: '%s' has %llu bytes, over the glTF JSON limit of %llu", what,
                         path, (unsigned long long)size, (unsigned long long)SV_GLTF_MAX_JSON_BYTES);
                return false;
            }
            want = size;
        }
    }
    size = want;
    if (!svg_take_budget(c, size, what)) {
        close(fd);
        return false;
    }
    uint8_t *buf = svg_xcalloc(c, size, 1);
    if (!buf) {
        close(fd);
        return false;
    }
    if (size && !read_all(fd, buf, size)) {
        close(fd);
        free(buf);
        svg_fail(c, SV_GLTF_ERROR_IO, "%s: cannot read '%s'", what, path);
        return false;
    }
    close(fd);
    *out = buf;
    *out_size = size;
    return true;
}

/* True when the relative path climbs above its start ("..", "a/../.."), lexically. */
static bool escapes_lexically(const char *rel)
{
    long depth = 0;
    const char *p = rel;
    while (*p) {
        const char *e = strchr(p, '/');
        size_t n = e ? (size_t)(e - p) : strlen(p);
        if (n == 2 && p[0] == '.' && p[1] == '.') {
            if (--depth < 0) return true;
        } else if (n && !(n == 1 && p[0] == '.')) {
            depth++;
        }
        p += n;
        if (*p == '/') p++;
    }
    return false;
}

/* True when real path `r` is `root` or inside it. */
static bool inside(const char *root, const char *r)
{
    size_t n = strlen(root);
    if (n == 1 && root[0] == '/') return true;
    return strncmp(r, root, n) == 0 && (r[n] == '\0' || r[n] == '/');
}

/* realpath of path, or of its folder when the file does not exist (images are resolved before they
 * are read). NULL with errno set otherwise. */
static char *real_of(const char *path)
{
    char *r = realpath(path, NULL);
    if (r || errno != ENOENT) return r;
    char *dir = svg_path_dirname(path);
    if (!dir) return NULL;
    r = realpath(dir, NULL);
    free(dir);
    return r;
}

char *svg_resolve_uri(ctx_ *c, const char *uri, const char *what, bool *literal_percent)
{
    char scheme[16];
    if (literal_percent) *literal_percent = false;
    if (svg_uri_has_scheme(uri, scheme, sizeof scheme)) {
        svg_fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: URI scheme '%s:' is not supported (only relative paths and data:)",
                 what, scheme);
        return NULL;
    }
    if (!c->g->base_dir) {
        svg_fail(c, SV_GLTF_ERROR_UNSUPPORTED, "%s: external URI '%.200s' but no base directory was given", what, uri);
        return NULL;
    }
    bool literal = false;
    char *decoded = svg_percent_decode(uri, &literal);
    if (!decoded) {
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: URI '%.200s' encodes a NUL byte (%%00)", what, uri);
        return NULL;
    }
    if (literal_percent) *literal_percent = literal;
    if (!decoded[0]) {
        free(decoded);
        svg_fail(c, SV_GLTF_ERROR_FORMAT, "%s: empty URI", what);
        return NULL;
    }
    bool allow = c->g->internal_ && c->g->internal_->allow_outside_paths;
    if (!allow && (decoded[0] == '/' || escapes_lexically(decoded))) {
        svg_fail(c, SV_GLTF_ERROR_OUTSIDE,
                 "%s: '%.300s' is %s the glTF's folder '%.200s'; refused (a trusted scene may "
                 "allow it: --allow-outside-paths)",
                 what, decoded, decoded[0] == '/' ? "an absolute path outside" : "outside", c->g->base_dir);
        free(decoded);
        return NULL;
    }
    char *path = svg_path_join(c->g->base_dir, decoded);
    free(decoded);
    if (!path) {
        svg_fail(c, SV_GLTF_ERROR_OUT_OF_MEMORY, "out of memory");
        return NULL;
    }
    if (!allow) {
        /* Symbolic links may still lead out: compare real paths when the folder exists. */
        char *root = realpath(c->g->base_dir, NULL);
        if (root) {
            char *r = real_of(path);
            int e = errno;
            bool ok = r && inside(root, r);
            if (!r && e != ENOENT) {
                svg_fail(c, SV_GLTF_ERROR_IO, "%s: cannot resolve '%.300s': %s", what, path,
                         e == ELOOP ? "too many levels of symbolic links (a symlink loop?)" : strerror(e));
            } else if (r && !ok) {
                svg_fail(c, SV_GLTF_ERROR_OUTSIDE,
                         "%s: '%.300s' leads to '%.300s', outside the glTF's folder '%.200s'; refused (a trusted scene "
                         "may allow it: --allow-outside-paths)",
                         what, path, r, root);
            }
            free(r);
            free(root);
            if (c->result != SV_GLTF_SUCCESS) {
                free(path);
                return NULL;
            }
        }
    }
    return path;
}
