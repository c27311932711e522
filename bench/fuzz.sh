#!/usr/bin/env bash
# usage: bench/fuzz.sh DURATION [TARGET...]   (seconds per target; e.g. bench/fuzz.sh 600 fuzz_bmp)
# Runs every libFuzzer target (tests/fuzz/) for DURATION seconds each, with
# ASan+UBSan, from seed corpora made of the real samples, the example rig
# files and `lifmcr synth` output. Prints per target: executions, coverage
# (cov: edges, ft: features), corpus size and crashes; exits 1 on any crash
# (the input is kept under build-fuzz/artifacts/<target>/).
#   bench/fuzz.sh DURATION [TARGET...]   e.g. bench/fuzz.sh 600 fuzz_bmp
#   LIFMCR_FUZZ_DIR   build folder (default build-fuzz)
#   LIFMCR_FUZZ_JOBS  targets run at once (default 1; each is one process)
#   LIFMCR_FUZZ_NICE  nice level of the fuzzers (default 19: the machine is shared)
set -euo pipefail
# --help: the header above, nothing else run.
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  sed -n '2,/^set -euo pipefail/s/^# \{0,1\}//p' "$0"
  exit 0
fi
cd "$(dirname "$0")/.."
duration=${1:?usage: bench/fuzz.sh DURATION [TARGET...]}
shift
all_targets=(fuzz_bmp fuzz_mla_xml fuzz_vicon_csv fuzz_vsk fuzz_rig_yaml fuzz_intrinsics_yaml
             fuzz_vicon_packet fuzz_lcm_decode fuzz_sequence_discovery fuzz_raw_image
             fuzz_registration_inputs)
