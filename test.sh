#!/usr/bin/env bash
# Runs the tests. Installs missing dependencies first (idempotent), then builds (scripts/build.sh).
#
#   ./test.sh                everything (what CI runs through .ci/run): C tests, the same C tests
#                            under ASan/UBSan, the fuzz targets for a bounded time, and all Python,
#                            Blender, chroot and engine tests, with the 25 slowest printed
#   ./test.sh fast           the fast tier (under 3 minutes on 2 cores): the C tests (core and
#                            engine, ctest) and the pytest tests that start no Blender, no chroot and
#                            no Vulkan engine (-m "not (blender or chroot or engine or slow)"); no
#                            ASan build, no fuzzing
#   ./test.sh [fast] ARGS    extra arguments go to pytest, e.g. ./test.sh -k export, ./test.sh fast -x
#
# The markers (blender, chroot, engine, farm, bench, slow) are assigned in tests/conftest.py and
# registered in pyproject.toml; pytest -m selects any mix of them.
# SCHNEE_FUZZ_SECONDS sets the fuzzing time per target (default here 25 s, to keep the suite near
# 25 min; the fuzz scripts run side by side).
set -euo pipefail
cd "$(dirname "$0")"
export SCHNEE_WERROR=ON

tier=full
case "${1:-}" in
  fast) tier=fast; shift ;;
  -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
esac

scripts/deps.sh
# Builds take the lock the helpers' builds take, so two builds of one tree never run at once.
flock /tmp/schnee-build.lock scripts/build.sh

echo "== C tests"
ctest --test-dir build --output-on-failure -j 2

if [ "$tier" = full ]; then
  echo "== C tests under ASan/UBSan"
  flock /tmp/schnee-build.lock bash -c '
    cmake -S . -B build-asan -G Ninja -DSCHNEE_SANITIZE=ON -DSCHNEE_WERROR=ON -DSCHNEE_BUILD_PYTHON=OFF \
      -DCMAKE_BUILD_TYPE=Debug >/dev/null
    cmake --build build-asan -j "$(nproc)"'
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j 2 -L native

  echo "== fuzz targets (bounded, side by side)"
  # Each fuzzer is single-threaded: running the three scripts at once keeps both cores busy.
  export SCHNEE_FUZZ_SECONDS="${SCHNEE_FUZZ_SECONDS:-25}"
  fuzz_logs=$(mktemp -d)
  pids=()
  for f in tests/fuzz/run_*.sh; do
    [ -e "$f" ] || continue
    bash "$f" >"$fuzz_logs/$(basename "$f").log" 2>&1 &
    pids+=("$!")
  done
  fuzz_failed=0
  for pid in "${pids[@]}"; do wait "$pid" || fuzz_failed=1; done
  cat "$fuzz_logs"/*.log
  rm -rf "$fuzz_logs"
  [ "$fuzz_failed" = 0 ] || { echo "fuzz: a target failed (its output is above)"; exit 1; }
fi

echo "== Python, Blender and engine tests ($tier)"
# Debian's Python (the one Blender embeds and the module is built for), not a python3 on PATH.
# Everything is installed and built by now: a skipped test means a broken setup, so it fails.
export SCHNEE_STRICT_SKIPS=1
pytest_args=(tests -q -p no:cacheprovider --durations=25)
if [ "$tier" = fast ]; then pytest_args+=(-m "not (blender or chroot or engine or slow)"); fi
exec /usr/bin/python3 -m pytest "${pytest_args[@]}" "$@"
