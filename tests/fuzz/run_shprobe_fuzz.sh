#!/usr/bin/env bash
# Fuzzes the .shprobe readers with libFuzzer + ASan + UBSan for a bounded time: the memory reader
# (native/fuzz/fuzz_shprobe.c) for SCHNEE_FUZZ_SECONDS (default 60), then the file readers against it
# (native/fuzz/fuzz_shprobe_file.c: pb_shprobe_read / _read_header on the same bytes in a file, issue
# 14) for half that time. Builds with clang straight from the core sources they need (no
# OpenImageIO / Embree), seeds the corpus with a valid v1 and v2 file written by the real writer, and
# exits non-zero on any crash, leak or UB report. Prints one summary line per target.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds="${SCHNEE_FUZZ_SECONDS:-60}"
work="${SCHNEE_FUZZ_DIR:-build/fuzz-shprobe}"
mkdir -p "$work/corpus" "$work/artifacts"
CC="${CLANG:-clang}"
flags=(-std=c11 -g -O1 -Inative/include -Wall -Wextra -Werror -Wno-unused-parameter)
# The core's sources that the readers need (the .shprobe files, the interpolation, errors).
core=(native/src/pb_shprobe.c native/src/pb_shprobe_read.c native/src/pb_shprobe_v3.c native/src/pb_shprobe_write.c
  native/src/pb_interp.c native/src/pb_cotree.c native/src/pb_cotree_boxes.c native/src/pb_tetra.c
  native/src/pb_interp_v3.c native/src/pb_common.c)
san=(-fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer)

for target in fuzz_shprobe fuzz_shprobe_file; do
  "$CC" "${flags[@]}" "${san[@]}" "native/fuzz/$target.c" "${core[@]}" -lqhull_r -lm -o "$work/$target"
done

