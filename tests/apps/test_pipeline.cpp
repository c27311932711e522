// The live pipeline on memq:// with a synthetic sequence: every frame is
// processed and published or counted as skipped; the skip policy (newest
// wins) under a slowed stage; the published depth is the processing output;
// live Vicon over UDP reaches LIFMCR_VICON the way `lifmcr record --publish`
// wires it.

#include "acquisition/rig_controller.h"
#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/pipeline.h"
#include "apps/pipeline/replay_runner.h"
#include "drivers/vicon_udp_sender.h"
#include "drivers/vicon_udp_source.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/pipeline_stats_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <map>
#include <oneapi/tbb/info.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <thread>
#include <unistd.h>

namespace lifmcr::apps {
namespace {

synth::SynthParams TinyRig(int frames) {
  auto params = synth::MakePreset("small");
  EXPECT_TRUE(params.ok());
  params->rig.frames = frames;
  params->rig.cameras = 2;
  params->rig.seed = 7;
  return *params;
}

// Every message of the run, decoded by channel.
struct Received {
  std::map<std::string, int> count;
  std::map<std::string, std::vector<std::int64_t>> utimes;
  std::map<std::pair<std::string, std::int64_t>, lifmcr_lcm::depth_image_t> depth;  // serial, frame
  std::map<std::string, std::vector<std::int64_t>> preview_frames;                  // by serial
  std::optional<lifmcr_lcm::pipeline_stats_t> last_stats;

  void OnAny(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    ++count[channel];
    if (channel == kStatsChannel) {
      lifmcr_lcm::pipeline_stats_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      last_stats = m;
      utimes[channel].push_back(m.utime);
    } else if (channel == kViconChannel) {
      lifmcr_lcm::vicon_frame_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      utimes[channel].push_back(m.utime);
    } else if (channel.ends_with("_DEPTH")) {
      lifmcr_lcm::depth_image_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      utimes[channel].push_back(m.utime);
      depth[{m.serial, m.frame_id}] = m;
    } else {
      lifmcr_lcm::preview_image_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      utimes[channel].push_back(m.utime);
      EXPECT_EQ(m.size, static_cast<int>(m.data.size()));
      EXPECT_LE(m.size, 4 << 20);
      if (channel.ends_with("_PREVIEW")) preview_frames[m.serial].push_back(m.frame_id);
    }
  }
};

void Drain(lcm::LCM& bus) {
  while (bus.handleTimeout(0) > 0) {
  }
}

TEST(Pipeline, MaxRateProcessesAndPublishesEveryFrameWithDepthFromProcessing) {
  test::TempDir dir;
  const int frames = 3;
  auto summary = synth::WriteSyntheticDataset(dir.path(), TinyRig(frames));
  ASSERT_TRUE(summary.ok()) << summary.error().message;

  lcm::LCM bus("memq://");
  ASSERT_TRUE(bus.good());
  Received received;
  bus.subscribe("LIFMCR_.*", &Received::OnAny, &received);
  ReplayRunOptions options;
  options.sequence_dir = summary->sequence_dir;
  options.rate.kind = ReplayRate::Kind::kMax;
  options.pipeline.bus = &bus;
  auto result = RunReplay(options);
  ASSERT_TRUE(result.ok()) << result.error().message;
  Drain(bus);

  const PipelineReport& r = result->report;
  EXPECT_EQ(result->frames_in_sequence, 2u * frames);
  EXPECT_EQ(r.frames_in, 2u * frames);
  EXPECT_EQ(r.processed, 2u * frames) << r.FinalReport();
  EXPECT_EQ(r.skipped, 0u);
  EXPECT_EQ(r.failed, 0u) << r.last_error;
  EXPECT_TRUE(r.Accounted());
  EXPECT_EQ(r.sync_lost, 0u) << r.drops;

  const auto layout = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(layout.ok());
  std::vector<std::string> serials;
  for (const auto& camera : layout->cameras) serials.push_back(camera.serial);
  ASSERT_EQ(serials.size(), 2u);
  for (const std::string& serial : serials) {
    EXPECT_EQ(received.count[CameraChannel(serial, "PREVIEW")], frames) << serial;
    EXPECT_EQ(received.count[CameraChannel(serial, "DEPTH")], frames) << serial;
    EXPECT_EQ(received.count[CameraChannel(serial, "TF")], frames) << serial;
  }
  EXPECT_GT(received.count[kViconChannel], 0);
  EXPECT_EQ(static_cast<std::uint64_t>(received.count[kViconChannel]), r.published_vicon);
  ASSERT_TRUE(received.last_stats.has_value());
  for (auto& [channel, utimes] : received.utimes)
    for (std::size_t k = 1; k < utimes.size(); ++k) EXPECT_GE(utimes[k], utimes[k - 1]) << channel;

  // The published depth decodes to what the processing stage computes for
  // the same frame, within the 8-bit quantisation (one step, (max - min) / 254).
  auto processor = DepthProcessor::ForSequence(summary->sequence_dir.string(), serials);
  ASSERT_TRUE(processor.ok()) << processor.error().message;
  const std::string serial = serials[0];
  const auto& folder = layout->cameras[0];
  const std::int64_t frame_number = folder.frames[1];
  auto image = ReadBmp(*folder.FramePath(frame_number));
  ASSERT_TRUE(image.ok());
  Frame frame;
  frame.serial = serial;
  frame.frame_id = static_cast<std::uint64_t>(frame_number);
  frame.image = image->View();
  auto expected = (*processor)->Process(frame);
  ASSERT_TRUE(expected.ok()) << expected.error().message;
  ASSERT_TRUE(expected->depth.has_value());
  const auto it = received.depth.find({serial, frame_number});
  ASSERT_NE(it, received.depth.end());
  const lifmcr_lcm::depth_image_t& m = it->second;
  EXPECT_EQ(m.width, expected->depth->width);
  EXPECT_EQ(m.height, expected->depth->height);
  int w = 0, h = 0;
  auto decoded = DecodeDepth(m.data, m.scale, m.offset, &w, &h);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  ASSERT_EQ(decoded->size(), expected->depth->values.size());
  std::size_t valid = 0;
  for (std::size_t k = 0; k < decoded->size(); ++k) {
    const float a = (*decoded)[k], b = expected->depth->values[k];
    ASSERT_EQ(std::isnan(a), std::isnan(b)) << k;
    if (std::isnan(a)) continue;
    ++valid;
    EXPECT_NEAR(a, b, m.scale) << k;
  }
  EXPECT_GT(valid, 0u);
  EXPECT_NEAR(m.valid_fraction, static_cast<double>(valid) / decoded->size(), 1e-6);
}

// A stage that takes `delay` per frame (previews only).
class SlowProcessor final : public FrameProcessor {
 public:
  explicit SlowProcessor(std::chrono::milliseconds delay) : delay_(delay) {}
  Expected<ProcessedFrame> Process(const Frame& frame) override {
    std::this_thread::sleep_for(delay_);
    return preview_.Process(frame);
  }
  std::string name() const override { return "slow"; }

