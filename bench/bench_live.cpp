// bench_live: live registration's throughput and latency, beside baselines
// measured in the same run.
//
// A synthetic rig (default preset medium, 2 cameras, the table scene;
// rendering not timed) is replayed at its trigger rate (10 Hz, newest wins)
// through `lifmcr replay --reference`'s path (RunReplay with
// LiveRegistrationOptions): a reference map of camera 0 from the ground
// truth (registration/map/ground_truth_map.h, written and read back as a map
// folder), true intrinsics, depth and previews published on memq://. Three
// runs of --seconds each:
//   track        the localizer as it runs live: tracked when it has a pose,
//                relocalised otherwise;
//   relocalise   the baseline: every frame relocalised (global matching and
//                full LO-RANSAC), LocalizerOptions::track = false;
//   depth only   no registration: what processing and publishing alone give.
// How the rendered frames are replayed (--loop):
//   pingpong     (the default) forward then backward through them, 0 1 .. N-1
//                N-2 .. 1 0 1 .., as one sequence whose trigger index keeps
//                increasing: the cameras move on continuously as a live rig
//                does (they only turn round at each end). The sequence is a
//                folder of links to the rendered frames (a folder of the run's own
//                under /tmp, removed when it ends; the calibration linked beside it), long enough for --seconds at
//                10 Hz; the replay loops it only beyond that.
//   restart      the rendered sequence looped: at each pass's first trigger
//                both cameras jump from the last frame's pose back to the
//                first's and the trigger index restarts, so the localizer
//                drops their state and relocalises them (the relocalisation
//                run measures that cost on every frame). At r32 with 8
//                frames a pass (0.8 s) is shorter than a relocalisation, and
//                that jump decided the figures.
// Per run: extrinsics per second per camera X, frame -> extrinsics latency
// (arrival of camera X's frame at the pipeline -> its c0_from_cx on LCM;
// p50, p99), frames taken (localised; depth only: processed) and skipped
// per second (and frames in, of the 20 offered per second: over the whole
// run, the set-up before the first frame and the drain after the last make
// most of the difference, so also over the span from the first frame in to
// the last, where only the replay cameras' losses, sync's and the pauses
// between passes of the loop do), previews and depth maps published per
// second (with a
// registration stage the depth lane's, apps/pipeline/pipeline.h), the
// per-lens depth maps and TF images per second (every frame taken), and
// Localize's mean time tracked vs relocalised. The extrinsics rate also per
// second of frames in (the span from the first frame in to the last, without
// the set-up before the first frame), which the track run's gates line
// (PrintGates) judges. Ratios: track / relocalise
// extrinsics rate and latency; depth maps published track / depth only
// (what localising every frame costs the depth lane).
// Accuracy (track and relocalise runs): each extrinsics message received in
// the window against GroundTruth/poses_<serial>.csv of its trigger (the
// replay's trigger index is the sequence's frame number, from 0 again each
// pass of the loop): c0_from_cx_true = world_from_c0^-1 world_from_cx, the
// translation difference (mm) and the angle of R_est^T R_true (deg),
// median and p90, over all `ok` messages, split by how camera X's pose was
// made (the message's localisation: tracked, re-anchored, relocalised) and
// by how both cameras' poses were made (ExtrinsicsRecord's
// reference_localisation: c0_from_cx carries both poses' errors); the
// fraction of messages (triggers with both poses) that are `ok`, and the
// others by the camera whose pose is missing, skipped (passed through while
// that camera was being relocalised) or failed. Ratios: track / relocalise
// errors (above 1: tracking's poses are worse than relocalising every frame).
//
//   bench_live [--preset small|medium|r32] [--frames N (24)] [--seconds S]
//              [--concurrency N] [--keep DIR] [--runs track,relocalise,depth]
//              [--lens-nice 0..19 (15)] [--lens-queue 1..8 (4)] [--depth-idle 0|1 (1)]
//              [--loop pingpong|restart (pingpong)] [--cold-reanchor-rounds R]
//              [--refine-step 0..3] [--widen-ahead N>=2] [--reanchor-every N>=1]
//              [--rows FILE]
// --keep DIR renders into DIR once and reuses it (same preset and frames)
// in later runs; DIR is left in place.
// Goals (2 cores): >= 5 Hz per camera at medium, >= 2 Hz at r32.

#include "bench/bench_usage.h"
#include "apps/pipeline/camera_setup.h"
#include "apps/pipeline/live_registration.h"
#include "apps/pipeline/process_settings.h"
#include "apps/pipeline/replay_runner.h"
#include "registration/map/ground_truth_map.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/map/poses_csv.h"
#include "registration/map/reference_map.h"
#include "replay/layout.h"
#include "replay/synth/cameras_yaml.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"

#include <lcm/lcm-cpp.hpp>
#include <lifmcr_lcm/camera_pose_t.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <sys/resource.h>
#include <thread>
#include <vector>

