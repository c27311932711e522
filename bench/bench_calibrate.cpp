// bench_calibrate: `lifmcr calibrate`'s library on a synthetic sequence
// (default 40 frames of the medium preset; `--preset r32 --frames 10` for
// the full sensor): time and peak memory of frame processing (virtual depth,
// TF, SIFT, ArUco) and of the calibration (initialisation + plenoptic bundle
// adjustment), with Ceres' own solver time and iterations, and the accuracy
// gates against the ground truth:
//   - from nominal values 5 % off (f_L and b_L0 x1.05, B x0.95);
//   - recalibration (f_L, B fixed at the truth) from b_L0 10 % off (on the
//     same processed frames).
// Baseline in the same run: the mean processing time of one frame; the
// calibration is reported as a ratio to it.
// The sequence is written first by the `lifmcr synth` executable (a separate
// process, not timed, so its memory does not count), or given by --sequence.
// Its motion is `orbit` by default, the motion a user's calibration sequence
// has (views of the plate from varied angles, more than 20 degrees about two
// axes; trajectory.h), at its designed amplitude (--speed-scale 1).
//   bench_calibrate [--preset medium|r32|small] [--frames N] [--sequence SEQ_DIR]
//                   [--motion orbit|smooth|...] [--speed-scale X] [--keep]

#include "bench/bench_usage.h"
#include "processing/camera_model.h"
#include "registration/calibration/calibration.h"
#include "registration/features/calibration_frames.h"
#include "registration/calibration/calibration_gates.h"
#include "registration/features/intrinsics_yaml.h"
#include "replay/layout.h"

#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

using namespace lifmcr;
using namespace lifmcr::registration;
namespace fs = std::filesystem;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double PeakRssMb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

