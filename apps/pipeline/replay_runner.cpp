// RunReplay (replay_runner.h).

#include "apps/pipeline/replay_runner.h"

#include "drivers/replay_camera.h"
#include "drivers/vicon_csv_source.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/vicon_csv.h"

#include <climits>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <ctime>
#include <sstream>
#include <thread>

namespace lifmcr::apps {
namespace {
std::int64_t NowNs() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}
}  // namespace

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
  if (pool_buffers < 1 || pool_buffers > 1024) return Error{"replay: pool_buffers: expected 1..1024"};
  if (Status s = preview.Check(); !s) return Error{"replay: " + s.error().message};
  if (Status s = pipeline.Check(); !s) return Error{"replay: " + s.error().message};
  // loop, processing: any value; on_status and stop may be empty.
  return Status::Ok();
}

std::string ReplayRunResult::FinalReport() const {
  std::ostringstream out;
  out << "replayed: " << cameras << " camera(s), " << frames_in_sequence
      << " frame files per pass, " << passes << " pass(es)\n"
      << report.FinalReport();
  out << "replay cameras: " << camera_underruns << " frames lost for lack of a buffer, "
      << camera_failed << " unreadable\n";
  return out.str();
}

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

  std::vector<std::string> serials;
  for (const CameraFolder& folder : sequence->cameras) serials.push_back(folder.serial);
  ReplayRunResult result;
  // A ReplayCamera plays its folder once (Start resumes, never rewinds):
  // every pass opens fresh ones.
  std::vector<std::unique_ptr<ReplayCamera>> cameras;
  auto open_cameras = [&]() -> Status {
    cameras.clear();
    for (std::size_t i = 0; i < sequence->cameras.size(); ++i) {
      ReplayCameraOptions camera_options;
      camera_options.camera_index = static_cast<int>(i);
      camera_options.pool_buffers = options.pool_buffers;
      camera_options.trigger_period = period;
      camera_options.pacing = max_rate ? ReplayPacing::kAsFastAsPossible : ReplayPacing::kOriginal;
      if (Status s = camera_options.Check(); !s) return s;
      auto camera = std::make_unique<ReplayCamera>(sequence->cameras[i].dir, camera_options);
      if (Status s = camera->Open(); !s) return s;
      cameras.push_back(std::move(camera));
    }
    return Status::Ok();
  };
  auto collect_camera_stats = [&] {
    for (auto& camera : cameras) {
      const CameraStats stats = camera->Stats();
      result.camera_underruns += stats.underruns;
      result.camera_failed += stats.failed;
    }
  };
  if (Status s = open_cameras(); !s) return s.error();
  for (const auto& camera : cameras) result.frames_in_sequence += camera->frame_count();
  result.cameras = static_cast<int>(cameras.size());

  std::unique_ptr<ViconCsvSource> vicon;
  std::int64_t first_vicon_frame = 0;
  double vicon_rate = 80.0;
  if (!sequence->vicon_csvs.empty()) {
    auto csv = ReadViconCsv(sequence->vicon_csvs.front());
    if (!csv) return csv.error();
    const ViconBlock* block = csv->Find("Objects");
    if (!block) block = csv->Find("Segments");
    if (!block || block->subjects.empty() || block->frames.empty())
      return Error{sequence->vicon_csvs.front().string() + ": no Objects block with poses"};
    first_vicon_frame = block->frames.front();
    vicon_rate = block->rate_hz > 0 ? block->rate_hz : 80.0;
    ViconCsvSourceOptions vicon_options;
    vicon_options.objects = block->subjects;
    vicon_options.realtime = !max_rate;
    vicon_options.rate_hz = vicon_rate * factor;
    auto source = ViconCsvSource::FromCsv(*csv, vicon_options);
    if (!source) return source.error();
    vicon = std::move(*source);
  }

  FrameSetAssemblerOptions sync;
  sync.serials = serials;
  sync.trigger.trigger_period_ns = period.count();
  sync.trigger.counter_bits = 64;
  sync.trigger.counter_skips_zero = false;
  sync.vicon_expected = vicon != nullptr;
  sync.vicon_divider = 8;
  sync.vicon_rate_hz = vicon_rate * factor;
  if (vicon) sync.vicon_f0 = first_vicon_frame;
  // At --rate max host time says nothing about the triggers: a set waits for
  // every camera (a camera's gap is closed by its next frame, the end of the
  // sequence by Flush), however slow processing is.
  if (max_rate) sync.lateness_ns = 3'600'000'000'000;

  if (!processor) {
    if (options.processing) {
      auto depth =
          DepthProcessor::ForSequence(options.sequence_dir.string(), serials, options.preview);
      if (!depth) return depth.error();
      processor = std::move(*depth);
    } else {
      if (Status s = options.preview.Check(); !s) return s.error();
      processor = std::make_unique<PreviewProcessor>(options.preview);
    }
  }
  PipelineOptions pipeline_options = options.pipeline;
  pipeline_options.skip_when_busy = !max_rate;
  auto pipeline = Pipeline::Create(sync, std::move(processor), pipeline_options);
  if (!pipeline) return pipeline.error();
  Pipeline& p = **pipeline;

  auto stopped = [&] { return options.stop && options.stop->load(); };
  for (;;) {
    ++result.passes;
    std::atomic<int> running{0};
    // Per camera, the trigger index of its last delivered frame (-1: none
    // yet): at max rate Vicon stays one trigger ahead of the slowest camera.
    std::vector<std::atomic<std::int64_t>> last_trigger(cameras.size());
    for (auto& index : last_trigger) index = -1;
    std::atomic<bool> abort{false};
    std::vector<std::thread> threads;
    const std::int64_t pass_start_ns = NowNs();
    // Device time of trigger 0: the first frame number of the sequence.
    std::int64_t first_device_ns = INT64_MAX;
    for (const CameraFolder& folder : sequence->cameras)
      if (!folder.frames.empty())
        first_device_ns = std::min(first_device_ns, folder.frames.front() * period.count());
    for (auto& camera : cameras)
      if (Status s = camera->Start(); !s) return s.error();
    if (vicon)
      if (Status s = vicon->Start(); !s) return s.error();
    for (std::size_t i = 0; i < cameras.size(); ++i) {
      ++running;
      threads.emplace_back([&, i] {
        while (!abort) {
          auto frame = cameras[i]->NextFrame(std::chrono::milliseconds(200));
          if (!frame) break;  // the folder is gone: counted as failed by the camera
          if (*frame) {
            // At --rate max the replay's own clock is the host clock the
            // assembler sees (frames placed by their trigger, not by when the
            // pipeline let them be read); latency is measured from AddFrame.
            const std::int64_t trigger = ((*frame)->device_ns - first_device_ns) / period.count();
            if (max_rate) (*frame)->host_ns = pass_start_ns + (*frame)->device_ns - first_device_ns;
            p.AddFrame(std::move(**frame));
            last_trigger[i] = std::max(last_trigger[i].load(), trigger);
          } else if (cameras[i]->Finished()) {
            break;
          }
        }
        --running;
      });
    }
    if (vicon) {
      ++running;
      threads.emplace_back([&] {
        std::int64_t last_vicon_frame = first_vicon_frame - 1;
        int in_burst = 0;
        while (!abort && !vicon->Finished()) {
          if (max_rate) {
            // Vicon goes out in bursts of one trigger's frames (vicon_divider)
            // at least a millisecond apart, each at most one trigger ahead of
            // the slowest camera still playing, by frame numbers (gaps in a
            // camera's files or in the Vicon rows shift nothing): the Vicon
            // frame of trigger k is out once every camera delivered trigger
            // k - 1, so a FrameSet never waits for it. Why bursts stay small:
            // an LCM subscriber queues at most 30 messages by default
            // (lcm-logger's cannot be raised) and drops the rest of a burst
            // when its handler thread is not scheduled in time.
            std::int64_t slowest = INT64_MAX;
            for (std::size_t i = 0; i < cameras.size(); ++i)
              if (!cameras[i]->Finished()) slowest = std::min(slowest, last_trigger[i].load());
            const bool ahead =
                slowest != INT64_MAX &&
                last_vicon_frame >= first_vicon_frame + sync.vicon_divider * (slowest + 2) - 1;
            if (ahead || in_burst >= sync.vicon_divider) {
              std::this_thread::sleep_for(std::chrono::milliseconds(1));
              in_burst = 0;
              continue;
            }
          }
          auto frame = vicon->Next(std::chrono::milliseconds(200));
          if (!frame) break;
          if (*frame) {
            if (max_rate)
              (*frame)->host_ns =
                  pass_start_ns +
                  static_cast<std::int64_t>(
                      static_cast<double>((*frame)->vicon_frame - first_vicon_frame) * 1e9 /
                      sync.vicon_rate_hz);
            last_vicon_frame = (*frame)->vicon_frame;
            ++in_burst;
            p.AddVicon(**frame);
          }
        }
        --running;
      });
    }
    auto next_status = std::chrono::steady_clock::now() + std::chrono::seconds(1);
    while (running > 0) {
      if (stopped()) abort = true;
      p.Poll();
      if (options.on_status && std::chrono::steady_clock::now() >= next_status) {
        options.on_status(p.Report());
        next_status += std::chrono::seconds(1);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    for (std::thread& t : threads) t.join();
    for (auto& camera : cameras) (void)camera->Stop();
    if (vicon) (void)vicon->Stop();
    p.EndPass();
    collect_camera_stats();
    if (!options.loop || stopped()) break;
    if (Status s = open_cameras(); !s) return s.error();
  }
  p.Finish();
  result.report = p.Report();
  return result;
}

}  // namespace lifmcr::apps
