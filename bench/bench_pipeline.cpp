// bench_pipeline: the live pipeline's two figures, each beside a baseline
// measured in the same run.
//
// 1. Camera frames. A synthetic sequence (default preset medium; rendering is
//    not timed) replayed through the live pipeline as fast as possible with
//    processing on (depth + TF): frames per second end to end, processing time
//    per frame, and the latency from frame arrival to its messages on LCM
//    (p50, p99); beside it the throughput of processing alone (the same
//    frames, one after the other, through the same stage): the ratio is the
//    pipeline's overhead (or, above 1, what its concurrency gains).
//
// 2. Vicon. Tracker object-stream packets sent by a ViconUdpSender over
//    loopback UDP into the path `lifmcr record --publish` takes: ViconUdpSource
//    -> the RigController's Vicon thread (and its FrameSetAssembler, whose
//    FrameSets are the pipeline's frames) -> Pipeline::AddVicon -> LIFMCR_VICON
//    on LCM, where a subscriber thread of this process timestamps each
//    message's arrival. Per packet: sent -> message received (p50, p99, max),
//    beside the baseline sent -> parsed ViconFrame handed on by the Vicon
//    thread (what any consumer of the stream pays), and their ratio. On
//    memq:// and on udpm over loopback (skipped, with the reason, when no
//    message comes back over it); once with the pipeline idle and once while
//    the sequence's cameras are replayed in a loop at the trigger rate (about
//    10 Hz) with depth processing on (newest wins), as on a recording rig.
//    The goal is p99 under 5 ms.
//
//   bench_pipeline [--preset small|medium|r32] [--frames N] [--cameras N]
//                  [--concurrency N] [--lcm URL] [--vicon-packets N]
//                  [--vicon-hz HZ] [--udpm URL] [--processing-nice N]
//                  [--vicon-priority N] [--no-frames] [--no-vicon]
//                  [--sequence SEQ_DIR] [--no-intrinsics] [--baseline-binary PATH]
// --sequence: an existing sequence (e.g. `lifmcr synth --preset medium`'s)
// instead of rendering one; --preset, --frames and --cameras are then its.
// The processing chain has the sequence's true intrinsics
// (GroundTruth/cameras.yaml) as in a replay with --reference, so its lambda
// (the micro-lens centres) is the camera's; --no-intrinsics: lambda 1.
// Part 1 publishes on --lcm (default memq://; messages are published, not
// read). The Vicon rate is raised from 80 Hz (default 400) so a run takes
// seconds; --vicon-hz 80 gives the real rate.
// --baseline-binary PATH: after part 1, this run starts PATH (another build's
// bench_pipeline) with the same --preset and --frames and --no-vicon, shows
// its output, and prints this build's frames/s over its (processing alone and
// end to end): a speed-up measured side by side in one run, on one machine.

#include "bench/bench_usage.h"
#include "acquisition/rig_controller.h"
#include "acquisition/thread_priority.h"
#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/pipeline.h"
#include "apps/pipeline/process_settings.h"
#include "apps/pipeline/replay_runner.h"
#include "bench/paced_vicon.h"
#include "drivers/replay_camera.h"
#include "drivers/vicon_udp_sender.h"
#include "drivers/vicon_udp_source.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"

#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <future>
#include <filesystem>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <string>
#include <thread>
#include <vector>

using namespace lifmcr;

namespace {

using Clock = std::chrono::steady_clock;

std::int64_t SteadyNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

struct BenchArgs {
  std::string preset = "medium";
  int frames = 6, cameras = 2, concurrency = 2;
  std::string frame_lcm_url = "memq://";
  int vicon_packets = 2000;
  double vicon_hz = 400;
  // A port of its own, so a monitor on the default one is not flooded.
  std::string udpm_url = "udpm://239.255.76.67:7713?ttl=0&recv_buf_size=4194304";
  int processing_nice = apps::PipelineOptions{}.processing_nice;
  // The Vicon thread's SCHED_FIFO priority, as `lifmcr record` sets it for a
  // live stream; 0 shows the ordinary scheduler.
  int vicon_priority = lifmcr::RigControllerOptions::kLiveViconPriority;
  bool frame_part = true;
  bool vicon_part = true;
  // An existing sequence instead of rendering one (its cameras and frames).
  std::string sequence;
  // The sequence's true intrinsics (GroundTruth/cameras.yaml): the chain's
  // lambda (micro-lens centres, processing/plenoptic_frame.h) is the
  // camera's, as in a replay with --reference; without them it is 1.
  bool intrinsics = true;
  // Another build's bench_pipeline, run after part 1 for the ratio.
  std::string baseline_binary;
};

// Part 1's two rates, for the ratio against --baseline-binary.
struct FrameRates {
  double pipeline_fps = 0;
  double alone_fps = 0;
};

Expected<int> ParseInt(const std::string& option, const std::string& text, int min, int max) {
  int value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < min || value > max)
    return Error{option + ": expected an integer in [" + std::to_string(min) + ", " +
                 std::to_string(max) + "], got '" + text + "'"};
  return value;
}

