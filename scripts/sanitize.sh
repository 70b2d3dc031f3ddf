#!/usr/bin/env bash
# CI step: builds the unit tests with AddressSanitizer + UndefinedBehaviorSanitizer
# (-DENDOCAST_SANITIZE=ON, RelWithDebInfo) in build-asan/ and runs them with ctest.
# The command-line tests (cli_tests) are not built, and tests reading the real scans (RealData) are
# excluded: too slow under ASan. Any sanitizer report fails the test (UBSan does not recover).
# Usage: bash scripts/sanitize.sh [extra ctest arguments]
set -euo pipefail
cd "$(dirname "$0")/.."
TARGETS=(${ENDOCAST_SANITIZE_TARGETS:-meshpost_tests endocast_tests})
bash scripts/install-deps.sh
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DENDOCAST_SANITIZE=ON >/dev/null
cmake --build build-asan -j"$(nproc)" --target "${TARGETS[@]}"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}"
cd build-asan
# Targets not built show up as <name>_NOT_BUILT: excluded with the real-data and CLI tests.
ctest --output-on-failure -j"$(nproc)" -E 'NOT_BUILT|RealData|Cli' "$@"
