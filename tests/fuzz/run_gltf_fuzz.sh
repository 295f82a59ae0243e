#!/usr/bin/env bash
# Fuzzes the engine's glTF loader (engine/gltf/fuzz_gltf.c) with libFuzzer + ASan + UBSan for a
# bounded time and prints one summary line. Non-zero exit when the fuzzer finds a crash, leak,
# timeout or sanitizer report (the reproducer is kept as tests/fuzz/crash-gltf-*).
#
#   SCHNEE_FUZZ_SECONDS=60 tests/fuzz/run_gltf_fuzz.sh     (default 60 s)
#
# The corpus grows in tests/fuzz/corpus-gltf/ (gitignored) from seeds generated at each run by
# tests/engine/gltf/make_seeds.py; the binary is built directly with clang into build-fuzz/.
set -euo pipefail
cd "$(dirname "$0")/../.."

seconds="${SCHNEE_FUZZ_SECONDS:-60}"
out=build-fuzz
corpus=tests/fuzz/corpus-gltf
mkdir -p "$out" "$corpus" "$out/seeds-gltf"

clang -std=gnu11 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined \
  -Wall -Wextra -Wshadow -Wno-unused-parameter -Werror \
  -Iengine/gltf -Iengine/ext -Ishaders -I/usr/include/cjson \
  engine/gltf/fuzz_gltf.c engine/gltf/sv_gltf.c engine/gltf/sv_gltf_[bfjmnu]*.c engine/ext/sv_ext.c \
  -lcjson -lm -o "$out/fuzz_gltf"

/usr/bin/python3 tests/engine/gltf/make_seeds.py "$out/seeds-gltf" "$out/gltf.dict"

log="$out/fuzz_gltf.log"
set +e
ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  "$out/fuzz_gltf" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
  -dict="$out/gltf.dict" -artifact_prefix=tests/fuzz/crash-gltf- -print_final_stats=1 \
  "$corpus" "$out/seeds-gltf" >"$log" 2>&1
rc=$?
set -e

runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
files=$(find "$corpus" -type f | wc -l)
if [ "$rc" -ne 0 ]; then
  tail -n 60 "$log" >&2
  artifact=$(grep -o 'tests/fuzz/crash-gltf-[^ ]*' "$log" | tail -1)
  echo "fuzz gltf: FAILED (exit $rc) after ${runs:-?} runs; reproducer: ${artifact:-see $log}"
  exit 1
fi
echo "fuzz gltf: ok, ${runs:-?} runs in ${seconds} s, coverage ${cov:-?} edges, corpus ${files} files"
