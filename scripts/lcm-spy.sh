#!/usr/bin/env bash
# usage: scripts/lcm-spy.sh [lcm-spy OPTIONS...]   (e.g. --lcm-url=URL)
# Starts lcm-spy with the lifmcr message types (build/lcm_types/lifmcr_lcm_types.jar).
# Debian's own `lcm-spy` script fails on Java 17 (it passes -Xincgc) and forces its
# own -cp, so the Java class is started directly. Extra arguments go to lcm-spy,
# e.g. --lcm-url='udpm://239.255.76.67:7667?ttl=0'.
#   LIFMCR_BUILD_DIR  build folder holding the jar (default: build)
set -euo pipefail
# --help: the header above, nothing else run.
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  sed -n '2,/^set -euo pipefail/s/^# \{0,1\}//p' "$0"
  exit 0
fi
cd "$(dirname "$0")/.."
jar="${LIFMCR_BUILD_DIR:-build}/lcm_types/lifmcr_lcm_types.jar"
if [[ ! -f "$jar" ]]; then
  echo "lcm-spy.sh: $jar is missing; build it with scripts/setup.sh" >&2
  exit 1
fi
for dep in /usr/share/java/lcm.jar /usr/share/java/jchart2d.jar; do
  if [[ ! -f "$dep" ]]; then
    echo "lcm-spy.sh: $dep is missing (apt-get install liblcm-java libjchart2d-java)" >&2
    exit 1
  fi
done
if [[ -z "${DISPLAY:-}" ]]; then
  echo "lcm-spy.sh: no DISPLAY; lcm-spy needs X (ssh -X, or xvfb-run scripts/lcm-spy.sh)" >&2
  exit 1
fi
# Java's UDP receive buffer is net.core.rmem_default (208 KB on Debian): depth
# maps and previews (fragmented, up to a few hundred KB) are then lost in part.
rmem=$(cat /proc/sys/net/core/rmem_default 2>/dev/null || echo 0)
if ((rmem < 4194304)); then
  echo "lcm-spy.sh: net.core.rmem_default is $rmem; lcm-spy will miss large messages." >&2
  echo "lcm-spy.sh: as root: sysctl -w net.core.rmem_max=8388608 net.core.rmem_default=4194304" >&2
fi
exec java -Djava.net.preferIPv4Stack=true \
  -cp "/usr/share/java/lcm.jar:/usr/share/java/jchart2d.jar:$jar" lcm.spy.Spy "$@"