Expected<BenchArgs> ParseArgs(int argc, char** argv) {
  BenchArgs args;
  for (int k = 1; k < argc; ++k) {
    const std::string option = argv[k];
    if (option == "--no-vicon" || option == "--no-frames") {
      (option == "--no-vicon" ? args.vicon_part : args.frame_part) = false;
      continue;
    }
    if (option == "--no-intrinsics") {
      args.intrinsics = false;
      continue;
    }
    if (k + 1 >= argc) return Error{option + ": expected a value (see the usage at the top)"};
    const std::string value = argv[++k];
    Expected<int> number = 0;
    if (option == "--preset") {
      args.preset = value;
    } else if (option == "--lcm") {
      args.frame_lcm_url = value;
    } else if (option == "--udpm") {
      args.udpm_url = value;
    } else if (option == "--sequence") {
      args.sequence = value;
    } else if (option == "--baseline-binary") {
      if (!std::filesystem::is_regular_file(value))
        return Error{"--baseline-binary: expected an executable file, got '" + value + "'"};
      args.baseline_binary = value;
    } else if (option == "--frames") {
      if (!(number = ParseInt(option, value, 1, 100000))) return number.error();
      args.frames = *number;
    } else if (option == "--cameras") {
      if (!(number = ParseInt(option, value, 1, 16))) return number.error();
      args.cameras = *number;
    } else if (option == "--concurrency") {
      if (!(number = ParseInt(option, value, 1, 64))) return number.error();
      args.concurrency = *number;
    } else if (option == "--processing-nice") {
      if (!(number = ParseInt(option, value, 0, 19))) return number.error();
      args.processing_nice = *number;
    } else if (option == "--vicon-priority") {
      if (!(number = ParseInt(option, value, 0, 99))) return number.error();
      args.vicon_priority = *number;
    } else if (option == "--vicon-packets") {
      if (!(number = ParseInt(option, value, 16, 10'000'000))) return number.error();
      args.vicon_packets = *number;
    } else if (option == "--vicon-hz") {
      double hz = 0;
      const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), hz);
      if (ec != std::errc() || end != value.data() + value.size() || !(hz >= 10 && hz <= 20000))
        return Error{"--vicon-hz: expected a rate in [10, 20000] Hz, got '" + value + "'"};
      args.vicon_hz = hz;
    } else {
      return Error{"unknown option " + option +
                   " (see the usage at the top of bench_pipeline.cpp)"};
    }
  }
  return args;
}

// Nearest-rank percentile of `values_ns`, in microseconds (0 when empty).
double PercentileUs(std::vector<std::int64_t> values_ns, double p) {
  if (values_ns.empty()) return 0.0;
  std::sort(values_ns.begin(), values_ns.end());
  const auto index = static_cast<std::size_t>(p * static_cast<double>(values_ns.size() - 1) + 0.5);
  return static_cast<double>(values_ns[index]) / 1e3;
}

