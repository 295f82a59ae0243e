#!/usr/bin/env bash
# Builds the Blender 4.2+ extension package from the staged extension source folder with Blender's
# own tools, run in a Debian 13 chroot (Blender 4.3; scripts/blender-chroot.sh creates it when missing):
#   blender --command extension build --source-dir SRC --output-filepath OUT
#   blender --command extension validate OUT
#
#   scripts/build_extension.sh SRC_DIR OUT_ZIP      (cmake --build build --target schnee_extension)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
src="$(realpath "$1")"
out="$(realpath -m "$2")"
[ -f "$src/blender_manifest.toml" ] || { echo "build_extension: no blender_manifest.toml in $src" >&2; exit 1; }
suite="${SCHNEE_EXTENSION_SUITE:-trixie}"
root="$("$here/blender-chroot.sh" ensure "$suite")"
work="$(mktemp -d "$root/tmp/schnee-ext.XXXXXX")"
trap 'rm -rf "$work"' EXIT
inner="/tmp/$(basename "$work")"
cp -a "$src" "$work/src"
mkdir -p "$work/out"
name="$(basename "$out")"
"$here/blender-chroot.sh" run "$suite" -- blender --factory-startup --command extension build \
    --source-dir "$inner/src" --output-filepath "$inner/out/$name"
"$here/blender-chroot.sh" run "$suite" -- blender --factory-startup --command extension validate "$inner/out/$name"
mkdir -p "$(dirname "$out")"
cp "$work/out/$name" "$out.partial"
mv "$out.partial" "$out"
echo "build_extension: wrote $out"
