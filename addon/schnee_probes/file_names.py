"""Names of the files a bake keeps beside its output, within the file system's limit on one name.

A bake writes more than its output: the journal ``<output>.journal``, a shard's
``<output>.shard-K-of-N.journal``, a moved-aside ``<journal>.previous``, the lock
``<journal>.lock``, the farm's ``<output>.farm`` folder and temporary ``… .partial`` files renamed
into place. Linux file systems allow 255 bytes per name (NAME_MAX), so an output name that is itself
legal (240 characters) made the journal's temporary name too long, and the bake failed after its
first render (issue 31).

:func:`sibling` keeps each derived name as it always was when it fits. Beyond 255 bytes it replaces
the end of the output's name by ``~`` and 16 hex digits of the name's SHA-256: the same in every run
and on every farm node (a resumed bake, a requeued shard and the merge find the same files), still
distinct per output, and still in the output's folder (renames and links stay atomic there). Plain
Python (no Blender).
"""
from __future__ import annotations

import hashlib
import os

NAME_MAX = 255          # bytes per name: ext4, XFS, Btrfs, tmpfs, NFS
# Room a temporary name leaves for the temporary name of a writer it is handed to: the native
# writers write atomically themselves, to "<name>.tmp.XXXXXX" (native/src/pb_common.c, 11 bytes) or
# ".<name>.tmp-XXXXXX<ext>" (pb_image_oiio.cpp, 12 bytes + the extension).
WRITER_ROOM = 32
_DIGEST_HEX = 16        # 64 bits of SHA-256: collisions between two outputs of one folder are not a concern


def _bytes(text: str) -> int:
    return len(os.fsencode(text))


def sibling(path: str, suffix: str, limit: int = NAME_MAX) -> str:
    """``path + suffix``, or when that name (its last component) is longer than ``limit`` bytes,
    ``<start of the name>~<16 hex digits of SHA-256 of the name><suffix>`` in the same folder.
    ``suffix`` starts with ``.`` and is short (it is kept whole)."""
    folder, name = os.path.split(path)
    if _bytes(name + suffix) <= limit:
        return path + suffix
    room = limit - _bytes(suffix) - 1 - _DIGEST_HEX
    if room < 1:
        raise ValueError(f"suffix {suffix!r} leaves no room for a name")
    head = name
    while _bytes(head) > room:  # whole characters: a multi-byte UTF-8 character is never cut
        head = head[:-1]
    digest = hashlib.sha256(os.fsencode(name)).hexdigest()[:_DIGEST_HEX]
    return os.path.join(folder, f"{head}~{digest}{suffix}")


def temporary(path: str, tag: str = "") -> str:
    """A temporary name beside ``path`` for a file renamed (or linked) onto it:
    ``<path>.<tag>.partial``, shortened like :func:`sibling` to :data:`WRITER_ROOM` bytes below the
    limit (a native writer given it adds its own temporary suffix). ``tag`` defaults to
    ``<pid>-<8 random hex digits>``, unique per process and call, so two bakes writing the same folder
    never share one."""
    tag = tag or f"{os.getpid()}-{os.urandom(4).hex()}"
    return sibling(path, f".{tag}.partial", NAME_MAX - WRITER_ROOM)