 private:
  std::chrono::milliseconds delay_;
  PreviewProcessor preview_;
};

// How many frames a ConcurrencyProbe processed at once at most, and the
// lowest nice value of the threads it ran on (owned by the test: the stage
// goes with the pipeline).
struct ProbeCounts {
  std::atomic<int> running{0}, most_at_once{0}, lowest_nice{100};
};

class ConcurrencyProbe final : public FrameProcessor {
 public:
  explicit ConcurrencyProbe(ProbeCounts* counts) : counts_(counts) {}
  Expected<ProcessedFrame> Process(const Frame& frame) override {
    const int now = ++counts_->running;
    int seen = counts_->most_at_once.load();
    while (now > seen && !counts_->most_at_once.compare_exchange_weak(seen, now)) {
    }
    errno = 0;
    const int nice = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
    if (errno == 0) {
      int lowest = counts_->lowest_nice.load();
      while (nice < lowest && !counts_->lowest_nice.compare_exchange_weak(lowest, nice)) {
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(150));
    --counts_->running;
    return preview_.Process(frame);
  }
  std::string name() const override { return "probe"; }

 private:
  ProbeCounts* counts_;
  PreviewProcessor preview_;
};

// Frames are processed max_concurrency at once (up to the cores), on worker
// threads at processing_nice: the command's loop never helps TBB, so the
// default arena (cores - 1 workers, a slot kept for a master) processed one
// frame at a time.
TEST(Pipeline, ProcessesMaxConcurrencyFramesAtOnceAtTheLowerPriority) {
  const int cores = tbb::info::default_concurrency();
  test::TempDir dir;
  auto summary = synth::WriteSyntheticDataset(dir.path(), TinyRig(4));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  lcm::LCM bus("memq://");
  ReplayRunOptions options;
  options.sequence_dir = summary->sequence_dir;
  options.rate.kind = ReplayRate::Kind::kMax;
  options.pipeline.bus = &bus;
  options.pipeline.max_concurrency = 2;
  options.pipeline.processing_nice = 7;
  ProbeCounts counts;
  auto result = RunReplay(options, std::make_unique<ConcurrencyProbe>(&counts));
  ASSERT_TRUE(result.ok()) << result.error().message;
  EXPECT_EQ(result->report.processed, 8u) << result->report.FinalReport();
  EXPECT_EQ(counts.most_at_once, std::min(2, cores));
  // processing_nice is relative to the thread that made the pipeline (a
  // worker lowered further by an earlier pipeline of the process keeps it).
  const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
  EXPECT_GE(counts.lowest_nice, std::min(19, base + 7));
  EXPECT_LE(counts.lowest_nice, 19);
  options.pipeline.processing_nice = 20;
  EXPECT_FALSE(options.pipeline.Check().ok());
}

TEST(Pipeline, SlowStageSkipsTheOlderFramesCountsThemAndKeepsTheNewest) {
  test::TempDir dir;
  const int frames = 12;
  auto summary = synth::WriteSyntheticDataset(dir.path(), TinyRig(frames));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  lcm::LCM bus("memq://");
  Received received;
  bus.subscribe("LIFMCR_.*", &Received::OnAny, &received);
  ReplayRunOptions options;
  options.sequence_dir = summary->sequence_dir;
  options.rate = *ReplayRate::Parse("4");  // 40 Hz, two cameras: 80 frames/s
  options.pipeline.bus = &bus;
  options.pipeline.max_concurrency = 1;
  options.pool_buffers = 16;
  // 60 ms per frame: about 16 frames/s processed of 80 offered.
  auto result = RunReplay(options, std::make_unique<SlowProcessor>(std::chrono::milliseconds(60)));
  ASSERT_TRUE(result.ok()) << result.error().message;
  Drain(bus);
  const PipelineReport& r = result->report;
  EXPECT_EQ(result->camera_underruns, 0u);
  EXPECT_EQ(r.frames_in, 2u * frames) << r.FinalReport();
  EXPECT_GT(r.skipped, 0u) << r.FinalReport();
  EXPECT_GT(r.processed, 0u);
  EXPECT_EQ(r.failed, 0u);
  EXPECT_TRUE(r.Accounted()) << r.FinalReport();
  int previews = 0;
  for (const auto& [serial, ids] : received.preview_frames) {
    previews += static_cast<int>(ids.size());
    // Newest wins: the last frame of each camera is never the one skipped.
    ASSERT_FALSE(ids.empty());
    EXPECT_EQ(*std::max_element(ids.begin(), ids.end()), frames - 1)
        << serial << " " << ::testing::PrintToString(ids) << "\n"
        << r.FinalReport();
  }
  EXPECT_EQ(static_cast<std::uint64_t>(previews), r.processed);
  // No camera starves: the freed worker goes to the camera served least recently.
  for (const auto& [serial, ids] : received.preview_frames)
    EXPECT_GE(ids.size() * 4, r.processed) << serial << " got " << ids.size();
  // The skip count is on the statistics channel.
  ASSERT_TRUE(received.last_stats.has_value());
  std::int64_t skipped_on_lcm = -1;
  for (const auto& d : received.last_stats->drops)
    if (d.kind == "skipped_for_processing") skipped_on_lcm = d.count;
  EXPECT_EQ(skipped_on_lcm, static_cast<std::int64_t>(r.skipped));
}

struct ViconMessages {
  std::vector<lifmcr_lcm::vicon_frame_t> frames;
  void OnMessage(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    lifmcr_lcm::vicon_frame_t m;
    ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
    frames.push_back(m);
  }
};

// The wiring of `lifmcr record --publish` with a live Vicon: Tracker packets
// over loopback UDP -> ViconUdpSource -> the RigController's Vicon thread ->
// its observer -> Pipeline::AddVicon -> LIFMCR_VICON. Every frame is
// published once, in order, with the poses sent (right-handed, mm), an
// object missing from a datagram as occluded, and is_trigger on every
// divider-th frame from f0.
TEST(Pipeline, LiveViconFromUdpIsPublishedWithItsPoses) {
  constexpr std::int64_t kFirstFrame = 5000;
  constexpr int kFrames = 40;
  lcm::LCM bus("memq://");
  ASSERT_TRUE(bus.good());
  ViconMessages received;
  bus.subscribe(kViconChannel, &ViconMessages::OnMessage, &received);

  FrameSetAssemblerOptions sync;
  sync.serials = {"CAM0"};
  sync.vicon_divider = 8;
  sync.vicon_rate_hz = 80;
  sync.trigger.trigger_period_ns = 100'000'000;
  sync.vicon_f0 = kFirstFrame + 3;
  PipelineOptions options;
  options.bus = &bus;
  auto pipeline = Pipeline::Create(sync, std::make_unique<PreviewProcessor>(), options);
  ASSERT_TRUE(pipeline.ok()) << pipeline.error().message;
  Pipeline* p = pipeline->get();

  ViconUdpSourceOptions source_options;
  source_options.address = "127.0.0.1";
  source_options.port = 0;
  source_options.objects = {"plate", "cam0"};
  auto source = std::make_unique<ViconUdpSource>(source_options);
  ViconUdpSource* source_view = source.get();
  RigObserver observer;
  observer.on_vicon = [p](const ViconFrame& frame) { p->AddVicon(frame); };
  RigController controller({}, {}, std::move(source), nullptr, {}, observer);
  ASSERT_TRUE(controller.Start().ok());
  auto sender = ViconUdpSender::Open("127.0.0.1", source_view->BoundPort());
  ASSERT_TRUE(sender.ok()) << sender.error().message;

  auto plate_pose = [](int k) {
    Pose pose = Pose::Identity();
    pose.linear() = Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    pose.translation() = Eigen::Vector3d(k, 2.0 * k, 3.0 * k);
    return pose;
  };
  for (int k = 0; k < kFrames; ++k) {
    ViconFrame frame;
    frame.vicon_frame = kFirstFrame + k;
    frame.objects.push_back({"plate", plate_pose(k)});
    // cam0 is out of view on odd frames: left out of the datagram.
    if (k % 2 == 0) frame.objects.push_back({"cam0", Pose::Identity()});
    ASSERT_TRUE(sender->Send(frame).ok());
    // Paced a little, so the test does not lean on the socket buffer.
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (received.frames.size() < kFrames && std::chrono::steady_clock::now() < deadline)
    bus.handleTimeout(50);
  controller.Stop();
  p->Finish();
  Drain(bus);

  ASSERT_EQ(received.frames.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(p->Report().published_vicon, static_cast<std::uint64_t>(kFrames));
  for (int k = 0; k < kFrames; ++k) {
    const lifmcr_lcm::vicon_frame_t& m = received.frames[k];
    EXPECT_EQ(m.vicon_frame, kFirstFrame + k);
    EXPECT_EQ(m.is_trigger, (k - 3) % 8 == 0) << k;
    EXPECT_GT(m.utime, 0);
    ASSERT_EQ(m.num_objects, 2);
    ASSERT_EQ(m.objects.size(), 2u);
    EXPECT_EQ(m.objects[0].name, "plate");
    EXPECT_FALSE(m.objects[0].occluded);
    const Pose expected = plate_pose(k);
    const Eigen::Quaterniond q(expected.rotation());
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(m.objects[0].t_mm[i], expected.translation()[i], 1e-9);
    // q and -q are the same rotation.
    const double sign = q.w() * m.objects[0].q_wxyz[0] < 0 ? -1.0 : 1.0;
    EXPECT_NEAR(sign * m.objects[0].q_wxyz[0], q.w(), 1e-9) << k;
    EXPECT_NEAR(sign * m.objects[0].q_wxyz[1], q.x(), 1e-9) << k;
    EXPECT_NEAR(sign * m.objects[0].q_wxyz[2], q.y(), 1e-9) << k;
    EXPECT_NEAR(sign * m.objects[0].q_wxyz[3], q.z(), 1e-9) << k;
    EXPECT_EQ(m.objects[1].name, "cam0");
    EXPECT_EQ(m.objects[1].occluded, k % 2 == 1) << k;
  }
}

TEST(Pipeline, RateParsing) {
  EXPECT_EQ(ReplayRate::Parse("original")->kind, ReplayRate::Kind::kOriginal);
  EXPECT_EQ(ReplayRate::Parse("max")->kind, ReplayRate::Kind::kMax);
  EXPECT_DOUBLE_EQ(ReplayRate::Parse("2.5")->factor, 2.5);
  EXPECT_FALSE(ReplayRate::Parse("fast").ok());
  EXPECT_FALSE(ReplayRate::Parse("0").ok());
  EXPECT_FALSE(ReplayRate::Parse("-1").ok());
}

TEST(Pipeline, DepthQuantisationRoundTrips) {
  std::vector<float> values = {1.5f, NAN, 3.25f, 2.0f, NAN, 4.0f};
  for (const int bits : {8, 16}) {
    auto encoded = EncodeDepth(values, 3, 2, bits);
    ASSERT_TRUE(encoded.ok());
    EXPECT_NEAR(encoded->valid_fraction, 4.0 / 6.0, 1e-6);
    // One step over the map's own range: 254 or 65534 steps from 1.5 to 4.
    EXPECT_NEAR(encoded->scale, 2.5 / (bits == 8 ? 254 : 65534), 1e-7);
    int w = 0, h = 0;
    auto decoded = DecodeDepth(encoded->png, encoded->scale, encoded->offset, &w, &h);
    ASSERT_TRUE(decoded.ok());
    EXPECT_EQ(w, 3);
    EXPECT_EQ(h, 2);
    for (std::size_t k = 0; k < values.size(); ++k) {
      EXPECT_EQ(std::isnan(values[k]), std::isnan((*decoded)[k]));
      if (!std::isnan(values[k])) {
        EXPECT_NEAR(values[k], (*decoded)[k], encoded->scale / 2 + 1e-6) << bits;
      }
    }
  }
  EXPECT_FALSE(EncodeDepth(values, 3, 2, 12).ok());
}

}  // namespace
}  // namespace lifmcr::apps
