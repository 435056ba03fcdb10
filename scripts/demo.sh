#!/usr/bin/env bash
# Quick start, command 1: install dependencies, build, and run the main job (`carat demo`).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/build.sh
./build/apps/carat/carat demo "$@"
