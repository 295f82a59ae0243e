#!/bin/bash
# The engine's frame time on a lent GPU machine (bench/results/engine_gpu.md). Runs THERE, from the repo
# root, over what bench/device/prep_engine_gpu.py put into DIR (default .devgpu, carried with the call),
# after the Vulkan loader's packages in .gl (/work/.library/device/README.md) are unpacked:
#   for f in .gl/*.deb; do dpkg -x $f /; done; ldconfig; bash bench/device/engine_gpu.sh
# Writes $OUT/engine_gpu.log (every run's timing lines, tagged) and $OUT/frame.pfm (the frame that
# prep_engine_gpu.py compare checks against lavapipe's).
set -u
DIR=${1:-.devgpu}
OUT=${OUT:-/tmp/engine_gpu_out}
FRAMES=${FRAMES:-60}
ROUNDS=${ROUNDS:-2}
mkdir -p "$OUT"
LOG=$OUT/engine_gpu.log
# prep_engine_gpu.py packs the libraries (lib.tar.xz: the tree and DIR must travel within 64 MiB).
[ -d "$DIR/lib" ] || tar xJf "$DIR/lib.tar.xz" -C "$DIR"
export LD_LIBRARY_PATH=$PWD/$DIR/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
for f in /usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json /usr/share/vulkan/icd.d/nvidia_icd.json \
         /etc/vulkan/icd.d/nvidia_icd.json; do
    if [ -f "$f" ]; then export VK_DRIVER_FILES=$f VK_ICD_FILENAMES=$f; break; fi
done
VIEW=$DIR/bin/schnee-view-noimage
S=$DIR/scenes
{
    echo "# $(date -u +%FT%TZ) $(uname -r); ICD ${VK_DRIVER_FILES:-none found}"
    nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,memory.total --format=csv,noheader 2>&1
    nproc
} >"$LOG"

run() { # tag scene args...
    local tag=$1 scene=$2
    shift 2
    local err
    err=$("$VIEW" "$scene" --headless --output "$OUT/t.pfm" --frames "$FRAMES" "$@" 2>&1 >/dev/null)
    local rc=$?
    echo "$err" | grep -E "device |frame\(s\) at|GPU time|probe brick|warning|error" | sed "s|^|$tag rc=$rc: |" >>"$LOG"
}

HD="--width 1920 --height 1080"
# bin/schnee-view-noimage.old, when there (prep_engine_gpu.py prep --old BINARY), runs the scene-pass
# configurations too, interleaved with the current build on the same machine.
BINS="$VIEW"
[ -x "$VIEW.old" ] && BINS="$VIEW.old $VIEW"
# SET=bricks: issue 30's table (bench_engine_v3.py --bricks-table's four configurations, --no-direct) on the
# generated room's v1 grid, its v3 octree and the bundled room (scenes/bundled/scene.gltf), plus the raster
# floor as --debug normals, the brick lookup's parts as --debug brick-level / brick-validity; then the
# bundled room per pixel (bricks) at FRAME_ARGS for the comparison.
if [ "${SET:-shader}" = bricks ]; then
    for r in $(seq "$ROUNDS"); do
        for b in $BINS; do
            VIEW=$b
            v=new
            [ "${b%.old}" != "$b" ] && v=old
            for sc in room room_v3 bundled/scene; do
                # The bundled room's sky is an EXR, which the viewer without OpenImageIO cannot read.
                nosky=
                [ "$sc" = bundled/scene ] && nosky=--no-sky
                for cfg in "object buffers" "pixel bricks" "pixel buffers" "off buffers"; do
                    set -- $cfg
                    run "r$r $v $sc $1-$2" "$S/$sc.gltf" $HD --no-direct $nosky --probe-mode "$1" --probe-path "$2"
                done
                run "r$r $v $sc debug-normals" "$S/$sc.gltf" $HD --no-direct $nosky --debug normals
                # The brick lookup's parts: the indirection alone (brick-level), + the sample's D (brick-validity).
                for dbg in brick-level brick-validity; do
                    run "r$r $v $sc debug-$dbg" "$S/$sc.gltf" $HD --no-direct $nosky --probe-path bricks --debug $dbg
                done
            done
        done
    done
    VIEW=$DIR/bin/schnee-view-noimage
    "$VIEW" "$S/bundled/scene.gltf" --headless --output "$OUT/frame_bundled.pfm" --width 640 --height 360 \
        --probe-mode pixel --probe-path bricks --no-sky >>"$LOG" 2>&1
    rm -f "$OUT/t.pfm"
    cat "$LOG"
    exit 0