targets=("$@")
((${#targets[@]})) || targets=("${all_targets[@]}")
dir=${LIFMCR_FUZZ_DIR:-build-fuzz}
jobs=${LIFMCR_FUZZ_JOBS:-1}
nice_level=${LIFMCR_FUZZ_NICE:-19}

if [[ ! -f "$dir/CMakeCache.txt" ]]; then
  cmake -S . -B "$dir" -DLIFMCR_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ >"$dir.configure.log" 2>&1 ||
    { cat "$dir.configure.log" >&2; exit 1; }
fi
cmake --build "$dir" -j "$(nproc)" --target "${targets[@]}" >"$dir.build.log" 2>&1 ||
  { grep -v -E '^\[ *[0-9]+%\]' "$dir.build.log" | tail -n 60 >&2; exit 1; }

# Seeds (re-made every run; the growing corpus is kept in $dir/corpus).
seeds=$dir/seeds
rm -rf "$seeds"
mkdir -p "$seeds"
for t in "${all_targets[@]}"; do mkdir -p "$seeds/$t" "$dir/corpus/$t"; done
for t in "${targets[@]}"; do rm -rf "$dir/artifacts/$t"; mkdir -p "$dir/artifacts/$t"; done
samples=tests/data/samples
cp "$samples"/*.xml "$seeds/fuzz_mla_xml/"
cp "$samples"/*.vsk "$seeds/fuzz_vsk/"
for f in "$samples"/*.csv; do { printf '\0'; cat "$f"; } >"$seeds/fuzz_vicon_csv/$(basename "$f")"; done
cp config/examples/*.yaml "$seeds/fuzz_rig_yaml/"
# The MLA target's first two bytes are the image size.
for f in "$seeds"/fuzz_mla_xml/*.xml; do { printf '\x30\x20'; cat "$f"; } >"$f.seed"; rm "$f"; done
lifmcr=${LIFMCR_BINARY:-build/apps/lifmcr}
if [[ -x "$lifmcr" ]]; then
  synth=$(mktemp -d)
  "$lifmcr" synth --out "$synth" --preset small --frames 2 --cameras 2 --quiet >/dev/null 2>&1 || true
  find "$synth" -name cameras.yaml -exec cp {} "$seeds/fuzz_intrinsics_yaml/" \;
  find "$synth" -name '*.vsk' -exec cp {} "$seeds/fuzz_vsk/synth.vsk" \;
  n=0
  for f in $(find "$synth" -name '*_MLA.xml'); do
    n=$((n + 1)); { printf '\x40\x30'; cat "$f"; } >"$seeds/fuzz_mla_xml/synth$n.seed"
  done
  # Registration inputs: selector byte 0 intrinsics, 1 plate, 2 poses CSV.
  for f in $(find "$synth" -name cameras.yaml); do
    { printf '\0'; cat "$f"; } >"$seeds/fuzz_registration_inputs/cameras0.yaml"
    { printf '\1'; cat "$f"; } >"$seeds/fuzz_registration_inputs/plate1.yaml"
  done
  for f in $(find "$synth" -name 'poses_*.csv'); do
    { printf '\2'; head -c 8192 "$f"; } >"$seeds/fuzz_registration_inputs/$(basename "$f")"
  done
  for f in $(find "$synth" -name 'sequence_*.csv'); do
    { printf '\0'; head -c 8192 "$f"; } >"$seeds/fuzz_vicon_csv/synth.csv"
  done
  rm -rf "$synth"
fi
python3 - "$seeds" <<'PY'
import os, struct, sys
seeds = sys.argv[1]
def bmp(w, h, bits, top_down=False):
    row = (w * bits // 8 + 3) // 4 * 4
    palette = b''.join(bytes((i, i, i, 0)) for i in range(256)) if bits == 8 else b''
    offset = 14 + 40 + len(palette)
    size = offset + row * h
    head = b'BM' + struct.pack('<IHHI', size, 0, 0, offset)
    info = struct.pack('<IiiHHIIiiII', 40, w, -h if top_down else h, 1, bits, 0, row * h, 2835, 2835,
                       256 if bits == 8 else 0, 0)
    return head + info + palette + bytes((i * 7) & 255 for i in range(row * h))
for name, data in {'grey_7x5': bmp(7, 5, 8), 'bgr_6x3': bmp(6, 3, 24),
                   'grey_top_down': bmp(4, 4, 8, True)}.items():
    open(os.path.join(seeds, 'fuzz_bmp', name + '.bmp'), 'wb').write(data)
def packet(frame, objects):
    out = struct.pack('<IB', frame, len(objects))
    for name, values in objects:
        out += struct.pack('<BH', 0, 72) + name.encode().ljust(24, b'\0') + struct.pack('<6d', *values)
    return out
open(os.path.join(seeds, 'fuzz_vicon_packet', 'two'), 'wb').write(
    packet(1000, [('cam0', (1, 2, 3, 0.1, 0.2, 0.3)), ('plate', (0, 0, 0, 0, 0, 0))]))
open(os.path.join(seeds, 'fuzz_vicon_packet', 'empty'), 'wb').write(packet(7, []))
# LCM: the first byte picks the type (the target puts the hash in front).
def s(text): return struct.pack('>i', len(text) + 1) + text.encode() + b'\0'
lcm = {
  'preview': b'\x00' + struct.pack('>q', 1) + s('40398673') + struct.pack('>qqiiiiibbi', 3, 4, 64, 48, 8, 6, 8, 1, 0, 4) + b'abcd',
  'depth': b'\x01' + struct.pack('>q', 1) + s('1') + struct.pack('>qqbbiifffffbi', 3, 4, 0, 1, 2, 2, 1, 0, 0.5, 1, 3, 0, 4) + b'\0\0\0\0',
  'extrinsics': b'\x02' + struct.pack('>q', 1) + s('a') + s('b') + struct.pack('>q', 2) + s('pnp') + struct.pack('>43d', *([0.0] * 43)) + struct.pack('>id', 10, 0.5) + s('ok'),
  'vicon': b'\x03' + struct.pack('>qqbi', 1, 2, 1, 1) + s('cam0') + b'\x00' + struct.pack('>7d', 1, 2, 3, 1, 0, 0, 0),
  'stats': b'\x04' + struct.pack('>qi', 1, 1) + s('depth') + struct.pack('>diiddqq', 10, 1, 4, 5, 9, 100, 2) + struct.pack('>i', 1) + s('vicon') + struct.pack('>q', 3),
}
for name, data in lcm.items():
    open(os.path.join(seeds, 'fuzz_lcm_decode', name), 'wb').write(data)
# Registration inputs: selector byte 3, an aruco_corners.csv.
open(os.path.join(seeds, 'fuzz_registration_inputs', 'corners'), 'wb').write(
    b'\x03frame,marker_id,corner,tf_x_px,tf_y_px,virtual_depth\n0,0,0,10.5,20.25,3.5\n0,0,1,12,20,\n1,3,3,4,5,2.75\n')
# Raw images: small PNGs (8- and 16-bit grey, 8-bit BGR) and uncompressed TIFFs.
import zlib
def png(w, h, depth, colour):
    channels = 3 if colour == 2 else 1
    row = bytes(((x * 37 + y * 11) & 255) for x in range(w * channels * depth // 8) for y in [0])
    raw = b''.join(b'\0' + row for y in range(h))
    chunk = lambda t, d: struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d))
    return (b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, depth, colour, 0, 0, 0)) +
            chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b''))
def tiff(w, h, bits, fmt=1):
    pixels = bytes((i * 13) & 255 for i in range(w * h * bits // 8))
    entries = [(256, 3, 1, w), (257, 3, 1, h), (258, 3, 1, bits), (259, 3, 1, 1), (262, 3, 1, 1),
               (273, 4, 1, 8), (277, 3, 1, 1), (278, 3, 1, h), (279, 4, 1, len(pixels)), (339, 3, 1, fmt)]
    ifd = struct.pack('<H', len(entries)) + b''.join(
        struct.pack('<HHI', t, k, n) + (struct.pack('<HH', v, 0) if k == 3 else struct.pack('<I', v))
        for t, k, n, v in entries) + struct.pack('<I', 0)
    return b'II*\0' + struct.pack('<I', 8 + len(pixels)) + pixels + ifd
for name, data in {'grey8.png': png(16, 8, 8, 0), 'grey16.png': png(8, 4, 16, 0),
                   'bgr8.png': png(6, 4, 8, 2), 'grey8.tiff': tiff(16, 8, 8),
                   'grey16.tiff': tiff(8, 4, 16), 'float32.tiff': tiff(4, 4, 32, 3)}.items():
    open(os.path.join(seeds, 'fuzz_raw_image', name), 'wb').write(data)
for name in ('grey_7x5', 'bgr_6x3'):
    open(os.path.join(seeds, 'fuzz_raw_image', name + '.bmp'), 'wb').write(
        open(os.path.join(seeds, 'fuzz_bmp', name + '.bmp'), 'rb').read())
# Sequence discovery: (op, name) byte pairs building a small dataset.
tree = bytes([0, 15, 0, 16, 0, 5, 1, 6, 3, 0, 0, 7, 1, 9, 1, 10, 3, 0, 3, 0, 3, 0, 0, 0, 0, 2, 1, 13, 3, 0, 0, 3, 1, 4])
open(os.path.join(seeds, 'fuzz_sequence_discovery', 'dataset'), 'wb').write(tree)
open(os.path.join(seeds, 'fuzz_sequence_discovery', 'loops'), 'wb').write(bytes([0, 15, 4, 16, 5, 9, 6, 13, 7, 17, 1, 18]))
PY
# The synth YAML and the rig examples also seed the intrinsics target.
cp config/examples/*.yaml "$seeds/fuzz_intrinsics_yaml/"

max_len_of() {
  case $1 in
    fuzz_bmp|fuzz_vicon_packet|fuzz_lcm_decode) echo 4096 ;;
    fuzz_sequence_discovery) echo 256 ;;
    *) echo 16384 ;;
  esac
}

run_one() {
  local t=$1
  local log=$dir/fuzz.$t.log
  # -timeout: a single input over 10 s is a hang; -rss_limit_mb: over 2 GB is a leak or
  # an unbounded allocation; both count as crashes.
  nice -n "$nice_level" "$dir/tests/fuzz/$t" "$dir/corpus/$t" "$seeds/$t" \
    -max_total_time="$duration" -max_len="$(max_len_of "$t")" -timeout=10 -rss_limit_mb=2048 \
    -malloc_limit_mb=1024 -print_final_stats=1 -artifact_prefix="$dir/artifacts/$t/" \
    >"$log" 2>&1 || true
}

export -f run_one max_len_of
export dir seeds duration nice_level
printf '%s\n' "${targets[@]}" | xargs -P "$jobs" -I{} bash -c 'run_one {}'

status=0
printf '%-26s %12s %10s %8s %8s %8s %s\n' target executions exec/s cov ft corpus crashes
for t in "${targets[@]}"; do
  log=$dir/fuzz.$t.log
  execs=$(grep -o 'stat::number_of_executed_units: [0-9]*' "$log" | awk '{print $2}' | tail -1)
  rate=$(( ${execs:-0} / duration ))
  last=$(grep -E '^#[0-9]+' "$log" | tail -1)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
  corpus=$(ls "$dir/corpus/$t" | wc -l)
  crashes=$(ls "$dir/artifacts/$t" | wc -l)
  printf '%-26s %12s %10s %8s %8s %8s %s\n' "$t" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" \
    "$corpus" "$crashes"
  if ((crashes > 0)) || grep -q -E 'ERROR: (AddressSanitizer|libFuzzer|UndefinedBehaviorSanitizer)|runtime error|fuzz property violated' "$log"; then
    status=1
    echo "  $t: see $log and $dir/artifacts/$t/" >&2
  fi
done
exit $status