namespace {

using namespace lifmcr;
namespace fs = std::filesystem;

struct Args {
  std::string preset = "medium";
  // 24: the loop's jump from the last frame back to the first (the cameras'
  // poses a whole orbit segment apart) relocalises both cameras each pass,
  // which a live rig never sees; with 6 frames that was every 0.6 s, and the
  // frames a relocalisation passes through (~3 triggers) took half of the
  // triggers' extrinsics (3.25 Hz per camera at medium against 8.6-8.7 with
  // 24 frames, docs/registration.md).
  int frames = 24;
  double seconds = 30;
  int concurrency = 2;
  int lens_nice = 15;  // PipelineOptions::lens_nice
  int lens_queue = apps::PipelineOptions{}.lens_queue;
  int depth_idle = 1;  // PipelineOptions::depth_idle
  // LocalizerOptions::cold_reanchor_rounds (-1: the localizer's default):
  // the first pose re-anchored in its own frame, to compare live.
  int cold_reanchor_rounds = -1;
  // GuidedMatchOptions::refine_step of the re-anchoring and
  // LocalizerOptions::widen_ahead (-1: the localizer's defaults).
  int refine_step = -1;
  int widen_ahead = -1;
  // LocalizerOptions::reanchor_every and reanchor_every_refined (-1: the
  // localizer's defaults), to compare re-anchoring cadences live.
  int reanchor_every = -1;
  // The track run's ok messages, one CSV row each (empty: none written).
  std::string rows;
  std::string keep;  // empty: a temporary folder
  // Which runs (comma-separated): track, relocalise, depth; the ratios need all three.
  bool track = true, relocalise = true, depth = true;
  // --loop: the rendered frames forward then backward (continuous motion,
  // trigger index increasing), or looped from frame 0 again (header comment).
  bool pingpong = true;
};

bool ParseArgs(int argc, char** argv, Args* a) {
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "--help" || k == "-h") return false;
    if (i + 1 >= argc) return false;
    const std::string v = argv[++i];
    char* end = nullptr;
    if (k == "--preset") {
      a->preset = v;
    } else if (k == "--frames") {
      a->frames = static_cast<int>(std::strtol(v.c_str(), &end, 10));
    } else if (k == "--seconds") {
      a->seconds = std::strtod(v.c_str(), &end);
    } else if (k == "--keep") {
      a->keep = v;
    } else if (k == "--runs") {
      a->track = a->relocalise = a->depth = false;
      std::size_t from = 0;
      while (from <= v.size()) {
        const std::size_t comma = std::min(v.find(',', from), v.size());
        const std::string run = v.substr(from, comma - from);
        if (run == "track") {
          a->track = true;
        } else if (run == "relocalise") {
          a->relocalise = true;
        } else if (run == "depth") {
          a->depth = true;
        } else {
          return false;
        }
        from = comma + 1;
      }
    } else if (k == "--concurrency") {
      a->concurrency = static_cast<int>(std::strtol(v.c_str(), &end, 10));
    } else if (k == "--depth-idle") {
      a->depth_idle = static_cast<int>(std::strtol(v.c_str(), &end, 10));
    } else if (k == "--lens-nice") {
      a->lens_nice = static_cast<int>(std::strtol(v.c_str(), &end, 10));
    } else if (k == "--lens-queue") {
      a->lens_queue = static_cast<int>(std::strtol(v.c_str(), &end, 10));
    } else if (k == "--cold-reanchor-rounds") {
      a->cold_reanchor_rounds = static_cast<int>(std::strtol(v.c_str(), &end, 10));
      if (a->cold_reanchor_rounds < 0) return false;
    } else if (k == "--refine-step") {
      a->refine_step = static_cast<int>(std::strtol(v.c_str(), &end, 10));
      if (a->refine_step < 0 || a->refine_step > 3) return false;
    } else if (k == "--reanchor-every") {
      a->reanchor_every = static_cast<int>(std::strtol(v.c_str(), &end, 10));
      if (a->reanchor_every < 1) return false;
    } else if (k == "--rows") {
      a->rows = v;
    } else if (k == "--widen-ahead") {
      a->widen_ahead = static_cast<int>(std::strtol(v.c_str(), &end, 10));
      if (a->widen_ahead < 2) return false;
    } else if (k == "--loop") {
      if (v != "pingpong" && v != "restart") return false;
      a->pingpong = v == "pingpong";
    } else {
      return false;
    }
    if (end != nullptr && *end != '\0') return false;
  }
  return a->frames >= 3 && a->seconds > 0 && a->concurrency >= 1 && a->lens_nice >= 0 &&
         (a->depth_idle == 0 || a->depth_idle == 1) &&
         a->lens_nice <= 19 && a->lens_queue >= 1 && a->lens_queue <= 8 &&
         (a->track || a->relocalise || a->depth);
}

std::int64_t NowRealtimeNs() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// User + system CPU time of the process so far (s): on a loaded machine the
// cost per frame is comparable where rates are not.
double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const auto seconds = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
  };
  return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

double Percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
}

// serial -> frame -> world_from_cam (GroundTruth/poses_<serial>.csv).
using Truth = std::map<std::string, std::map<std::int64_t, Pose>>;

// The extrinsics' errors against the ground truth (header comment).
struct Accuracy {
  struct Errors {
    std::vector<double> t_mm, r_deg;
  };
  std::map<std::string, Errors> by_localisation;  // of camera X's pose, ok messages only
  // By both cameras' localisations, "0 tracked, X relocalised".
  std::map<std::string, Errors> by_pair;
  std::map<std::int64_t, Errors> by_frame;  // by the rendered frame the trigger shows
  // Every ok message in the order received: the window's first and last
  // quarters (does the error grow as the run goes on?).
  struct TriggerError {
    std::int64_t trigger = 0, frame = 0;
    double t_mm = 0, r_deg = 0;
    std::string zero_how, x_how;  // how camera 0's and camera X's poses were made
  };
  std::vector<TriggerError> by_trigger;
  Errors all;
  int messages = 0, ok = 0, without_truth = 0;
  // By which camera's pose is missing and why: "camera 0 skipped" (passed
  // through while camera 0 was being relocalised; ComposeExtrinsics
  // prefixes its status with "reference camera: "), "camera 0 failed",
  // "camera X skipped", "camera X failed".
  std::map<std::string, int> not_ok;
  std::string last_failure;  // the status of the last "failed" one

  // `frame`: the rendered frame trigger r.trigger_index shows.
  void Add(const Truth& truth, const apps::ExtrinsicsRecord& r, std::int64_t frame) {
    ++messages;
    const processing::CameraPose& p = r.c0_from_cx;
    if (p.status != "ok") {
      const bool zero = p.status.starts_with("reference camera: ");
      const bool skipped = zero ? p.status.find("not localised") != std::string::npos
                                : p.localisation == "skipped";
      ++not_ok[std::string(zero ? "camera 0 " : "camera X ") + (skipped ? "skipped" : "failed")];
      if (!skipped) last_failure = p.status;
      return;
    }
    ++ok;
    const auto zero = truth.find(r.reference_serial), x = truth.find(r.serial);
    if (zero == truth.end() || x == truth.end() || !zero->second.count(r.trigger_index) ||
        !x->second.count(r.trigger_index)) {
      ++without_truth;
      return;
    }
    const Pose expected =
        zero->second.at(r.trigger_index).inverse() * x->second.at(r.trigger_index);
    const double t = registration::TranslationDifference(p.transform, expected);
    const double deg = registration::RotationDifferenceDeg(p.transform, expected);
    const std::string x_how = p.localisation.empty() ? "-" : p.localisation;
    const std::string zero_how =
        r.reference_localisation.empty() ? "-" : r.reference_localisation;
    for (Errors* e :
         {&all, &by_localisation[x_how], &by_pair["0 " + zero_how + ", X " + x_how],
          &by_frame[frame]}) {
      e->t_mm.push_back(t);
      e->r_deg.push_back(deg);
    }
    by_trigger.push_back({r.trigger_index, frame, t, deg, zero_how, x_how});
  }
};

