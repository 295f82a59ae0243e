#!/usr/bin/env bash
# Debian chroots with a stock Blender and nothing of ours, for testing the packaged add-on against
# real Blender releases: trixie (Debian 13, Blender 4.3) and sid (Debian unstable, Blender 5.x).
# The "dev" flavour (SUITE trixie-dev, sid-dev) holds the build dependencies instead of Blender, for
# building the tree from source against newer Embree / OpenImageIO (tests/build_versions/).
#
#   scripts/blender-chroot.sh ensure SUITE          create the chroot if missing; print its path
#   scripts/blender-chroot.sh run SUITE -- CMD...   run CMD inside it (with /proc, /dev, /dev/shm)
#   scripts/blender-chroot.sh path SUITE            print its path (no creation)
#
# Chroots live outside the repository, in $SCHNEE_CHROOT_DIR (default /var/cache/schnee-chroots),
# one directory per suite, and are reused by later runs. Creation is idempotent and lock-protected
# (flock on SUITE.lock): it builds into SUITE.tmp and renames it to SUITE only when Blender runs,
# so a half-made chroot is never used. Needs root and debootstrap (scripts/deps.sh installs it).
# `run` mounts /proc and /dev in a private mount namespace (unshare -m): the mounts vanish with the
# command, nothing stays mounted on the host.
set -euo pipefail

ROOT="${SCHNEE_CHROOT_DIR:-/var/cache/schnee-chroots}"
MIRROR="${SCHNEE_DEBIAN_MIRROR:-http://deb.debian.org/debian}"
# Blender, and numpy: every blender.org build bundles numpy, Debian packages it separately (and its
# blender package does not depend on it). Mesa's GL/EGL (libgl1, libegl1, libgl1-mesa-dri: llvmpipe):
# Blender's gpu module needs a GL context for the viewport overlay's tests (docs/overlay.md), and sid's
# blender package does not pull them in. Nothing else: no Embree, OpenImageIO or dev packages.
PACKAGES=(blender python3-numpy libgl1 libegl1 libgl1-mesa-dri)
# The dev flavour: exactly the build dependencies of the C core, the engine and the Python module,
# patchelf for the add-on zip that the default build also writes (cmake/addon_zip.cmake), and
# blender-data (data only, no Blender) for the studio HDRIs the native test test_sh_hdri reads.
DEV_PACKAGES=(build-essential cmake ninja-build pkg-config libembree-dev libopenimageio-dev libqhull-dev
    libvulkan-dev glslc libcjson-dev libglfw3-dev python3-dev python3-numpy patchelf blender-data)

usage() {
    echo "usage: $0 ensure|path SUITE | run SUITE -- CMD..." >&2
    exit 2
}

[ $# -ge 2 ] || usage
action="$1"
suite="$2"
shift 2
case "$suite" in
trixie | sid | forky) flavour=blender ;;
trixie-dev | sid-dev | forky-dev)
    flavour=dev
    PACKAGES=("${DEV_PACKAGES[@]}")
    ;;
*)
    echo "blender-chroot: unsupported suite '$suite' (trixie, sid, forky, each also as SUITE-dev)" >&2
    exit 2
    ;;
esac
PACKAGE_LIST="${PACKAGES[*]}"
# Written last, when the chroot works: Blender's version line, or the dev flavour's package versions.
MARK=.schnee-blender-version
[ "$flavour" = dev ] && MARK=.schnee-dev-versions
dist="${suite%-dev}"
dir="$ROOT/$suite"

# Runs CMD inside chroot directory $1 with /proc, /dev and a private /dev/shm (TBB, Python use it).
in_chroot() {
    local d="$1"
    shift
    # shellcheck disable=SC2016  # the inner script expands its own positional parameters
    unshare --mount --propagation private -- /bin/sh -c '
        d="$1"; shift
        mount -t proc proc "$d/proc"
        mount --bind /dev "$d/dev"
        mount -t devpts -o newinstance,ptmxmode=0666 devpts "$d/dev/pts" 2>/dev/null || true
        mkdir -p "$d/dev/shm" && mount -t tmpfs -o size=1g tmpfs "$d/dev/shm"
        exec chroot "$d" /usr/bin/env -i HOME=/root LANG=C.UTF-8 \
            PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin "$@"
    ' sh "$d" "$@"
}

