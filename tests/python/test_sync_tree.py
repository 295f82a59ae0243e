"""scripts/sync_tree.py, the copy of the checkout into each dev chroot's build folder
(scripts/build-chroot.sh): DEST ends up holding exactly the listed files, a file whose bytes and mode
already match keeps its copy and mtime (so Ninja rebuilds nothing for it, whatever mtime a fresh
clone gave the checkout), and a changed file gets the copy time as its mtime even when the checkout's
mtime is older than the build. Runtime < 1 s."""
import os
import subprocess
import sys
import time

from conftest import REPO

SCRIPT = REPO / "scripts" / "sync_tree.py"


def _sync(src, dest, names):
    proc = subprocess.run([sys.executable, str(SCRIPT), str(dest)], input="\0".join(names).encode() + b"\0",
                          cwd=src, capture_output=True, timeout=60)
    assert proc.returncode == 0, proc.stderr.decode()
    return proc.stderr.decode()


def test_sync_keeps_unchanged_copies_and_renews_changed_ones(tmp_path):
    src, dest = tmp_path / "src", tmp_path / "dest"
    (src / "a" / "b").mkdir(parents=True)
    (src / "same.c").write_text("int same;\n")
    (src / "a" / "b" / "changed.c").write_text("int v2;\n")
    (src / "tool.sh").write_text("#!/bin/sh\n")
    os.chmod(src / "tool.sh", 0o755)
    (src / "new.h").write_text("#define NEW 1\n")
    (dest / "a" / "b").mkdir(parents=True)
    (dest / "gone" / "deep").mkdir(parents=True)
    (dest / "same.c").write_text("int same;\n")
    (dest / "a" / "b" / "changed.c").write_text("int v1;\n")
    (dest / "tool.sh").write_text("#!/bin/sh\n")          # same bytes, other mode
    (dest / "gone" / "deep" / "stale.o").write_text("x")
    old = time.time() - 10 * 86400
    for p in ("same.c", "a/b/changed.c", "tool.sh"):
        os.utime(dest / p, (old, old))
    ancient = time.time() - 1000 * 86400                     # a checkout older than the build
    os.utime(src / "a" / "b" / "changed.c", (ancient, ancient))
    before = time.time()
    log = _sync(src, dest, ["same.c", "a/b/changed.c", "tool.sh", "new.h"])
    assert "4 files, 3 copied, 1 removed" in log
    assert os.stat(dest / "same.c").st_mtime == old                      # kept: no rebuild
    assert (dest / "a" / "b" / "changed.c").read_text() == "int v2;\n"
    assert os.stat(dest / "a" / "b" / "changed.c").st_mtime >= before - 1   # newer than any build output
    assert os.stat(dest / "tool.sh").st_mode & 0o777 == 0o755
    assert (dest / "new.h").read_text() == "#define NEW 1\n"
    assert not (dest / "gone").exists()
    assert sorted(str(p.relative_to(dest)) for p in dest.rglob("*") if p.is_file()) == [
        "a/b/changed.c", "new.h", "same.c", "tool.sh"]
    assert "4 files, 0 copied, 0 removed" in _sync(src, dest, ["same.c", "a/b/changed.c", "tool.sh", "new.h"])
