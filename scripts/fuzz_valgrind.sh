#!/usr/bin/env bash
# Builds the libFuzzer targets without sanitizers (build-fuzz-vg/, ENDOCAST_FUZZ_SANITIZERS=OFF) and
# fuzzes each under valgrind for a bounded time, on a copy of its seed corpus. ASan sees only the
# code it instrumented; ITK is not, so a heap overflow inside ITK (it may corrupt ASan's own heap
# records and fail an allocator CHECK much later) or voxels ITK left uninitialised show only here
# (docs/reliability.md, finding 16). About 200 executions/s for fuzz_mhd, far fewer than with ASan:
# not part of .ci/run; run it after a change to the ITK-backed readers.
# Fails on any valgrind error, crash or broken guarantee; the reproducer is left in
# build-fuzz-vg/fuzz-out/<target>/.
# Usage: bash scripts/fuzz_valgrind.sh [seconds per target, default 300] [target ...]
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-300}"
shift || true
TARGETS=("$@")
if [ "${#TARGETS[@]}" -eq 0 ]; then TARGETS=(fuzz_nrrd fuzz_nifti fuzz_mhd); fi
command -v valgrind >/dev/null || { echo "fuzz_valgrind.sh needs valgrind (apt-get install valgrind)"; exit 2; }
CC=clang CXX=clang++ cmake -S . -B build-fuzz-vg -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_C_FLAGS=-gdwarf-4 -DCMAKE_CXX_FLAGS=-gdwarf-4 \
  -DENDOCAST_BUILD_FUZZERS=ON -DENDOCAST_FUZZ_SANITIZERS=OFF -DENDOCAST_BUILD_TESTS=OFF >/dev/null
cmake --build build-fuzz-vg -j"$(nproc)" --target "${TARGETS[@]}"
OUT=build-fuzz-vg/fuzz-out
failed=()
for t in "${TARGETS[@]}"; do
  corpus="$OUT/$t/corpus"
  rm -rf "$OUT/$t"
  mkdir -p "$corpus"
  if [ -d "tests/fuzz/corpus/$t" ]; then cp -r "tests/fuzz/corpus/$t/." "$corpus/"; fi
  log="$OUT/$t/log.txt"
  echo "fuzz under valgrind: $t for ${SECONDS_PER_TARGET}s"
  rc=0
  valgrind -q --error-exitcode=99 "build-fuzz-vg/tests/fuzz/$t" "$corpus" -max_total_time="$SECONDS_PER_TARGET" \
    -max_len=4096 -timeout=60 -rss_limit_mb=0 -artifact_prefix="$OUT/$t/" >"$log" 2>&1 || rc=$?
  if [ "$rc" -ne 0 ] || grep -q '^==[0-9]*== [A-Z]' "$log"; then
    echo "fuzz under valgrind: $t FAILED (exit $rc), log $log:"
    grep -v '^###' "$log" | grep -A20 '^==[0-9]*== [A-Z]' | head -n 60 || tail -n 40 "$log"
    failed+=("$t")
  else
    echo "fuzz under valgrind: $t ok, $(sed -n 's/^Done \([0-9]*\) runs.*/\1/p' "$log" | tail -n 1) executions"
  fi
done
if [ "${#failed[@]}" -ne 0 ]; then echo "fuzz under valgrind: FAILED: ${failed[*]}"; exit 1; fi
echo "fuzz under valgrind: all ${#TARGETS[@]} targets passed"
