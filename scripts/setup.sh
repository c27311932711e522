#!/usr/bin/env bash
# Installs every dependency of lifmcr from Debian bookworm packages (as root),
# then configures and builds it in Release under build/.
# Idempotent: when everything is installed it only runs the (incremental) build.
#   LIFMCR_BUILD_DIR   build folder (default: build)
#   LIFMCR_BUILD_TYPE  CMake build type (default: Release)
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(
  build-essential cmake pkg-config ccache git
  libeigen3-dev libopencv-dev libopencv-contrib-dev libceres-dev libpcl-dev libtbb-dev
  libspdlog-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev libtinyxml2-dev libtiff-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libaravis-dev aravis-tools aravis-tools-cli libusb-1.0-0-dev
  liblcm-dev liblcm-bin liblcm-java libjchart2d-java default-jdk-headless
  iproute2 procps
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  if [[ $(id -u) -ne 0 ]]; then
    echo "setup.sh: missing packages: ${missing[*]}" >&2
    echo "setup.sh: run as root (or: sudo apt-get install ${missing[*]})" >&2
    exit 1
  fi
  echo "setup.sh: installing ${#missing[@]} packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${packages[@]}" >/dev/null
fi

build_dir=${LIFMCR_BUILD_DIR:-build}
build_type=${LIFMCR_BUILD_TYPE:-Release}
jobs=$(nproc 2>/dev/null || echo 2)
mkdir -p "$build_dir"
log="$build_dir/build.log"
if [[ ! -f "$build_dir/CMakeCache.txt" ]]; then
  echo "setup.sh: configuring and building in $build_dir ($build_type); the first build takes a few minutes"
  if ! cmake -S . -B "$build_dir" -DCMAKE_BUILD_TYPE="$build_type" >"$log" 2>&1; then
    cat "$log" >&2
    echo "setup.sh: configure failed" >&2
    exit 1
  fi
fi
if ! cmake --build "$build_dir" -j "$jobs" >"$log" 2>&1; then
  grep -v -E '^\[ *[0-9]+%\]' "$log" | tail -n 80 >&2
  echo "setup.sh: build failed; full log in $log" >&2
  exit 1
fi
