#!/usr/bin/env bash
# Builds carat's tests with AddressSanitizer + UndefinedBehaviorSanitizer (build-asan/) and runs
# them; any sanitizer report fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCARAT_SANITIZE=ON -DCARAT_BUILD_BENCHMARKS=OFF
cmake --build build-asan -j"$(nproc)"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}"
ctest --test-dir build-asan --output-on-failure -j"$(nproc)" --timeout 900
