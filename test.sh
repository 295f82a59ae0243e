#!/usr/bin/env bash
# Runs every test: C tests (normal + ASan/UBSan build), fuzz targets for a bounded time, and the
# Python / Blender / engine tests. Installs missing dependencies first (idempotent), then builds.
set -euo pipefail
cd "$(dirname "$0")"
export SCHNEE_WERROR=ON

scripts/deps.sh
scripts/build.sh

echo "== C tests"
ctest --test-dir build --output-on-failure -j 2

echo "== C tests under ASan/UBSan"
cmake -S . -B build-asan -G Ninja -DSCHNEE_SANITIZE=ON -DSCHNEE_WERROR=ON -DSCHNEE_BUILD_PYTHON=OFF \
  -DCMAKE_BUILD_TYPE=Debug >/dev/null
cmake --build build-asan -j "$(nproc)"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan --output-on-failure -j 2 -L native

echo "== fuzz targets (bounded)"
for f in tests/fuzz/run_*.sh; do
  [ -e "$f" ] && bash "$f"
done

echo "== Python, Blender and engine tests"
# Debian's Python (the one Blender embeds and the module is built for), not a python3 on PATH.
# Everything is installed and built by now: a skipped test means a broken setup, so it fails.
export SCHNEE_STRICT_SKIPS=1
exec /usr/bin/python3 -m pytest tests -q -p no:cacheprovider "$@"