fi
# SET=pass: the per-pixel probe pass (docs/engine.md "The per-pixel probe pass"): per object, per pixel from the
# bricks in the compute pass and in the fragment shader, per pixel from the buffers in the compute pass, off,
# and the raster floor, on the three scenes of SET=bricks, current build only; the probe pass's own time is
# the GPU line's "after the objects' raster" figure.
if [ "${SET:-shader}" = pass ]; then
    for r in $(seq "$ROUNDS"); do
        for sc in room room_v3 bundled/scene; do
            nosky=
            [ "$sc" = bundled/scene ] && nosky=--no-sky
            for cfg in "object buffers compute" "pixel bricks compute" "pixel bricks fragment" \
                       "pixel buffers compute" "off buffers compute"; do
                set -- $cfg
                run "r$r $sc $1-$2-$3" "$S/$sc.gltf" $HD --no-direct $nosky --probe-mode "$1" --probe-path "$2" \
                    --probe-pass "$3"
            done
            run "r$r $sc debug-normals" "$S/$sc.gltf" $HD --no-direct $nosky --debug normals
        done
    done
    "$VIEW" "$S/bundled/scene.gltf" --headless --output "$OUT/frame_bundled.pfm" --width 640 --height 360 \
        --probe-mode pixel --probe-path bricks --no-sky >>"$LOG" 2>&1
    rm -f "$OUT/t.pfm"
    cat "$LOG"
    exit 0
fi
# SET=repr: the probe representations instead (bench_engine_representations.py's configurations on the
# v1 grid room, --no-direct), current build only.
if [ "${SET:-shader}" = repr ]; then
    for r in $(seq "$ROUNDS"); do
        for m in object pixel; do
            for st in float half; do
                for rep in sh ambientCube; do
                    run "r$r new $m-$rep-$st" "$S/room.gltf" $HD --probe-mode $m --probe-representation $rep \
                        --probe-storage $st --no-direct --shadow-res 0
                done
            done
        done
    done
    cat "$LOG"
    exit 0
fi
for r in $(seq "$ROUNDS"); do
    for b in $BINS; do
        VIEW=$b
        v=new
        [ "${b%.old}" != "$b" ] && v=old
        run "r$r $v grid-object" "$S/room.gltf" $HD --probe-mode object --shadow-res 0
        run "r$r $v grid-pixel" "$S/room.gltf" $HD --probe-mode pixel --shadow-res 0
        run "r$r $v octree-object" "$S/room_v3.gltf" $HD --probe-mode object --shadow-res 0
        run "r$r $v octree-pixel" "$S/room_v3.gltf" $HD --probe-mode pixel --shadow-res 0
    done
    VIEW=$DIR/bin/schnee-view-noimage
    run "r$r new debug-normals" "$S/room_v3.gltf" $HD --debug normals --shadow-res 0
    run "r$r new octree-pixel-lamp" "$S/room_v3.gltf" $HD --probe-mode pixel
    run "r$r new octree-pixel-lamp-sun-c1" "$S/room_v3_sun.gltf" $HD --probe-mode pixel --shadow-cascades 1
    run "r$r new octree-pixel-lamp-sun-c4" "$S/room_v3_sun.gltf" $HD --probe-mode pixel --shadow-cascades 4
done
# The frame prep_engine_gpu.py compares (its FRAME_ARGS), linear HDR.
"$VIEW" "$S/room_v3_sun.gltf" --headless --output "$OUT/frame.pfm" --width 640 --height 360 --probe-mode pixel \
    >>"$LOG" 2>&1
rm -f "$OUT/t.pfm"
cat "$LOG"
