#!/usr/bin/env bash
# Builds carat's tests with AddressSanitizer + UndefinedBehaviorSanitizer (build-asan/, Clang) and
# runs them; any sanitizer report fails the run. The same tree holds the parsers' libFuzzer targets
# (the libraries carry libFuzzer's coverage hooks), so scripts/fuzz.sh can run them from here:
# CARAT_FUZZ_BUILD_DIR=build-asan bash scripts/fuzz.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
CARAT_WITH_CLANG=1 bash scripts/install-deps.sh
# Clang: it compiles this code base with both sanitizers about 2.4 times faster than GCC (GCC's
# UBSan instrumentation doubles its compile time). -g1: function names and line tables, all a
# sanitizer report needs. Examples and benchmarks are left out: they run the same library code as
# the tests, and the Release suite builds and runs them.
cmake -S . -B build-asan -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
  -DCARAT_SANITIZE=ON -DCARAT_BUILD_FUZZERS=ON -DCARAT_WERROR=ON -DCARAT_BUILD_BENCHMARKS=OFF \
  -DCARAT_BUILD_EXAMPLES=OFF ${CARAT_CMAKE_ARGS:-}
cmake --build build-asan -j"$(nproc)"
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:${UBSAN_OPTIONS:-}"
ctest --test-dir build-asan --output-on-failure -j"$(nproc)" --timeout 900
