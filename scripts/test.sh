#!/usr/bin/env bash
# Quick start, command 2: install dependencies, build, and run every test (ctest).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900
