// `lifmcr record`: records a rig live into the LiFMCR layout (acquisition/).

#include "acquisition/recorder.h"
#include "acquisition/rig_controller.h"
#include "apps/commands.h"
#include "apps/pipeline/camera_setup.h"
#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/live_registration.h"
#include "apps/pipeline/pipeline.h"
#include "apps/pipeline/process_settings.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "drivers/camera_factory.h"
#include "drivers/replay_camera.h"
#include "drivers/vicon_csv_source.h"
#include "drivers/vicon_udp_source.h"
#include "processing/frame_chain.h"
#include "replay/bayer.h"
#include "replay/layout.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <ctime>
#include <iomanip>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <pthread.h>
#include <sstream>
#include <signal.h>
#include <unistd.h>

namespace lifmcr::apps {
namespace {

constexpr int kExitLost = 1;
constexpr int kExitUsage = 2;
constexpr int kExitCannotStart = 3;

Expected<std::unique_ptr<ViconSource>> MakeViconSource(const RigConfig& rig) {
  ViconPoseOptions pose;
  pose.rotation = rig.vicon.rotation;
  pose.handedness = rig.vicon.handedness;
  switch (rig.vicon.source) {
    case ViconSourceKind::kNone:
      return std::unique_ptr<ViconSource>();
    case ViconSourceKind::kUdp:
      return std::unique_ptr<ViconSource>(
          std::make_unique<ViconUdpSource>(ViconUdpSourceOptions::FromRig(rig)));
    case ViconSourceKind::kCsv: {
      ViconCsvSourceOptions options;
      options.pose = pose;
      options.objects = ViconObjectsOfRig(rig);
      options.realtime = true;
      options.rate_hz = rig.vicon.rate_hz;
      auto source = ViconCsvSource::Open(rig.vicon.csv, options);
      if (!source) return source.error();
      return std::unique_ptr<ViconSource>(std::move(*source));
    }
  }
  return Error{"vicon: unknown source"};
}

struct Args {
  std::string rig;
  std::string out;
  double duration_s = 0;
  std::string scene = "00_Recording";
  std::string sequence = "seq";
  std::string replay;  // sequence folder the replay cameras serve
  bool no_sync = false;
  bool publish = false;
  std::string lcm_url;
  bool no_processing = false;
  std::string cameras;  // --cameras SERIAL[,SERIAL...]: this host's share of the rig
  // --reference MAP_DIR: live registration (rigid_mount: the rig file's).
  RegistrationArgs registration;
};

// The live pipeline beside the recorder (--publish), configured by the
// rig file's processing: and lcm: sections, --lcm and --no-processing
// overriding them: frames reach it through the controller's observer (a
// mutex-guarded hand-over); it never blocks a grab thread, so a slow stage
// costs skipped previews (newest_wins) or a later publication (block),
// never recorded frames.
// With --reference, live registration (live_registration.h) is set up in
// `live` and runs as the pipeline's registration stage.
// `relate`: the process holds every camera of the rig file (no --cameras
// leaving some out) and relates their poses itself; else its poses go out
// on POSE for `lifmcr relate` (the rig's registration.rigid_mount is then
// relate's to apply).
Expected<std::unique_ptr<Pipeline>> MakePublishPipeline(const RigConfig& rig, const Args& args,
                                                        bool relate,
                                                        std::optional<LiveRegistration>* live) {
  const PreviewOptions preview = PreviewOptionsFromRig(rig);
  if (Status s = preview.Check(); !s) return s.error();
  std::unique_ptr<FrameProcessor> processor;
  const bool processing = rig.processing.enabled && !args.no_processing;
  // Bayer cameras (pixel_format BayerXX8) are demosaiced before preview and
  // processing (frame_processor.h).
  PixelFormats formats;
  for (const CameraConfig& camera : rig.cameras)
    if (IsBayer(camera.pixel_format)) formats[camera.serial] = camera.pixel_format;
  std::vector<std::filesystem::path> intrinsics(args.registration.intrinsics.begin(),
                                                args.registration.intrinsics.end());
  if (!args.registration.reference.empty()) {
    if (!processing)
      return Error{"--reference needs processing (rig processing.enabled, not --no-processing)"};
    LiveRegistrationOptions live_options;
    live_options.reference_dir = args.registration.reference;
    live_options.intrinsics = intrinsics;
    live_options.extrinsics_csv = args.registration.extrinsics_csv;
    // Replay cameras (--replay SEQ): the sequence's ground truth last.
    if (!args.replay.empty())
      live_options.fallback_intrinsics.push_back(layout::CamerasYamlPath(args.replay));
    live_options.rigid_mount = relate && rig.registration.rigid_mount;
    live_options.relate = relate;
    live_options.monitor.changed_after = rig.registration.changed_after;
    live_options.monitor.settle_triggers = rig.registration.settle_triggers;
    std::vector<std::string> serials;
    for (const CameraConfig& camera : rig.cameras) serials.push_back(camera.serial);
    auto loaded = LoadLiveRegistration(live_options, serials);
    if (!loaded) return loaded.error();
    *live = std::move(*loaded);
    intrinsics = (*live)->intrinsics_files;
  }
  if (processing) {
    // The same chain and calibration lookup as replay (camera_setup.h): the
    // MLA file of each camera and the white image beside it.
    auto setups = LoadRigCameras(rig, intrinsics);
    if (!setups) return setups.error();
    if (Status s = DemosaicWhiteImages(formats, &*setups); !s) return s.error();
    auto chain = processing::ProcessingChain::Create(std::move(*setups),
                                                     DepthProcessor::ChainOptionsForPipeline());
    if (!chain) return chain.error();
    auto depth = std::make_unique<DepthProcessor>(std::move(*chain), preview, formats);
    // Each camera's per-lens estimator (and, with --reference, the
    // localizer's TF sampler) made before the cameras start: left to the
    // first frame, the lens lane spent about 0.6 s per camera at medium on
    // it while the frames the live cameras took meanwhile were skipped.
    const auto warm_start = std::chrono::steady_clock::now();
    auto left = depth->WarmWithoutFrames(live->has_value());
    if (!left) return left.error();
    const double warm_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - warm_start).count();
    // A stream of its own: std::fixed stays off std::cerr's later lines.
    std::ostringstream line;
    line << "lifmcr record: per-lens estimators" << (live->has_value() ? " and TF samplers" : "")
         << " of " << depth->chain().serials().size() - left->size()
         << " camera(s) made before the cameras start (" << std::fixed << std::setprecision(2)
         << warm_s << " s)";
    if (!left->empty())
      line << "; " << left->size() << " without a white image at their first frame";
    std::cerr << line.str() << "\n";
    processor = std::move(depth);
  } else {
    processor = std::make_unique<PreviewProcessor>(preview, formats);
  }
  FrameSetAssemblerOptions sync = FrameSetAssemblerOptions::FromRig(rig);
  PipelineOptions options = PipelineOptions::FromRig(rig);
  if (!args.lcm_url.empty()) options.publisher.url = args.lcm_url;
  // The controller's assembler makes the FrameSets (one per run; with
  // --no-sync too, without Vicon association).
  options.relate = relate;
  if (*live) (*live)->Configure(&options);
  return Pipeline::Create(sync, std::move(processor), options);
}

int Run(const Args& args) {
  // SIGINT/SIGTERM are taken synchronously by the main loop (sigtimedwait),
  // so they are blocked before any thread starts and every thread inherits
  // the mask. A file-size limit makes writes fail with EFBIG (counted, clean
  // stop) instead of killing the process with SIGXFSZ.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  std::signal(SIGXFSZ, SIG_IGN);
  std::signal(SIGPIPE, SIG_IGN);

  if (Status s = args.registration.Check(); !s) {
    std::cerr << "lifmcr record: " << s.error().message << "\n";
    return kExitUsage;
  }
  if (!args.publish && !args.registration.reference.empty()) {
    std::cerr << "lifmcr record: --reference needs --publish (registration runs in the live "
                 "pipeline)\n";
    return kExitUsage;
  }
  auto rig = LoadRigConfig(args.rig);
  if (!rig) {
    std::cerr << "lifmcr record: " << EscapeText(rig.error().message) << "\n";
    return kExitUsage;
  }
  // --cameras: this host's share of the rig; the others are left out of
  // everything below (armed, recorded, processed, published).
  const std::size_t rig_cameras = rig->cameras.size();
  // The Vicon stream is the whole rig's: every host receives and records
  // every object, whichever cameras it holds.
  const RigConfig whole_rig = *rig;
  if (!args.cameras.empty()) {
    std::vector<std::string> serials;
    for (const CameraConfig& camera : rig->cameras) serials.push_back(camera.serial);
    auto selected = SelectCameras(args.cameras, serials, args.rig);
    if (!selected) {
      std::cerr << "lifmcr record: " << EscapeText(selected.error().message) << "\n";
      return kExitUsage;
    }
    std::erase_if(rig->cameras, [&](const CameraConfig& camera) {
      return std::find(selected->begin(), selected->end(), camera.serial) == selected->end();
    });
  }
  const bool every_camera = rig->cameras.size() == rig_cameras;
  RecorderOptions options = RecorderOptions::FromRig(rig->recorder);
  options.vicon_objects = ViconObjectsOfRig(whole_rig);
  options.root_dir = args.out.empty() ? rig->recorder.out_dir : std::filesystem::path(args.out);
  options.scene = args.scene;
  options.sequence = args.sequence;
  if (options.root_dir.empty()) {
    std::cerr << "lifmcr record: no output folder: give --out (or recorder.out_dir in " << EscapeText(args.rig)
              << ")\n";
    return kExitUsage;
  }
  if (Status s = options.Check(); !s) {
    std::cerr << "lifmcr record: " << EscapeText(s.error().message) << "\n";
    return kExitUsage;
  }

  std::vector<std::unique_ptr<Camera>> cameras;
  std::vector<bool> software_trigger;
  for (std::size_t i = 0; i < rig->cameras.size(); ++i) {
    const CameraConfig& config = rig->cameras[i];
    CameraFactoryOptions factory;
    // The recorder's queue plus frames in the stream and in the grab thread;
    // with --publish also those the pipeline holds (the assembler's set, the
    // workers' and the lanes': PipelineOptions::FramesHeldPerCamera).
    factory.pool_buffers = rig->recorder.queue_frames + 4 +
                           (args.publish ? PipelineOptions::FromRig(*rig).FramesHeldPerCamera() : 0);
    factory.trigger_period = TriggerPeriod(rig->vicon);
    factory.replay_sequence_dir = args.replay;
    factory.replay_pacing = config.trigger.mode == TriggerMode::kSoftware
                                ? ReplayPacing::kSoftwareTrigger
                                : ReplayPacing::kOriginal;
    factory.free_run_rate_hz = config.trigger.mode == TriggerMode::kFreeRun
                                   ? rig->vicon.rate_hz / rig->vicon.trigger_divider
                                   : 0.0;
    auto camera = MakeCamera(config, static_cast<int>(i), factory);
    if (!camera) {
      std::cerr << "lifmcr record: " << EscapeText(camera.error().message) << "\n";
      return kExitCannotStart;
    }
    cameras.push_back(std::move(*camera));
    software_trigger.push_back(config.trigger.mode == TriggerMode::kSoftware);
  }
  auto vicon = MakeViconSource(whole_rig);
  if (!vicon) {
    std::cerr << "lifmcr record: " << EscapeText(vicon.error().message) << "\n";
    return kExitCannotStart;
  }
  auto recorder = Recorder::Create(*rig, options);
  if (!recorder) {
    std::cerr << "lifmcr record: " << EscapeText(recorder.error().message) << "\n";
    return kExitCannotStart;
  }
  std::unique_ptr<Pipeline> pipeline;
  std::optional<LiveRegistration> live;
  std::unique_ptr<ProcessSettings> process_settings;
  RigObserver observer;
  if (args.publish) {
    process_settings = ProcessSettings::ForPipeline(ProcessSettings::ArenasFor(
        !args.registration.reference.empty(),
        rig->processing.skip_policy == SkipPolicy::kNewestWins));
    auto made = MakePublishPipeline(*rig, args, every_camera, &live);
    if (!made) {
      std::cerr << "lifmcr record: --publish: " << EscapeText(made.error().message) << "\n";
      (*recorder)->Stop();
      return kExitCannotStart;
    }
    pipeline = std::move(*made);
    Pipeline* p = pipeline.get();
    // A copy of a Frame or FrameSet shares the pooled buffers (no pixel copy).
    observer.on_frame_set = [p](const FrameSet& set) { p->AddFrameSet(set); };
    observer.on_vicon = [p](const ViconFrame& frame) { p->AddVicon(frame); };
  }
  RigControllerOptions controller_options;
  controller_options.trigger_hz = rig->vicon.rate_hz / rig->vicon.trigger_divider;
  if (rig->vicon.source == ViconSourceKind::kUdp)
    controller_options.vicon_realtime_priority = RigControllerOptions::kLiveViconPriority;
  for (const CameraConfig& camera : rig->cameras)
    controller_options.device_clocks.push_back(camera.device_clock);
  // Cameras on a line this command does not drive (a trigger box pulsing all
  // the time) see its first pulses only once armed, one after the other: the
  // run starts at the first trigger every camera was armed for. Software
  // triggers start only after every camera is armed.
  controller_options.start_at_all_armed =
      std::any_of(rig->cameras.begin(), rig->cameras.end(), [](const CameraConfig& camera) {
        return camera.trigger.mode == TriggerMode::kHardware;
      });
  // The pipeline takes FrameSets, so --publish keeps the assembler even with
  // --no-sync, which then only leaves the Vicon association out.
  if (!args.no_sync || args.publish) {
    controller_options.sync = FrameSetAssemblerOptions::FromRig(*rig);
    if (args.no_sync) controller_options.sync->vicon_expected = false;
  }
  RigController controller(std::move(cameras), std::move(software_trigger), std::move(*vicon),
                           recorder->get(), controller_options, observer);
  if (Status s = controller.Start(); !s) {
    std::cerr << "lifmcr record: " << EscapeText(s.error().message) << "\n";
    (*recorder)->Stop();
    return kExitCannotStart;
  }
  std::cerr << "lifmcr record: recording " << rig->cameras.size() << " camera(s) into "
            << (*recorder)->sequence_dir().string() << " (Ctrl-C or SIGTERM stops)\n";

  const bool terminal = isatty(STDERR_FILENO) == 1;
  const auto start = std::chrono::steady_clock::now();
  auto next_status = start + std::chrono::seconds(1);
  std::string stop_why = "duration reached";
  for (;;) {
    const timespec wait{0, 100 * 1000 * 1000};
    const int signal_number = sigtimedwait(&stop_signals, nullptr, &wait);
    if (signal_number == SIGINT || signal_number == SIGTERM) {
      stop_why = signal_number == SIGINT ? "SIGINT" : "SIGTERM";
      break;
    }
    if ((*recorder)->failed()) {
      stop_why = "write error";
      break;
    }
    // A rig made only of replay cameras ends with its sequence: its frames
    // and, from a Vicon CSV, every Vicon frame of it (the recording then
    // holds the whole sequence, whatever the timing).
    if (controller.CamerasFinished() &&
        (whole_rig.vicon.source != ViconSourceKind::kCsv || controller.ViconFinished())) {
      stop_why = "end of the replayed sequence";
      break;
    }
    if (pipeline) pipeline->Poll();
    const auto now = std::chrono::steady_clock::now();
    if (args.duration_s > 0 &&
        std::chrono::duration<double>(now - start).count() >= args.duration_s)
      break;
    if (now >= next_status) {
      const RigHealth health = controller.Health();
      if (pipeline) pipeline->SetSyncDrops(health.sync_drops);
      const std::string line = health.StatusLine();
      if (terminal)
        std::cerr << "\r" << line << "\x1b[K" << std::flush;
      else
        std::cerr << line << "\n";
      next_status += std::chrono::seconds(1);
    }
  }
  if (terminal) std::cerr << "\n";
  std::cerr << "lifmcr record: stopping (" << stop_why << ")\n";
  controller.Stop();
  (*recorder)->Stop();
  const RigHealth health = controller.Health();
  std::cout << "sequence: " << (*recorder)->sequence_dir().string() << "\n"
            << "stopped by: " << stop_why << "\n"
            << health.FinalReport();
  // The operator's log keeps every loss with its cause (the report above
  // goes to stdout, which a service's supervisor may not keep).
  for (const std::string& line : health.LossLines()) spdlog::warn("record: {}", line);
  if (pipeline) {
    pipeline->SetSyncDrops(health.sync_drops);
    pipeline->Finish();
    std::cout << "published (--publish):\n" << pipeline->Report().FinalReport();
    if (live) std::cout << LiveRegistrationReport(*live);
  }
  return health.AnythingLost() ? kExitLost : 0;
}

}  // namespace

