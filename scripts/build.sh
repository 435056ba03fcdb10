#!/usr/bin/env bash
# Installs dependencies (Debian 12 packages) and builds carat in ./build (Release).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCARAT_WERROR=ON ${CARAT_CMAKE_ARGS:-}
cmake --build build -j"$(nproc)"
