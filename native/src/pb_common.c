#define _POSIX_C_SOURCE 200809L
#include "schnee/pb_common.h"

#include "pb_file.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

const char *pb_result_string(pb_result result)
{
    switch (result) {
    case PB_SUCCESS: return "success";
    case PB_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case PB_ERROR_OUT_OF_MEMORY: return "out of memory";
    case PB_ERROR_IO: return "I/O error";
    case PB_ERROR_FORMAT: return "malformed file";
    case PB_ERROR_NON_FINITE: return "non-finite value";
    case PB_ERROR_NEGATIVE: return "negative value";
    case PB_ERROR_TOO_SMALL: return "input too small";
    case PB_ERROR_TOO_LARGE: return "input too large";
    case PB_ERROR_OPEN_MESH: return "open mesh";
    case PB_ERROR_EMBREE: return "Embree error";
    case PB_ERROR_CANCELLED: return "cancelled";
    case PB_RESULT_COUNT_: break;
    }
    return "unknown error";
}

pb_result pb_error_set(pb_error *err, pb_result code, const char *fmt, ...)
{
    if (err && err->code == PB_SUCCESS && code != PB_SUCCESS) {
        va_list ap;
        va_start(ap, fmt);
        err->code = code;
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return code;
}

/* ---- files (pb_file.h) ------------------------------------------------------------------------ */

const char *pb_file_kind_(mode_t mode)
{
    if (S_ISREG(mode)) return "regular file";
    if (S_ISDIR(mode)) return "directory";
    if (S_ISFIFO(mode)) return "FIFO (named pipe)";
    if (S_ISCHR(mode)) return "character device";
    if (S_ISBLK(mode)) return "block device";
    if (S_ISSOCK(mode)) return "socket";
    if (S_ISLNK(mode)) return "symbolic link";
    return "special file";
}

void pb_describe_errno_(int e, char *buf, size_t n)
{
    if (strerror_r(e, buf, n) != 0) snprintf(buf, n, "errno %d", e);
}

static pb_result open_failed(const char *path, const char *step, int e, pb_error *err)
{
    char why[128];
    pb_describe_errno_(e, why, sizeof why);
    return pb_error_set(err, PB_ERROR_IO, "%s: cannot %s: %s%s", path, step, why,
                        e == ELOOP ? " (a symbolic link loop, or too many links in the path)" : "");
}

static pb_result not_regular(const char *path, mode_t mode, const char *what, pb_error *err)
{
    return pb_error_set(err, PB_ERROR_IO, "%s: not a regular file (a %s); only regular files are read as %s", path,
                        pb_file_kind_(mode), what);
}

pb_result pb_open_regular_(const char *path, const char *what, int *fd_out, uint64_t *size_out, pb_error *err)
{
    *fd_out = -1;
    *size_out = 0;
    struct stat st;
    if (stat(path, &st) != 0) return open_failed(path, "open", errno, err);
    if (!S_ISREG(st.st_mode)) return not_regular(path, st.st_mode, what, err);
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
    if (fd < 0) return open_failed(path, "open", errno, err);
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return open_failed(path, "stat", e, err);
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return not_regular(path, st.st_mode, what, err);
    }
    int flags = fcntl(fd, F_GETFL);
    if (flags >= 0) (void)fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
    *fd_out = fd;
    *size_out = st.st_size > 0 ? (uint64_t)st.st_size : 0u;
    return PB_SUCCESS;
}

pb_result pb_read_full_(int fd, const char *path, void *buf, size_t n, size_t *got, pb_error *err)
{
    size_t done = 0;
    while (done < n) {
        ssize_t k = read(fd, (char *)buf + done, n - done);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0) {
            int e = errno;
            *got = done;
            return open_failed(path, "read", e, err);
        }
        if (k == 0) break;
        done += (size_t)k;
    }
    *got = done;
    return PB_SUCCESS;
}

const char *pb_format_double_(double v, char *buf, size_t n)
{
    if (isnan(v)) return "nan";
    if (isinf(v)) return v > 0 ? "inf" : "-inf";
    snprintf(buf, n, "%g", v);
    return buf;
}

pb_result pb_write_atomic_(const char *path, const void *data, size_t size,
                           pb_result (*recheck)(const char *path, pb_error *err), pb_error *err)
{
    static const char suffix[] = ".tmp.XXXXXX";
    size_t n = strlen(path);
    char *tmp = malloc(n + sizeof suffix);
    if (!tmp) return pb_error_set(err, PB_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    memcpy(tmp, path, n);
    memcpy(tmp + n, suffix, sizeof suffix);

    char why[128];
    const char *step = "create a temporary file";
    int fd = mkstemp(tmp);
    if (fd < 0) goto fail;
    step = "write";
    for (size_t done = 0; done < size;) {
        ssize_t k = write(fd, (const uint8_t *)data + done, size - done);
        if (k < 0 && errno == EINTR) continue;
        if (k < 0) goto fail;
        done += (size_t)k;
    }
    step = "set permissions of";
    if (fchmod(fd, 0644) != 0) goto fail;
    step = "fsync";
    if (fsync(fd) != 0) goto fail;
    step = "close";
    {
        int c = close(fd);
        fd = -1;
        if (c != 0) goto fail;
    }
    /* Checked again just before the rename: something may have appeared there while writing. */
    if (recheck) {
        pb_result again = recheck(path, err);
        if (again != PB_SUCCESS) {
            unlink(tmp);
            free(tmp);
            return again;
        }
    }
    step = "rename the temporary file onto";
    if (rename(tmp, path) != 0) goto fail;
    free(tmp);

    /* Make the rename durable too (best effort: some filesystems refuse fsync on directories). */
    {
        const char *slash = strrchr(path, '/');
        char *dir = slash ? strndup(path, slash == path ? 1u : (size_t)(slash - path)) : strdup(".");
        if (dir) {
            int dfd = open(dir, O_RDONLY);
            if (dfd >= 0) {
                (void)fsync(dfd);
                close(dfd);
            }
            free(dir);
        }
    }
    return PB_SUCCESS;

fail:
    pb_describe_errno_(errno, why, sizeof why);
    if (fd >= 0) close(fd);
    if (strcmp(step, "create a temporary file") != 0) unlink(tmp);
    pb_error_set(err, PB_ERROR_IO, "%s: cannot %s %s: %s", path, step,
                 strcmp(step, "create a temporary file") == 0 ? "next to it" : "it", why);
    free(tmp);
    return PB_ERROR_IO;
}
