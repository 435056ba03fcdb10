#!/usr/bin/env bash
# Builds carat's libFuzzer targets with clang (build-fuzz/) and fuzzes each parser for a
# bounded time: scripts/fuzz.sh [SECONDS_PER_TARGET (default 60)] [TARGET...]
# With CARAT_FUZZ_RUNS=N set, each target runs N executions instead (SECONDS is then ignored).
# Each target uses its header-aware dictionary fuzz/<name>.dict when there is one.
# Crashes, leaks and slow inputs (> 1 s) fail the run; artifacts land in build-fuzz/artifacts/
# (or the tree CARAT_FUZZ_BUILD_DIR names).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
# CARAT_FUZZ_BUILD_DIR names a tree already configured with -DCARAT_BUILD_FUZZERS=ON (CI reuses
# scripts/test-sanitize.sh's build-asan/); otherwise build-fuzz/ is configured here.
build=${CARAT_FUZZ_BUILD_DIR:-build-fuzz}
CARAT_WITH_CLANG=1 bash scripts/install-deps.sh
if [[ -z "${CARAT_FUZZ_BUILD_DIR:-}" ]]; then
  # -O1 -g1 (line tables): the usual libFuzzer build, and a much shorter compile than -O2 -g.
  cmake -S . -B "$build" -DCMAKE_CXX_COMPILER=clang++ \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
    -DCARAT_BUILD_FUZZERS=ON -DCARAT_WERROR=ON -DCARAT_BUILD_TESTS=OFF -DCARAT_BUILD_BENCHMARKS=OFF \
    -DCARAT_BUILD_APPS=OFF -DCARAT_BUILD_EXAMPLES=OFF >/dev/null
fi
targets=("$@")
if ((${#targets[@]} == 0)); then
  for f in fuzz/*_fuzz.cpp; do targets+=("$(basename "$f" .cpp)"); done
fi
cmake --build "$build" -j"$(nproc)" --target "${targets[@]}"
mkdir -p "$build"/artifacts
for target in "${targets[@]}"; do
  name=${target%_fuzz}
  work=$build/corpus/$name
  mkdir -p "$work"
  limit=(-max_total_time="$seconds")
  [[ -n "${CARAT_FUZZ_RUNS:-}" ]] && limit=(-runs="$CARAT_FUZZ_RUNS")
  dict=()
  [[ -f "fuzz/$name.dict" ]] && dict=(-dict="fuzz/$name.dict")
  echo "== $target: ${limit[*]} ${dict[*]}"
  ./"$build"/fuzz/"$target" "$work" "fuzz/corpus/$name" "${limit[@]}" "${dict[@]}" -timeout=1 \
    -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 -artifact_prefix="$build"/artifacts/"$name"- \
    >"$build"/"$name".log 2>&1 || true
  grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb)|ERROR|SUMMARY" "$build"/"$name".log || true
  if ls "$build"/artifacts/"$name"-* >/dev/null 2>&1 || grep -q "SUMMARY:" "$build"/"$name".log; then
    echo "FAIL $target: see $build/artifacts/"; exit 1
  fi
done
