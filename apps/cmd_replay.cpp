// `lifmcr replay`: a sequence through the live pipeline onto LCM.

#include "apps/commands.h"
#include "apps/pipeline/camera_setup.h"
#include "apps/pipeline/process_settings.h"
#include "apps/pipeline/replay_runner.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "replay/sequence.h"

#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <unistd.h>

namespace lifmcr::apps {

std::string LcmUrlCheck(const std::string& url) {
  const std::optional<std::string> problem = LcmUrlProblem(url);
  return problem ? *problem : std::string();
}
namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop = true; }

struct Args {
  std::string sequence;
  std::string rate = "original";
  bool loop = false;
  std::string lcm_url;
  bool no_processing = false;
  int concurrency = 2;
  std::vector<std::string> pixel_formats;
  RegistrationArgs registration;
  std::string cameras;
};

}  // namespace

int RunReplayCommand(const std::string& sequence, const std::string& rate_text, bool loop,
                     const std::string& lcm_url, bool processing, int concurrency, const char* who,
                     const RegistrationArgs& registration,
                     const std::vector<std::string>& pixel_formats, const std::string& cameras) {
  auto rate = ReplayRate::Parse(rate_text);
  if (!rate) {
    std::cerr << who << ": " << EscapeText(rate.error().message) << "\n";
    return 2;
  }
  auto formats = ParsePixelFormatOptions(pixel_formats);
  if (!formats) {
    std::cerr << who << ": " << EscapeText(formats.error().message) << "\n";
    return 2;
  }
  // --cameras naming a camera the sequence lacks is a usage error (exit 2),
  // told before anything starts; RunReplay checks it again for its callers.
  if (!cameras.empty()) {
    if (auto layout = DiscoverSequence(sequence); layout) {
      std::vector<std::string> serials;
      for (const CameraFolder& folder : layout->cameras) serials.push_back(folder.serial);
      if (auto selected = SelectCameras(cameras, serials, sequence); !selected) {
        std::cerr << who << ": " << EscapeText(selected.error().message) << "\n";
        return 2;
      }
    }
  }
  g_stop = false;
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  const bool terminal = isatty(STDERR_FILENO) == 1;
  ReplayRunOptions options;
  options.sequence_dir = sequence;
  options.rate = *rate;
  options.loop = loop;
  options.processing = processing;
  options.pipeline.publisher.url = lcm_url;
  options.pipeline.max_concurrency = concurrency;
  options.stop = &g_stop;
  options.pixel_formats = std::move(*formats);
  options.cameras = cameras;
  for (const std::string& file : registration.intrinsics) options.intrinsics.emplace_back(file);
  if (!registration.reference.empty()) {
    LiveRegistrationOptions live;
    live.reference_dir = registration.reference;
    live.extrinsics_csv = registration.extrinsics_csv;
    live.rigid_mount = registration.rigid_mount;
    live.localizer.track = !registration.relocalise_every_frame;
    options.registration = live;
  } else if (Status s = registration.Check(); !s) {
    std::cerr << who << ": " << s.error().message << "\n";
    return 2;
  }
  options.on_status = [terminal](const PipelineReport& report) {
    if (terminal)
      std::cerr << "\r" << report.StatusLine() << "\x1b[K" << std::flush;
    else
      std::cerr << report.StatusLine() << "\n";
  };
  // Under --rate max the pipeline blocks (every frame processed on the workers).
  const auto process_settings = ProcessSettings::ForPipeline(ProcessSettings::ArenasFor(
      options.registration.has_value(), rate->kind != ReplayRate::Kind::kMax));
  auto result = RunReplay(options);
  if (terminal) std::cerr << "\n";
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  if (!result) {
    std::cerr << who << ": " << EscapeText(result.error().message) << "\n";
    return 3;
  }
  std::cout << result->FinalReport();
  if (!result->report.Accounted()) return 1;
  return result->report.failed > 0 ? 1 : 0;
}

int RunReplayCommand(const std::string& sequence, const std::string& rate_text, bool loop,
                     const std::string& lcm_url, bool processing, int concurrency,
                     const char* who) {
  return RunReplayCommand(sequence, rate_text, loop, lcm_url, processing, concurrency, who,
                          RegistrationArgs{}, {});
}