// CPU time of this process, all threads (processing alone runs nothing
// else: the pipeline of part 1 has stopped).
double ProcessCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// Part 1: frames at --rate max, and the same frames through processing alone.
int RunFramePart(const BenchArgs& args, const synth::SynthParams& params,
                 const std::filesystem::path& sequence_dir, FrameRates* rates) {
  apps::ReplayRunOptions options;
  options.sequence_dir = sequence_dir;
  options.rate.kind = apps::ReplayRate::Kind::kMax;
  options.pipeline.publisher.url = args.frame_lcm_url;
  options.pipeline.max_concurrency = args.concurrency;
  options.pipeline.processing_nice = args.processing_nice;
  // Little read-ahead: a frame's arrival is then close to when the pipeline
  // can take it, and the latency measures the pipeline rather than the queue.
  options.pool_buffers = args.concurrency + 1;
  std::vector<std::filesystem::path> intrinsics;
  if (args.intrinsics && std::filesystem::exists(layout::CamerasYamlPath(sequence_dir)))
    intrinsics.push_back(layout::CamerasYamlPath(sequence_dir));
  options.intrinsics = intrinsics;
  const auto start = Clock::now();
  auto result = apps::RunReplay(options);
  const double pipeline_s = std::chrono::duration<double>(Clock::now() - start).count();
  if (!result) {
    std::fprintf(stderr, "bench_pipeline: %s\n", result.error().message.c_str());
    return 3;
  }
  const apps::PipelineReport& r = result->report;

  // Processing alone: the same frames through the same stage, in memory.
  auto layout = DiscoverSequence(sequence_dir);
  if (!layout) {
    std::fprintf(stderr, "bench_pipeline: %s\n", layout.error().message.c_str());
    return 3;
  }
  std::vector<std::string> serials;
  for (const auto& c : layout->cameras) serials.push_back(c.serial);
  const auto setup_start = Clock::now();
  auto processor =
      apps::DepthProcessor::ForSequence(sequence_dir.string(), serials, {}, {}, intrinsics);
  if (!processor) {
    std::fprintf(stderr, "bench_pipeline: %s\n", processor.error().message.c_str());
    return 3;
  }
  const double setup_s = std::chrono::duration<double>(Clock::now() - setup_start).count();
  double alone_s = 0, alone_cpu_s = 0;
  int alone_frames = 0;
  // Per frame, CPU (all threads) split into each camera's first frame (the
  // chain's set-up: the workspace's geometry, the per-lens estimator's gain
  // and micro-image map) and the later ones, with the chain's stages (wall).
  std::vector<double> first_cpu, later_cpu, prepare, seed, search, tf;
  std::string last_search;  // the dense search's counts on the last frame
  for (const auto& camera : layout->cameras)
    for (std::int64_t f : camera.frames) {
      auto image = ReadBmp(*camera.FramePath(f));
      if (!image) {
        std::fprintf(stderr, "bench_pipeline: %s\n", image.error().message.c_str());
        return 3;
      }
      Frame frame;
      frame.serial = camera.serial;
      frame.image = image->View();
      const auto t0 = Clock::now();
      const double cpu0 = ProcessCpuSeconds();
      auto out = (*processor)->Process(frame);
      alone_s += std::chrono::duration<double>(Clock::now() - t0).count();
      const double cpu = ProcessCpuSeconds() - cpu0;
      alone_cpu_s += cpu;
      if (!out) {
        std::fprintf(stderr, "bench_pipeline: processing alone: %s\n", out.error().message.c_str());
        return 3;
      }
      (f == camera.frames.front() ? first_cpu : later_cpu).push_back(cpu);
      if (f != camera.frames.front() && out->products) {
        prepare.push_back(out->products->prepare_s);
        seed.push_back(out->products->seed_s);
        search.push_back(out->products->depth_s);
        tf.push_back(out->products->tf_s);
        last_search = out->products->raw_depth.stats.BriefReport();
      }
      ++alone_frames;
    }
  // The pipeline's time runs from its creation, after the processing stage
  // was set up (MLA grids, white images), to its last message: the setup is
  // left out of both sides of the ratio.
  const double pipeline_fps = static_cast<double>(r.processed) / r.elapsed_s;
  const double alone_fps = alone_frames / alone_s;
  std::printf("preset %s, %d cameras x %d frames (%dx%d), concurrency %d, LCM %s, %s\n",
              args.preset.c_str(), args.cameras, args.frames, params.camera.width_px,
              params.camera.height_px, args.concurrency, args.frame_lcm_url.c_str(),
              intrinsics.empty() ? "no intrinsics (lambda 1)"
                                 : ("intrinsics " + intrinsics[0].string()).c_str());
  std::printf(
      "pipeline end to end: %.2f frames/s (%llu processed, %llu skipped, %llu failed, %.2f s; "
      "%.2f s with the stage's setup)\n",
      pipeline_fps, static_cast<unsigned long long>(r.processed),
      static_cast<unsigned long long>(r.skipped), static_cast<unsigned long long>(r.failed),
      r.elapsed_s, pipeline_s);
  std::printf("processing stage setup (MLA grids, white images; not in the ratio): %.2f s\n",
              setup_s);
  std::printf("sync: %s\n", r.drops.c_str());
  std::printf(
      "stage process (preview + depth + TF + encoding): p50 %.1f ms, p99 %.1f ms per frame\n",
      r.process.p50_ms, r.process.p99_ms);
  std::printf("frame arrival -> depth on LCM: p50 %.1f ms, p99 %.1f ms\n", r.to_publication.p50_ms,
              r.to_publication.p99_ms);
  double load[3] = {0, 0, 0};
  if (getloadavg(load, 3) != 3) load[0] = load[1] = load[2] = -1;
  std::printf(
      "processing alone (same stage, sequential): %.2f frames/s, %.3f CPU-s per frame (all "
      "threads; load average %.2f %.2f %.2f)\n",
      alone_fps, alone_cpu_s / std::max(1, alone_frames), load[0], load[1], load[2]);
  const auto median = [](std::vector<double> v) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::printf(
      "processing alone per frame: each camera's first %.3f CPU-s (median; the chain's set-up), "
      "later frames %.3f CPU-s (median of %zu; wall: load %.3f s, per-lens seed %.3f s, dense "
      "search %.3f s, TF %.3f s)\n",
      median(first_cpu), median(later_cpu), later_cpu.size(), median(prepare), median(seed),
      median(search), median(tf));
  std::printf("dense search of the last frame: %s\n", last_search.c_str());
  std::printf("ratio pipeline / processing alone: %.2f\n", pipeline_fps / alone_fps);
  std::fflush(stdout);
  rates->pipeline_fps = pipeline_fps;
  rates->alone_fps = alone_fps;
  return r.Accounted() && r.failed == 0 && r.sync_lost == 0 ? 0 : 1;
}

