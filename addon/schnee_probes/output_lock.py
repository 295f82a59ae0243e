"""One bake at a time per output: an exclusive lock beside the bake's journal.

Two bakes of the same output (two terminals, a bake in the UI and one headless, a farm task started
twice) would append to one journal, move it aside under each other and replace each other's files;
started within a second, the second one died with a traceback when both created the journal
(issue 31). A volume bake takes this lock before placement and keeps it until it has written its
files or given up, so the second one refuses before it changes anything, naming the first.

The lock is ``flock`` on ``<journal>.lock``, a small file holding ``<pid> <host>`` of its holder.
The kernel releases it when the holder ends, however it ends (``kill -9`` included), so a lock is
never stale: a file left by a killed bake is taken over by the next one. The holder removes the
file when it is done. Linux NFS clients implement ``flock`` with byte-range locks, so farm nodes
sharing the output folder see each other's locks. Plain Python (no Blender).
"""
from __future__ import annotations

import fcntl
import os
import socket
import stat
import time
from typing import List, Optional

from .file_names import sibling
from .safe_open import file_kind

LOCK_SUFFIX = ".lock"
# How long a second bake waits for the first one to write its process id after taking the lock
# (the two steps are not one; the write follows at once).
_HOLDER_WAIT_S = 2.0


class OutputBusy(Exception):
    """The lock is held by another bake: ``pid`` and ``host`` as it wrote them (None if unknown)."""

    def __init__(self, path: str, pid: Optional[int], host: Optional[str]):
        self.path, self.pid, self.host = path, pid, host
        super().__init__(f"{path} is held by pid {pid} on {host}")

    def holder_text(self) -> str:
        """'pid 1234', 'pid 1234 on node7' (another host) or 'process unknown'."""
        if self.pid is None:
            return "process unknown"
        here = socket.gethostname()
        return f"pid {self.pid}" + (f" on {self.host}" if self.host and self.host != here else "")


def lock_path(journal_path: str) -> str:
    return sibling(journal_path, LOCK_SUFFIX)


class OutputLock:
    """``OutputLock(journal_path).acquire()`` takes the lock or raises :class:`OutputBusy` (another
    bake holds it) or OSError (the folder cannot be written; the message names the path);
    :meth:`release` (idempotent) removes the file and frees it. Folders created for the lock file
    are removed again by :meth:`release` while they are empty (a refused bake leaves nothing); a
    folder that another bake's files keep is left to that bake."""

    def __init__(self, journal_path: str):
        self.path = lock_path(journal_path)
        self._fd = -1
        self._created: List[str] = []

    @property
    def held(self) -> bool:
        return self._fd >= 0

    def acquire(self) -> None:
        if self._fd >= 0:
            return
        self._make_folder(os.path.dirname(self.path))
        try:
            self._fd = self._lock()
        except BaseException:
            self._remove_folders()
            raise

    def _lock(self) -> int:
        deadline = time.monotonic() + _HOLDER_WAIT_S
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW | os.O_NONBLOCK, 0o644)
            except FileNotFoundError:  # the bake that made the folder removed it (empty) meanwhile
                self._make_folder(os.path.dirname(self.path))
                continue
            try:
                st = os.fstat(fd)
                if not stat.S_ISREG(st.st_mode):
                    raise OSError(f"{self.path} exists and is a {file_kind(st.st_mode)}, not the bake's lock file; "
                                  "move it away")
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    pid, host = _holder(fd)
                    if pid is None and time.monotonic() < deadline:
                        os.close(fd)
                        time.sleep(0.02)  # the holder has the lock but has not written its id yet
                        continue
                    raise OutputBusy(self.path, pid, host) from None
                # The previous holder may have removed the file between our open and our lock: then
                # this lock is on a file nobody else sees. Only the file at the path counts.
                try:
                    now = os.stat(self.path, follow_symlinks=False)
                except FileNotFoundError:
                    now = None
                if now is None or (now.st_dev, now.st_ino) != (st.st_dev, st.st_ino):
                    os.close(fd)
                    continue
                os.ftruncate(fd, 0)
                os.pwrite(fd, f"{os.getpid()} {socket.gethostname()}\n".encode(), 0)
                return fd
            except BaseException:
                os.close(fd)
                raise

    def release(self) -> None:
        if self._fd < 0:
            return
        fd, self._fd = self._fd, -1
        try:
            st = os.fstat(fd)
            now = os.stat(self.path, follow_symlinks=False)
            if (now.st_dev, now.st_ino) == (st.st_dev, st.st_ino):
                os.unlink(self.path)  # while still locked: a waiting opener of this file retries
        except OSError:
            pass
        finally:
            os.close(fd)
            self._remove_folders()

    def _make_folder(self, folder: str) -> None:
        missing = []
        while folder and not os.path.isdir(folder):
            missing.append(folder)
            parent = os.path.dirname(folder)
            if parent == folder:
                break
            folder = parent
        for d in reversed(missing):
            try:
                os.mkdir(d)
            except FileExistsError:
                continue
            self._created.append(d)

    def _remove_folders(self) -> None:
        for d in reversed(self._created):
            try:
                os.rmdir(d)  # only while empty: a bake that wrote its files keeps them
            except OSError:
                break
        self._created = []

    def __enter__(self):
        self.acquire()
        return self

    def __exit__(self, *exc):
        self.release()


def _holder(fd: int):
    """(pid, host) written in the lock file, or (None, None) while it is empty or unreadable."""
    try:
        text = os.pread(fd, 512, 0).decode("utf-8", "replace").split()
        return int(text[0]), (text[1] if len(text) > 1 else None)
    except (OSError, ValueError, IndexError):
        return None, None