struct RunFigures {
  std::string label;
  double elapsed_s = 0;  // the whole run, until the frames in processing finished
  double window_s = 0;   // until the stop: extrinsics are counted within it
  std::map<std::string, int> extrinsics_ok;  // camera X -> messages with status ok
  int extrinsics = 0;
  std::vector<double> latency_ms;
  std::uint64_t processed = 0, skipped = 0, previews = 0, depth = 0;
  std::uint64_t lens_depth = 0, tf = 0;  // per-lens depth maps, TF images published
  std::uint64_t frames_in = 0, underruns = 0, incomplete_sets = 0;
  double frames_in_span_s = 0;  // first frame in -> last (PipelineReport::frames_in_span_s)
  double depth_cpu_s = 0;  // the depth lane's thread (registration runs only)
  std::string workers;     // the pipeline report's workers line (registration runs)
  std::uint64_t depth_seeded = 0;  // dense maps seeded by the lens lane's per-lens depth
  double to_pose_p50_ms = 0, to_pose_p99_ms = 0;
  double process_cpu_s = 0;  // the whole process's user + sys CPU during the run
  // Every POSE message (a frame a worker took) by how it was localised, the
  // relocalised ones split by where: the first trigger of a pass of the loop
  // (the cameras jump back to frame 0's pose: no pose to track from) or later.
  std::map<std::string, int> poses_by_localisation;
  int relocalised_at_pass_start = 0, relocalised_later = 0, passes = 0;
  std::string registration;
  Accuracy accuracy;
  double HzPerCamera() const { return PerCamera(window_s); }
  // Over the span from the first frame in to the last: the window less the
  // set-up before the first frame (at least 1.1-2.1 s of a 20 s window at
  // medium, 4.8-8.6 s at r32 on a quiet machine, more under load), when no
  // trigger can have extrinsics. The span ends with the last frame in, at or
  // after the window's end, so this rate does not count triggers the window
  // did not take.
  double HzPerCameraOfFramesIn() const { return PerCamera(frames_in_span_s); }
  double PerCamera(double seconds) const {
    if (extrinsics_ok.empty() || seconds <= 0) return 0;
    int n = 0;
    for (const auto& [serial, count] : extrinsics_ok) n += count;
    return n / seconds / static_cast<double>(extrinsics_ok.size());
  }
};

// a / b, 0 when b is 0.
double Ratio(double a, double b) { return b > 0 ? a / b : 0.0; }

// Drift: the error late in the window against early, on the same views.
// The frames differ by how far they are from the map's keyframes (a view
// further away measures worse whether tracked or not, docs/registration.md),
// so the window's first and last quarters of triggers compare whichever
// frames each holds; here each rendered frame's median error in the last
// quarter is set against its median in the first, over the frames seen in
// both, and the medians over those frames compared (a median: trigger 0,
// relocalised without a pose, is one frame's outlier).
struct Drift {
  int frames = 0;
  double first_mm = 0, last_mm = 0, first_deg = 0, last_deg = 0;
};

Drift DriftOf(const Accuracy& a) {
  Drift d;
  std::vector<Accuracy::TriggerError> sorted = a.by_trigger;
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& l, const auto& r) { return l.trigger < r.trigger; });
  const std::size_t quarter = sorted.size() / 4;
  if (quarter == 0) return d;
  std::map<std::int64_t, Accuracy::Errors> first, last;
  for (std::size_t i = 0; i < quarter; ++i) {
    const Accuracy::TriggerError &f = sorted[i], &l = sorted[sorted.size() - 1 - i];
    first[f.frame].t_mm.push_back(f.t_mm);
    first[f.frame].r_deg.push_back(f.r_deg);
    last[l.frame].t_mm.push_back(l.t_mm);
    last[l.frame].r_deg.push_back(l.r_deg);
  }
  Accuracy::Errors early_by_frame, late_by_frame;  // each frame's median
  for (const auto& [frame, early] : first) {
    const auto late = last.find(frame);
    if (late == last.end()) continue;
    ++d.frames;
    early_by_frame.t_mm.push_back(Percentile(early.t_mm, 0.5));
    early_by_frame.r_deg.push_back(Percentile(early.r_deg, 0.5));
    late_by_frame.t_mm.push_back(Percentile(late->second.t_mm, 0.5));
    late_by_frame.r_deg.push_back(Percentile(late->second.r_deg, 0.5));
  }
  if (d.frames > 0) {
    d.first_mm = Percentile(early_by_frame.t_mm, 0.5);
    d.first_deg = Percentile(early_by_frame.r_deg, 0.5);
    d.last_mm = Percentile(late_by_frame.t_mm, 0.5);
    d.last_deg = Percentile(late_by_frame.r_deg, 0.5);
  }
  return d;
}

