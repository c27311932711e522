// `lifmcr demo`: the whole chain on a small synthetic rig, each stage the
// `lifmcr` command a user would run on a recorded sequence, into one folder:
//
//   OUT/data/       lifmcr synth: table scene, 2 cameras, orbit motion (views
//                   that differ by > 20 deg about two axes: calibration and
//                   the hand-eye need them), from 1.8 m so the plate is seen
//   OUT/calibrate/  lifmcr calibrate camera 0 from nominal values 5 % off the
//                   truth (docs/calibration.md), principal point (the image
//                   centre) and distortion (none) held: 12 small frames do
//                   not determine them (a free principal point went 59 px
//                   off and the poses 13 mm / 0.7 deg; held: 3 mm / 0.1 deg)
//   OUT/replay/     lifmcr replay --reference: the sequence through the live
//                   pipeline on LCM, camera X registered to camera 0's map
//                   per trigger (camera_extrinsics_t on LCM, and the same
//                   rows in registration.csv). Offline (--rate max): every
//                   frame is registered, none passed through while its
//                   camera relocalises (a frame lost there left a half of the
//                   hand-eye split short). Every frame relocalised
//                   (--relocalise-every-frame): the 24 frames are ~3 deg and
//                   ~100 mm apart, where a tracked pose was about twice as
//                   far from the truth as a relocalised one (camera X 1.99
//                   against 0.98 mm RMS; docs/evaluation.md) and the
//                   correlated error of a tracked stretch kept the corrected
//                   absolute error above the relative one; it costs ~6 s.
//   OUT/evaluate/   lifmcr evaluate against Vicon, hand-eye split in halves
//
// Each stage runs as a child process of this executable (the same binary,
// /proc/self/exe), so its progress reaches the terminal as the command's
// own, and the demo prints the command line first: the recipe for a
// recorded sequence is the same lines with its folders.

#include "apps/commands.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "registration/features/intrinsics_yaml.h"
#include "replay/layout.h"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <spawn.h>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// The rig synth writes: camera 0 (the reference) and camera X.
const std::string kReference = "40398678";
const std::string kCameraX = "40398673";

struct Args {
  std::string out;
  int frames = 24;
  int calibration_frames = 0;  // 0: every frame (the map-frame evaluation needs camera 0's pose)
  int max_features = 2000;
  std::string lcm_url;
};

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

