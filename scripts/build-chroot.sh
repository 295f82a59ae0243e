#!/usr/bin/env bash
# Builds this checkout from source inside a Debian dev chroot (scripts/blender-chroot.sh, SUITE-dev:
# the build dependencies from that release, nothing else) and runs the native C tests there: proof
# that the tree builds against that release's Embree, OpenImageIO, compiler and CMake.
#
#   scripts/build-chroot.sh SUITE        SUITE: trixie (Debian 13) or sid (Debian unstable)
#
# The tracked and untracked-but-not-ignored files of the checkout are synced to
# /tmp/schnee-build/src inside the chroot (scripts/sync_tree.py: only files whose bytes or mode
# differ are copied, so a fresh clone or worktree of the same code leaves every mtime as it was);
# the build tree /tmp/schnee-build/build stays there between runs, so a rerun only rebuilds what
# changed (SCHNEE_BUILD_CHROOT_CLEAN=1: from scratch).
# Configured with -DSCHNEE_WERROR=ON, built with Ninja, then `ctest -L native`, then the Python
# module is imported with the chroot's python3 and bakes a placement (pb_embree_dyn.c opening the
# release's Embree). Prints the versions built against. Needs root (chroot).
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -eq 1 ] || {
    echo "usage: $0 trixie|sid" >&2
    exit 2
}
suite="$1"
dir="$(scripts/blender-chroot.sh ensure "$suite-dev")"
work="$dir/tmp/schnee-build"
mkdir -p "$work"
# One build per chroot at a time (the copy and the build tree are shared by every run).
exec 8>"$work.lock"
flock 8
if [ "${SCHNEE_BUILD_CHROOT_CLEAN:-0}" = 1 ]; then rm -rf "$work/build"; fi
rm -rf "$work/src.new" # (a copy of the whole tree before scripts/sync_tree.py)
mkdir -p "$work/src"
git ls-files -z -co --exclude-standard | while IFS= read -r -d '' f; do
    case "$f" in node_modules | node_modules/*) continue ;; esac
    if [ -f "$f" ]; then printf '%s\0' "$f"; fi
done | python3 scripts/sync_tree.py "$work/src"

jobs="${SCHNEE_BUILD_JOBS:-$(nproc)}"
# shellcheck disable=SC2016  # expanded inside the chroot
scripts/blender-chroot.sh run "$suite-dev" -- /bin/sh -ec '
    cd /tmp/schnee-build
    echo "build-chroot: $(. /etc/os-release; echo "$PRETTY_NAME"):" $(dpkg-query -W -f "\${Package} \${Version}  " \
        gcc cmake libembree-dev libopenimageio-dev python3-dev)
    cmake -S src -B build -G Ninja -DSCHNEE_WERROR=ON
    cmake --build build -j "$1"
    ctest --test-dir build -L native --output-on-failure -j "$1"
    python3 src/tests/build_versions/module_check.py src/addon/schnee_probes
' sh "$jobs"