# The dev flavour's ready marker: the versions the build tests report (docs/install.md quotes them).
dev_versions() {
    # shellcheck disable=SC2016  # dpkg-query's own ${...} fields
    in_chroot "$1" dpkg-query -W -f '${Package} ${Version}\n' cmake libembree-dev libopenimageio-dev gcc g++ \
        python3-dev >"$1/.schnee-dev-versions.new"
    mv "$1/.schnee-dev-versions.new" "$1/.schnee-dev-versions"
}

create() {
    local tmp="$dir.tmp"
    rm -rf "$tmp"
    echo "blender-chroot: debootstrap $dist into $tmp" >&2
    debootstrap --variant=minbase "$dist" "$tmp" "$MIRROR" >&2
    # sid's Release files can be past Valid-Until on a stale mirror snapshot; the check adds nothing here.
    echo 'Acquire::Check-Valid-Until "false";' >"$tmp/etc/apt/apt.conf.d/99schnee-no-valid-until"
    echo 'APT::Install-Recommends "false";' >"$tmp/etc/apt/apt.conf.d/99schnee-no-recommends"
    in_chroot "$tmp" apt-get -q update >&2
    in_chroot "$tmp" /usr/bin/env DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${PACKAGES[@]}" >&2
    echo "$PACKAGE_LIST" >"$tmp/.schnee-packages"
    in_chroot "$tmp" apt-get clean >&2
    if [ "$flavour" = dev ]; then
        in_chroot "$tmp" cc --version >/dev/null
        dev_versions "$tmp"
        mv "$tmp" "$dir"
        echo "blender-chroot: $suite ready: $(tr '\n' ' ' <"$dir/$MARK")" >&2
        return
    fi
    local probe
    probe="$(in_chroot "$tmp" blender -b --factory-startup --python-expr \
        'import bpy, sys; print("BLENDER_OK", bpy.app.version_string, sys.version.split()[0])' 2>&1)"
    case "$probe" in
    *BLENDER_OK*) ;;
    *)
        echo "blender-chroot: Blender does not run in $tmp:" >&2
        echo "$probe" | tail -20 >&2
        exit 1
        ;;
    esac
    in_chroot "$tmp" blender --version | head -1 >"$tmp/.schnee-blender-version"
    mv "$tmp" "$dir"
    echo "blender-chroot: $suite ready: $(cat "$dir/.schnee-blender-version")" >&2
}

ensure() {
    if [ -f "$dir/$MARK" ] && [ "$(cat "$dir/.schnee-packages" 2>/dev/null)" = "$PACKAGE_LIST" ]; then
        return
    fi
    mkdir -p "$ROOT"
    exec 9>"$ROOT/$suite.lock"
    flock 9
    if [ ! -f "$dir/$MARK" ]; then
        if [ "$(id -u)" != 0 ]; then
            echo "blender-chroot: creating a chroot needs root" >&2
            exit 1
        fi
        command -v debootstrap >/dev/null || {
            echo "blender-chroot: debootstrap missing (scripts/deps.sh installs it)" >&2
            exit 1
        }
        create
    elif [ "$(cat "$dir/.schnee-packages" 2>/dev/null)" != "$PACKAGE_LIST" ]; then
        # A chroot made by an earlier version of this script: add what the list gained.
        in_chroot "$dir" apt-get -q update >&2
        in_chroot "$dir" /usr/bin/env DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${PACKAGES[@]}" >&2
        in_chroot "$dir" apt-get clean >&2
        if [ "$flavour" = dev ]; then dev_versions "$dir"; fi
        echo "$PACKAGE_LIST" >"$dir/.schnee-packages"
    fi
    flock -u 9
}

case "$action" in
path) echo "$dir" ;;
ensure)
    ensure
    echo "$dir"
    ;;
run)
    [ "${1:-}" = "--" ] && shift
    [ $# -ge 1 ] || usage
    ensure
    in_chroot "$dir" "$@"
    ;;
*) usage ;;
esac
