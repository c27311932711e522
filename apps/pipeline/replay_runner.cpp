// RunReplay (replay_runner.h).

#include "apps/pipeline/replay_runner.h"

#include "acquisition/rig_controller.h"
#include "apps/pipeline/camera_setup.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "drivers/host_clock.h"
#include "drivers/replay_camera.h"
#include "drivers/vicon_csv_source.h"
#include "replay/bayer.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/vicon_csv.h"

#include <climits>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <ctime>
#include <optional>
#include <sstream>
#include <thread>

namespace lifmcr::apps {

Expected<ReplayRate> ReplayRate::Parse(const std::string& text) {
  ReplayRate rate;
  if (text == "original") return rate;
  if (text == "max") {
    rate.kind = Kind::kMax;
    return rate;
  }
  double factor = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), factor);
  if (ec != std::errc() || end != text.data() + text.size() || !(factor > 0) || factor > 1000)
    return Error{"--rate: expected original, max or a factor in (0, 1000], got '" + text + "'"};
  rate.kind = Kind::kFactor;
  rate.factor = factor;
  return rate;
}

Status ReplayRunOptions::Check() const {
  if (sequence_dir.empty()) return Error{"replay: sequence_dir: empty"};
  if (rate.kind == ReplayRate::Kind::kFactor && !(rate.factor > 0 && rate.factor <= 1000))
    return Error{"replay: rate.factor: expected in (0, 1000]"};
  if (pool_buffers < 0 || pool_buffers > 1024)
    return Error{"replay: pool_buffers: expected 0 (the pipeline's) or 1..1024"};
  if (Status s = preview.Check(); !s) return Error{"replay: " + s.error().message};
  if (Status s = pipeline.Check(); !s) return Error{"replay: " + s.error().message};
  if (registration)
    if (Status s = registration->Check(); !s) return Error{"replay: " + s.error().message};
  // pixel_formats: its serials are checked against the sequence by RunReplay.
  // loop, processing: any value; on_status and stop may be empty; intrinsics:
  // files read when the cameras are set up.
  return Status::Ok();
}

std::string ReplayRunResult::FinalReport() const {
  std::ostringstream out;
  out << "replayed: " << cameras << " camera(s), " << frames_in_sequence
      << " frame files per pass, " << passes << " pass(es)\n"
      << report.FinalReport();
  out << "replay cameras: " << camera_underruns << " frames lost for lack of a buffer, "
      << camera_failed << " unreadable\n"
      << registration;
  return out.str();
}

Expected<PixelFormats> ParsePixelFormatOptions(const std::vector<std::string>& values) {
  PixelFormats formats;
  for (const std::string& value : values) {
    const std::size_t eq = value.find('=');
    const std::string serial = eq == std::string::npos ? "" : value.substr(0, eq);
    const std::string name = eq == std::string::npos ? value : value.substr(eq + 1);
    const std::optional<CameraPixelFormat> format = ParseCameraPixelFormat(name);
    if (!format || (eq != std::string::npos && serial.empty())) {
      return Error{"--pixel-format '" + Excerpt(value) + "': expected FORMAT or SERIAL=FORMAT, " +
                   "FORMAT one of " + CameraPixelFormatNames()};
    }
    if (!formats.emplace(serial, *format).second) {
      return Error{"--pixel-format '" + Excerpt(value) + "': " +
                   (serial.empty() ? std::string("every camera's format") : "camera " + serial) +
                   " given twice"};
    }
  }
  return formats;
}