CommandRun AddRecordCommand(CLI::App& app) {
  auto args = std::make_shared<Args>();
  app.footer(
      "Records every camera of the rig file (armed for its trigger; software-triggered\n"
      "cameras are fired at vicon.rate_hz / vicon.trigger_divider) and every Vicon frame\n"
      "into OUT/SCENE/SEQUENCE in the LiFMCR layout: TypeE_<serial>/ raw BMPs numbered by\n"
      "trigger from each camera's frame counter (16-bit wrap aware; across a reconnect by\n"
      "host time), Vicon/sequence_01.csv (one line per received Vicon frame), and the MLA\n"
      "files and VSK copied into OUT/Calibration/. The sync assembler builds one FrameSet\n"
      "per trigger beside it; the report gives its Vicon frame of trigger 0 (f0: frame k\n"
      "fired on Vicon frame f0 + divider * k) and its losses by kind.\n"
      "Cameras: driver 'aravis' (GigE Vision, USB3 Vision, Aravis fake cameras) and\n"
      "'replay' (the camera folders of --replay SEQ, served at the trigger period, or per\n"
      "software trigger; the recording ends with the sequence when every camera replays,\n"
      "and with a Vicon CSV source once its frames are in too).\n"
      "--cameras SERIAL[,SERIAL...]: only these cameras of the rig file (a host's share of\n"
      "a rig on several hosts); every Vicon object is still recorded. With --publish\n"
      "--reference their poses go out on <PREFIX>_<SERIAL>_POSE and `lifmcr relate` makes\n"
      "the extrinsics; `lifmcr merge` joins the hosts' recordings.\n"
      "A status line on stderr (per camera fps, MB/s, recorder queue, lost frames; Vicon\n"
      "rate and gaps; disk backlog) is refreshed in place on a terminal, printed once a\n"
      "second otherwise. Stops after --duration, on SIGINT/SIGTERM, or by itself on a\n"
      "write error (disk full): files already written stay valid, the CSV ends with a\n"
      "complete line. The final report on stdout says what was kept and what was lost.\n"
      "Reads: --rig RIG.yaml (cameras, Vicon source, MLA files), the cameras and the Vicon\n"
      "stream (or --replay SEQ), with --reference MAP_DIR the map and --intrinsics files\n"
      "(live registration as lifmcr replay --reference; the rig's registration: section).\n"
      "Writes: OUT as above; with --publish the LCM channels of lifmcr replay, and the\n"
      "--extrinsics-csv file.\n"
      "Exit codes: 0 nothing lost; 1 a frame, a Vicon frame or a CSV line was lost, or a\n"
      "write error stopped the recording; 2 usage or rig file error; 3 a camera, the Vicon\n"
      "source or the output folder could not be started (an existing non-empty sequence\n"
      "folder is never overwritten).");
  app.add_option("--rig", args->rig, "Rig file (YAML, see config/README.md)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--out", args->out, "Dataset root to record into (default: recorder.out_dir)");
  app.add_option("--duration", args->duration_s, "Seconds to record; 0 = until a signal")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--scene", args->scene, "Scene folder name")->capture_default_str();
  app.add_option("--sequence", args->sequence, "Sequence folder name")->capture_default_str();
  app.add_flag("--publish", args->publish,
               "Run the live pipeline on the frames too and publish on LCM (as lifmcr replay)");
  app.add_option("--lcm", args->lcm_url, "LCM URL for --publish (default: the rig's lcm.url)")
      ->check(LcmUrlCheck, "LCM URL");
  app.add_flag("--no-processing", args->no_processing,
               "--publish previews only (no depth, no TF; as processing.enabled: false)");
  app.add_option("--cameras", args->cameras,
                 "SERIAL[,SERIAL...]: only these cameras of the rig file (this host's; default: "
                 "every one); with --publish --reference their poses go out on _POSE for "
                 "lifmcr relate");
  app.add_option("--replay", args->replay,
                 "Sequence folder that cameras with driver 'replay' serve")
      ->check(CLI::ExistingDirectory);
  AddRegistrationOptions(
      app, &args->registration,
      "--publish: live registration against this reference map (see lifmcr replay)");
  app.add_flag("--no-sync", args->no_sync,
               "Leave the sync assembler out (no FrameSets, no Vicon f0 in the report); "
               "with --publish the FrameSets are still made, without Vicon frames");
  return [args] { return Run(*args); };
}

}  // namespace lifmcr::apps