// `pass_triggers`: with --loop pingpong the triggers of one pass forward and
// back (2 frames - 2), 0 otherwise.
void PrintAccuracy(const Accuracy& a, std::int64_t pass_triggers) {
  std::printf("           accuracy vs GroundTruth: %d of %d messages ok (%.1f %%)", a.ok,
              a.messages, a.messages > 0 ? 100.0 * a.ok / a.messages : 0.0);
  if (!a.not_ok.empty()) {
    std::printf("; not ok:");
    for (const auto& [why, n] : a.not_ok) std::printf(" %s %d", why.c_str(), n);
    if (!a.last_failure.empty()) std::printf(" (last failure: %s)", a.last_failure.c_str());
  }
  if (a.without_truth > 0) std::printf("; %d ok without a ground truth", a.without_truth);
  std::printf("\n");
  auto line = [](const std::string& name, const Accuracy::Errors& e) {
    std::printf("           c0_from_cx error %-28s n=%-4zu median %6.3f mm / %6.4f deg   p90 %6.3f "
                "mm / %6.4f deg\n",
                name.c_str(), e.t_mm.size(), Percentile(e.t_mm, 0.5), Percentile(e.r_deg, 0.5),
                Percentile(e.t_mm, 0.9), Percentile(e.r_deg, 0.9));
  };
  line("all", a.all);
  for (const char* name : {"tracked", "re-anchored", "relocalised"})
    if (a.by_localisation.count(name)) line(name, a.by_localisation.at(name));
  for (const auto& [name, e] : a.by_localisation)
    if (name != "tracked" && name != "re-anchored" && name != "relocalised") line(name, e);
  if (a.by_pair.size() > 1)
    for (const auto& [name, e] : a.by_pair) line(name, e);
  // Which frames the figures above come from matters: the error of a frame
  // relocalised depends mostly on the frame, and the track run relocalises
  // at the loop's first frames.
  if (!a.by_frame.empty()) {
    std::printf("           median mm by rendered frame:");
    for (const auto& [frame, e] : a.by_frame)
      std::printf(" %lld:%.2f(%zu)", static_cast<long long>(frame), Percentile(e.t_mm, 0.5),
                  e.t_mm.size());
    std::printf("\n");
  }
  // By pass forward and back (--loop pingpong): every pass shows the same
  // frames, so a median growing from pass to pass is drift, not the frames
  // (the by-frame medians above vary with the frame: a view further from
  // the map's keyframes measures worse whether tracked or not,
  // docs/registration.md). The last pass is cut by the window.
  if (pass_triggers > 0 && !a.by_trigger.empty()) {
    std::map<std::int64_t, std::vector<double>> by_pass;
    for (const Accuracy::TriggerError& e : a.by_trigger)
      by_pass[e.trigger / pass_triggers].push_back(e.t_mm);
    std::printf("           median mm by pass of %lld triggers:",
                static_cast<long long>(pass_triggers));
    for (const auto& [pass, e] : by_pass)
      std::printf(" %lld:%.3f(%zu)", static_cast<long long>(pass), Percentile(e, 0.5), e.size());
    std::printf("\n");
  }
  // The window's first and last quarters of the ok messages (by trigger):
  // with --loop pingpong, whether the error grows as the rig moves on.
  if (a.by_trigger.size() >= 8) {
    std::vector<Accuracy::TriggerError> sorted = a.by_trigger;
    std::sort(sorted.begin(), sorted.end(),
              [](const auto& l, const auto& r) { return l.trigger < r.trigger; });
    const std::size_t quarter = sorted.size() / 4;
    std::vector<double> first, last;
    for (std::size_t i = 0; i < quarter; ++i) {
      first.push_back(sorted[i].t_mm);
      last.push_back(sorted[sorted.size() - 1 - i].t_mm);
    }
    std::printf("           median mm of the first / last quarter of the triggers (%zu each): "
                "%.3f / %.3f (last / first %.2f)\n",
                quarter, Percentile(first, 0.5), Percentile(last, 0.5),
                Percentile(first, 0.5) > 0 ? Percentile(last, 0.5) / Percentile(first, 0.5) : 0.0);
    const Drift d = DriftOf(a);
    if (d.frames > 0)
      std::printf("           drift, the same frames early and late: median over %d rendered "
                  "frames of each frame's median in the first / last quarter %.3f / %.3f mm, "
                  "%.4f / %.4f deg (last / first %.2f, %.2f)\n",
                  d.frames, d.first_mm, d.last_mm, d.first_deg, d.last_deg,
                  Ratio(d.last_mm, d.first_mm), Ratio(d.last_deg, d.first_deg));
  }
}

// Issue 30's gates on the track run, where the preset has them (medium,
// r32): the median (and p90 at r32) of c0_from_cx, extrinsics per second
// per camera of frames in, and at medium the drift figure (DriftOf).
void PrintGates(const std::string& preset, const RunFigures& f) {
  const Accuracy::Errors& e = f.accuracy.all;
  if ((preset != "medium" && preset != "r32") || e.t_mm.empty()) return;
  const bool r32 = preset == "r32";
  const double min_hz = r32 ? 5 : 8, hz = f.HzPerCameraOfFramesIn();
  const auto verdict = [](bool met) { return met ? "met" : "NOT met"; };
  const double t50 = Percentile(e.t_mm, 0.5), r50 = Percentile(e.r_deg, 0.5);
  std::printf("gates (%s): median %.3f mm / %.4f deg <= 0.5 mm / 0.03 deg %s", preset.c_str(), t50,
              r50, verdict(t50 <= 0.5 && r50 <= 0.03));
  if (r32) {
    const double t90 = Percentile(e.t_mm, 0.9), r90 = Percentile(e.r_deg, 0.9);
    std::printf("; p90 %.3f mm / %.4f deg <= 1 mm / 0.06 deg %s", t90, r90,
                verdict(t90 <= 1 && r90 <= 0.06));
  }
  std::printf("; %.2f extrinsics/s per camera of frames in (%.2f over the window) >= %.0f %s", hz,
              f.HzPerCamera(), min_hz, verdict(hz >= min_hz));
  if (!r32) {
    const Drift d = DriftOf(f.accuracy);
    const double ratio = std::max(Ratio(d.last_mm, d.first_mm), Ratio(d.last_deg, d.first_deg));
    if (d.frames > 0)
      std::printf("; drift last / first %.2f <= 1.2 %s", ratio, verdict(ratio <= 1.2));
    else
      std::printf("; drift not measured (no frame in both quarters)");
  }
  std::printf("\n");
}

// --rows: one CSV row per ok message of the track run, in trigger order, so
// that the error can be followed frame by frame and split by view and by
// how each camera's pose was made. False when the file cannot be written.
bool WriteRows(const fs::path& path, const Accuracy& a) {
  std::vector<Accuracy::TriggerError> sorted = a.by_trigger;
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& l, const auto& r) { return l.trigger < r.trigger; });
  std::FILE* file = std::fopen(path.c_str(), "w");
  if (file == nullptr) return false;
  std::fprintf(file, "trigger,frame,camera0,cameraX,t_mm,r_deg\n");
  for (const Accuracy::TriggerError& e : sorted)
    std::fprintf(file, "%lld,%lld,%s,%s,%.4f,%.5f\n", static_cast<long long>(e.trigger),
                 static_cast<long long>(e.frame), e.zero_how.c_str(), e.x_how.c_str(), e.t_mm,
                 e.r_deg);
  return std::fclose(file) == 0;
}

