#!/usr/bin/env bash
# Measures the pose-graph benchmark with each BLAS that CHOLMOD can load on Debian 12
# (reference BLAS, ATLAS, OpenBLAS serial), in one run, by pointing the loader at each one.
# Needs: libatlas3-base (apt-get install libatlas3-base) besides carat's dependencies.
set -euo pipefail
cd "$(dirname "$0")/.."
arch_dir="/usr/lib/$(dpkg-architecture -qDEB_HOST_MULTIARCH)"
for blas in openblas-serial atlas blas; do
  if [[ ! -e "$arch_dir/$blas/libblas.so.3" ]]; then
    echo "== $blas: not installed, skipped"; continue
  fi
  echo "== $blas"
  LD_LIBRARY_PATH="$arch_dir/$blas" ./build/bench/posegraph_bench --benchmark_filter='/auto/' \
    --benchmark_repetitions="${REPETITIONS:-3}" --benchmark_report_aggregates_only=true "$@"
done