void PrintGates(const char* label, const CalibrationResult& r, const fs::path& seq,
                const std::string& serial, bool fixed) {
  std::printf("%s: %s\n", label, r.BriefReport().c_str());
  Expected<GroundTruthComparison> c = CompareWithGroundTruth(r, seq, serial);
  if (!c) {
    std::printf("  ground truth: %s\n", c.error().message.c_str());
    return;
  }
  std::printf("  %s\n", c->BriefReport().c_str());
  const std::vector<std::string> missed = MissedGates(*c, GateThresholds{}, fixed);
  if (missed.empty()) std::printf("  every gate met\n");
  for (const std::string& m : missed) std::printf("  gate missed: %s\n", m.c_str());
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_calibrate [--preset medium|r32|small] [--frames N] [--sequence SEQ_DIR]\n"
    "                       [--motion orbit|smooth|...] [--speed-scale X] [--keep]\n"
    "lifmcr calibrate's library on a synthetic sequence (default 40 frames of medium, written\n"
    "by `lifmcr synth` unless --sequence gives one): time and peak memory of frame processing\n"
    "and of the calibration, Ceres' time and iterations, and the accuracy gates against the\n"
    "ground truth. --keep leaves the written sequence in place.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string preset = "medium", sequence, motion = "orbit";
  int frames = 40;
  double speed_scale = 1;
  bool keep = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--preset") preset = next();
    else if (a == "--frames") frames = std::atoi(next().c_str());
    else if (a == "--sequence") sequence = next();
    else if (a == "--motion") motion = next();
    else if (a == "--speed-scale") speed_scale = std::atof(next().c_str());
    else if (a == "--keep") keep = true;
    else {
      std::fprintf(stderr,
                   "usage: bench_calibrate [--preset medium|r32|small] [--frames N] "
                   "[--sequence SEQ_DIR] [--motion M] [--speed-scale X] [--keep]\n");
      return 2;
    }
  }
  // What the figures are of: the sequence given, or the preset and motion written.
  const std::string what = sequence.empty() ? preset + " " + motion : sequence;
  fs::path tmp;
  if (sequence.empty()) {
    tmp = fs::temp_directory_path() / ("bench_calibrate_" + std::to_string(::getpid()));
    fs::create_directories(tmp);
    const fs::path config = tmp / "synth.yaml";
    std::FILE* f = std::fopen(config.c_str(), "w");
    std::fprintf(f, "rig:\n  speed_scale: %g\n", speed_scale);
    std::fclose(f);
    const std::string command = std::string(LIFMCR_BINARY) + " synth --out " + tmp.string() +
                                " --preset " + preset + " --cameras 1 --frames " +
                                std::to_string(frames) + " --motion " + motion + " --config " + config.string() +
                                " --quiet";
    std::printf("writing the sequence (not timed): %s\n", command.c_str());
    if (std::system(command.c_str()) != 0) return 1;
    for (const auto& scene : fs::directory_iterator(tmp))
      if (scene.is_directory() && scene.path().filename() != "Calibration")
        for (const auto& seq : fs::directory_iterator(scene.path()))
          if (seq.is_directory()) sequence = seq.path().string();
  }
  const fs::path seq = sequence;
  const fs::path cameras_yaml = layout::CamerasYamlPath(seq);
  Expected<PlateLayout> plate = ReadPlateLayout(cameras_yaml);
  if (!plate) return std::fprintf(stderr, "%s\n", plate.error().message.c_str()), 1;
  std::string serial;
  for (const auto& e : fs::directory_iterator(seq))
    if (auto s = layout::ParseCameraFolderName(e.path().filename().string())) serial = *s;
  Expected<CameraCalibration> truth = ReadCameraCalibration(cameras_yaml, serial);
  if (!truth) return std::fprintf(stderr, "%s\n", truth.error().message.c_str()), 1;
  CameraCalibration initial = *truth;
  initial.intrinsics.main_focal_length_mm *= 1.05;
  initial.intrinsics.mla_to_main_lens_mm *= 1.05;
  initial.intrinsics.mla_to_sensor_mm *= 0.95;

  FrameLoaderOptions loader_options;
  loader_options.lambda = processing::CameraModel(initial.intrinsics).lambda();
  loader_options.features.max_features = 4000;
  auto loader = CalibrationFrameLoader::Open(seq, serial, {}, *plate, loader_options);
  if (!loader) return std::fprintf(stderr, "%s\n", loader.error().message.c_str()), 1;
  CalibrationInput input;
  input.serial = serial;
  input.initial = initial;
  input.micro_images = &(*loader)->micro_images();
  double t = Now();
  for (const std::int64_t f : (*loader)->frames()) {
    if (static_cast<int>(input.frames.size()) >= frames) break;
    Expected<CalibrationFrame> frame = (*loader)->Load(f);
    if (!frame) return std::fprintf(stderr, "%s\n", frame.error().message.c_str()), 1;
    input.frames.push_back(std::move(*frame));
  }
  const double processing_s = Now() - t;
  const double per_frame_s = processing_s / input.frames.size();
  const double rss_frames = PeakRssMb();
  std::printf("%s, %d x %d, %zu frames: processing %.1f s (%.2f s per frame: depth, TF, SIFT, "
              "ArUco), peak RSS %.0f MB\n",
              what.c_str(), (*loader)->width(), (*loader)->height(), input.frames.size(),
              processing_s, per_frame_s, rss_frames);

  CalibrationOptions options;
  t = Now();
  Expected<CalibrationResult> r = Calibrate(input, options);
  const double calibrate_s = Now() - t;
  if (!r) return std::fprintf(stderr, "%s\n", r.error().message.c_str()), 1;
  std::printf("calibration %.1f s (Ceres %.1f s, %d iterations), %.1f x the processing of one "
              "frame; peak RSS %.0f MB\n",
              calibrate_s, r->solver_seconds, r->iterations, calibrate_s / per_frame_s,
              PeakRssMb());
  PrintGates("from 5 % off", *r, seq, serial, false);

  CalibrationInput recal = input;
  recal.initial = *truth;
  recal.initial.intrinsics.mla_to_main_lens_mm *= 1.10;
  recal.frames_lambda = loader_options.lambda;  // the frames are not processed again
  options.recalibrate = true;
  t = Now();
  Expected<CalibrationResult> rr = Calibrate(recal, options);
  if (!rr) {
    std::printf("recalibration from b_L0 +10 %%: %s\n", rr.error().message.c_str());
  } else {
    std::printf("recalibration %.1f s (Ceres %.1f s, %d iterations)\n", Now() - t,
                rr->solver_seconds, rr->iterations);
    PrintGates("recalibration from b_L0 +10 %", *rr, seq, serial, true);
  }
  if (!tmp.empty() && !keep) fs::remove_all(tmp);
  return 0;
}