// "1.20 1.35 1.40\n" (/proc/loadavg's first three), or "?\n".
std::string LoadAverage() {
  std::FILE* file = std::fopen("/proc/loadavg", "r");
  if (file == nullptr) return "?\n";
  double a = 0, b = 0, c = 0;
  const int n = std::fscanf(file, "%lf %lf %lf", &a, &b, &c);
  std::fclose(file);
  if (n != 3) return "?\n";
  char text[64];
  std::snprintf(text, sizeof text, "%.2f %.2f %.2f\n", a, b, c);
  return text;
}

enum class Mode { kTrack, kRelocalise, kDepthOnly };

// The rendered frame that trigger k of the replayed sequence shows: with
// --loop pingpong 0 1 .. n-1 n-2 .. 1 0 1 .. (period 2n - 2), else k.
std::int64_t ShownFrame(const Args& args, std::int64_t k) {
  if (!args.pingpong) return k;
  const std::int64_t period = 2 * static_cast<std::int64_t>(args.frames) - 2;
  const std::int64_t i = k % period;
  return i < args.frames ? i : period - i;
}

// The pingpong sequence (--loop pingpong) under `root` (emptied first): per
// camera `triggers` links, frame k to the rendered frame ShownFrame(k), the
// rendered sequence's GroundTruth/cameras.yaml and its dataset's Calibration
// linked (no Vicon: nothing here needs it). Links, not copies: the frames
// are read as the replay reads any sequence. Returns the sequence folder.
Expected<fs::path> WritePingPongSequence(const Args& args, const fs::path& rendered,
                                         const std::vector<std::string>& serials,
                                         const fs::path& root, std::int64_t triggers) {
  std::error_code ec;
  fs::remove_all(root, ec);
  const fs::path rendered_abs = fs::absolute(rendered);
  const fs::path sequence = root / rendered_abs.parent_path().filename() / rendered_abs.filename();
  const auto fail = [&](const fs::path& path) -> Expected<fs::path> {
    return Error{"bench_live: " + path.string() + ": " + ec.message()};
  };
  for (const std::string& serial : serials) {
    const fs::path camera = sequence / layout::CameraFolderName(serial);
    if (fs::create_directories(camera, ec); ec) return fail(camera);
    for (std::int64_t k = 0; k < triggers; ++k) {
      const fs::path link = camera / layout::RawFrameFileName(serial, k);
      fs::create_symlink(layout::RawFramePath(rendered_abs, serial, ShownFrame(args, k)), link, ec);
      if (ec) return fail(link);
    }
  }
  const fs::path yaml = layout::CamerasYamlPath(sequence);
  if (fs::create_directories(yaml.parent_path(), ec); ec) return fail(yaml.parent_path());
  if (fs::create_symlink(layout::CamerasYamlPath(rendered_abs), yaml, ec); ec) return fail(yaml);
  const fs::path calibration = root / layout::kCalibrationFolder;
  fs::create_directory_symlink(
      rendered_abs.parent_path().parent_path() / layout::kCalibrationFolder, calibration, ec);
  if (ec) return fail(calibration);
  return sequence;
}