namespace {

// The Bayer cameras among `serials` by `given` (ReplayRunOptions::pixel_formats).
Expected<PixelFormats> BayerCameras(const PixelFormats& given,
                                    const std::vector<std::string>& serials,
                                    const std::filesystem::path& sequence_dir) {
  for (const auto& [serial, format] : given) {
    if (!serial.empty() && std::find(serials.begin(), serials.end(), serial) == serials.end()) {
      return Error{"--pixel-format: camera '" + Excerpt(serial) + "' is not in " +
                   sequence_dir.string() + " (its TypeE_<serial>/ folders: " +
                   [&] {
                     std::string list;
                     for (const std::string& s : serials) list += (list.empty() ? "" : ", ") + s;
                     return list;
                   }() +
                   ")"};
    }
  }
  PixelFormats bayer;
  const auto every = given.find("");
  for (const std::string& serial : serials) {
    const auto named = given.find(serial);
    const auto it = named != given.end() ? named : every;
    if (it != given.end() && IsBayer(it->second)) bayer[serial] = it->second;
  }
  return bayer;
}

}  // namespace

Expected<ReplayRunResult> RunReplay(const ReplayRunOptions& options,
                                    std::unique_ptr<FrameProcessor> processor) {
  if (Status s = options.Check(); !s) return s.error();
  auto sequence = DiscoverSequence(options.sequence_dir);
  if (!sequence) return sequence.error();
  if (sequence->cameras.empty())
    return Error{options.sequence_dir.string() + ": no TypeE_<serial>/ camera folder"};
  const bool max_rate = options.rate.kind == ReplayRate::Kind::kMax;
  const double factor = options.rate.kind == ReplayRate::Kind::kFactor ? options.rate.factor : 1.0;
  const std::chrono::nanoseconds period(static_cast<std::int64_t>(100'000'000 / factor));

  // Device time of trigger 0: the first frame number of the sequence, of
  // every camera (also those --cameras leaves out), so a host playing some
  // cameras numbers the triggers as one playing all of them.
  std::int64_t first_device_ns = INT64_MAX;
  for (const CameraFolder& folder : sequence->cameras)
    if (!folder.frames.empty())
      first_device_ns = std::min(first_device_ns, folder.frames.front() * period.count());
  if (first_device_ns == INT64_MAX) first_device_ns = 0;
  std::vector<std::string> all_serials;
  for (const CameraFolder& folder : sequence->cameras) all_serials.push_back(folder.serial);
  auto selected = SelectCameras(options.cameras, all_serials, options.sequence_dir.string());
  if (!selected) return selected.error();
  const bool every_camera = selected->size() == all_serials.size();
  std::erase_if(sequence->cameras, [&](const CameraFolder& folder) {
    return std::find(selected->begin(), selected->end(), folder.serial) == selected->end();
  });
  const std::vector<std::string>& serials = *selected;
  auto bayer = BayerCameras(options.pixel_formats, all_serials, options.sequence_dir);
  if (!bayer) return bayer.error();

  std::optional<ViconCsv> csv;
  const ViconBlock* block = nullptr;
  std::int64_t first_vicon_frame = 0;
  double vicon_rate = 80.0;
  if (!sequence->vicon_csvs.empty()) {
    auto read = ReadViconCsv(sequence->vicon_csvs.front());
    if (!read) return read.error();
    csv = std::move(*read);
    block = csv->Find("Objects");
    if (!block) block = csv->Find("Segments");
    if (!block || block->subjects.empty() || block->frames.empty())
      return Error{sequence->vicon_csvs.front().string() + ": no Objects block with poses"};
    first_vicon_frame = block->frames.front();
    vicon_rate = block->rate_hz > 0 ? block->rate_hz : 80.0;
  }

  ReplayRunResult result;
  // The sources of one pass: a ReplayCamera plays its folder once (Start
  // resumes, never rewinds), so every pass opens fresh ones. At --rate max
  // they stamp host_ns on the sequence's own clock from `clock_start_ns`:
  // frames are placed by their trigger, not by when the pipeline let them
  // be read.
  struct Sources {
    std::vector<std::unique_ptr<Camera>> cameras;
    std::vector<const ReplayCamera*> replay;  // the same cameras, for their stats
    std::unique_ptr<ViconSource> vicon;
  };
  auto open_sources = [&](std::int64_t clock_start_ns) -> Expected<Sources> {
    Sources sources;
    for (std::size_t i = 0; i < sequence->cameras.size(); ++i) {
      ReplayCameraOptions camera_options;
      camera_options.camera_index = static_cast<int>(i);
      camera_options.pool_buffers = options.pool_buffers > 0
                                        ? options.pool_buffers
                                        : 1 + options.pipeline.FramesHeldPerCamera();
      camera_options.trigger_period = period;
      camera_options.pacing = max_rate ? ReplayPacing::kAsFastAsPossible : ReplayPacing::kOriginal;
      if (max_rate) {
        camera_options.sequence_clock_start_ns = clock_start_ns;
        camera_options.sequence_origin_device_ns = first_device_ns;
      }
      if (Status s = camera_options.Check(); !s) return s.error();
      // Opened by RigController::Start.
      auto camera = std::make_unique<ReplayCamera>(sequence->cameras[i].dir, camera_options);
      sources.replay.push_back(camera.get());
      sources.cameras.push_back(std::move(camera));
    }
    if (csv) {
      ViconCsvSourceOptions vicon_options;
      vicon_options.objects = block->subjects;
      vicon_options.realtime = !max_rate;
      vicon_options.rate_hz = vicon_rate * factor;
      if (max_rate) vicon_options.sequence_clock_start_ns = clock_start_ns;
      auto source = ViconCsvSource::FromCsv(*csv, vicon_options);
      if (!source) return source.error();
      sources.vicon = std::move(*source);
    }
    return sources;
  };

  FrameSetAssemblerOptions sync;
  sync.serials = serials;
  sync.trigger.trigger_period_ns = period.count();
  sync.trigger.counter_bits = 64;
  sync.trigger.counter_skips_zero = false;
  sync.vicon_expected = csv.has_value();
  sync.vicon_divider = 8;
  sync.vicon_rate_hz = vicon_rate * factor;
  if (csv) sync.vicon_f0 = first_vicon_frame;
  // At --rate max host time says nothing about the triggers: a set waits for
  // every camera (a camera's gap is closed by its next frame, the end of the
  // sequence by Flush), however slow processing is.
  if (max_rate) sync.lateness_ns = 3'600'000'000'000;

  // Live registration: the map, the intrinsics search, the stage.
  std::vector<std::filesystem::path> intrinsics = options.intrinsics;
  std::optional<LiveRegistration> live;
  PipelineOptions pipeline_options = options.pipeline;
  if (options.registration) {
    if (!options.processing)
      return Error{"replay: live registration needs processing (not --no-processing)"};
    LiveRegistrationOptions live_options = *options.registration;
    live_options.intrinsics.insert(live_options.intrinsics.begin(), options.intrinsics.begin(),
                                   options.intrinsics.end());
    live_options.fallback_intrinsics.push_back(layout::CamerasYamlPath(options.sequence_dir));
    // At --rate max nothing is late: every frame is localised, each after its
    // camera's earlier ones (LocalizerOptions::wait_for_earlier_frames).
    if (max_rate) live_options.localizer.wait_for_earlier_frames = true;
    live_options.relate = every_camera;
    auto loaded = LoadLiveRegistration(live_options, serials);
    if (!loaded) return loaded.error();
    live = std::move(*loaded);
    intrinsics = live->intrinsics_files;
    live->Configure(&pipeline_options);
  }

  if (!processor) {
    if (options.processing) {
      auto depth = DepthProcessor::ForSequence(options.sequence_dir.string(), serials,
                                               options.preview, *bayer, intrinsics);
      if (!depth) return depth.error();
      // Newest wins: each camera's per-lens estimator (and the localizer's
      // TF sampler) made from its first frame before the cameras start; left
      // to the first frame, the lens lane spent the first 0.6 s per camera
      // at medium on it while the frames that came meanwhile were skipped.
      if (!max_rate) {
        const auto warm_start = std::chrono::steady_clock::now();
        for (const CameraFolder& folder : sequence->cameras) {
          if (std::find(serials.begin(), serials.end(), folder.serial) == serials.end() ||
              folder.frames.empty())
            continue;
          const auto path = folder.FramePath(folder.frames.front());
          if (!path) continue;
          auto image = ReadBmp(*path);
          if (!image) return image.error();
          Frame first;
          first.serial = folder.serial;
          first.image = image->View();
          if (Status s = (*depth)->Warm(first, options.registration.has_value()); !s)
            return s.error();
        }
        spdlog::info("processing: per-lens estimators, dense workspaces{} of {} camera(s) made "
                     "before the replay ({:.2f} s)",
                     options.registration ? " and TF samplers" : "", serials.size(),
                     std::chrono::duration<double>(std::chrono::steady_clock::now() - warm_start)
                         .count());
      }
      processor = std::move(*depth);
    } else {
      if (Status s = options.preview.Check(); !s) return s.error();
      processor = std::make_unique<PreviewProcessor>(options.preview, *bayer);
    }
  }
  pipeline_options.skip_when_busy = !max_rate;
  pipeline_options.relate = every_camera;
  auto pipeline = Pipeline::Create(sync, std::move(processor), pipeline_options);
  if (!pipeline) return pipeline.error();
  Pipeline& p = **pipeline;

  // The grab loop is the rig's (acquisition/rig_controller.h): a grab thread
  // per replay camera and the Vicon thread feed its assembler, whose
  // FrameSets go to the pipeline (one assembler per run), and Vicon frames
  // go out at once. At --rate max the cameras wait for free buffers
  // (back-pressure from the pipeline, every frame processed) and Vicon is
  // paced one trigger ahead of the slowest camera.
  RigObserver observer;
  observer.on_frame_set = [&p](const FrameSet& set) { p.AddFrameSet(set); };
  observer.on_vicon = [&p](const ViconFrame& frame) { p.AddVicon(frame); };
  RigControllerOptions controller_options;
  controller_options.sync = sync;
  controller_options.trigger_hz = 0;  // no software triggers; first frames by the rig's first
  controller_options.drain = std::chrono::milliseconds(0);  // a pass ends when everything is in
  controller_options.vicon_lead_triggers = max_rate ? 1 : 0;

  auto stopped = [&] { return options.stop && options.stop->load(); };
  for (;;) {
    ++result.passes;
    auto sources = open_sources(HostRealtimeNs());
    if (!sources) return sources.error();
    if (result.passes == 1) {
      for (const CameraFolder& folder : sequence->cameras)
        result.frames_in_sequence += folder.frames.size();
      result.cameras = static_cast<int>(sources->replay.size());
    }
    std::vector<const ReplayCamera*> replay = sources->replay;
    ViconSource* vicon = sources->vicon.get();
    RigController controller(std::move(sources->cameras),
                             std::vector<bool>(replay.size(), false), std::move(sources->vicon),
                             nullptr, controller_options, observer);
    if (Status s = controller.Start(); !s) return s.error();
    auto next_status = std::chrono::steady_clock::now() + std::chrono::seconds(1);
    while (!(controller.CamerasFinished() && (vicon == nullptr || vicon->Finished()))) {
      if (stopped()) break;
      p.Poll();
      if (std::chrono::steady_clock::now() >= next_status) {
        p.SetSyncDrops(controller.Health().sync_drops);
        if (options.on_status) options.on_status(p.Report());
        next_status += std::chrono::seconds(1);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    controller.Stop();  // the assembler's last sets go to the pipeline
    p.SetSyncDrops(controller.Health().sync_drops);
    p.EndPass();
    for (const ReplayCamera* camera : replay) {
      const CameraStats stats = camera->Stats();
      result.camera_underruns += stats.underruns;
      result.camera_failed += stats.failed;
    }
    if (!options.loop || stopped()) break;
  }
  p.Finish();
  result.report = p.Report();
  if (live) result.registration = LiveRegistrationReport(*live);
  return result;
}

}  // namespace lifmcr::apps
