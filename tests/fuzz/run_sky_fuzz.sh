#!/usr/bin/env bash
# Fuzzes the engine's sky/EXR path (tests/fuzz/fuzz_sky.c: file checks, EXR/PNG header limits,
# OpenImageIO decode through pb_image_read, GGX prefilter) with libFuzzer + ASan + UBSan for a
# bounded time and prints one summary line. Non-zero exit when the fuzzer finds a crash, leak,
# timeout or sanitizer report (the reproducer is kept as tests/fuzz/crash-sky-*).
#
#   SCHNEE_FUZZ_SECONDS=60 tests/fuzz/run_sky_fuzz.sh     (default 60 s)
#
# Seeds are small EXR/HDR/PNG files written at each run by oiiotool; the corpus grows in
# tests/fuzz/corpus-sky/ (gitignored); the binary is built directly with clang into build-fuzz/.
# OpenImageIO itself is not instrumented (Debian's library); the engine code and the core are.
set -euo pipefail
cd "$(dirname "$0")/../.."

seconds="${SCHNEE_FUZZ_SECONDS:-60}"
out=build-fuzz
corpus=tests/fuzz/corpus-sky
seeds="$out/seeds-sky"
mkdir -p "$out" "$corpus" "$seeds"

san=(-g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer)
warn=(-Wall -Wextra -Wshadow -Wno-unused-parameter -Werror)
inc=(-Iengine/src -Iengine/gltf -Iengine/ext -Ishaders -Inative/include -I/usr/include/cjson)
objs=()
for src in tests/fuzz/fuzz_sky.c engine/src/sv_sky.c engine/gltf/sv_gltf.c engine/gltf/sv_gltf_[bfjmnu]*.c \
  native/src/pb_common.c; do
  obj="$out/sky-$(basename "$src" .c).o"
  clang -std=gnu11 "${san[@]}" "${warn[@]}" "${inc[@]}" -DSV_SKY_MAX_PIXELS=4096 -c "$src" -o "$obj"
  objs+=("$obj")
done
clang++ -std=c++17 "${san[@]}" -Inative/include $(pkg-config --cflags OpenImageIO) -c native/src/pb_image_oiio.cpp \
  -o "$out/sky-pb_image_oiio.o"
clang++ "${san[@]}" "${objs[@]}" "$out/sky-pb_image_oiio.o" $(pkg-config --libs OpenImageIO) -lcjson -lm \
  -o "$out/fuzz_sky"

# Seeds: tiny images of the formats the sky may be in (the bake writes float EXR).
oiiotool --pattern fill:topleft=0.1,0.2,0.3:topright=4,2,1:bottomleft=0,0,0:bottomright=1,1,1 16x8 3 -d float \
  -o "$seeds/float.exr" >/dev/null
oiiotool "$seeds/float.exr" -d half --compression piz -o "$seeds/half-piz.exr" >/dev/null
oiiotool "$seeds/float.exr" -d half --compression zip --tile 8 8 -o "$seeds/tiled.exr" >/dev/null
oiiotool "$seeds/float.exr" -o "$seeds/sky.hdr" >/dev/null
oiiotool "$seeds/float.exr" -d uint8 -o "$seeds/sky.png" >/dev/null

log="$out/fuzz_sky.log"
set +e
SCHNEE_FUZZ_DIR="$out" ASAN_OPTIONS=detect_leaks=1:fast_unwind_on_malloc=0 LSAN_OPTIONS=suppressions=tests/fuzz/sky_lsan.supp \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  "$out/fuzz_sky" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
  -artifact_prefix=tests/fuzz/crash-sky- -print_final_stats=1 -close_fd_mask=2 \
  "$corpus" "$seeds" >"$log" 2>&1
rc=$?
set -e

runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
files=$(find "$corpus" -type f | wc -l)
if [ "$rc" -ne 0 ]; then
  tail -n 60 "$log" >&2
  artifact=$(grep -o 'tests/fuzz/crash-sky-[^ ]*' "$log" | tail -1)
  echo "fuzz sky: FAILED (exit $rc) after ${runs:-?} runs; reproducer: ${artifact:-see $log}"
  exit 1
fi
echo "fuzz sky: ok, ${runs:-?} runs in ${seconds} s, coverage ${cov:-?} edges, corpus ${files} files"
