#!/usr/bin/env bash
# The main job on the embedded default: sets up when anything is missing
# (scripts/setup.sh: packages as root, then the build), then runs `lifmcr demo`:
# a small synthetic rig replayed through the live pipeline on LCM, with the
# summary and how to watch it. Arguments go to `lifmcr demo` (see --help).
set -euo pipefail
cd "$(dirname "$0")/.."
build_dir=${LIFMCR_BUILD_DIR:-build}
scripts/setup.sh
exec "$build_dir/apps/lifmcr" demo "$@"