std::string Quote(const std::string& word) {
  if (word.find_first_of(" '\"\\$") == std::string::npos) return word;
  std::string q = "'";
  for (const char c : word) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// Runs `lifmcr ARGS...` (this executable) with the terminal's stdout and
// stderr; returns its exit code, or -1 when it could not be started or died.
int RunStage(const std::vector<std::string>& args) {
  std::vector<std::string> argv_text{"lifmcr"};
  argv_text.insert(argv_text.end(), args.begin(), args.end());
  std::string shown = "  $ lifmcr";
  for (const std::string& a : args) shown += " " + Quote(a);
  std::cerr << shown << "\n" << std::flush;
  std::vector<char*> argv;
  for (std::string& a : argv_text) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::cout << std::flush;
  pid_t pid = 0;
  if (posix_spawn(&pid, "/proc/self/exe", nullptr, nullptr, argv.data(), environ) != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

class Stages {
 public:
  explicit Stages(int count) : count_(count), start_(Clock::now()) {}
  void Begin(const std::string& what) {
    stage_start_ = Clock::now();
    std::fprintf(stderr, "\n[%d/%d] %s (%.0f s so far)\n", ++at_, count_, what.c_str(),
                 Seconds(start_));
  }
  void End(const std::string& what) const {
    std::fprintf(stderr, "[%d/%d] %s: %.1f s\n", at_, count_, what.c_str(), Seconds(stage_start_));
  }
  double Total() const { return Seconds(start_); }

 private:
  int count_;
  int at_ = 0;
  Clock::time_point start_, stage_start_;
};

int Fail(const std::string& message, int code) {
  std::cerr << "lifmcr demo: " << EscapeText(message) << "\n";
  return code;
}

// Nominal intrinsics as a lens data sheet would give them: the truth with
// f_L and b_L0 5 % long and B 5 % short (each alone 5 % off is no camera,
// docs/calibration.md), the rest as the synthetic camera has it.
Status WriteNominalIntrinsics(const fs::path& truth, const fs::path& out) {
  Expected<registration::CameraCalibration> k = registration::ReadCameraCalibration(truth, kReference);
  if (!k) return k.error();
  k->intrinsics.main_focal_length_mm *= 1.05;
  k->intrinsics.mla_to_main_lens_mm *= 1.05;
  k->intrinsics.mla_to_sensor_mm *= 0.95;
  registration::CalibrationAnnotation note;
  note.summary = "nominal values for lifmcr demo: the truth with f_L, b_L0 +5 % and B -5 %";
  return registration::WriteIntrinsicsYaml(out, kReference, *k, note);
}

// "0,2,4,..": `count` frames spread over the sequence's `frames`.
std::string SpreadFrames(int frames, int count) {
  std::string list;
  for (int k = 0; k < count; ++k) {
    const int f = static_cast<int>(static_cast<long long>(k) * frames / count);
    list += (k ? "," : "") + std::to_string(f);
  }
  return list;
}

int RunDemo(const Args& args) {
  if (args.calibration_frames > args.frames)
    return Fail("--calibration-frames must not exceed --frames", 2);
  const int calibration_frames = args.calibration_frames > 0 ? args.calibration_frames : args.frames;
  fs::path out = args.out;
  if (out.empty()) {
    std::string pattern = (fs::temp_directory_path() / "lifmcr-demo-XXXXXX").string();
    if (mkdtemp(pattern.data()) == nullptr)
      return Fail("cannot create a temporary folder in " + fs::temp_directory_path().string(), 3);
    out = pattern;
  }
  out = fs::absolute(out);
  const fs::path data = out / "data", calibrate = out / "calibrate", registered = out / "replay",
                 evaluate = out / "evaluate";
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) return Fail(out.string() + ": " + ec.message(), 3);
  std::cerr << "lifmcr demo: synth -> calibrate camera 0 -> replay with live registration -> "
               "evaluate against Vicon, into "
            << out.string() << "\n";
  Stages stages(4);

  stages.Begin("synth: " + std::to_string(args.frames) +
               " frames of 2 cameras, table scene, orbit motion, preset small");
  const fs::path synth_yaml = out / "synth.yaml";
  {
    std::ofstream f(synth_yaml);
    f << "# lifmcr demo: far enough for the marker plate to be in view (calibration's scale)\n"
         "rig:\n  viewing_distance_mm: 1800\n";
    if (!f) return Fail(synth_yaml.string() + ": cannot write", 3);
  }
  if (int code = RunStage({"synth", "--out", data.string(), "--preset", "small", "--frames",
                           std::to_string(args.frames), "--cameras", "2", "--motion", "orbit",
                           "--config", synth_yaml.string()});
      code != 0)
    return Fail("synth failed (exit " + std::to_string(code) + ")", 1);
  stages.End("synth");
  const fs::path seq = data / "00_Synthetic" / "Sequence_00";

  stages.Begin("calibrate camera " + kReference + " on " + std::to_string(calibration_frames) +
               " frames, from nominal values 5 % off");
  fs::create_directories(calibrate, ec);
  const fs::path initial = calibrate / "nominal.yaml";
  if (Status s = WriteNominalIntrinsics(layout::CamerasYamlPath(seq), initial); !s)
    return Fail(s.error().message, 1);
  const int calibrate_code =
      RunStage({"calibrate", seq.string(), "--camera", kReference, "--out", calibrate.string(),
                "--initial", initial.string(), "--frames",
                SpreadFrames(args.frames, calibration_frames), "--max-features",
                std::to_string(args.max_features), "--fix-principal-point", "--fix-distortion",
                // Every point seen twice: the few small frames' map is what
                // live tracking follows (calibrate's default also asks rays
                // 5 degrees apart, which few small views from 1.8 m give).
                "--min-map-observations", "2", "--min-map-angle", "0", "--ground-truth"});
  if (calibrate_code == 3)
    std::cerr << "lifmcr demo: the calibration is flagged (calibrate/calibration_report.md says "
                 "why); going on with it\n";
  else if (calibrate_code != 0)
    return Fail("calibrate failed (exit " + std::to_string(calibrate_code) + ")", 1);
  stages.End("calibrate");

  stages.Begin("replay on LCM with live registration of camera " + kCameraX + " in camera " +
               kReference + "'s map");
  // Camera 0 as calibrated (the map's intrinsics.yaml); camera X as the
  // synthetic rig made it (GroundTruth/cameras.yaml; a recorded rig
  // calibrates each camera: lifmcr calibrate --camera SERIAL).
  std::vector<std::string> replay{"replay", seq.string(), "--rate", "max", "--reference",
                                  calibrate.string(), "--relocalise-every-frame",
                                  "--extrinsics-csv", (registered / "registration.csv").string()};
  if (!args.lcm_url.empty()) replay.insert(replay.end(), {"--lcm", args.lcm_url});
  fs::create_directories(registered, ec);
  if (int code = RunStage(replay); code != 0)
    return Fail("replay failed (exit " + std::to_string(code) + ")", 1);
  stages.End("replay");

  stages.Begin("evaluate against Vicon, hand-eye estimated on one half and applied to the other");
  const int evaluate_code = RunStage(
      {"evaluate", seq.string(), "--registration", (registered / "registration.csv").string(),
       "--reference-poses", (calibrate / ("poses_" + kReference + ".csv")).string(),
       "--map", calibrate.string(), "--split", "half", "--out", evaluate.string()});
  if (evaluate_code != 0 && evaluate_code != 3)
    return Fail("evaluate failed (exit " + std::to_string(evaluate_code) + ")", 1);
  stages.End("evaluate");

  std::cout << "\nlifmcr demo: done in " << static_cast<int>(stages.Total() + 0.5) << " s\n"
            << "  report:  " << (evaluate / "evaluation.md").string() << "\n"
            << "  plots:   " << (evaluate / "plots").string() << "/ (trajectories_top.png, "
            << "map_pnp_" << kCameraX << "_errors.png, ...)\n"
            << "  calibration: " << (calibrate / "calibration_report.md").string() << "\n"
            << "  data:    " << seq.string() << "\n";
  return 0;
}

}  // namespace

CommandRun AddDemoCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  app.footer(
      "The whole chain on a small synthetic rig, one stage after the other, each the lifmcr\n"
      "command printed before it runs: synth (2 cameras, table scene, orbit motion) ->\n"
      "calibrate camera 0 from nominal values -> replay on LCM with live registration of\n"
      "camera X in camera 0's map -> evaluate against Vicon with the hand-eye correction\n"
      "(estimated on one half of the frames, applied to the other). Ends with the\n"
      "evaluation table and where the plots are.\n"
      "The replay is offline (--rate max): it waits for processing and registers every\n"
      "frame, none passed through while its camera relocalises, and it relocalises every\n"
      "frame (--relocalise-every-frame) rather than tracking: the frames are ~3 deg and\n"
      "~100 mm apart, too far for tracking to keep its accuracy (docs/evaluation.md).\n"
      "What it shows: c0_from_cx after the hand-eye correction within its relative\n"
      "(frame-to-frame) error, the gate of the evaluation.\n"
      "Reads: nothing. Writes: into --out (default: a new temporary folder) data/ (the rig),\n"
      "calibrate/, replay/registration.csv, evaluate/ (evaluation.md, plots/*.png).\n"
      "Exit codes: 0 every stage ran; 1 a stage failed (its message says which); 2 usage\n"
      "error; 3 the folder could not be written.");
  app.add_option("--out", args->out, "Folder for every stage's output (default: a new temporary folder)");
  app.add_option("--frames", args->frames,
                 "Triggers to render (each half of the hand-eye split needs 10 with both "
                 "cameras registered)")
      ->check(CLI::Range(4, 10000))
      ->capture_default_str();
  app.add_option("--calibration-frames", args->calibration_frames,
                 "Frames of camera 0 to calibrate on, spread over the sequence (0: all; the "
                 "map-frame evaluation has camera 0's pose only on these)")
      ->check(CLI::Range(0, 10000))
      ->capture_default_str();
  app.add_option("--max-features", args->max_features, "SIFT keypoints per TF image")
      ->check(CLI::Range(100, 100000))
      ->capture_default_str();
  app.add_option("--lcm", args->lcm_url,
                 "LCM URL of the replay (default: LCM's, udpm://239.255.76.67:7667; watch with "
                 "lifmcr monitor or scripts/lcm-spy.sh)")
      ->check(LcmUrlCheck, "LCM URL");
  return [args] { return RunDemo(*args); };
}

}  // namespace lifmcr::apps
