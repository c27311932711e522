#!/usr/bin/env bash
# Sets up (through scripts/setup.sh) when anything is missing, builds, and runs
# every test with ctest. Exits non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${LIFMCR_BUILD_DIR:-build}

scripts/setup.sh
jobs=$(nproc 2>/dev/null || echo 2)
ctest --test-dir "$build_dir" --output-on-failure -j "$jobs" "$@"
