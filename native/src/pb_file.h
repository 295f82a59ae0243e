/* Internal (not installed): opening input files safely, shared by the .shprobe reader/writer and the
 * OpenImageIO reader. Documented in docs/shprobe-format.md ("Opening files"). */
#ifndef SCHNEE_PB_FILE_H
#define SCHNEE_PB_FILE_H

#include "schnee/pb_common.h"

#include <sys/types.h>

#ifdef __cplusplus
extern "C" {
#endif

/* English name of a file type from st_mode ("directory", "FIFO (named pipe)", "character device", ...). */
const char *pb_file_kind_(mode_t mode);

/* Opens an existing regular file for reading without ever blocking or touching anything else:
 * stat() first, so a directory, FIFO, device or socket is refused before it is opened; then
 * open(O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY) and fstat() again (the file may have been
 * replaced in between: it must still be a regular file). Symbolic links are followed; a loop fails
 * with a message that says so. `what` names the expected content for messages ("a .shprobe file").
 * Messages start with the path. On success *fd is open (blocking mode restored) and *size is its size. */
pb_result pb_open_regular_(const char *path, const char *what, int *fd, uint64_t *size, pb_error *err);

/* Reads up to n bytes (fewer only at end of file); EINTR is retried. */
pb_result pb_read_full_(int fd, const char *path, void *buf, size_t n, size_t *got, pb_error *err);

/* Writes `size` bytes to `path` atomically: a temporary file next to it (mkstemp), written, mode 0644,
 * fsync'ed and closed, then `recheck(path)` (NULL: none; the .shprobe writer checks that nothing but
 * a .shprobe file appeared there meanwhile) just before the rename onto `path`, and a best-effort
 * fsync of the folder. The temporary file is removed on any failure. Messages start with the path. */
pb_result pb_write_atomic_(const char *path, const void *data, size_t size,
                           pb_result (*recheck)(const char *path, pb_error *err), pb_error *err);

/* strerror_r of `e` into buf ("errno N" when it has no text for it). */
void pb_describe_errno_(int e, char *buf, size_t n);

/* "nan", "inf", "-inf" or the value with %g (never "-nan"): for messages about non-finite data. */
const char *pb_format_double_(double v, char *buf, size_t n);

#ifdef __cplusplus
}
#endif
#endif
