#!/usr/bin/env bash
# usage: bench/soak.sh MINUTES [WORK_DIR]
# Soak run: replay + record + publish of a synthetic rig for MINUTES, with
# faults on a schedule, then a full-disk phase. Reports frames in/out/lost by
# kind (lifmcr record's final report), resident memory over time, and checks
# that nothing already recorded was lost (every recorded frame's header read
# back by `lifmcr info`, counts equal to what the recorder says it wrote).
#   bench/soak.sh MINUTES [WORK_DIR]
# Needs build/apps/lifmcr, python3 and lcm-logger (Debian liblcm-bin).
#
# The rig: two replay cameras (driver.loop: true) of a synthetic sequence
# (256x192 Bayer frames, 10 Hz triggers in software), a Vicon Tracker UDP
# stream at 80 Hz from a sender in this script, the recorder, and --publish
# (depth and previews on LCM, UDP multicast on loopback, ttl 0).
# Faults, every minute (t = seconds into the minute):
#   10..20  camera 2 disappears (its folder is moved away) and returns
#   30..33  Vicon stream gap (the sender stops; the Vicon keeps counting)
#   40..50  slow LCM receiver (lcm-logger stopped with SIGSTOP, then SIGCONT)
# At the end: SIGTERM to the recorder (a clean stop is expected); then a
# second, short recording with a 20 MB file-size limit (a full disk): it must
# stop by itself, keeping every file written before.
# Memory: VmRSS of the recorder every 5 s; "flat" = the last third's maximum
# within 10 % (and 20 MB) of the maximum after the 2-minute warm-up.
set -euo pipefail
# --help: the header above, nothing else run.
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  sed -n '2,/^set -euo pipefail/s/^# \{0,1\}//p' "$0"
  exit 0
fi
cd "$(dirname "$0")/.."
minutes=${1:?usage: bench/soak.sh MINUTES [WORK_DIR]}
work=${2:-$(mktemp -d /tmp/lifmcr_soak.XXXXXX)}
lifmcr=$PWD/build/apps/lifmcr
[[ -x $lifmcr ]] || { echo "soak.sh: build lifmcr first (build/apps/lifmcr)" >&2; exit 2; }
command -v lcm-logger >/dev/null || { echo "soak.sh: lcm-logger missing (liblcm-bin)" >&2; exit 2; }
mkdir -p "$work"
echo "soak.sh: $minutes min in $work"
port=$((52000 + RANDOM % 1000))
lcm_url="udpm://239.255.76.67:$((7700 + RANDOM % 200))?ttl=0"

# ---------------------------------------------------------------- the rig
cat >"$work/synth.yaml" <<YAML
camera: {width_px: 256, height_px: 192, micro_image_pitch_px: 16, bayer: true}
YAML
"$lifmcr" synth --out "$work/data" --preset small --config "$work/synth.yaml" --cameras 2 \
  --frames 30 --quiet >"$work/synth.log" 2>&1
seq=$(dirname "$(find "$work/data" -type d -name Vicon | head -1)")
calib=$work/data/Calibration/02_MLA_Calibration
serials=($(ls "$seq" | sed -n 's/^TypeE_\(.*\)$/\1/p' | sort))
replay=$work/replay_seq
rm -rf "$replay"
cp -r "$seq" "$replay"
cat >"$work/rig.yaml" <<YAML
rig: {name: soak}
cameras:
  - serial: "${serials[0]}"
    name: cam0
    role: reference
    driver: {kind: replay, loop: true}
    mla_file: $calib/TypeE_${serials[0]}_MLA.xml
    trigger: {mode: software}
    pixel_format: BayerRG8
    vicon_object: cam0
  - serial: "${serials[1]}"
    name: cam1
    role: registered
    driver: {kind: replay, loop: true}
    mla_file: $calib/TypeE_${serials[1]}_MLA.xml
    trigger: {mode: software}
    pixel_format: BayerRG8
    vicon_object: cam1
vicon:
  source: udp
  udp: {address: 127.0.0.1, port: $port}
  plate_object: plate
  rate_hz: 80
  trigger_divider: 8
recorder: {queue_frames: 8, direct_io: false}
processing: {threads: 1}
YAML