struct ProbeReceiver {
  bool came_back = false;
  void OnMessage(const lcm::ReceiveBuffer*, const std::string&) { came_back = true; }
};

// When each packet's LIFMCR_VICON message reached the subscriber, by packet
// index (vicon_frame - first_frame); steady clock, 0 = not (yet).
struct ViconArrivals {
  std::int64_t first_frame = 0;
  std::vector<std::atomic<std::int64_t>> at_ns;
  std::atomic<std::uint64_t> received{0}, unexpected{0};

  void OnMessage(const lcm::ReceiveBuffer* buffer, const std::string&) {
    const std::int64_t now = SteadyNs();
    lifmcr_lcm::vicon_frame_t message;
    if (message.decode(buffer->data, 0, buffer->data_size) < 0) {
      ++unexpected;
      return;
    }
    const std::int64_t index = message.vicon_frame - first_frame;
    if (index < 0 || index >= static_cast<std::int64_t>(at_ns.size())) {
      ++unexpected;
      return;
    }
    at_ns[static_cast<std::size_t>(index)].store(now, std::memory_order_relaxed);
    ++received;
  }
};

// Whether messages published on `url` come back to a subscriber of this
// process within about a second (udpm needs a multicast route); why not, when not.
Status CheckLoopback(const std::string& url) {
  lcm::LCM subscriber(url), publisher(url);
  if (!subscriber.good() || !publisher.good()) return Error{"cannot open " + url};
  ProbeReceiver receiver;
  auto* subscription =
      subscriber.subscribe("LIFMCR_BENCH_PROBE", &ProbeReceiver::OnMessage, &receiver);
  const std::uint8_t probe = 1;
  for (int attempt = 0; attempt < 10 && !receiver.came_back; ++attempt) {
    publisher.publish("LIFMCR_BENCH_PROBE", &probe, 1);
    subscriber.handleTimeout(100);
  }
  subscriber.unsubscribe(subscription);
  if (!receiver.came_back)
    return Error{"no message came back over " + url +
                 " within 1 s (route multicast over loopback, as root: ip link set lo multicast "
                 "on; ip route add 239.255.76.67/32 dev lo)"};
  return Status::Ok();
}

struct ViconRunSetup {
  std::string url;
  bool frames_flowing = false;  // the sequence's cameras replayed in a loop meanwhile
};

