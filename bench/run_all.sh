#!/usr/bin/env bash
# usage: bench/run_all.sh [--quick] [--out FILE]   (the variables below)
# Runs every benchmark of bench/ one after the other and writes one Markdown
# table of their figures (default bench/results.md): the commit, the date, the
# CPU model, the cores and the load average before and after, then per
# benchmark each figure, its baseline measured in the same run, the ratio the
# benchmark prints (its direction is in bench/README.md), the exit status and
# the wall time. Every benchmark's full output is kept in the log folder.
#   --quick   smallest presets and few frames: a few minutes on 2 cores;
#             bench/fuzz.sh and bench/soak.sh are left out (listed as not run).
#   (none)    every benchmark with its default settings (r32 and medium
#             presets, 40 calibration frames, fuzz 30 s per target, soak
#             10 min): hours on 2 cores.
#   --out FILE  where the table goes (default bench/results.md)
#   LIFMCR_BUILD_DIR        build folder with the benchmarks (default build)
#   LIFMCR_BENCH_LOGS       folder for the outputs (default: a new temporary folder)
#   LIFMCR_BENCH_RECORD_DIR folder bench_record writes into (default /var/tmp)
# A benchmark that fails or whose figure is not found gives a row saying so;
# the script carries on and exits 1 at the end when any did.
# Figures depend on what else runs: read the load average beside them.
set -euo pipefail
# --help: the header above, nothing else run.
if [[ "${1:-}" == -h || "${1:-}" == --help ]]; then
  sed -n '2,/^set -euo pipefail/s/^# \{0,1\}//p' "$0"
  exit 0
fi
cd "$(dirname "$0")/.."

quick=0
out=bench/results.md
while (($#)); do
  case $1 in
    --quick) quick=1 ;;
    --out) out=${2:?--out needs a file}; shift ;;
    -h | --help) ;;
    *) echo "run_all.sh: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
  shift
done

build=${LIFMCR_BUILD_DIR:-build}
bench=$build/bench
lifmcr=$build/apps/lifmcr
for b in bench_bmp bench_sync bench_pnp bench_lcm_sizes bench_scene bench_render bench_depth \
  bench_record bench_pipeline bench_live bench_calibrate bench_depth_bias bench_map_matching \
  bench_batch; do
  [[ -x $bench/$b ]] || { echo "run_all.sh: $bench/$b missing: build first (scripts/setup.sh)" >&2; exit 2; }
done
[[ -x $lifmcr ]] || { echo "run_all.sh: $lifmcr missing: build first" >&2; exit 2; }
logs=${LIFMCR_BENCH_LOGS:-$(mktemp -d /tmp/lifmcr-bench-all-XXXXXX)}
mkdir -p "$logs"
record_dir=${LIFMCR_BENCH_RECORD_DIR:-/var/tmp}/lifmcr-run-all-$$
trap 'rm -rf "$record_dir"' EXIT

commit=$(git rev-parse --short HEAD 2>/dev/null || echo unknown)
git diff --quiet HEAD 2>/dev/null || commit="$commit (with uncommitted changes)"
cpu=$(awk -F': ' '/^model name/ {print $2; exit}' /proc/cpuinfo 2>/dev/null || echo unknown)
cores=$(nproc 2>/dev/null || echo "?")
load_start=$(cut -d' ' -f1-3 /proc/loadavg)
started=$(date -u '+%Y-%m-%d %H:%M UTC')
t_start=$(date +%s)
mode=$([[ $quick == 1 ]] && echo "--quick" || echo "full")

rows=()     # table rows, in order
failed=0

# run NAME LOG COMMAND...: runs one benchmark, its output into LOG; sets rc, wall.
run() {
  local name=$1 log=$2
  shift 2
  echo "run_all.sh: $name: $*" >&2
  local s e
  s=$(date +%s.%N)
  set +e
  "$@" >"$log" 2>&1
  rc=$?
  set -e
  e=$(date +%s.%N)
  wall=$(awk -v s="$s" -v e="$e" 'BEGIN { printf "%.0f", e - s }')
}

