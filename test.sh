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
# pytest runs on SCHNEE_TEST_WORKERS workers (default 2; pytest-xdist, Debian's python3-pytest-xdist),
# each test file whole on one worker (--dist loadfile: a file's module fixtures are made once), the
# longest files first (tests/conftest.py); SCHNEE_TEST_WORKERS=0 runs it in this process, serially.
# The ASan/UBSan build runs niced in the background while the fuzz targets and pytest run (it takes
# the CPU the workers leave idle); its output is printed, and its C tests run, at the end.
# SCHNEE_FUZZ_SECONDS sets the fuzzing time per target (default here 25 s; the fuzz scripts run side
# by side, in the foreground, so that their time is not shared with pytest).
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

asan_log=""
# Waits for the background ASan/UBSan build and prints its output, then runs its C tests in the
# foreground (not niced: some have wall-clock watchdogs); returns non-zero when either failed.
finish_asan() {
  [ -n "$asan_log" ] || return 0
  echo "== C tests under ASan/UBSan (built in the background)"
  local rc=0
  wait "$asan_pid" || rc=$?
  cat "$asan_log"
  rm -f "$asan_log"
  asan_log=""
  if [ "$rc" != 0 ]; then
    echo "ASan/UBSan: the build failed (exit $rc; its output is above)"
    return "$rc"
  fi
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir build-asan --output-on-failure -j 2 -L native
}

if [ "$tier" = full ]; then
  # The ASan/UBSan build in the background at nice 10: the fuzzers and pytest keep their CPU, the
  # build takes what they leave. Its own lock (only test.sh builds build-asan): niced, it may take as
  # long as pytest, and holding /tmp/schnee-build.lock that long would stall every other build.
  asan_log=$(mktemp)
  mkdir -p build-asan
  flock build-asan/.schnee-build.lock nice -n 10 bash -c '
    cmake -S . -B build-asan -G Ninja -DSCHNEE_SANITIZE=ON -DSCHNEE_WERROR=ON -DSCHNEE_BUILD_PYTHON=OFF \
      -DCMAKE_BUILD_TYPE=Debug >/dev/null
    cmake --build build-asan -j "$(nproc)"' >"$asan_log" 2>&1 &
  asan_pid=$!
  echo "== ASan/UBSan build: started in the background (pid $asan_pid); its C tests run at the end"

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
  [ "$fuzz_failed" = 0 ] || { echo "fuzz: a target failed (its output is above)"; finish_asan || true; exit 1; }
fi

echo "== Python, Blender and engine tests ($tier)"
# Debian's Python (the one Blender embeds and the module is built for), not a python3 on PATH.
# Everything is installed and built by now: a skipped test means a broken setup, so it fails.
export SCHNEE_STRICT_SKIPS=1
pytest_args=(tests -q -p no:cacheprovider --durations=25)
if [ "$tier" = fast ]; then pytest_args+=(-m "not (blender or chroot or engine or slow)"); fi
workers="${SCHNEE_TEST_WORKERS:-2}"
if [ "$workers" != 0 ]; then pytest_args+=(-n "$workers" --dist loadfile); fi
pytest_rc=0
/usr/bin/python3 -m pytest "${pytest_args[@]}" "$@" || pytest_rc=$?

finish_asan || { [ "$pytest_rc" != 0 ] || pytest_rc=1; }
exit "$pytest_rc"