# ---------------------------------------------------------------- helpers
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -CONT "$p" 2>/dev/null || true; kill "$p" 2>/dev/null || true; done
  [[ -d "$replay/TypeE_${serials[1]}.gone" ]] && mv "$replay/TypeE_${serials[1]}.gone" "$replay/TypeE_${serials[1]}"
  mountpoint -q "$work/small_disk" 2>/dev/null && umount "$work/small_disk"
  true
}
trap cleanup EXIT

# The Vicon Tracker UDP object stream (drivers/vicon_tracker_packet.h) at 80 Hz;
# while $work/vicon_pause exists nothing is sent but the frame number counts on.
python3 - "$port" "$work/vicon_pause" >"$work/vicon_sender.log" 2>&1 <<'PY' &
import math, os, socket, struct, sys, time
port, pause = int(sys.argv[1]), sys.argv[2]
sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
frame, due, sent = 1000, time.monotonic(), 0
while True:
    if not os.path.exists(pause):
        out = struct.pack('<IB', frame, 3)
        for i, name in enumerate(('cam0', 'cam1', 'plate')):
            a = 0.001 * frame + i
            out += struct.pack('<BH', 0, 72) + name.encode().ljust(24, b'\0')
            out += struct.pack('<6d', 100.0 * math.cos(a), 10.0 * i, 1500.0, 0.0, 0.0, 0.1 * math.sin(a))
        sock.sendto(out, ('127.0.0.1', port))
        sent += 1
    frame += 1
    due += 1 / 80
    time.sleep(max(0.0, due - time.monotonic()))
PY
pids+=($!)

lcm-logger --lcm-url="$lcm_url" -f "$work/published.lcm" >"$work/lcm_logger.log" 2>&1 &
logger_pid=$!
pids+=($logger_pid)

# ---------------------------------------------------------------- the run
"$lifmcr" record --rig "$work/rig.yaml" --replay "$replay" --out "$work/rec" --sequence soak \
  --publish --lcm "$lcm_url" >"$work/record.out" 2>"$work/record.err" &
rec=$!
pids+=($rec)
echo "t_s,rss_mb" >"$work/rss.csv"
start=$(date +%s)
end=$((start + 60 * minutes))
faults=0
camera_gone=0 vicon_paused=0 logger_stopped=0 next_sample=0
# States, not edges: a slow iteration cannot skip a fault's start or end.
while (( $(date +%s) < end )); do
  t=$(( $(date +%s) - start )); s=$((t % 60))
  kill -0 "$rec" 2>/dev/null || { echo "soak.sh: the recorder ended early" >&2; break; }
  if ((t >= next_sample)); then
    rss=$(awk '/VmRSS/ {print $2}' "/proc/$rec/status" 2>/dev/null || echo 0)
    echo "$t,$((rss / 1024))" >>"$work/rss.csv"
    next_sample=$((next_sample + 5))
  fi
  want=$((s >= 10 && s < 20))
  if ((want != camera_gone)); then
    if ((want)); then
      mv "$replay/TypeE_${serials[1]}" "$replay/TypeE_${serials[1]}.gone"; faults=$((faults + 1))
    else
      mv "$replay/TypeE_${serials[1]}.gone" "$replay/TypeE_${serials[1]}"
    fi
    camera_gone=$want
  fi
  want=$((s >= 30 && s < 33))
  if ((want != vicon_paused)); then
    if ((want)); then touch "$work/vicon_pause"; faults=$((faults + 1)); else rm -f "$work/vicon_pause"; fi
    vicon_paused=$want
  fi
  want=$((s >= 40 && s < 50))
  if ((want != logger_stopped)); then
    if ((want)); then kill -STOP "$logger_pid"; faults=$((faults + 1)); else kill -CONT "$logger_pid"; fi
    logger_stopped=$want
  fi
  sleep 0.5
done
rm -f "$work/vicon_pause"
kill -CONT "$logger_pid" 2>/dev/null || true
[[ -d "$replay/TypeE_${serials[1]}.gone" ]] && mv "$replay/TypeE_${serials[1]}.gone" "$replay/TypeE_${serials[1]}"
kill -TERM "$rec" 2>/dev/null || true
set +e
wait "$rec"
rec_exit=$?
set -e

