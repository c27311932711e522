#!/usr/bin/env bash
# usage: bench/timed_replay.sh SEQ_DIR MAP_DIR OUT_DIR [lifmcr replay options...]
# A timed replay (`lifmcr replay SEQ_DIR --rate original --reference MAP_DIR`:
# newest wins, registration first, the lens and depth lanes) recorded by a
# stock lcm-logger on a UDP multicast group over loopback (ttl 0), then the
# log counted per camera by build/bench/bench_replay_log: frames replayed,
# DEPTH messages per-lens and dense (their `geometry`), TF, POSE by
# localisation, EXTRINSICS per trigger, and the frames with a depth and a TF
# message (the gate: >= 90 % of each camera's frames).
#   bench/timed_replay.sh SEQ_DIR MAP_DIR OUT_DIR [--intrinsics FILE ...]
# OUT_DIR gets run.lcmlog, replay.txt (the replay's output, with its final
# report: the lens lane's processed / skipped / failed and CPU per frame),
# counts.txt and the load average before and after (uptime). The replay runs
# under /usr/bin/time -v (its CPU time in replay.txt). Needs root (the
# loopback route of the group), lcm-logger (Debian liblcm-bin) and
# build/apps/lifmcr and build/bench/bench_replay_log built. The logger runs
# at nice -10 with a 4 MiB receive buffer: a starved logger drops messages,
# which is not the replay's loss. LIFMCR_GROUP (default 239.255.76.91) and
# LIFMCR_PORT (default 7691) choose the group; LIFMCR_BINARY another lifmcr
# (an older build, to compare on the same machine and log counter).
set -euo pipefail
# --help: the header above, nothing else run.
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  sed -n '2,/^set -euo pipefail/s/^# \{0,1\}//p' "$0"
  exit 0
fi
if [[ $# -lt 3 ]]; then
  sed -n '2p' "$0" | sed 's/^# //' >&2
  exit 2
fi
root="$(cd "$(dirname "$0")/.." && pwd)"
seq_dir="$1" map_dir="$2" out="$3"
shift 3
lifmcr="${LIFMCR_BINARY:-$root/build/apps/lifmcr}"
counter="$root/build/bench/bench_replay_log"
for program in "$lifmcr" "$counter"; do
  [[ -x "$program" ]] || { echo "timed_replay.sh: $program not built" >&2; exit 1; }
done
command -v lcm-logger >/dev/null || { echo "timed_replay.sh: lcm-logger missing" >&2; exit 1; }
[[ $(id -u) -eq 0 ]] || { echo "timed_replay.sh: needs root (loopback multicast route)" >&2; exit 1; }
group="${LIFMCR_GROUP:-239.255.76.91}"
port="${LIFMCR_PORT:-7691}"
url="udpm://$group:$port?ttl=0"
mkdir -p "$out"
log="$out/run.lcmlog"
rm -f "$log"

ip link set lo multicast on
added_route=0
if ip route add "$group/32" dev lo 2>/dev/null; then added_route=1; fi
logger_pid=""
cleanup() {
  if [[ -n "$logger_pid" ]]; then kill -INT "$logger_pid" 2>/dev/null || true; wait "$logger_pid" 2>/dev/null || true; fi
  if [[ $added_route -eq 1 ]]; then ip route del "$group/32" dev lo 2>/dev/null || true; fi
}
trap cleanup EXIT

nice -n -10 lcm-logger -q --lcm-url="$url&recv_buf_size=4194304" --channel='LIFMCR_.*' "$log" \
  >/dev/null 2>&1 &
logger_pid=$!
# The logger creates its file when it has subscribed; the replay loads its
# map and chain for seconds before its first frame anyway.
for _ in $(seq 50); do [[ -f "$log" ]] && break; sleep 0.1; done
sleep 0.5

{ echo "before: $(uptime)"; } | tee "$out/load.txt"
/usr/bin/time -v "$lifmcr" replay "$seq_dir" --rate original --lcm "$url" \
  --reference "$map_dir" "$@" >"$out/replay.txt" 2>&1 || {
  echo "timed_replay.sh: lifmcr replay failed:" >&2; tail -20 "$out/replay.txt" >&2; exit 1; }
{ echo "after:  $(uptime)"; } | tee -a "$out/load.txt"
sleep 1  # the last datagrams written (the logger flushes every 100 ms)
kill -INT "$logger_pid"
wait "$logger_pid" 2>/dev/null || true
logger_pid=""

grep -E "^(frames in|workers|lens lane skipped|depth lane|published|depth messages|poses)" "$out/replay.txt" || true
grep -E "User time|System time|Elapsed" "$out/replay.txt" || true
"$counter" --log "$log" --sequence "$seq_dir" | tee "$out/counts.txt"