# row BENCH FIGURE VALUE BASELINE BASELINE_VALUE RATIO
row() {
  local v=${3:-} b=${5:-} r=${6:-}
  if [[ -z $v ]]; then
    v="not found (see the log)"
    failed=1
  fi
  local f=$2 bl=$4
  v=${v//|/\\|} b=${b//|/\\|} f=${f//|/\\|} bl=${bl//|/\\|}
  rows+=("| $1 | $f | $v | $bl | $b | ${r:--} | $rc | $wall |")
}

# status BENCH: a row for a benchmark whose exit status is its figure.
status_row() {
  rows+=("| $1 | $2 | $3 | | | - | $rc | $wall |")
}

# --- bench_bmp
n=$([[ $quick == 1 ]] && echo 3 || echo 9)
run bench_bmp "$logs/bench_bmp.log" "$bench/bench_bmp" "$n"
for c in "Mono8 bottom-up" "BGR8 bottom-up"; do
  line=$(grep "^$c" "$logs/bench_bmp.log" || true)
  into=$(awk -F'|' '{split($2, a, " "); print a[3]}' <<<"$line")
  rd=$(awk -F'|' '{split($2, a, " "); print a[1]}' <<<"$line")
  ratio=$(awk -F'|' '{split($3, r, " "); print r[1]}' <<<"$line")
  row bench_bmp "ReadBmpInto, $c R32 frame, MB/s" "$into" "one read() of the file, MB/s" "$rd" "$ratio"
done

# --- bench_sync
n=$([[ $quick == 1 ]] && echo 2000 || echo 16000)
run bench_sync "$logs/bench_sync.log" "$bench/bench_sync" "$n"
p99=$(awk '/packet -> FrameSet/ {for (i = 1; i <= NF; i++) if ($i == "p99") print $(i + 1)}' "$logs/bench_sync.log")
b99=$(awk '/packet -> ViconFrame \(baseline\)/ {for (i = 1; i <= NF; i++) if ($i == "p99") print $(i + 1)}' "$logs/bench_sync.log")
ratio=$(sed -n 's/.*ratio FrameSet \/ baseline: .*p99 \([0-9.]*x\).*/\1/p' "$logs/bench_sync.log")
row bench_sync "Vicon packet -> FrameSet p99, us" "$p99" "packet -> ViconFrame p99, us" "$b99" "$ratio"

# --- bench_pnp
if [[ $quick == 1 ]]; then args=(--problems 5 --repeat 1); else args=(); fi
run bench_pnp "$logs/bench_pnp.log" "$bench/bench_pnp" "${args[@]}"
for o in 50 80; do
  sect=$(awk -v o="$o" '/^outliers/ {on = ($2 == o)} on' "$logs/bench_pnp.log")
  t=$(awk '/lifmcr PnP \(LO-RANSAC\+Ceres\)/ {print $(NF - 9)}' <<<"$sect")
  ocv=$(awk '/OpenCV USAC inner LO/ {print $(NF - 9)}' <<<"$sect")
  ratio=$(sed -n 's/.*ratio time OpenCV (inner LO) \/ lifmcr: \([0-9.]*x\) with the Ceres step.*/\1/p' <<<"$sect")
  row bench_pnp "plenoptic PnP, $o % outliers, ms" "$t" "OpenCV USAC inner LO + RefineLM, ms" "$ocv" "$ratio"
done

# --- bench_lcm_sizes
if [[ $quick == 1 ]]; then args=(--presets small); else args=(); fi
run bench_lcm_sizes "$logs/bench_lcm_sizes.log" "$bench/bench_lcm_sizes" "${args[@]}"
while read -r preset largest ratio; do
  row bench_lcm_sizes "largest message per frame, $preset, bytes" "$largest" "stock receive buffer, bytes" 212992 "$ratio"
done < <(awk '/largest \/ stock rmem_default/ {r = $0; sub(/.*rmem_default /, "", r); sub(/;.*/, "", r); print $1, $7, r}' \
  "$logs/bench_lcm_sizes.log")
grep -q "largest / stock rmem_default" "$logs/bench_lcm_sizes.log" || row bench_lcm_sizes "largest message" "" "" "" ""

# --- bench_scene
if [[ $quick == 1 ]]; then args=(--preset small); else args=(); fi
run bench_scene "$logs/bench_scene.log" "$bench/bench_scene" "${args[@]}"
table=$(awk '/^scene table/ {getline; print $8}' "$logs/bench_scene.log")
plain=$(awk '/^scene plain/ {getline; print $8}' "$logs/bench_scene.log")
ratio=$(sed -n 's/^SIFT on the processed TF image: table \/ plain \(x[0-9.]*\).*/\1/p' "$logs/bench_scene.log")
row bench_scene "SIFT keypoints on the TF image, table scene" "$table" "the same, plain scene" "$plain" "$ratio"

# --- bench_render
if [[ $quick == 1 ]]; then args=(--preset small --repeat 1); else args=(); fi
run bench_render "$logs/bench_render.log" "$bench/bench_render" "${args[@]}"
t=$(sed -n 's/^raw frame: \([0-9.]*\) s median.*/\1/p' "$logs/bench_render.log")
mp=$(sed -n 's/^raw frame: .*(\([0-9.]*\) MP\/s).*/\1/p' "$logs/bench_render.log")
b=$(sed -n 's/^baseline, scene plain: raw frame \([0-9.]*\) s.*/\1/p' "$logs/bench_render.log")
ratio=$(sed -n 's/.*this scene \/ plain: raw \(x[0-9.]*\).*/\1/p' "$logs/bench_render.log")
row bench_render "raw frame of the table scene, s (${mp:-?} MP/s)" "$t" "the same frame, plain scene, s" "$b" "$ratio"

# --- bench_depth (the 2-core figure: taskset -c 0,1 where there are more)
if [[ $quick == 1 ]]; then args=(--preset small --repeat 1); else args=(); fi
pin=()
((cores > 2)) && command -v taskset >/dev/null && pin=(taskset -c 0,1)
run bench_depth "$logs/bench_depth.log" "${pin[@]}" "$bench/bench_depth" "${args[@]}"
d=$(sed -n 's/^depth: \([0-9.]*\) raw MP\/s.*/\1/p' "$logs/bench_depth.log")
nb=$(sed -n 's/^naive block matching: \([0-9.]*\) raw MP\/s.*/\1/p' "$logs/bench_depth.log")
ratio=$(sed -n 's/^naive block matching: .*ratio \([0-9.]*x\).*/\1/p' "$logs/bench_depth.log")
row bench_depth "virtual depth, raw MP/s" "$d" "brute-force block matching (1 thread), raw MP/s" "$nb" "$ratio"
acc=$(sed -n 's/^depth: .*; \(coverage [^:]*\): .*/\1/p' "$logs/bench_depth.log")
gates=$(sed -n 's/^depth: .*: \(gates [a-z ]*\)$/\1/p' "$logs/bench_depth.log")
row bench_depth "virtual depth accuracy vs ground truth" "$acc" "gates: coverage 50 %, median 2 %, outliers 5 %" "${gates:-}" "-"
tf=$(sed -n 's/^tf: \([0-9.]*\) output MP\/s.*/\1/p' "$logs/bench_depth.log")
ntf=$(sed -n 's/^naive TF .*: \([0-9.]*\) output MP\/s.*/\1/p' "$logs/bench_depth.log")
ratio=$(sed -n 's/^naive TF .*ratio \([0-9.]*x\).*/\1/p' "$logs/bench_depth.log")
row bench_depth "TF depth + TF image, output MP/s" "$tf" "naive renderer (1 thread), output MP/s" "$ntf" "$ratio"

# --- bench_record
mkdir -p "$record_dir"
gb=$([[ $quick == 1 ]] && echo 0.5 || echo 3)
run bench_record "$logs/bench_record.log" "$bench/bench_record" "$record_dir" "$gb"
mb=$(sed -n 's/.* = \([0-9.]*\) MB\/s sustained.*/\1/p' "$logs/bench_record.log")
dd=$(sed -n 's/.*mean \([0-9.]*\) MB\/s.*/\1/p' "$logs/bench_record.log")
ratio=$(sed -n 's/.*ratio recorder \/ dd: \([0-9.]*\).*/\1/p' "$logs/bench_record.log")
row bench_record "recorder, 2 R32-sized cameras, MB/s ($(sed -n 's/.*disk path: \(.*\)$/\1/p' "$logs/bench_record.log" | head -1))" \
  "$mb" "dd oflag=direct, same folder, MB/s" "$dd" "$ratio"
rm -rf "$record_dir"

# --- bench_pipeline
if [[ $quick == 1 ]]; then args=(--preset small --frames 3 --vicon-packets 400); else args=(); fi
run bench_pipeline "$logs/bench_pipeline.log" "$bench/bench_pipeline" "${args[@]}"
fps=$(sed -n 's/^pipeline end to end: \([0-9.]*\) frames\/s.*/\1/p' "$logs/bench_pipeline.log")
alone=$(sed -n 's/^processing alone (same stage, sequential): \([0-9.]*\) frames\/s.*/\1/p' "$logs/bench_pipeline.log")
ratio=$(sed -n 's/^ratio pipeline \/ processing alone: \([0-9.]*\).*/\1/p' "$logs/bench_pipeline.log")
row bench_pipeline "live pipeline end to end, frames/s" "$fps" "processing alone, frames/s" "$alone" "$ratio"
for block in "memq://, pipeline idle" "memq://, camera frames flowing"; do
  sect=$(awk -v b="Vicon over $block" 'index($0, b) == 1 {on = 1; next} /^Vicon over|^[a-z]/ {on = 0} on' \
    "$logs/bench_pipeline.log")
  lcm=$(awk '/LIFMCR_VICON received/ {for (i = 1; i <= NF; i++) if ($i == "p99") print $(i + 1)}' <<<"$sect")
  base=$(awk '/ViconFrame parsed/ {for (i = 1; i <= NF; i++) if ($i == "p99") print $(i + 1)}' <<<"$sect")
  ratio=$(sed -n 's/.*ratio LCM \/ baseline: .*p99 \([0-9.]*x\).*/\1/p' <<<"$sect")
  row bench_pipeline "Vicon packet -> LCM p99 ($block), us" "$lcm" "packet -> parsed p99, us" "$base" "$ratio"
done

# --- bench_live
if [[ $quick == 1 ]]; then args=(--preset small --frames 3 --seconds 5); else args=(); fi
run bench_live "$logs/bench_live.log" "$bench/bench_live" "${args[@]}"
tr_hz=$(sed -n 's/^track *extrinsics \([0-9.]*\) Hz per camera.*/\1/p' "$logs/bench_live.log")
re_hz=$(sed -n 's/^relocalise *extrinsics \([0-9.]*\) Hz per camera.*/\1/p' "$logs/bench_live.log")
ratio=$(sed -n 's/^ratios: extrinsics rate track \/ relocalise \([0-9.]*\);.*/\1/p' "$logs/bench_live.log")
row bench_live "live registration, tracking, extrinsics/s per camera" "$tr_hz" "every frame relocalised, extrinsics/s" "$re_hz" "$ratio"
err() { awk -v run="$1" '$1 == run {on = 1} on && /c0_from_cx error all/ {print $(NF - 10), $(NF - 9), $(NF - 8), $(NF - 7), $(NF - 6); exit}' \
  "$logs/bench_live.log"; }
ratio=$(sed -n 's/.*track \/ relocalise (c0_from_cx error.*translation median \([0-9.]*\) .*/\1/p' "$logs/bench_live.log")
row bench_live "c0_from_cx median error, tracking" "$(err track)" "every frame relocalised" "$(err relocalise)" "$ratio"

# --- bench_calibrate, one run per motion (quick: 8 small frames from 1.8 m,
# where the plate is whole in view; full: 40 medium frames)
for motion in orbit smooth handheld; do
  log="$logs/bench_calibrate_$motion.log"
  if [[ $quick == 1 ]]; then
    mkdir -p "$logs/calibrate_$motion"
    printf 'rig:\n  viewing_distance_mm: 1800\n' >"$logs/calibrate_$motion/synth.yaml"
    "$lifmcr" synth --out "$logs/calibrate_$motion" --preset small --cameras 1 --frames 8 --motion "$motion" \
      --config "$logs/calibrate_$motion/synth.yaml" --quiet >"$logs/calibrate_synth_$motion.log" 2>&1 || true
    args=(--sequence "$logs/calibrate_$motion/00_Synthetic/Sequence_00" --frames 8)
  else
    args=(--motion "$motion")
  fi
  run bench_calibrate "$log" "$bench/bench_calibrate" "${args[@]}"
  t=$(sed -n 's/^calibration \([0-9.]*\) s (.*/\1/p' "$log" | head -1)
  per=$(sed -n 's/.*processing [0-9.]* s (\([0-9.]*\) s per frame.*/\1/p' "$log" | head -1)
  ratio=$(sed -n 's/^calibration .*, \([0-9.]*\) x the processing of one frame.*/\1/p' "$log" | head -1)
  row bench_calibrate "$motion: calibration (initialisation + bundle adjustment), s" "$t" "processing of one frame, s" "$per" "$ratio"
  acc=$(awk '/^from 5 % off/ {getline; sub(/^ *vs ground truth: /, ""); print; exit}' "$log" |
    sed 's/, keypoint v.*//; s/ (\([0-9]*\) points;[^)]*)/ (\1 points)/')
  row bench_calibrate "$motion: from 5 % off, vs ground truth" "$acc" "gates: 0.5 %, 1 px, 0.3 px, 1 mm, 1 mm / 0.05 deg, 0.2 %" "" "-"
done

# --- bench_depth_bias (on a synthetic frame written here)
preset=$([[ $quick == 1 ]] && echo small || echo medium)
"$lifmcr" synth --out "$logs/bias_seq" --preset "$preset" --cameras 1 --frames 1 --quiet >"$logs/bias_synth.log" 2>&1 || true
run bench_depth_bias "$logs/bench_depth_bias.log" "$bench/bench_depth_bias" "$logs/bias_seq/00_Synthetic/Sequence_00" 0
fit=$(sed -n 's/^fit v_measured = .*pulled to \(B [-+0-9.]* %\).*/\1/p' "$logs/bench_depth_bias.log")
base=$(sed -n 's/.*baseline median |error| \([0-9.]* %\).*/\1/p' "$logs/bench_depth_bias.log")
ratio=$(sed -n 's/.*baseline median |error| .*: ratio \([-0-9.a-z]*\).*/\1/p' "$logs/bench_depth_bias.log")
row bench_depth_bias "virtual depth bias ($preset frame), as the B a calibration is pulled to" "$fit" \
  "median per-pixel |error|" "$base" "$ratio"

# --- bench_map_matching (a small rig written by the benchmark)
if [[ $quick == 1 ]]; then
  args=(--frames 10 --map-points 1700,4000 --queries 1 --repeat 1 --observations ground-truth)
else args=(); fi
run bench_map_matching "$logs/bench_map_matching.log" "$bench/bench_map_matching" "${args[@]}"
line=$(grep '^largest map' "$logs/bench_map_matching.log" || true)
pts=$(sed -n 's/^largest map \([0-9]*\) points.*/\1/p' <<<"$line")
appr=$(sed -n 's/.*: approximate \([0-9.]*\) ms, .*/\1/p' <<<"$line")
ex=$(sed -n 's/.*, exact \([0-9.]*\) ms per frame.*/\1/p' <<<"$line")
ratio=$(sed -n 's/.*, ratio \([0-9.]*x\),.*/\1/p' <<<"$line")
row bench_map_matching "one frame's matching + PnP against a map of $pts points (kd-forest), ms" \
  "$appr" "exact (brute-force) matching + PnP, ms" "$ex" "$ratio"

# --- bench_batch
if [[ $quick == 1 ]]; then args=(--preset small --frames 4 --repeat 1); else args=(); fi
run bench_batch "$logs/bench_batch.log" "$bench/bench_batch" "${args[@]}"
t2=$(sed -n 's/^2 shards on 2 cores \([0-9.]*\) s against.*/\1/p' "$logs/bench_batch.log")
t1=$(sed -n 's/^2 shards on 2 cores .* against 1 shard on 1 core \([0-9.]*\) s.*/\1/p' "$logs/bench_batch.log")
speedup=$(sed -n 's/^2 shards on 2 cores .*: \([0-9.]*x\) (goal.*/\1/p' "$logs/bench_batch.log")
row bench_batch "depth plan, 2 shards on 2 cores, s" "$t2" "1 shard on 1 core, s" "$t1" "$speedup"
bare=$(sed -n 's/^[0-9]* units; fastest of [0-9]*: bare commands \([0-9.]*\) s.*/\1/p' "$logs/bench_batch.log")
one=$(sed -n 's/^[0-9]* units; .* batch run 1 shard \([0-9.]*\) s$/\1/p' "$logs/bench_batch.log")
over=$(sed -n 's/^overhead of batch run: .*, \([-+0-9.]* %\) of wall time.*/\1/p' "$logs/bench_batch.log")
row bench_batch "batch run of the depth plan, 1 shard, s" "$one" "the bare commands, s" "$bare" "$over"

# --- bench/fuzz.sh and bench/soak.sh (full run only)
if [[ $quick == 1 ]]; then
  rc=-; wall=-
  status_row bench/fuzz.sh "libFuzzer targets, 30 s each" "not run with --quick"
  status_row bench/soak.sh "record + replay + publish with faults" "not run with --quick"
else
  run fuzz.sh "$logs/fuzz.log" bench/fuzz.sh 30
  if grep -q '^target  *executions' "$logs/fuzz.log"; then
    crashes=$(awk 'f && NF >= 7 {c += $7} /^target +executions/ {f = 1} END {print c + 0}' "$logs/fuzz.log")
    status_row bench/fuzz.sh "libFuzzer targets, 30 s each" "crashes: $crashes"
  else
    status_row bench/fuzz.sh "libFuzzer targets, 30 s each" "did not run: see the log"
    failed=1
  fi
  run soak.sh "$logs/soak.log" bench/soak.sh 10
  status_row bench/soak.sh "10 min of record + replay + publish with faults" \
    "$([[ $rc == 0 ]] && echo "every check passed (exit 0)" || echo "failed: see the log")"
  [[ $rc == 0 ]] || failed=1
fi

load_end=$(cut -d' ' -f1-3 /proc/loadavg)
minutes=$(( ($(date +%s) - t_start + 30) / 60 ))

mkdir -p "$(dirname "$out")"
{
  echo "# Benchmark figures"
  echo
  echo "Written by \`bench/run_all.sh $([[ $quick == 1 ]] && echo --quick)\` (what each benchmark measures, and the"
  echo "direction of each ratio: [bench/README.md](README.md)). Rerun it to replace this file."
  echo
  echo "| | |"
  echo "| --- | --- |"
  echo "| commit | $commit |"
  echo "| date | $started |"
  echo "| mode | $mode |"
  echo "| CPU | $cpu, $cores cores |"
  echo "| load average (1, 5, 15 min) | $load_start at the start, $load_end at the end |"
  echo "| wall time | $minutes min |"
  echo
  echo "| benchmark | figure | value | baseline (same run) | baseline value | ratio | exit | wall s |"
  echo "| --- | --- | --- | --- | --- | --- | --- | --- |"
  printf '%s\n' "${rows[@]}"
  echo
  echo "Outputs of this run: \`$logs\` (not kept in the repository). An exit status of 1"
  echo "with figures beside it is a goal the benchmark reports as not met (see its log)."
} >"$out"
echo "run_all.sh: wrote $out ($mode, $minutes min; logs in $logs)" >&2
cat "$out"
exit "$failed"
