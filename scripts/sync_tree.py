#!/usr/bin/env python3
"""Make DEST hold exactly the files named on standard input (NUL-separated paths relative to the
current directory), touching only what differs, so that a build tree made from DEST rebuilds only
what changed.

    git ls-files -z -co --exclude-standard | scripts/sync_tree.py DEST

A file whose bytes and mode already equal DEST's copy keeps that copy and its mtime. A fresh clone
or worktree gives every file a new mtime, so copying the whole tree made Ninja rebuild everything.
A new or changed file is copied with its mode and the time of the copy as its mtime, so it is newer
than every output of the build, whatever mtime the checkout gave it.
Files and empty folders of DEST that are not on the list are removed. Used by
scripts/build-chroot.sh for the build tree kept in each dev chroot.
"""
import os
import shutil
import stat
import sys


def same(src: str, dst: str) -> bool:
    try:
        a, b = os.stat(src), os.lstat(dst)
    except FileNotFoundError:
        return False
    if not stat.S_ISREG(b.st_mode) or a.st_size != b.st_size or stat.S_IMODE(a.st_mode) != stat.S_IMODE(b.st_mode):
        return False
    with open(src, "rb") as fa, open(dst, "rb") as fb:
        while True:
            x, y = fa.read(1 << 20), fb.read(1 << 20)
            if x != y:
                return False
            if not x:
                return True


def main() -> int:
    if len(sys.argv) != 2:
        print("usage: sync_tree.py DEST < NUL-separated paths", file=sys.stderr)
        return 2
    dest = sys.argv[1]
    names = [n for n in sys.stdin.buffer.read().decode("utf-8", "surrogateescape").split("\0") if n]
    keep, copied = set(), 0
    for name in names:
        keep.add(os.path.normpath(name))
        target = os.path.join(dest, name)
        if same(name, target):
            continue
        os.makedirs(os.path.dirname(target) or ".", exist_ok=True)
        if os.path.lexists(target) and not os.path.isfile(target):
            shutil.rmtree(target) if os.path.isdir(target) else os.remove(target)
        tmp = target + ".sync-tmp"
        shutil.copy(name, tmp)   # bytes and mode; the mtime is now's
        os.replace(tmp, target)
        copied += 1
    removed = 0
    for root, dirs, files in os.walk(dest, topdown=False):
        for f in files:
            path = os.path.join(root, f)
            if os.path.normpath(os.path.relpath(path, dest)) not in keep:
                os.remove(path)
                removed += 1
        for d in dirs:
            path = os.path.join(root, d)
            if not os.listdir(path):
                os.rmdir(path)
    print(f"sync_tree: {len(names)} files, {copied} copied, {removed} removed", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
