#!/usr/bin/env bash
# usage: scripts/demo.sh [lifmcr demo OPTIONS...]   (the options: build/apps/lifmcr demo --help)
# The main job on the embedded default: sets up when anything is missing
# (scripts/setup.sh: packages as root, then the build), then runs `lifmcr demo`:
# the whole chain on a small synthetic rig (synth -> calibrate camera 0 ->
# replay with live registration on LCM -> evaluate against Vicon), ending with
# the evaluation table and where the plots are. Arguments go to `lifmcr demo`
# (see --help).
set -euo pipefail
# --help: the header above, nothing else run.
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  sed -n '2,/^set -euo pipefail/s/^# \{0,1\}//p' "$0"
  exit 0
fi
cd "$(dirname "$0")/.."
build_dir=${LIFMCR_BUILD_DIR:-build}
# The demo runs the `lifmcr` binary alone: its target, not the tests and
# benchmarks (scripts/test.sh builds everything).
LIFMCR_BUILD_TARGETS=${LIFMCR_BUILD_TARGETS:-lifmcr} scripts/setup.sh
exec "$build_dir/apps/lifmcr" demo "$@"
