"""Opening input files the way the native readers do (native/src/pb_common.c, issue 14): without
blocking (a FIFO or a device never hangs the bake), regular files only (checked after the open, so
a swapped path cannot slip through), and bounded by a size limit before anything is read."""
from __future__ import annotations

import errno
import os
import stat

_KINDS = ((stat.S_ISDIR, "directory"), (stat.S_ISFIFO, "FIFO (named pipe)"), (stat.S_ISCHR, "character device"),
          (stat.S_ISBLK, "block device"), (stat.S_ISSOCK, "socket"), (stat.S_ISLNK, "symbolic link"))


class RefusedFile(OSError):
    """The path cannot be read as asked: ``code`` is "I/O error" or "input too large"; the message
    starts with the path and never quotes the file's content."""

    def __init__(self, message: str, code: str):
        super().__init__(message)
        self.code = code


def file_kind(mode: int) -> str:
    """'directory', 'FIFO (named pipe)', ... for a st_mode that is not a regular file."""
    return next((name for test, name in _KINDS if test(mode)), "special file")


def open_regular(path: str, what: str, max_bytes: int):
    """(binary file object, size) of the regular file at ``path``; RefusedFile otherwise. ``what``
    names the format in the message ("an image")."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        loop = " (a symbolic link loop, or too many links in the path)" if exc.errno == errno.ELOOP else ""
        raise RefusedFile(f"{path}: cannot open: {exc.strerror}{loop}", "I/O error") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise RefusedFile(f"{path}: not a regular file (a {file_kind(st.st_mode)}); only regular files are "
                              f"read as {what}", "I/O error")
        if st.st_size > max_bytes:
            raise RefusedFile(f"{path}: the file is {st.st_size} bytes, above the limit of {max_bytes} bytes for "
                              f"{what}", "input too large")
        os.set_blocking(fd, True)  # a regular file never blocks; plain reads from here on
        return os.fdopen(fd, "rb"), st.st_size
    except BaseException:
        os.close(fd)
        raise