RunFigures Run(const Args& args, const fs::path& sequence, const fs::path& map_dir,
               const Truth& truth, Mode mode) {
  RunFigures f;
  f.label = mode == Mode::kTrack ? "track" : mode == Mode::kRelocalise ? "relocalise" : "depth only";
  lcm::LCM bus("memq://");
  std::mutex mutex;
  struct PoseTally {
    RunFigures* f;
    std::mutex* mutex;
    void On(const lcm::ReceiveBuffer*, const std::string&, const lifmcr_lcm::camera_pose_t* m) {
      std::lock_guard lock(*mutex);
      ++f->poses_by_localisation[m->status == "ok" || m->localisation == "skipped"
                                     ? m->localisation
                                     : m->localisation + " (failed)"];
      if (m->localisation == "relocalised")
        ++(m->trigger_index == 0 ? f->relocalised_at_pass_start : f->relocalised_later);
      f->passes = std::max(f->passes, static_cast<int>(m->pass) + 1);
    }
  } tally{&f, &mutex};
  bus.subscribe("LIFMCR_.*_POSE", &PoseTally::On, &tally);
  apps::ReplayRunOptions options;
  options.sequence_dir = sequence;
  options.rate.kind = apps::ReplayRate::Kind::kOriginal;
  options.loop = true;
  options.pipeline.publisher.bus = &bus;
  options.pipeline.max_concurrency = args.concurrency;
  options.pipeline.lens_nice = args.lens_nice;
  options.pipeline.lens_queue = args.lens_queue;
  options.pipeline.depth_idle = args.depth_idle != 0;
  options.intrinsics = {layout::CamerasYamlPath(sequence)};
  if (mode != Mode::kDepthOnly) {
    apps::LiveRegistrationOptions live;
    live.reference_dir = map_dir;
    live.localizer.track = mode == Mode::kTrack;
    if (args.cold_reanchor_rounds >= 0)
      live.localizer.cold_reanchor_rounds = args.cold_reanchor_rounds;
    if (args.refine_step >= 0) live.localizer.guided.refine_step = args.refine_step;
    if (args.widen_ahead >= 0) live.localizer.widen_ahead = args.widen_ahead;
    if (args.reanchor_every >= 1)
      live.localizer.reanchor_every = live.localizer.reanchor_every_refined = args.reanchor_every;
    options.registration = live;
    options.pipeline.on_extrinsics = [&](const apps::ExtrinsicsRecord& r) {
      const double ms = static_cast<double>(NowRealtimeNs() - r.arrival_ns) / 1e6;
      std::lock_guard lock(mutex);
      if (f.window_s > 0) return;  // after the window: frames finishing on the way out
      ++f.extrinsics;
      if (r.c0_from_cx.status == "ok") ++f.extrinsics_ok[r.serial];
      f.latency_ms.push_back(ms);
      f.accuracy.Add(truth, r, ShownFrame(args, r.trigger_index));
    };
  }
  std::atomic<bool> stop{false};
  options.stop = &stop;
  // The POSE messages handled as they come (memq delivers on handle()).
  std::atomic<bool> handling{true};
  std::thread handler([&] {
    while (handling) bus.handleTimeout(50);
  });
  const auto start = std::chrono::steady_clock::now();
  std::thread timer([&] {
    const auto end = std::chrono::steady_clock::now() +
                     std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                         std::chrono::duration<double>(args.seconds));
    while (std::chrono::steady_clock::now() < end && !stop)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    {
      std::lock_guard lock(mutex);
      f.window_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
    stop = true;
  });
  const double cpu_start = ProcessCpuSeconds();
  auto result = apps::RunReplay(options);
  f.process_cpu_s = ProcessCpuSeconds() - cpu_start;
  f.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  stop = true;
  timer.join();
  handling = false;
  handler.join();
  while (bus.handleTimeout(0) > 0) {
  }
  if (!result) {
    std::fprintf(stderr, "bench_live: %s: %s\n", f.label.c_str(), result.error().message.c_str());
    std::exit(3);
  }
  f.processed = result->report.processed;
  f.skipped = result->report.skipped;
  f.previews = result->report.published_previews;
  f.depth = result->report.published_depth;
  f.lens_depth = result->report.published_lens_depth;
  f.tf = result->report.published_tf;
  f.frames_in = result->report.frames_in;
  f.frames_in_span_s = result->report.frames_in_span_s;
  f.underruns = result->camera_underruns;
  f.incomplete_sets = result->report.incomplete_sets;
  f.depth_cpu_s = result->report.depth_cpu_s;
  f.depth_seeded = result->report.depth_seeded_by_lenses;
  f.to_pose_p50_ms = result->report.to_pose.p50_ms;
  f.to_pose_p99_ms = result->report.to_pose.p99_ms;
  {
    // The report's line of the workers' and the lens lane's CPU per frame.
    const std::string report = result->report.FinalReport();
    const auto at = report.find("workers (registration first)");
    // With the next line: why the lens lane skipped what it skipped.
    if (at != std::string::npos) {
      std::size_t end = report.find('\n', at);
      if (end != std::string::npos && report.compare(end + 1, 17, "lens lane skipped") == 0)
        end = report.find('\n', end + 1);
      f.workers = report.substr(at, end == std::string::npos ? end : end + 1 - at);
      for (std::size_t nl = f.workers.find('\n');
           nl != std::string::npos && nl + 1 < f.workers.size(); nl = f.workers.find('\n', nl + 1))
        f.workers.insert(nl + 1, "           ");
    }
  }
  f.registration = result->registration;
  return f;
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_live [--preset small|medium|r32] [--frames N>=3] [--seconds S]\n"
    "                  [--concurrency N] [--keep DIR] [--runs track,relocalise,depth]\n"
    "                  [--lens-nice 0..19] [--lens-queue 1..8] [--depth-idle 0|1]\n"
    "                  [--loop pingpong|restart] [--cold-reanchor-rounds R]\n"
    "                  [--refine-step 0..3] [--widen-ahead N>=2] [--reanchor-every N>=1]\n"
    "                  [--rows FILE]\n"
    "Live registration of a synthetic rig (default medium) replayed at its trigger rate\n"
    "through `lifmcr replay --reference`'s path, three runs of --seconds: tracking, every\n"
    "frame relocalised (the baseline) and depth only. Per run: extrinsics per second per\n"
    "camera, frame -> extrinsics latency, and the errors against the ground truth by how\n"
    "each pose was made. --keep DIR renders into DIR once and reuses it; --runs picks\n"
    "some of the three runs (the ratios need all three). --lens-nice: the lens lane's\n"
    "nice value above the command's (15; the workers run at +10). --lens-queue: frames of\n"
    "a camera that wait for the lens lane before the oldest is skipped (4). --depth-idle 0: the\n"
    "depth lane computes at nice 19 instead of under SCHED_IDLE (1, the default).\n"
    "--loop pingpong (the default): the rendered frames forward then backward, 0 .. N-1 ..\n"
    "0 .., as one sequence whose trigger index keeps increasing (a rig moving on\n"
    "continuously; links to the frames in a folder of the run's\n"
    "own under /tmp, removed at its end); restart: the frames looped from\n"
    "0 again, so both cameras jump back and are relocalised at each pass's first trigger.\n"
    "--cold-reanchor-rounds R: a camera's first pose (relocalised without a pose)\n"
    "re-anchored in its own frame in R rounds of guided matching (the localizer's\n"
    "default when not given).\n"
    "--refine-step S: each matched keypoint of a re-anchoring's render at step 4 or coarser\n"
    "(r32) found again every S TF px (GuidedMatchOptions::refine_step; 0: off).\n"
    "--widen-ahead N: frames N or more triggers after their camera's last pose are tracked\n"
    "with one more pyramid level and twice the shift (LocalizerOptions::widen_ahead).\n"
    "--reanchor-every N: a camera re-anchored after N frames tracked (LocalizerOptions::\n"
    "reanchor_every and reanchor_every_refined; the localizer's defaults when not given).\n"
    "--rows FILE: the track run's ok messages as CSV, one row each in trigger order:\n"
    "trigger, rendered frame, how camera 0's and camera X's poses were made, c0_from_cx's\n"
    "error (mm, deg).\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  // Every run is live (newest_wins) with the localizer but the depth-only one.
  const auto process_settings = apps::ProcessSettings::ForPipeline(HeapArenas::kPerThread);
  Args args;
  if (!ParseArgs(argc, argv, &args)) {
    std::fprintf(stderr,
                 "usage: bench_live [--preset small|medium|r32] [--frames N>=3] [--seconds S] "
                 "[--concurrency N] [--keep DIR] [--runs track,relocalise,depth] "
                 "[--lens-nice 0..19] [--lens-queue 1..8] [--depth-idle 0|1] [--loop pingpong|restart] "
                 "[--cold-reanchor-rounds R] [--refine-step 0..3] [--widen-ahead N>=2] "
                 "[--reanchor-every N>=1] [--rows FILE]\n");
    return 2;
  }
  auto params = synth::MakePreset(args.preset);
  if (!params) {
    std::fprintf(stderr, "bench_live: %s\n", params.error().message.c_str());
    return 2;
  }
  params->rig.frames = args.frames;
  params->rig.cameras = 2;
  char tmpl[] = "/tmp/lifmcr-bench-live-XXXXXX";
  if (args.keep.empty() && !mkdtemp(tmpl)) {
    std::fprintf(stderr, "bench_live: cannot create %s: %s\n", tmpl, std::strerror(errno));
    return 3;
  }
  const fs::path dir = args.keep.empty() ? fs::path(tmpl) : fs::path(args.keep);
  fs::path sequence_dir = dir / "data" / params->rig.scene_folder / params->rig.sequence;
  if (!args.keep.empty() && fs::exists(layout::CamerasYamlPath(sequence_dir))) {
    std::fprintf(stderr, "bench_live: reusing %s\n", sequence_dir.c_str());
  } else {
    std::fprintf(stderr, "bench_live: rendering 2 x %d frames of preset %s into %s (not timed)\n",
                 args.frames, args.preset.c_str(), dir.c_str());
    auto summary = synth::WriteSyntheticDataset(dir / "data", *params, {});
    if (!summary) {
      std::fprintf(stderr, "bench_live: %s\n", summary.error().message.c_str());
      if (args.keep.empty()) fs::remove_all(dir);
      return 3;
    }
    sequence_dir = sequence_dir;
  }
  // Camera 0's map from its ground truth, frames 0..2 (what `lifmcr register
  // --reference-from-ground-truth` makes), as a map folder.
  const fs::path cameras_yaml = layout::CamerasYamlPath(sequence_dir);
  auto serials = synth::ReadCameraSerialsYaml(cameras_yaml);
  if (!serials || serials->empty()) {
    std::fprintf(stderr, "bench_live: %s: no cameras\n", cameras_yaml.c_str());
    return 3;
  }
  auto k = apps::ReadIntrinsics(cameras_yaml, serials->front());
  if (!k) {
    std::fprintf(stderr, "bench_live: %s\n", k.error().message.c_str());
    return 3;
  }
  registration::GroundTruthMapOptions map_options;
  map_options.features.max_features = 4000;  // as `lifmcr register` makes it
  auto map = registration::BuildGroundTruthMap(sequence_dir, serials->front(), {0, 1, 2},
                                               processing::CameraModel(*k), map_options);
  if (!map) {
    std::fprintf(stderr, "bench_live: %s\n", map.error().message.c_str());
    return 3;
  }
  const fs::path map_dir = dir / "map";
  if (Status s = registration::WriteReferenceMap(map_dir, *map); !s) {
    std::fprintf(stderr, "bench_live: %s\n", s.error().message.c_str());
    return 3;
  }
  std::printf("bench_live: preset %s, 2 cameras x %d frames %s at 10 Hz for %.0f s per run, "
              "%d frames at once, lens lane at nice +%d with %d frames waiting per camera, depth lane %s, map of %zu points, %u hardware "
              "threads\n",
              args.preset.c_str(), args.frames,
              args.pingpong ? "forward and back (--loop pingpong)" : "looped (--loop restart)",
              args.seconds, args.concurrency, args.lens_nice, args.lens_queue,
              args.depth_idle ? "under SCHED_IDLE" : "at nice 19",
              map->points.size(), std::thread::hardware_concurrency());
  Truth truth;
  for (const std::string& serial : *serials) {
    auto poses = registration::ReadPosesCsv(layout::PosesCsvPath(sequence_dir, serial));
    if (!poses) {
      std::fprintf(stderr, "bench_live: %s\n", poses.error().message.c_str());
      return 3;
    }
    for (const registration::FramePose& p : *poses) truth[serial][p.frame] = p.world_from_cam;
  }
  // The replayed sequence: the rendered one, or its pingpong of links long
  // enough for a run's window (and a margin: the replay loops it beyond).
  fs::path replayed = sequence_dir;
  fs::path pingpong_root;
  struct RemoveOnExit {
    const fs::path& path;
    ~RemoveOnExit() {
      std::error_code ec;
      if (!path.empty()) fs::remove_all(path, ec);
    }
  } remove_pingpong{pingpong_root};
  if (args.pingpong) {
    const auto triggers = static_cast<std::int64_t>(std::ceil(args.seconds * 10)) + 2 * args.frames;
    // Links in a folder of this run's own, removed when the run ends: a kept
    // rig (--keep) stays as rendered, and runs on the same rig at once do not
    // empty each other's links.
    char links_tmpl[] = "/tmp/lifmcr-bench-live-pingpong-XXXXXX";
    if (!mkdtemp(links_tmpl)) {
      std::fprintf(stderr, "bench_live: cannot create %s: %s\n", links_tmpl, std::strerror(errno));
      return 3;
    }
    pingpong_root = links_tmpl;
    auto written = WritePingPongSequence(args, sequence_dir, *serials, pingpong_root, triggers);
    if (!written) {
      std::fprintf(stderr, "%s\n", written.error().message.c_str());
      return 3;
    }
    replayed = *written;
    Truth shown;
    for (const auto& [serial, frames] : truth)
      for (std::int64_t k = 0; k < triggers; ++k) {
        const auto it = frames.find(ShownFrame(args, k));
        if (it != frames.end()) shown[serial][k] = it->second;
      }
    truth = std::move(shown);
  }
  std::vector<RunFigures> runs;
  for (const Mode mode : {Mode::kTrack, Mode::kRelocalise, Mode::kDepthOnly}) {
    if ((mode == Mode::kTrack && !args.track) || (mode == Mode::kRelocalise && !args.relocalise) ||
        (mode == Mode::kDepthOnly && !args.depth))
      continue;
    runs.push_back(Run(args, replayed, map_dir, truth, mode));
    const RunFigures& f = runs.back();
    std::printf("%-10s extrinsics %.2f Hz per camera (%d messages; %.2f per second of frames in), "
                "frame -> extrinsics p50 %.0f "
                "ms p99 %.0f ms | frames taken %.2f/s skipped %.2f/s | previews %.2f/s "
                "depth %.2f/s over %.1f s\n",
                f.label.c_str(), f.HzPerCamera(), f.extrinsics, f.HzPerCameraOfFramesIn(),
                Percentile(f.latency_ms, 0.5),
                Percentile(f.latency_ms, 0.99), f.processed / f.elapsed_s, f.skipped / f.elapsed_s,
                f.previews / f.elapsed_s, f.depth / f.elapsed_s, f.elapsed_s);
    std::printf("           per-lens depth %.2f/s (%.0f %% of the frames in), TF images %.2f/s\n",
                f.lens_depth / f.elapsed_s,
                f.frames_in > 0 ? 100.0 * static_cast<double>(f.lens_depth) / f.frames_in : 0.0,
                f.tf / f.elapsed_s);
    std::printf("           frames in %.2f/s (of 20 offered), lost by the replay cameras %.2f/s, "
                "incomplete sets %.2f/s\n",
                f.frames_in / f.elapsed_s, f.underruns / f.elapsed_s,
                f.incomplete_sets / f.elapsed_s);
    // The rates above divide by the whole run (its set-up before the first
    // frame and the drain after the last); between the first frame in and
    // the last the cameras deliver 20 per second where none is lost.
    if (f.frames_in_span_s > 0) {
      const double triggers = 20 * f.frames_in_span_s + 2;  // both ends' sets
      std::printf("           between the first frame in and the last (%.1f s): frames in %.2f/s "
                  "(of 20 offered), per-lens depth of %.0f %% of the frames offered there\n",
                  f.frames_in_span_s, static_cast<double>(f.frames_in - 2) / f.frames_in_span_s,
                  100.0 * static_cast<double>(f.lens_depth) / triggers);
    }
    if (f.depth_cpu_s > 0)
      std::printf("           depth lane CPU %.1f s (%.0f %% of one core), %llu dense maps seeded "
                  "by the lens lane's per-lens depth\n",
                  f.depth_cpu_s, 100 * f.depth_cpu_s / f.elapsed_s,
                  static_cast<unsigned long long>(f.depth_seeded));
    if (!f.workers.empty()) std::printf("           %s", f.workers.c_str());
    std::printf("           process CPU %.1f s (user + sys): %.0f CPU-ms per frame taken, the "
                "workers' and the replay's share (without the depth lane) %.0f; load average "
                "%s",
                f.process_cpu_s, f.processed > 0 ? 1e3 * f.process_cpu_s / f.processed : 0.0,
                f.processed > 0 ? 1e3 * (f.process_cpu_s - f.depth_cpu_s) / f.processed : 0.0,
                LoadAverage().c_str());
    if (f.to_pose_p50_ms > 0)
      std::printf("           frame -> its pose on LCM p50 %.0f ms p99 %.0f ms\n",
                  f.to_pose_p50_ms, f.to_pose_p99_ms);
    if (!f.registration.empty()) std::printf("           %s", f.registration.c_str());
    if (!f.poses_by_localisation.empty()) {
      std::printf("           poses published:");
      for (const auto& [how, n] : f.poses_by_localisation) std::printf(" %s %d", how.c_str(), n);
      std::printf("; relocalised at a pass's first trigger %d, later %d (%d passes of the loop)\n",
                  f.relocalised_at_pass_start, f.relocalised_later, f.passes);
    }
    if (mode != Mode::kDepthOnly)
      PrintAccuracy(f.accuracy, args.pingpong ? 2 * static_cast<std::int64_t>(args.frames) - 2 : 0);
    if (mode == Mode::kTrack) PrintGates(args.preset, f);
    if (mode == Mode::kTrack && !args.rows.empty() && !WriteRows(args.rows, f.accuracy)) {
      std::fprintf(stderr, "bench_live: --rows: cannot write %s\n", args.rows.c_str());
      return 3;
    }
    std::fflush(stdout);
  }
  if (runs.size() < 3) {
    if (args.keep.empty()) fs::remove_all(dir);
    return 0;  // the ratios need all three runs
  }
  const RunFigures &track = runs[0], &relocalise = runs[1], &depth = runs[2];
  std::printf("ratios: extrinsics rate track / relocalise %.2f; latency p50 relocalise / track "
              "%.2f; depth maps published track / depth only %.2f\n",
              relocalise.HzPerCamera() > 0 ? track.HzPerCamera() / relocalise.HzPerCamera() : 0.0,
              Percentile(track.latency_ms, 0.5) > 0
                  ? Percentile(relocalise.latency_ms, 0.5) / Percentile(track.latency_ms, 0.5)
                  : 0.0,
              depth.depth > 0 ? (track.depth / track.elapsed_s) / (depth.depth / depth.elapsed_s)
                              : 0.0);
  {
    const Accuracy &a = track.accuracy, &b = relocalise.accuracy;
    std::printf("accuracy ratios track / relocalise (c0_from_cx error, ok messages; above 1: "
                "track worse): translation median %.2f p90 %.2f, rotation median %.2f p90 %.2f; "
                "ok fraction %.2f",
                Ratio(Percentile(a.all.t_mm, 0.5), Percentile(b.all.t_mm, 0.5)),
                Ratio(Percentile(a.all.t_mm, 0.9), Percentile(b.all.t_mm, 0.9)),
                Ratio(Percentile(a.all.r_deg, 0.5), Percentile(b.all.r_deg, 0.5)),
                Ratio(Percentile(a.all.r_deg, 0.9), Percentile(b.all.r_deg, 0.9)),
                Ratio(Ratio(a.ok, a.messages), Ratio(b.ok, b.messages)));
    if (a.by_localisation.count("tracked"))
      std::printf("; tracked poses only: translation median %.2f, rotation median %.2f",
                  Ratio(Percentile(a.by_localisation.at("tracked").t_mm, 0.5),
                        Percentile(b.all.t_mm, 0.5)),
                  Ratio(Percentile(a.by_localisation.at("tracked").r_deg, 0.5),
                        Percentile(b.all.r_deg, 0.5)));
    std::printf("\n");
  }
  if (args.keep.empty()) fs::remove_all(dir);
  return 0;
}