# ---------------------------------------------------------------- full disk
# A real full disk where possible: an 8 MB tmpfs (root can mount one); else
# a 200 KiB file-size limit, which the Vicon CSV outgrows after ~25 s and
# whose write then fails with EFBIG as on a full disk.
disk_root=$work/small_disk
mkdir -p "$disk_root"
if mount -t tmpfs -o size=8m tmpfs "$disk_root" 2>/dev/null; then
  disk_how="an 8 MB tmpfs filling up (ENOSPC)"
  limit=unlimited
else
  disk_how="a 200 KiB file-size limit (EFBIG)"
  limit=200
fi
disk_exit=0
(
  ulimit -f "$limit"
  exec "$lifmcr" record --rig "$work/rig.yaml" --replay "$replay" --out "$disk_root" \
    --sequence full_disk --duration 120 >"$work/disk.out" 2>"$work/disk.err"
) || disk_exit=$?

# ---------------------------------------------------------------- checks
check_recording() {  # root name report: every frame's header reads back; counts match the report
  local root=$1 name=$2 report=$3
  "$lifmcr" info --json "$root/00_Recording/$name" >"$work/info_$name.json" 2>"$work/info_$name.err" || true
  python3 - "$work/info_$name.json" "$report" "$name" <<'PY'
import json, re, sys
info = json.load(open(sys.argv[1]))
report = open(sys.argv[2]).read()
seq = info['sequence']
ok = True
for cam in seq['cameras']:
    m = re.search(r'camera %s: recorded (\d+)' % re.escape(cam['serial']), report)
    written = int(m.group(1)) if m else -1
    problems = cam.get('problems', [])
    print('  %s %s: recorder wrote %d, on disk %d frames, %d headers checked, %d unreadable' % (
        sys.argv[3], cam['serial'], written, cam['frame_count'], cam['frames_checked'], len(problems)))
    ok &= written == cam['frame_count'] and not problems
for v in seq['vicon']:
    for b in v.get('blocks', []):
        print('  %s Vicon CSV: %d rows, problems %d' % (sys.argv[3], b['frames'], len(v.get('problems', []))))
    ok &= not v.get('problems')
print('  %s: %s' % (sys.argv[3], 'nothing recorded was lost' if ok else 'RECORDED DATA LOST OR UNREADABLE'))
sys.exit(0 if ok else 1)
PY
}

status=0
echo
echo "=== soak: $minutes min, $faults faults injected (camera gone 10 s, Vicon gap 3 s, LCM receiver stopped 10 s, each minute), SIGTERM at the end"
echo "--- recorder (exit $rec_exit; 0 = nothing lost, 1 = losses counted below)"
cat "$work/record.out"
echo "--- resident memory of the recorder (MB), every 5 s"
python3 - "$work/rss.csv" <<'PY'
import csv, sys
rows = [(int(r['t_s']), int(r['rss_mb'])) for r in csv.DictReader(open(sys.argv[1])) if int(r['rss_mb']) > 0]
if not rows:
    print('  no samples'); sys.exit(0)
per_min = {}
for t, r in rows: per_min.setdefault(t // 60, []).append(r)
print('  minute: max RSS MB  ' + '  '.join('%d:%d' % (m, max(v)) for m, v in sorted(per_min.items())))
warm = [r for t, r in rows if t >= 120] or [r for _, r in rows]
last = [r for t, r in rows if t >= rows[-1][0] * 2 // 3] or warm
flat = max(last) <= max(warm[: max(1, len(warm) // 3)]) * 1.10 + 20
print('  after warm-up (t >= 120 s): min %d, max %d MB; last third max %d MB -> %s' % (
    min(warm), max(warm), max(last), 'flat' if flat else 'GROWING'))
PY
echo "--- full-disk phase: $disk_how (exit $disk_exit; expected 1: stopped by a write error)"
grep -E "stopped by|camera|disk|result" "$work/disk.out" || true
grep -q "stopped by: write error" "$work/disk.out" || { echo "  the full disk did not stop the recording"; status=1; }
echo "--- what was recorded, read back"
check_recording "$work/rec" soak "$work/record.out" || status=1
check_recording "$disk_root" full_disk "$work/disk.out" || status=1
mountpoint -q "$disk_root" && umount "$disk_root"
echo "--- published: $(stat -c %s "$work/published.lcm" 2>/dev/null || echo 0) bytes logged by the (sometimes stopped) lcm-logger"
grep -E "^published|^  " "$work/record.out" | sed -n '/published/,$p' | head -20 || true
exit $status
