#!/usr/bin/env bash
# Starts lcm-spy with the lifmcr message types (build/lcm_types/lifmcr_lcm_types.jar).
# Debian's own `lcm-spy` script fails on Java 17 (it passes -Xincgc) and forces its
# own -cp, so the Java class is started directly. Extra arguments go to lcm-spy,
# e.g. --lcm-url='udpm://239.255.76.67:7667?ttl=0'.
#   LIFMCR_BUILD_DIR  build folder holding the jar (default: build)
set -euo pipefail
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
exec java -Djava.net.preferIPv4Stack=true \
  -cp "/usr/share/java/lcm.jar:/usr/share/java/jchart2d.jar:$jar" lcm.spy.Spy "$@"
