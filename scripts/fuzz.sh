#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/, clang + ASan + UBSan) in build-fuzz/ and runs each for
# a bounded time on a copy of its seed corpus (tests/fuzz/corpus/<target>/ is never written).
# Fails (non-zero exit) on any crash, leak, timeout, out-of-memory, or sanitizer report; the
# reproducer is left in build-fuzz/fuzz-out/<target>/ (crash-*, leak-*, timeout-*, oom-*).
# Usage: bash scripts/fuzz.sh [seconds per target, default 30] [target ...]
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_PER_TARGET="${1:-30}"
shift || true
TARGETS=("$@")
if [ "${#TARGETS[@]}" -eq 0 ]; then
  TARGETS=(fuzz_mesh_stl fuzz_mesh_ply fuzz_mesh_obj fuzz_mesh_off fuzz_raw fuzz_dicom fuzz_nrrd fuzz_nifti fuzz_mhd fuzz_tiff)
fi

bash scripts/install-deps.sh
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DENDOCAST_BUILD_FUZZERS=ON -DENDOCAST_BUILD_TESTS=OFF -DENDOCAST_BUILD_PYTHON=OFF >/dev/null
cmake --build build-fuzz -j"$(nproc)" --target "${TARGETS[@]}"

OUT=build-fuzz/fuzz-out
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}"
failed=()
summary=()
for t in "${TARGETS[@]}"; do
  corpus="$OUT/$t/corpus"
  rm -rf "$OUT/$t"
  mkdir -p "$corpus"
  if [ -d "tests/fuzz/corpus/$t" ]; then cp -r "tests/fuzz/corpus/$t/." "$corpus/"; fi
  log="$OUT/$t/log.txt"
  echo "fuzz: $t for ${SECONDS_PER_TARGET}s"
  rc=0
  "build-fuzz/tests/fuzz/$t" "$corpus" -max_total_time="$SECONDS_PER_TARGET" -max_len=4096 \
    -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$OUT/$t/" \
    >"$log" 2>&1 || rc=$?
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' | tail -n 1 || echo "?")  # printed twice after a crash
  if [ "$rc" -ne 0 ] || grep -q 'ERROR: AddressSanitizer\|ERROR: LeakSanitizer\|runtime error:\|ERROR: libFuzzer' "$log"; then
    echo "fuzz: $t FAILED (exit $rc), log $log:"
    tail -n 60 "$log"
    failed+=("$t")
    summary+=("$t: FAILED after $execs executions")
  else
    summary+=("$t: ok, $execs executions in ${SECONDS_PER_TARGET}s, corpus $(ls "$corpus" | wc -l) inputs")
  fi
done
echo "fuzz summary:"
printf '  %s\n' "${summary[@]}"
if [ "${#failed[@]}" -ne 0 ]; then
  echo "fuzz: FAILED: ${failed[*]}"
  exit 1
fi
echo "fuzz: all ${#TARGETS[@]} targets passed"
