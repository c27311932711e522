#!/usr/bin/env bash
# usage: scripts/setup.sh   (no arguments; the variables below)
# Installs every dependency of lifmcr from Debian bookworm packages (as root),
# raises the kernel's UDP receive buffers for LCM (as root; otherwise prints
# the commands), then configures and builds it in Release under build/.
# Idempotent: when everything is installed it only runs the (incremental) build.
# Each package is used by the build, the tests or a shipped tool:
#   OpenCV (imgcodecs: PNG/TIFF/JPEG I/O, imgproc, aruco; features2d and calib3d
#   for calibration/registration), Ceres (bundle adjustment), Eigen, TBB,
#   Highway (SIMD with runtime dispatch in processing/), spdlog,
#   yaml-cpp, CLI11, nlohmann-json, tinyxml2, GoogleTest/GoogleMock, Aravis and
#   libusb (GenICam cameras), LCM with Java and jchart2d (lcm-gen, lcm-logger,
#   the lcm-spy jar), iproute2 and procps (loopback multicast, sysctl), slurm-wlm,
#   munge and GNU parallel (batch plans run by a Slurm job array and by parallel).
#   LIFMCR_BUILD_DIR   build folder (default: build)
#   LIFMCR_BUILD_TYPE  CMake build type (default: Release)
#   LIFMCR_BUILD_TARGETS  the targets to build, space-separated (default: all;
#                      scripts/demo.sh builds only `lifmcr`)
set -euo pipefail
# --help: the header above, nothing else run.
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  sed -n '2,/^set -euo pipefail/s/^# \{0,1\}//p' "$0"
  exit 0
fi
cd "$(dirname "$0")/.."

packages=(
  build-essential cmake pkg-config ccache git
  libeigen3-dev libopencv-dev libopencv-contrib-dev libceres-dev libtbb-dev libhwy-dev
  libspdlog-dev libyaml-cpp-dev libcli11-dev nlohmann-json3-dev libtinyxml2-dev
  libgtest-dev libgmock-dev
  libaravis-dev aravis-tools aravis-tools-cli libusb-1.0-0-dev
  liblcm-dev liblcm-bin liblcm-java libjchart2d-java default-jdk-headless
  iproute2 procps
  slurm-wlm munge parallel  # batch plans on a Slurm job array and GNU parallel (tests/batch/test_cluster.cpp)
  clang libfuzzer-14-dev python3  # the libFuzzer pass of scripts/test.sh; bench/fuzz.sh, bench/soak.sh
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

# LCM over UDP multicast: a message larger than the socket's receive buffer
# (Linux default net.core.rmem_default = 208 KiB) is dropped whole when the
# receiver falls behind. LCM's "UDP Multicast Setup" page recommends raising
# both the default and the maximum (its example: 2 MiB); the maximum is 64 MiB
# so a receiver may ask for more with `?recv_buf_size=` in its URL.
sysctl_file=/etc/sysctl.d/60-lifmcr-lcm.conf
sysctl_lines=$'net.core.rmem_default=2097152\nnet.core.rmem_max=67108864'
if [[ $(id -u) -eq 0 ]]; then
  if [[ ! -f $sysctl_file ]] || [[ "$(cat "$sysctl_file")" != *"$sysctl_lines"* ]]; then
    printf '# lifmcr (scripts/setup.sh): UDP receive buffers for LCM, as LCM'"'"'s\n# "UDP Multicast Setup" page recommends.\n%s\n' \
      "$sysctl_lines" >"$sysctl_file"
    echo "setup.sh: installed $sysctl_file (net.core.rmem_default=2 MiB, rmem_max=64 MiB for LCM)"
  fi
  # Applied now too, raising only (a host tuned higher keeps its values).
  for setting in net.core.rmem_default=2097152 net.core.rmem_max=67108864; do
    key=${setting%%=*} want=${setting#*=}
    have=$(sysctl -n "$key" 2>/dev/null || echo 0)
    if ((have < want)) && ! sysctl -q -w "$setting" 2>/dev/null; then
      echo "setup.sh: could not set $setting now (read-only /proc/sys in a container?);" \
        "$sysctl_file applies it at the next boot" >&2
    fi
  done
elif [[ $(sysctl -n net.core.rmem_default 2>/dev/null || echo 0) -lt 2097152 ]]; then
  echo "setup.sh: LCM receivers keep up better with larger UDP buffers; as root run:" >&2
  echo "  printf 'net.core.rmem_default=2097152\nnet.core.rmem_max=67108864\n' >$sysctl_file" \
    "&& sysctl -p $sysctl_file" >&2
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
targets=()
for t in ${LIFMCR_BUILD_TARGETS:-}; do targets+=(--target "$t"); done
if ! cmake --build "$build_dir" -j "$jobs" "${targets[@]}" >"$log" 2>&1; then
  grep -v -E '^\[ *[0-9]+%\]' "$log" | tail -n 80 >&2
  echo "setup.sh: build failed; full log in $log" >&2
  exit 1
fi