// Part 2, one run: see the top of the file.
int RunViconPart(const BenchArgs& args, const std::filesystem::path& sequence_dir,
                 const ViconRunSetup& setup) {
  constexpr std::int64_t kFirstFrame = 100000;
  const std::vector<std::string> objects = {"plate", "cam0", "cam1"};
  const std::string label = setup.url.substr(0, setup.url.find('?')) +
                            (setup.frames_flowing ? ", camera frames flowing" : ", pipeline idle");
  auto layout = DiscoverSequence(sequence_dir);
  if (!layout) {
    std::fprintf(stderr, "bench_pipeline: %s\n", layout.error().message.c_str());
    return 3;
  }
  std::vector<std::string> serials;
  for (const auto& c : layout->cameras) serials.push_back(c.serial);

  // The trigger rate stays about 10 Hz whatever the Vicon rate: the divider
  // follows it, as a rig file's vicon.trigger_divider would.
  const int divider = std::max(1, static_cast<int>(std::lround(args.vicon_hz / 10.0)));
  const std::chrono::nanoseconds trigger_period(std::llround(1e9 * divider / args.vicon_hz));
  FrameSetAssemblerOptions sync;
  sync.serials = serials;
  sync.trigger.trigger_period_ns = trigger_period.count();
  sync.trigger.counter_bits = 64;
  sync.trigger.counter_skips_zero = false;
  sync.vicon_divider = divider;
  sync.vicon_rate_hz = args.vicon_hz;
  sync.vicon_phase_tolerance_ns = std::llround(0.5e9 / args.vicon_hz);

  // memq:// is one bus per LCM instance: the pipeline publishes on the
  // subscriber's. Over udpm the pipeline opens its own, as in `lifmcr record`.
  lcm::LCM bus(setup.url);
  if (!bus.good()) {
    std::fprintf(stderr, "bench_pipeline: cannot open LCM %s\n", setup.url.c_str());
    return 3;
  }
  apps::PipelineOptions pipeline_options;
  pipeline_options.max_concurrency = args.concurrency;
  pipeline_options.processing_nice = args.processing_nice;
  pipeline_options.skip_when_busy = true;
  if (setup.url.starts_with("memq://"))
    pipeline_options.publisher.bus = &bus;
  else
    pipeline_options.publisher.url = setup.url;
  auto processor = apps::DepthProcessor::ForSequence(sequence_dir.string(), serials);
  if (!processor) {
    std::fprintf(stderr, "bench_pipeline: %s\n", processor.error().message.c_str());
    return 3;
  }
  auto pipeline = apps::Pipeline::Create(sync, std::move(*processor), pipeline_options);
  if (!pipeline) {
    std::fprintf(stderr, "bench_pipeline: %s\n", pipeline.error().message.c_str());
    return 3;
  }
  apps::Pipeline* p = pipeline->get();

  const std::size_t packets = static_cast<std::size_t>(args.vicon_packets);
  std::vector<std::atomic<std::int64_t>> sent_ns(packets), parsed_ns(packets);
  ViconArrivals arrivals;
  arrivals.first_frame = kFirstFrame;
  arrivals.at_ns = std::vector<std::atomic<std::int64_t>>(packets);
  std::atomic<bool> subscribing{true};
  std::promise<void> subscribed;
  std::thread subscriber([&] {
    // The receiver of a latency-critical stream runs real-time as well (a
    // controller would); under the ordinary scheduler this figure would be
    // the receiver's own wake-up latency on a loaded host, not the path's.
    // It subscribes after raising itself: LCM's udpm provider starts its
    // receive thread at the first subscription, and that thread inherits the
    // policy of the thread that starts it.
    if (args.vicon_priority > 0) (void)RaiseThreadToRealtime(args.vicon_priority);
    bus.subscribe(apps::kViconChannel, &ViconArrivals::OnMessage, &arrivals);
    subscribed.set_value();
    while (subscribing) bus.handleTimeout(50);
  });
  subscribed.get_future().wait();

  std::vector<std::unique_ptr<Camera>> cameras;
  if (setup.frames_flowing) {
    for (std::size_t i = 0; i < layout->cameras.size(); ++i) {
      ReplayCameraOptions camera_options;
      camera_options.camera_index = static_cast<int>(i);
      camera_options.trigger_period = trigger_period;
      camera_options.pacing = ReplayPacing::kOriginal;
      camera_options.loop = true;
      // As `lifmcr record --publish` sizes it: frames the pipeline holds
      // (sync, one per worker, one waiting per camera) and some slack.
      camera_options.pool_buffers = args.concurrency + 6;
      cameras.push_back(std::make_unique<ReplayCamera>(layout->cameras[i].dir, camera_options));
    }
  }
  ViconUdpSourceOptions source_options;
  source_options.address = "127.0.0.1";
  source_options.port = 0;
  source_options.objects = objects;
  auto source = std::make_unique<ViconUdpSource>(source_options);
  ViconUdpSource* source_view = source.get();
  // One assembler, the controller's, as in `lifmcr record --publish`.
  RigObserver observer;
  observer.on_frame_set = [p](const FrameSet& set) { p->AddFrameSet(set); };
  observer.on_vicon = [&, p](const ViconFrame& frame) {
    const std::int64_t index = frame.vicon_frame - kFirstFrame;
    if (index >= 0 && index < static_cast<std::int64_t>(packets))
      parsed_ns[index].store(SteadyNs(), std::memory_order_relaxed);
    p->AddVicon(frame);
  };
  RigControllerOptions controller_options;
  controller_options.sync = sync;
  controller_options.trigger_hz = args.vicon_hz / divider;
  // As `lifmcr record` runs a live UDP stream (apps/cmd_record.cpp).
  controller_options.vicon_realtime_priority = args.vicon_priority;
  const std::size_t camera_count = cameras.size();
  RigController controller(std::move(cameras), std::vector<bool>(camera_count, false),
                           std::move(source), nullptr, controller_options, observer);
  if (Status s = controller.Start(); !s) {
    subscribing = false;
    subscriber.join();
    std::fprintf(stderr, "bench_pipeline: %s\n", s.error().message.c_str());
    return 3;
  }
  auto sender = ViconUdpSender::Open("127.0.0.1", source_view->BoundPort());
  if (!sender) {
    controller.Stop();
    subscribing = false;
    subscriber.join();
    std::fprintf(stderr, "bench_pipeline: %s\n", sender.error().message.c_str());
    return 3;
  }

  // With frames flowing, Vicon starts once every worker is busy.
  if (setup.frames_flowing) {
    const auto give_up = Clock::now() + std::chrono::seconds(60);
    while (Clock::now() < give_up &&
           p->Report().frames_in < static_cast<std::uint64_t>(args.concurrency)) {
      p->Poll();
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  const apps::PipelineReport before = p->Report();
  std::atomic<bool> sending{true};
  std::string send_error;
  std::thread sending_thread([&] {
    send_error = bench::SendPacedVicon(*sender, objects, kFirstFrame, args.vicon_hz, sent_ns);
    sending = false;
  });
  // The command's loop, as in `lifmcr record`: the pipeline polled for
  // FrameSets (and its statistics) while the threads run.
  while (sending) {
    p->Poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  sending_thread.join();
  // The last messages are on their way.
  const auto tail_end = Clock::now() + std::chrono::milliseconds(500);
  while (arrivals.received < packets && Clock::now() < tail_end) {
    p->Poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const apps::PipelineReport during = p->Report();
  controller.Stop();
  p->SetSyncDrops(controller.Health().sync_drops);
  p->Finish();
  subscribing = false;
  subscriber.join();
  if (!send_error.empty()) {
    std::fprintf(stderr, "bench_pipeline: %s\n", send_error.c_str());
    return 3;
  }

  std::vector<std::int64_t> to_lcm, parsed;
  std::uint64_t parsed_count = 0;
  for (std::size_t i = 0; i < packets; ++i) {
    const std::int64_t sent = sent_ns[i].load(), at_parse = parsed_ns[i].load(),
                       at_lcm = arrivals.at_ns[i].load();
    if (at_parse) ++parsed_count;
    if (!sent || !at_parse || !at_lcm) continue;
    parsed.push_back(at_parse - sent);
    to_lcm.push_back(at_lcm - sent);
  }
  const double lcm_p50 = PercentileUs(to_lcm, 0.5), lcm_p99 = PercentileUs(to_lcm, 0.99),
               lcm_max = PercentileUs(to_lcm, 1.0);
  const double parsed_p50 = PercentileUs(parsed, 0.5), parsed_p99 = PercentileUs(parsed, 0.99),
               parsed_max = PercentileUs(parsed, 1.0);
  std::printf("Vicon over %s: %zu packets at %.0f Hz, %llu parsed, %llu on LCM (%llu lost)\n",
              label.c_str(), packets, args.vicon_hz, static_cast<unsigned long long>(parsed_count),
              static_cast<unsigned long long>(arrivals.received.load()),
              static_cast<unsigned long long>(packets -
                                              std::min<std::uint64_t>(packets, arrivals.received)));
  std::printf("  %-38s p50 %8.1f us   p99 %8.1f us   max %8.1f us\n",
              "packet -> LIFMCR_VICON received", lcm_p50, lcm_p99, lcm_max);
  std::printf("  %-38s p50 %8.1f us   p99 %8.1f us   max %8.1f us\n",
              "packet -> ViconFrame parsed (baseline)", parsed_p50, parsed_p99, parsed_max);
  std::printf("  ratio LCM / baseline: p50 %.2fx, p99 %.2fx; goal p99 < 5 ms: %s\n",
              lcm_p50 / parsed_p50, lcm_p99 / parsed_p99,
              !to_lcm.empty() && lcm_p99 < 5000.0 ? "met" : "NOT met");
  if (setup.frames_flowing) {
    const double seconds = during.elapsed_s - before.elapsed_s;
    std::printf(
        "  camera frames meanwhile: %zu cameras at %.1f Hz, %llu in, %llu processed (%.2f "
        "frames/s), %llu skipped (newest wins)\n",
        serials.size(), 1e9 / static_cast<double>(trigger_period.count()),
        static_cast<unsigned long long>(during.frames_in - before.frames_in),
        static_cast<unsigned long long>(during.processed - before.processed),
        seconds > 0 ? static_cast<double>(during.processed - before.processed) / seconds : 0.0,
        static_cast<unsigned long long>(during.skipped - before.skipped));
  }
  if (arrivals.unexpected)
    std::printf("  %llu unexpected messages\n",
                static_cast<unsigned long long>(arrivals.unexpected.load()));
  std::fflush(stdout);
  return arrivals.received == packets && lcm_p99 < 5000.0 ? 0 : 1;
}

// A word for sh: single-quoted, each ' inside written as '\'' (close the
// quote, an escaped quote, reopen).
std::string ShellQuoted(const std::string& word) {
  std::string out = "'";
  for (const char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// Runs another build's bench_pipeline on the same preset and frames (it
// renders its own: the synthetic sequence is the same for the same preset) and
// prints its output and the ratios of this build's rates to its. Returns 1
// when its rates cannot be read from its output.
int RunBaseline(const BenchArgs& args, const FrameRates& ours) {
  std::string command = ShellQuoted(args.baseline_binary) + " --preset " +
                        ShellQuoted(args.preset) + " --frames " + std::to_string(args.frames) +
                        " --no-vicon 2>&1";
  std::printf("baseline: %s\n", command.c_str());
  std::fflush(stdout);
  FILE* pipe = popen(command.c_str(), "r");
  if (!pipe) {
    std::printf("baseline: cannot start %s: %s\n", args.baseline_binary.c_str(),
                std::strerror(errno));
    return 1;
  }
  double alone_fps = 0, pipeline_fps = 0;
  char line[4096];
  while (std::fgets(line, sizeof line, pipe)) {
    // Its figures, not its log lines.
    if (line[0] != '[' || !std::strstr(line, "] [info] ")) std::printf("baseline | %s", line);
    std::sscanf(line, "processing alone (same stage, sequential): %lf", &alone_fps);
    std::sscanf(line, "pipeline end to end: %lf", &pipeline_fps);
  }
  const int status = pclose(pipe);
  if (alone_fps <= 0 || pipeline_fps <= 0) {
    std::printf("baseline: no frames/s read from its output (exit status %d)\n", status);
    return 1;
  }
  std::printf(
      "this build / baseline: processing alone %.2f / %.2f frames/s = %.2fx, end to end %.2f / "
      "%.2f = %.2fx\n",
      ours.alone_fps, alone_fps, ours.alone_fps / alone_fps, ours.pipeline_fps, pipeline_fps,
      ours.pipeline_fps / pipeline_fps);
  return 0;
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_pipeline [--preset small|medium|r32] [--frames N] [--cameras N]\n"
    "                      [--concurrency N] [--lcm URL] [--vicon-packets N] [--vicon-hz HZ]\n"
    "                      [--udpm URL] [--processing-nice N] [--vicon-priority N]\n"
    "                      [--no-frames] [--no-vicon] [--sequence SEQ_DIR] [--no-intrinsics]\n"
    "                      [--baseline-binary PATH]\n"
    "--sequence SEQ_DIR: that sequence's frames and cameras instead of rendering a preset.\n"
    "The chain has the sequence's true intrinsics (GroundTruth/cameras.yaml: its lambda)\n"
    "unless --no-intrinsics (lambda 1, as a replay without intrinsics).\n"
    "1. Camera frames: a synthetic sequence (default medium) through the live pipeline as fast\n"
    "   as possible (depth + TF), frames/s, processing time and arrival-to-LCM latency, beside\n"
    "   processing alone; part 1 publishes on --lcm (default memq://).\n"
    "2. Vicon: Tracker packets over loopback UDP through record --publish's path to LCM,\n"
    "   sent -> received p50/p99/max beside sent -> parsed (default 400 Hz; --vicon-hz 80 is\n"
    "   the real rate), on memq:// and on udpm (--udpm).\n"
    "--baseline-binary PATH: after part 1, run PATH (another build's bench_pipeline) with the\n"
    "same --preset and --frames and --no-vicon, and print this build's frames/s over its.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  const auto process_settings = lifmcr::apps::ProcessSettings::ForPipeline();
  auto args = ParseArgs(argc, argv);
  if (!args) {
    std::fprintf(stderr, "bench_pipeline: %s\n", args.error().message.c_str());
    return 2;
  }
  if (!args->baseline_binary.empty() && !args->sequence.empty()) {
    std::fprintf(stderr,
                 "bench_pipeline: --baseline-binary renders the preset in both builds; it does not "
                 "take --sequence\n");
    return 2;
  }
  auto params = synth::MakePreset(args->preset);
  if (!params) {
    std::fprintf(stderr, "bench_pipeline: %s\n", params.error().message.c_str());
    return 2;
  }
  params->rig.frames = args->frames;
  params->rig.cameras = args->cameras;
  if (!args->sequence.empty()) {
    // A sequence given: nothing rendered, nothing removed; the frames and
    // cameras are its own.
    auto layout = DiscoverSequence(args->sequence);
    if (!layout) {
      std::fprintf(stderr, "bench_pipeline: %s\n", layout.error().message.c_str());
      return 2;
    }
    args->cameras = static_cast<int>(layout->cameras.size());
    args->frames = layout->cameras.empty() ? 0 : static_cast<int>(layout->cameras[0].frames.size());
    args->preset = "(" + args->sequence + ")";
    if (auto raw = ReadBmp(*layout->cameras.at(0).FramePath(layout->cameras[0].frames.at(0)))) {
      params->camera.width_px = raw->width;
      params->camera.height_px = raw->height;
    }
    FrameRates rates;
    int exit_code = args->frame_part ? RunFramePart(*args, *params, args->sequence, &rates) : 0;
    if (args->vicon_part)
      for (const bool frames_flowing : {false, true})
        exit_code = std::max(exit_code, RunViconPart(*args, args->sequence,
                                                     {"memq://", frames_flowing}));
    return exit_code;
  }
  char tmpl[] = "/tmp/lifmcr-bench-pipeline-XXXXXX";
  if (!mkdtemp(tmpl)) {
    std::fprintf(stderr, "bench_pipeline: cannot create %s: %s\n", tmpl, std::strerror(errno));
    return 3;
  }
  const std::filesystem::path dir = tmpl;
  std::fprintf(stderr,
               "bench_pipeline: rendering %d x %d frames of preset %s into %s (not timed; r32 "
               "frames take a while)\n",
               args->cameras, args->frames, args->preset.c_str(), tmpl);
  const auto render_start = Clock::now();
  auto summary = synth::WriteSyntheticDataset(dir, *params, {});
  if (!summary) {
    std::fprintf(stderr, "bench_pipeline: %s\n", summary.error().message.c_str());
    std::filesystem::remove_all(dir);
    return 3;
  }
  std::printf("rendering (not timed in any figure): %.1f s\n",
              std::chrono::duration<double>(Clock::now() - render_start).count());

  FrameRates rates;
  int exit_code =
      args->frame_part ? RunFramePart(*args, *params, summary->sequence_dir, &rates) : 0;
  if (args->frame_part && !args->baseline_binary.empty())
    exit_code = std::max(exit_code, RunBaseline(*args, rates));
  if (args->vicon_part) {
    std::vector<std::string> urls = {"memq://"};
    if (Status loopback = CheckLoopback(args->udpm_url); loopback)
      urls.push_back(args->udpm_url);
    else
      std::printf("Vicon over udpm: skipped: %s\n", loopback.error().message.c_str());
    for (const std::string& url : urls)
      for (const bool frames_flowing : {false, true}) {
        const int code = RunViconPart(*args, summary->sequence_dir, {url, frames_flowing});
        exit_code = std::max(exit_code, code);
      }
  }
  std::filesystem::remove_all(dir);
  return exit_code;
}