# Seeds: a v1 (band 2) and a v2 (band 4, positions, rotated axes, validity) written by the writer, and
# version 3 files: an octree with hanging nodes (SH band 1, binary16) and tetrahedra (ambient cubes);
# a version 4 kd corner tree (boxes, split tree).
cat > "$work/make_seeds.c" <<'SEED'
#include "schnee/pb_interp.h"
#include "schnee/pb_shprobe.h"
#include <stdio.h>
#include <string.h>
int main(int argc, char **argv)
{
    const uint32_t dims[3] = {2, 2, 1};
    for (int v = 1; v <= 2; v++) {
        pb_shprobe *p = NULL;
        pb_error err;
        memset(&err, 0, sizeof err);
        if (pb_shprobe_create(2, v == 1 ? 2 : 4, dims, v == 2, &p, &err)) return 1;
        p->grid_spacing = 0.5f;
        for (int i = 0; i < 4; i++) p->grid[i] = i % 3 == 2 ? -1 : i % 2;
        p->coeffs[0] = 1.5f;
        if (v == 2) {
            static const float axes[9] = {0, 0, 1, 1, 0, 0, 0, 1, 0};
            memcpy(p->grid_axes, axes, sizeof axes);
            p->validity[1] = 0.5f;
            p->positions[3] = 2.0f;
        }
        char path[512];
        snprintf(path, sizeof path, "%s/seed_v%d.shprobe", argv[1], v);
        if (pb_shprobe_write(path, p, &err)) { fprintf(stderr, "%s\n", err.message); return 1; }
        pb_shprobe_destroy(p);
    }
    /* v3 octree: two leaves, the left split (26 probes, 5 hanging nodes), SH band 1, binary16. */
    const double o[3] = {0, 0, 0};
    const uint32_t roots[3] = {2, 1, 1};
    pb_cotree *t = NULL;
    pb_error err;
    memset(&err, 0, sizeof err);
    uint8_t split[2] = {1, 0};
    if (pb_cotree_create(o, 0.5, 1, roots, &t, &err) || pb_cotree_split(t, split, NULL, &err) ||
        pb_cotree_finalize(t, &err))
        return 1;
    pb_shprobe *p = NULL;
    if (pb_shprobe_from_cotree(t, PB_SHPROBE_SH, 1, &p, &err)) return 1;
    p->storage = PB_SHPROBE_FLOAT16;
    p->coeffs[0] = 1.5f;
    char path[512];
    snprintf(path, sizeof path, "%s/seed_v3_octree.shprobe", argv[1]);
    if (pb_shprobe_write(path, p, &err)) { fprintf(stderr, "%s\n", err.message); return 1; }
    pb_shprobe_destroy(p);
    pb_cotree_destroy(t);
    /* v3 tetrahedra: 5 points, ambient cubes float32. */
    const double pos[15] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
    pb_tetra *tt = NULL;
    if (pb_tetra_create(pos, 5, &tt, &err) || pb_shprobe_from_tetra(tt, pos, PB_SHPROBE_AMBIENT_CUBE, 2, &p, &err))
        return 1;
    snprintf(path, sizeof path, "%s/seed_v3_tetra.shprobe", argv[1]);
    if (pb_shprobe_write(path, p, &err)) { fprintf(stderr, "%s\n", err.message); return 1; }
    pb_shprobe_destroy(p);
    pb_tetra_destroy(tt);
    /* v4 kd corner tree: the left root halved along y, the right one along x and its upper half along z
     * (slabs, hanging nodes, the nesting rule's forced splits), SH band 0. */
    uint8_t axes[2] = {2, 1};
    const uint32_t roots4[3] = {2, 1, 1};
    if (pb_cotree_create(o, 0.5, 1, roots4, &t, &err) || pb_cotree_split_axes(t, axes, NULL, &err)) return 1;
    uint8_t more[4] = {0, 0, 0, 4};
    if (pb_cotree_split_axes(t, more, NULL, &err) || pb_cotree_finalize(t, &err) ||
        pb_shprobe_from_cotree(t, PB_SHPROBE_SH, 0, &p, &err) || p->version != 4)
        return 1;
    p->coeffs[0] = 1.5f;
    snprintf(path, sizeof path, "%s/seed_v4_kdtree.shprobe", argv[1]);
    if (pb_shprobe_write(path, p, &err)) { fprintf(stderr, "%s\n", err.message); return 1; }
    pb_shprobe_destroy(p);
    pb_cotree_destroy(t);
    return 0;
}
SEED
"$CC" "${flags[@]}" -fsanitize=address,undefined "$work/make_seeds.c" "${core[@]}" -lqhull_r -lm -o "$work/make_seeds"
"$work/make_seeds" "$work/corpus"

# run_target NAME SECONDS: fuzzes on a copy of the seed corpus; exits non-zero on any finding.
run_target() {
  local name="$1" secs="$2" log="$work/$1.log" corpus="$work/corpus-$1"
  mkdir -p "$corpus"
  cp -n "$work"/corpus/seed_v*.shprobe "$corpus"/
  set +e
  ASAN_OPTIONS=detect_leaks=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$work/$name" "$corpus" -max_total_time="$secs" -max_len=4096 -timeout=10 \
    -rss_limit_mb=2048 -artifact_prefix="$work/artifacts/$name-" -print_final_stats=1 >"$log" 2>&1
  local rc=$?
  set -e
  local runs
  runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  if [ "$rc" -ne 0 ]; then
    tail -n 60 "$log"
    echo "$name: FAILED (exit $rc) after ${runs} runs in <= ${secs} s; crash input in $work/artifacts/"
    exit 1
  fi
  echo "$name: ok, ${runs} runs in ${secs} s, no crash (corpus $(ls "$corpus" | wc -l) files, log $log)"
}
run_target fuzz_shprobe "$seconds"
run_target fuzz_shprobe_file "$(( seconds / 2 > 0 ? seconds / 2 : 1 ))"