CommandRun AddReplayCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  app.footer(
      "Plays SEQ_DIR (a LiFMCR sequence: TypeE_<serial>/ raw frames, Vicon/sequence_XX.csv)\n"
      "with the replay camera and the CSV Vicon source through the live pipeline: sync,\n"
      "processing (preview; virtual depth and the totally focused image from the MLA\n"
      "files in the Calibration/ folder beside the scene), LCM. Channels:\n"
      "LIFMCR_<SERIAL>_PREVIEW, _DEPTH, _TF, LIFMCR_VICON, LIFMCR_STATS.\n"
      "--reference MAP_DIR (lifmcr calibrate's --out, or lifmcr register's reference/):\n"
      "live registration: every camera localised against the map's camera (camera 0),\n"
      "tracked from its last poses or relocalised, c0_from_cx per trigger on\n"
      "LIFMCR_<SERIAL>_EXTRINSICS and, with --extrinsics-csv FILE, as registration.csv rows\n"
      "(lifmcr evaluate --registration FILE). Intrinsics: MAP_DIR/intrinsics.yaml, the\n"
      "--intrinsics files, then SEQ_DIR/GroundTruth/cameras.yaml, the first that lists\n"
      "the camera.\n"
      "--rate original|FACTOR: timed; frames processing cannot keep up with are skipped\n"
      "(the newest wins) and counted, and a frame of a camera that is being relocalised\n"
      "passes through unregistered. --rate max: paced by the pipeline, every frame is\n"
      "processed and registered (a frame waits for its camera's earlier ones).\n"
      "--relocalise-every-frame: every frame localised from SIFT matches against the map\n"
      "(~0.5 s a frame) instead of tracked from the last pose (~40 ms): for sequences\n"
      "whose frames are far apart (lifmcr demo's 24 frames, 3 deg and 100 mm apart).\n"
      "A status line on stderr, the final report on stdout (frames in, processed,\n"
      "skipped, failed, published). Watch with `lifmcr monitor` or scripts/lcm-spy.sh.\n"
      "--pixel-format: a LiFMCR dataset does not record its cameras' pixel format (the BMPs\n"
      "are 8-bit grey); name Bayer cameras (BayerRG8 for every camera, or SERIAL=BayerRG8,\n"
      "repeatable) and their mosaics are demosaiced: previews and the TF image in colour,\n"
      "depth on luminance, as `lifmcr record --publish` does from the rig file.\n"
      "--cameras SERIAL[,SERIAL...]: only these cameras are played, processed and published\n"
      "(one host's share of a rig on several hosts; triggers numbered as for the whole\n"
      "sequence). With --reference and only some cameras, every pose w0_from_cam goes out\n"
      "on LIFMCR_<SERIAL>_POSE and `lifmcr relate` makes the extrinsics (--extrinsics-csv\n"
      "and --rigid-mount are relate's then).\n"
      "Reads: SEQ_DIR and the Calibration/ folder beside its scene (MLA files, white images\n"
      "when present), MAP_DIR and the --intrinsics files. Writes: the LCM channels above;\n"
      "the --extrinsics-csv file.\n"
      "Exit codes: 0 every frame accounted for and none failed; 1 a processing failure;\n"
      "2 usage; 3 the sequence, its calibration or LCM cannot be opened.");
  app.add_option("SEQ_DIR", args->sequence, "Sequence folder")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--rate", args->rate, "original | max | FACTOR (e.g. 2 = twice as fast)")
      ->capture_default_str();
  app.add_flag("--loop", args->loop, "Play again from the start until Ctrl-C");
  app.add_option("--lcm", args->lcm_url, "LCM URL (default: LCM's, udpm://239.255.76.67:7667)")
      ->check(LcmUrlCheck, "LCM URL");
  app.add_flag("--no-processing", args->no_processing, "Previews only (no depth, no TF)");
  app.add_option("--concurrency", args->concurrency, "Frames processed at once")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--pixel-format", args->pixel_formats,
                 "[SERIAL=]FORMAT: the cameras' pixel format (Mono8, BGR8, BayerRG8, BayerGR8, "
                 "BayerGB8, BayerBG8); without SERIAL, every camera's");
  app.add_option("--cameras", args->cameras,
                 "SERIAL[,SERIAL...]: play only these cameras of SEQ_DIR (default: every one)");
  AddRegistrationOptions(app, &args->registration,
                         "Reference map folder: live registration of every camera to its camera");
  app.add_flag("--rigid-mount", args->registration.rigid_mount,
               "With --reference: flag a camera whose c0_from_cx leaves its running estimate "
               "(as the rig file's registration.rigid_mount)");
  app.add_flag("--relocalise-every-frame", args->registration.relocalise_every_frame,
               "With --reference: relocalise every frame from SIFT matches instead of tracking "
               "from the last pose (slower; for sequences whose frames are far apart)");
  return [args] {
    return RunReplayCommand(args->sequence, args->rate, args->loop, args->lcm_url,
                            !args->no_processing, args->concurrency, "lifmcr replay",
                            args->registration, args->pixel_formats, args->cameras);
  };
}

}  // namespace lifmcr::apps
