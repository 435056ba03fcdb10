#!/usr/bin/env bash
# Builds carat's libFuzzer targets with clang (build-fuzz/) and fuzzes each parser for a
# bounded time: scripts/fuzz.sh [SECONDS_PER_TARGET (default 60)] [TARGET...]
# With CARAT_FUZZ_RUNS=N set, each target runs N executions instead (SECONDS is then ignored).
# Each target uses its header-aware dictionary fuzz/<name>.dict when there is one.
# Crashes, leaks and slow inputs (> 1 s) fail the run; artifacts land in build-fuzz/artifacts/.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
bash scripts/install-deps.sh
if ! command -v clang++ >/dev/null || ! dpkg-query -W -f='${Status}' libclang-rt-14-dev 2>/dev/null | grep -q "ok installed"; then
  SUDO=""; [[ "$(id -u)" != "0" ]] && SUDO="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends clang libclang-rt-14-dev >/dev/null
fi
# -O1 -g1 (line tables): the usual libFuzzer build, and a much shorter compile than -O2 -g.
CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DCARAT_BUILD_FUZZERS=ON -DCARAT_WERROR=ON \
  -DCARAT_BUILD_TESTS=OFF -DCARAT_BUILD_BENCHMARKS=OFF -DCARAT_BUILD_APPS=OFF >/dev/null
targets=("$@")
if ((${#targets[@]} == 0)); then
  for f in fuzz/*_fuzz.cpp; do targets+=("$(basename "$f" .cpp)"); done
fi
cmake --build build-fuzz -j"$(nproc)" --target "${targets[@]}"
mkdir -p build-fuzz/artifacts
for target in "${targets[@]}"; do
  name=${target%_fuzz}
  work=build-fuzz/corpus/$name
  mkdir -p "$work"
  limit=(-max_total_time="$seconds")
  [[ -n "${CARAT_FUZZ_RUNS:-}" ]] && limit=(-runs="$CARAT_FUZZ_RUNS")
  dict=()
  [[ -f "fuzz/$name.dict" ]] && dict=(-dict="fuzz/$name.dict")
  echo "== $target: ${limit[*]} ${dict[*]}"
  ./build-fuzz/fuzz/"$target" "$work" "fuzz/corpus/$name" "${limit[@]}" "${dict[@]}" -timeout=1 \
    -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 -artifact_prefix=build-fuzz/artifacts/"$name"- \
    >build-fuzz/"$name".log 2>&1 || true
  grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb)|ERROR|SUMMARY" build-fuzz/"$name".log || true
  if ls build-fuzz/artifacts/"$name"-* >/dev/null 2>&1 || grep -q "SUMMARY:" build-fuzz/"$name".log; then
    echo "FAIL $target: see build-fuzz/artifacts/"; exit 1
  fi
done
