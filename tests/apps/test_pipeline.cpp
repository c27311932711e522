// The live pipeline on memq:// with a synthetic sequence: every frame is
// processed and published or counted as skipped; the skip policy (newest
// wins) under a slowed stage; the published depth is the processing output;
// live Vicon over UDP reaches LIFMCR_VICON the way `lifmcr record --publish`
// wires it.

#include "acquisition/recorder.h"
#include "acquisition/rig_controller.h"
#include "apps/pipeline/camera_setup.h"
#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/pipeline.h"
#include "apps/pipeline/process_settings.h"
#include "apps/pipeline/replay_runner.h"
#include "config/rig_config.h"
#include "drivers/replay_camera.h"
#include "drivers/vicon_udp_sender.h"
#include "drivers/vicon_udp_source.h"
#include "processing/frame_chain.h"
#include "processing/registration_stage.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <atomic>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <lifmcr_lcm/camera_extrinsics_t.hpp>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/pipeline_stats_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <map>
#include <mutex>
#include <oneapi/tbb/info.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <functional>
#include <set>
#include <sched.h>
#include <thread>
#include <unistd.h>

namespace lifmcr::apps {
namespace {

// As the commands do before they run the pipeline (process_settings.h).
const std::unique_ptr<ProcessSettings> kProcessSettings = ProcessSettings::ForPipeline();

synth::SynthParams TinyRig(int frames) {
  auto params = synth::MakePreset("small");
  EXPECT_TRUE(params.ok());
  params->rig.frames = frames;
  params->rig.cameras = 2;
  params->rig.seed = 7;
  params->rig.scene = "plain";  // the pipeline is under test, not the scene: the faster render
  return *params;
}

// A tiny rig of one trigger written into `dir`: its folder, serials and
// each camera's first raw frame (what the registration tests feed the
// pipeline, given again for every trigger).
struct TinyRigFrames {
  std::filesystem::path sequence_dir;
  std::vector<std::string> serials;
  std::vector<OwnedImage> raw;
};
Expected<TinyRigFrames> WriteTinyRigFrames(const std::filesystem::path& dir) {
  auto summary = synth::WriteSyntheticDataset(dir, TinyRig(1));
  if (!summary) return summary.error();
  const auto layout = DiscoverSequence(summary->sequence_dir);
  if (!layout) return layout.error();
  TinyRigFrames rig{summary->sequence_dir, {}, {}};
  for (const CameraFolder& camera : layout->cameras) {
    rig.serials.push_back(camera.serial);
    auto image = ReadBmp(camera.dir / camera.frame_files.front());
    if (!image) return image.error();
    rig.raw.push_back(std::move(*image));
  }
  return rig;
}

// Every message of the run, decoded by channel.
struct Received {
  std::map<std::string, int> count;
  std::map<std::string, std::vector<std::int64_t>> utimes;
  std::map<std::pair<std::string, std::int64_t>, lifmcr_lcm::depth_image_t> depth;  // serial, frame
  std::map<std::pair<std::string, std::int64_t>, lifmcr_lcm::depth_image_t> lens_depth;
  std::map<std::string, std::set<std::int64_t>> tf_frames;  // by serial
  std::map<std::string, std::vector<std::int64_t>> preview_frames;                  // by serial
  std::map<std::string, std::map<std::int64_t, std::int64_t>> preview_trigger;  // serial: id -> trigger
  std::optional<lifmcr_lcm::pipeline_stats_t> last_stats;

  void OnAny(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    ++count[channel];
    if (channel.ends_with("_STATS")) {
      lifmcr_lcm::pipeline_stats_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      last_stats = m;
      utimes[channel].push_back(m.utime);
    } else if (channel.ends_with("_EXTRINSICS") || channel.ends_with("_POSE")) {
      // Counted only (ExtrinsicsMessages decodes them where they are under test;
      // the POSE messages: test_pose_pairing.cpp, test_multi_host.cpp).
    } else if (channel.ends_with("_VICON")) {
      lifmcr_lcm::vicon_frame_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      utimes[channel].push_back(m.utime);
    } else if (channel.ends_with("_DEPTH")) {
      lifmcr_lcm::depth_image_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      utimes[channel].push_back(m.utime);
      if (m.geometry == lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID)
        lens_depth[{m.serial, m.frame_id}] = m;
      else
        depth[{m.serial, m.frame_id}] = m;
    } else {
      lifmcr_lcm::preview_image_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      utimes[channel].push_back(m.utime);
      EXPECT_EQ(m.size, static_cast<int>(m.data.size()));
      EXPECT_LE(m.size, 4 << 20);
      if (channel.ends_with("_TF")) tf_frames[m.serial].insert(m.frame_id);
      if (channel.ends_with("_PREVIEW")) {
        preview_frames[m.serial].push_back(m.frame_id);
        preview_trigger[m.serial][m.frame_id] = m.trigger_index;
      }
    }
  }
};

std::int64_t NowNsForTest() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

// The frame set of `trigger` from the cameras `serials`, each frame in a
// buffer of `pool` that fill(camera, data) writes and describes.
FrameSet MakeFrameSet(std::int64_t trigger, const std::vector<std::string>& serials,
                      FramePool& pool,
                      const std::function<ImageView(int camera, std::uint8_t* data)>& fill) {
  FrameSet set;
  set.trigger_index = trigger;
  set.vicon_frame = -1;
  for (int camera = 0; camera < static_cast<int>(serials.size()); ++camera) {
    Frame frame;
    frame.camera_index = camera;
    frame.serial = serials[camera];
    frame.frame_id = static_cast<std::uint64_t>(trigger);
    frame.host_ns = NowNsForTest();
    frame.buffer = pool.Acquire();
    if (!frame.buffer) {
      ADD_FAILURE() << "the test's frame pool is exhausted";
      break;
    }
    frame.image = fill(camera, frame.buffer->data);
    set.frames.push_back(std::move(frame));
  }
  return set;
}

// The frame set of `trigger` whose frame of each camera is a copy of
// raw[camera] in a buffer of `pool`.
FrameSet MakeCopiedFrameSet(std::int64_t trigger, const std::vector<std::string>& serials,
                            FramePool& pool, const std::vector<OwnedImage>& raw) {
  return MakeFrameSet(trigger, serials, pool, [&](int camera, std::uint8_t* data) {
    const ConstImageView src = raw[camera].View();
    std::copy_n(raw[camera].pixels.data(), raw[camera].pixels.size(), data);
    return ImageView{data, src.width, src.height, src.stride_bytes, src.format};
  });
}

void Drain(lcm::LCM& bus) {
  while (bus.handleTimeout(0) > 0) {
  }
}

// A replay at --rate max, previews only, with the rig file's processing: and
// lcm: sections, published on `bus`.
ReplayRunOptions PreviewsAsTheRigSays(const std::filesystem::path& sequence_dir,
                                      const RigConfig& rig, lcm::LCM* bus) {
  ReplayRunOptions options;
  options.sequence_dir = sequence_dir;
  options.rate.kind = ReplayRate::Kind::kMax;
  options.processing = false;
  options.preview = PreviewOptionsFromRig(rig);
  options.pipeline = PipelineOptions::FromRig(rig);
  options.pipeline.publisher.bus = bus;
  return options;
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
  options.pipeline.publisher.bus = &bus;
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
    // Per frame the dense depth (TF grid) and the per-lens depth (lens grid).
    EXPECT_EQ(received.count[CameraChannel(serial, "DEPTH")], 2 * frames) << serial;
    EXPECT_EQ(received.count[CameraChannel(serial, "TF")], frames) << serial;
  }
  EXPECT_EQ(received.lens_depth.size(), 2u * frames);
  EXPECT_EQ(r.published_lens_depth, 2u * frames);
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
  options.pipeline.publisher.bus = &bus;
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
  options.pipeline.processing_nice = 10;
  for (const int lens_nice : {-1, 20}) {
    options.pipeline.lens_nice = lens_nice;
    ASSERT_FALSE(options.pipeline.Check().ok());
    EXPECT_NE(options.pipeline.Check().error().message.find("lens_nice"), std::string::npos);
  }
  options.pipeline.lens_nice = 15;
  for (const int lens_queue : {0, 9}) {
    options.pipeline.lens_queue = lens_queue;
    ASSERT_FALSE(options.pipeline.Check().ok());
    EXPECT_NE(options.pipeline.Check().error().message.find("lens_queue"), std::string::npos);
  }
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
  options.pipeline.publisher.bus = &bus;
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
// over loopback UDP -> ViconUdpSource -> the RigController's Vicon thread
// (its assembler takes them too) -> its observer -> Pipeline::AddVicon ->
// LIFMCR_VICON. Every frame is
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
  options.publisher.bus = &bus;
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
  observer.on_frame_set = [p](const FrameSet& set) { p->AddFrameSet(set); };
  observer.on_vicon = [p](const ViconFrame& frame) { p->AddVicon(frame); };
  RigControllerOptions controller_options;
  controller_options.sync = sync;
  RigController controller({}, {}, std::move(source), nullptr, controller_options, observer);
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

// processing.threads of the rig file: the pipeline's arena has that many
// workers, so with one thread frames are never processed two at once, even
// with two allowed in flight.
TEST(Pipeline, ThreadsOfTheRigFileBoundTheFramesProcessedAtOnce) {
  test::TempDir dir;
  auto summary = synth::WriteSyntheticDataset(dir.path(), TinyRig(3));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  RigConfig rig;
  rig.processing.threads = 1;
  lcm::LCM bus("memq://");
  ReplayRunOptions options;
  options.sequence_dir = summary->sequence_dir;
  options.rate.kind = ReplayRate::Kind::kMax;
  options.pipeline = PipelineOptions::FromRig(rig);
  options.pipeline.publisher.bus = &bus;
  options.pipeline.max_concurrency = 2;
  ProbeCounts counts;
  auto result = RunReplay(options, std::make_unique<ConcurrencyProbe>(&counts));
  ASSERT_TRUE(result.ok()) << result.error().message;
  EXPECT_EQ(result->report.processed, 6u) << result->report.FinalReport();
  EXPECT_EQ(counts.most_at_once, 1);
}

// lcm.channel_prefix, lcm.publish_previews and processing.preview_max_px of
// the rig file change what is published.
TEST(Pipeline, RigLcmSectionSetsTheChannelsAndThePreviews) {
  test::TempDir dir;
  const int frames = 2;
  auto summary = synth::WriteSyntheticDataset(dir.path(), TinyRig(frames));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  for (const bool previews : {true, false}) {
    RigConfig rig;
    rig.lcm.channel_prefix = "RIG_TEST";
    rig.lcm.publish_previews = previews;
    rig.processing.preview_max_px = 64;
    lcm::LCM bus("memq://");
    Received received;
    bus.subscribe(".*", &Received::OnAny, &received);
    auto result = RunReplay(PreviewsAsTheRigSays(summary->sequence_dir, rig, &bus));
    ASSERT_TRUE(result.ok()) << result.error().message;
    Drain(bus);
    EXPECT_EQ(result->report.processed, 2u * frames);
    int camera_messages = 0;
    for (const auto& [channel, n] : received.count) {
      EXPECT_TRUE(channel.starts_with("RIG_TEST_")) << channel;
      if (channel.ends_with("_PREVIEW")) camera_messages += n;
    }
    EXPECT_GT(received.count["RIG_TEST_STATS"], 0);
    EXPECT_GT(received.count["RIG_TEST_VICON"], 0);
    EXPECT_EQ(camera_messages, previews ? 2 * frames : 0);
    EXPECT_EQ(result->report.published_previews, previews ? 2u * frames : 0u);
  }
  // The preview size: read back from a message.
  RigConfig rig;
  rig.lcm.channel_prefix = "RIG_SIZE";
  rig.processing.preview_max_px = 64;
  lcm::LCM bus("memq://");
  std::vector<lifmcr_lcm::preview_image_t> previews;
  struct Collect {
    std::vector<lifmcr_lcm::preview_image_t>* out;
    void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
      lifmcr_lcm::preview_image_t m;
      ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
      out->push_back(m);
    }
  } collect{&previews};
  bus.subscribe("RIG_SIZE_.*_PREVIEW", &Collect::On, &collect);
  ASSERT_TRUE(RunReplay(PreviewsAsTheRigSays(summary->sequence_dir, rig, &bus)).ok());
  Drain(bus);
  ASSERT_EQ(previews.size(), 2u * frames);
  for (const auto& m : previews) {
    EXPECT_EQ(std::max(m.width, m.height), 64);
    EXPECT_GT(m.source_width, 64);
  }
  // A bad prefix is an error naming the field.
  PipelineOptions bad;
  bad.publisher.channel_prefix = "lower";
  ASSERT_FALSE(bad.Check().ok());
  EXPECT_NE(bad.Check().error().message.find("channel_prefix"), std::string::npos);
  bad = PipelineOptions{};
  bad.threads = -1;
  EXPECT_NE(bad.Check().error().message.find("threads"), std::string::npos);
  PreviewOptions preview;
  preview.depth_max_side = 0;
  ASSERT_FALSE(preview.Check().ok());
  EXPECT_NE(preview.Check().error().message.find("depth_max_side"), std::string::npos);
}

// A registration stage that knows each camera's pose: w0_from_cx is a
// rotation about z by 0.1 c rad and a shift of 100 c mm along x, trigger
// after trigger (camera c).
class KnownPoseStage final : public processing::RegistrationStage {
 public:
  static Pose W0FromC(int camera) {
    Pose pose = Pose::Identity();
    pose.linear() = Eigen::AngleAxisd(0.1 * camera, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    pose.translation() = Eigen::Vector3d(100.0 * camera, 5, -3);
    return pose;
  }
  std::string name() const override { return "known"; }
  Expected<std::optional<processing::CameraPose>> Localize(
      const processing::StageFrame& frame) override {
    EXPECT_NE(frame.products, nullptr);
    EXPECT_GT(frame.products->tf.width, 0);
    EXPECT_NE(frame.camera, nullptr);
    ++calls;
    processing::CameraPose pose;
    pose.transform = W0FromC(frame.camera_index);
    pose.method = "known";
    pose.inliers = 42;
    pose.localisation = "by camera " + std::to_string(frame.camera_index);
    return std::optional<processing::CameraPose>(pose);
  }
  std::atomic<int> calls{0};
};

struct ExtrinsicsMessages {
  std::vector<lifmcr_lcm::camera_extrinsics_t> messages;
  std::vector<std::string> channels;
  void On(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    lifmcr_lcm::camera_extrinsics_t m;
    ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
    messages.push_back(m);
    channels.push_back(channel);
  }
};

// The stage after processing: every processed frame goes through it; once
// camera 0 and camera 1 have a pose of a trigger, c0_from_c1 =
// (w0_from_c0)^-1 w0_from_c1 is published on <PREFIX>_<SERIAL>_EXTRINSICS
// with the trigger index; the pass-through stage publishes none.
TEST(Pipeline, RegistrationStagePosesBecomeExtrinsicsPerTrigger) {
  test::TempDir dir;
  const int frames = 2;
  auto summary = synth::WriteSyntheticDataset(dir.path(), TinyRig(frames));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const auto layout = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(layout.ok());
  for (const bool pass_through : {false, true}) {
    lcm::LCM bus("memq://");
    ExtrinsicsMessages received;
    bus.subscribe(".*_EXTRINSICS", &ExtrinsicsMessages::On, &received);
    auto stage = std::make_shared<KnownPoseStage>();
    ReplayRunOptions options;
    options.sequence_dir = summary->sequence_dir;
    options.rate.kind = ReplayRate::Kind::kMax;
    options.pipeline.publisher.bus = &bus;
    if (!pass_through) options.pipeline.registration = stage;
    std::mutex records_mutex;
    std::vector<ExtrinsicsRecord> records;  // what --extrinsics-csv and bench_live get
    options.pipeline.on_extrinsics = [&](const ExtrinsicsRecord& record) {
      std::lock_guard lock(records_mutex);
      records.push_back(record);
    };
    auto result = RunReplay(options);
    ASSERT_TRUE(result.ok()) << result.error().message;
    Drain(bus);
    const PipelineReport& r = result->report;
    EXPECT_EQ(r.processed, 2u * frames) << r.FinalReport();
    if (pass_through) {
      EXPECT_EQ(stage->calls, 0);
      EXPECT_TRUE(received.messages.empty());
      EXPECT_EQ(r.published_extrinsics, 0u);
      continue;
    }
    EXPECT_EQ(stage->calls, 2 * frames);
    EXPECT_EQ(r.localized, 2u * frames);
    ASSERT_EQ(received.messages.size(), static_cast<std::size_t>(frames)) << r.FinalReport();
    EXPECT_EQ(r.published_extrinsics, static_cast<std::uint64_t>(frames));
    const Pose expected = KnownPoseStage::W0FromC(0).inverse() * KnownPoseStage::W0FromC(1);
    std::vector<std::int64_t> triggers;
    for (std::size_t k = 0; k < received.messages.size(); ++k) {
      const auto& m = received.messages[k];
      EXPECT_EQ(m.reference_serial, layout->cameras[0].serial);
      EXPECT_EQ(m.serial, layout->cameras[1].serial);
      EXPECT_EQ(received.channels[k], "LIFMCR_" + layout->cameras[1].serial + "_EXTRINSICS");
      EXPECT_EQ(m.method, "known");
      EXPECT_EQ(m.inliers, 42);
      EXPECT_EQ(m.status, "ok");
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(m.t_mm[i], expected.translation()[i], 1e-9);
      const Eigen::Quaterniond q(expected.rotation());
      const double sign = q.w() * m.q_wxyz[0] < 0 ? -1.0 : 1.0;
      EXPECT_NEAR(sign * m.q_wxyz[3], q.z(), 1e-9);
      EXPECT_NEAR(sign * m.q_wxyz[0], q.w(), 1e-9);
      triggers.push_back(m.trigger_index);
    }
    std::sort(triggers.begin(), triggers.end());
    EXPECT_EQ(triggers, (std::vector<std::int64_t>{0, 1}));
    // The record carries how each camera's pose was made: camera 1's in its
    // c0_from_cx (as the message), camera 0's beside it.
    ASSERT_EQ(records.size(), static_cast<std::size_t>(frames));
    for (const ExtrinsicsRecord& record : records) {
      EXPECT_EQ(record.c0_from_cx.localisation, "by camera 1");
      EXPECT_EQ(record.reference_localisation, "by camera 0");
    }
  }
}

// A stage that localises from the raw frame alone (registration first).
class RawPoseStage final : public processing::RegistrationStage {
 public:
  std::string name() const override { return "raw-known"; }
  Expected<std::optional<processing::CameraPose>> Localize(
      const processing::StageFrame& frame) override {
    EXPECT_NE(frame.raw.data, nullptr);
    processing::CameraPose pose;
    pose.transform = KnownPoseStage::W0FromC(frame.camera_index);
    pose.method = "known";
    return std::optional<processing::CameraPose>(pose);
  }
};

// A pipeline of `serials` at 10 Hz without Vicon on `bus`, registration
// first (options.registration, RawPoseStage when null; newest wins, 2 frames
// at once): the lanes' set-up, with the rest of `options` as given.
Expected<std::unique_ptr<Pipeline>> CreateLanesPipeline(const std::vector<std::string>& serials,
                                                        std::unique_ptr<FrameProcessor> processor,
                                                        lcm::LCM* bus, PipelineOptions options) {
  options.publisher.bus = bus;
  if (!options.registration) options.registration = std::make_shared<RawPoseStage>();
  options.skip_when_busy = true;
  options.max_concurrency = 2;
  FrameSetAssemblerOptions sync;
  sync.serials = serials;
  sync.trigger.trigger_period_ns = 100'000'000;
  sync.vicon_expected = false;
  return Pipeline::Create(sync, std::move(processor), options);
}

// Registration first (a stage, newest wins: a timed replay): every frame
// taken goes to the lens lane (the ones the workers localise and the ones
// they skip), which publishes its per-lens depth
// on _DEPTH (GEOMETRY_LENS_GRID) and its lens preview on _TF unless a newer
// frame of its camera came first, whatever the depth lane manages; the message's
// lens grid maps each cell to its micro image's centre, and its values are
// the chain's per-lens depth of that frame within the 16-bit quantisation.
TEST(Pipeline, PerLensDepthAndPreviewForEveryFrameTakenWithRegistrationFirst) {
  test::TempDir dir;
  const int frames = 3;
  auto summary = synth::WriteSyntheticDataset(dir.path(), TinyRig(frames));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const auto layout = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(layout.ok());
  lcm::LCM bus("memq://");
  Received received;
  bus.subscribe("LIFMCR_.*", &Received::OnAny, &received);
  ReplayRunOptions options;
  options.sequence_dir = summary->sequence_dir;
  options.rate.kind = ReplayRate::Kind::kOriginal;
  options.pipeline.publisher.bus = &bus;
  options.pipeline.registration = std::make_shared<RawPoseStage>();
  auto result = RunReplay(options);
  ASSERT_TRUE(result.ok()) << result.error().message;
  Drain(bus);
  const PipelineReport& r = result->report;
  EXPECT_EQ(r.failed, 0u) << r.last_error;
  EXPECT_EQ(r.lens_failed, 0u) << r.last_error;
  ASSERT_GT(r.processed, 0u) << r.FinalReport();
  EXPECT_EQ(r.localized, r.processed);
  // Every frame taken went to the lens lane: its per-lens depth was
  // published there unless a newer frame of its camera replaced it first.
  EXPECT_EQ(r.lens_frames + r.lens_skipped + r.lens_failed, r.frames_in) << r.FinalReport();
  EXPECT_EQ(r.lens_replaced + r.lens_stale, r.lens_skipped) << r.FinalReport();
  ASSERT_GT(r.lens_frames, 0u) << r.FinalReport();
  // One per-lens map per frame of the lens lane, and a TF image for each of them.
  EXPECT_EQ(r.published_lens_depth, r.lens_frames) << r.FinalReport();
  EXPECT_EQ(received.lens_depth.size(), r.lens_frames) << r.FinalReport();
  for (const auto& [key, m] : received.lens_depth) {
    EXPECT_EQ(received.tf_frames[key.first].count(key.second), 1u)
        << key.first << " frame " << key.second << " has no TF image";
    EXPECT_EQ(m.geometry, lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID);
  }

  // One message against the chain's own product for its frame.
  ASSERT_FALSE(received.lens_depth.empty());
  const auto& [key, m] = *received.lens_depth.begin();
  const CameraFolder* folder = nullptr;
  for (const auto& camera : layout->cameras)
    if (camera.serial == key.first) folder = &camera;
  ASSERT_NE(folder, nullptr);
  auto image = ReadBmp(*folder->FramePath(key.second));
  ASSERT_TRUE(image.ok());
  EXPECT_EQ(m.raw_width, image->width);
  EXPECT_EQ(m.raw_height, image->height);
  auto processor = DepthProcessor::ForSequence(summary->sequence_dir.string(), {key.first});
  ASSERT_TRUE(processor.ok()) << processor.error().message;
  processing::CameraChain* chain = (*processor)->chain().Find(key.first);
  ASSERT_NE(chain, nullptr);
  auto lease = chain->ProcessLenses(image->View(), 0);
  ASSERT_TRUE(lease.ok()) << lease.error().message;
  const processing::LensDepthMap& expected = (*lease)->depth;
  ASSERT_EQ(m.width, expected.grid.cols);
  ASSERT_EQ(m.height, expected.grid.rows);
  int w = 0, h = 0;
  auto decoded = DecodeDepth(m.data, m.scale, m.offset, &w, &h);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  ASSERT_EQ(w, m.width);
  ASSERT_EQ(h, m.height);
  const auto estimator = chain->LensEstimator(image->View());
  ASSERT_TRUE(estimator.ok());
  const processing::PlenopticFrame& geometry = (*estimator)->geometry();
  const auto floor_div2 = [](int j) { return j >= 0 ? j / 2 : -((1 - j) / 2); };
  int lenses = 0, valid = 0;
  for (int row = 0; row < m.height; ++row)
    for (int col = 0; col < m.width; ++col) {
      // The message's rule (lcm_types/depth_image_t.lcm).
      const int j = m.lens_j_top - row;
      const int i = col + m.lens_col_base - floor_div2(j);
      const int k = geometry.LensAt(i, j);
      const std::size_t cell = static_cast<std::size_t>(row) * m.width + col;
      const float v = (*decoded)[cell], want = expected.virtual_depth[cell];
      ASSERT_EQ(std::isnan(v), std::isnan(want)) << col << "," << row;
      if (!std::isnan(v)) {
        ++valid;
        ASSERT_NEAR(v, want, m.scale) << col << "," << row;
      }
      if (k < 0) continue;
      ++lenses;
      const processing::MicroImage& lens = geometry.lenses[k];
      const double x = m.lens_origin_px[0] + i * m.lens_step_i_px[0] + j * m.lens_step_j_px[0];
      const double y = m.lens_origin_px[1] + i * m.lens_step_i_px[1] + j * m.lens_step_j_px[1];
      ASSERT_NEAR(x, lens.centre_px.x(), 1e-6);
      ASSERT_NEAR(y, lens.centre_px.y(), 1e-6);
      const int sign = m.lens_type_sign;
      ASSERT_EQ(((sign * (i - j)) % 3 + 3) % 3, lens.type);
      // The lens's virtual point at v: the micro-lens centre l_k and the
      // micro-image centre c_k on one ray, x_v = l_k + v (c_k - l_k).
      const double lambda = m.lambda;
      const Eigen::Vector2d p(m.principal_point_px[0], m.principal_point_px[1]);
      const Eigen::Vector2d c(x, y);
      const double vv = 3.0;
      const Eigen::Vector2d x_v = p + (lambda + vv * (1 - lambda)) * (c - p);
      ASSERT_LT((x_v - (lens.lens_px + vv * (lens.centre_px - lens.lens_px))).norm(), 1e-6);
    }
  EXPECT_EQ(lenses, static_cast<int>(geometry.lenses.size()));
  EXPECT_GT(valid, 0);
  EXPECT_NEAR(m.valid_fraction, static_cast<double>(valid) / decoded->size(), 1e-6);
}

// The depth lane's frames of camera 1 wait in Process until the test lets
// them go, one per Release(); camera 0's go at once.
struct DepthGate {
  std::mutex mutex;
  std::condition_variable cv;
  int released = 0, entered = 0, waiting = 0, timed_out = 0;
  void Release() {
    {
      std::lock_guard lock(mutex);
      ++released;
    }
    cv.notify_all();
  }
  // Until camera 1's frame number `n` (1-based) waits in Process.
  bool WaitUntilHeld(int n) {
    std::unique_lock lock(mutex);
    return cv.wait_for(lock, std::chrono::seconds(10), [&] { return entered >= n && waiting > 0; });
  }
};

class GatedProcessor final : public FrameProcessor {
 public:
  explicit GatedProcessor(DepthGate* gate) : gate_(gate) {}
  Expected<ProcessedFrame> Process(const Frame& frame) override {
    if (frame.camera_index == 1) {
      std::unique_lock lock(gate_->mutex);
      const int ordinal = ++gate_->entered;
      ++gate_->waiting;
      gate_->cv.notify_all();
      // Bounded, so that a pipeline that waits for this frame fails the
      // test instead of hanging it.
      if (!gate_->cv.wait_for(lock, std::chrono::seconds(5),
                              [&] { return gate_->released >= ordinal; }))
        ++gate_->timed_out;
      --gate_->waiting;
    }
    return preview_.Process(frame);
  }
  std::string name() const override { return "gated"; }

 private:
  DepthGate* gate_;
  PreviewProcessor preview_;
};

// Not the pass-through: under newest_wins the frames go through the depth
// lane (the processor has no chain, so nothing is localised).
class NoPoseStage final : public processing::RegistrationStage {
 public:
  std::string name() const override { return "none"; }
  Expected<std::optional<processing::CameraPose>> Localize(const processing::StageFrame&) override {
    return std::optional<processing::CameraPose>();
  }
};

// Registration first (newest_wins with a stage): a pass's end does not wait
// for the depth lane's frame (at medium seconds: the replay's cameras stood
// still that long at every pass of a loop), but Finish waits for every frame
// the lane holds, and the lane's frames are all accounted for after Finish.
// When the graph's publishing node published the lane's frames, Finish once
// returned while the lane processed a frame, which then reached the node
// after it was destroyed (bench_live: segmentation fault / "pure virtual
// method called"); the lane publishes on its own thread now, and
// Pipeline's destructor still must not end before the lane's last frame.
TEST(Pipeline, DepthLaneFramesOutliveAPassNeverThePipeline) {
  for (int round = 0; round < 3; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    lcm::LCM bus("memq://");
    Received received;
    bus.subscribe("LIFMCR_.*", &Received::OnAny, &received);
    DepthGate gate;
    PipelineOptions options;
    options.publisher.bus = &bus;
    options.registration = std::make_shared<NoPoseStage>();
    options.skip_when_busy = true;
    FrameSetAssemblerOptions sync;
    sync.serials = {"100", "101"};
    sync.trigger.trigger_period_ns = 100'000'000;
    sync.vicon_expected = false;
    auto created = Pipeline::Create(sync, std::make_unique<GatedProcessor>(&gate), options);
    ASSERT_TRUE(created.ok()) << created.error().message;
    std::unique_ptr<Pipeline> pipeline = std::move(*created);
    const auto pool = FramePool::Create(8, 64 * 48);
    const auto add_set = [&](std::int64_t trigger) {
      pipeline->AddFrameSet(
          MakeFrameSet(trigger, sync.serials, *pool, [&](int camera, std::uint8_t* data) {
            std::fill_n(data, 64 * 48, static_cast<std::uint8_t>(40 * camera + trigger));
            return ImageView{data, 64, 48, 64, PixelFormat::kMono8};
          }));
      pipeline->Poll();
    };
    add_set(0);
    ASSERT_TRUE(gate.WaitUntilHeld(1));  // the lane holds camera 1's frame 0
    add_set(1);
    // The pass ends with the lane's frame in Process: EndPass does not wait for it.
    pipeline->EndPass();
    {
      std::lock_guard lock(gate.mutex);
      EXPECT_EQ(gate.waiting, 1);
      EXPECT_EQ(gate.timed_out, 0);
    }
    // Camera 1's frame 0 published, then camera 0's newest (served least
    // recently) at once if the lens lane has handed it on, then the lane
    // takes camera 1's frame 1.
    gate.Release();
    ASSERT_TRUE(gate.WaitUntilHeld(2));
    std::atomic<bool> finished{false};
    std::thread finish([&] {
      pipeline->Finish();
      finished = true;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    EXPECT_FALSE(finished) << "Finish returned while the depth lane held a frame";
    gate.Release();
    finish.join();
    const PipelineReport r = pipeline->Report();
    EXPECT_EQ(r.processed + r.failed, 4u) << r.FinalReport();
    // Every frame counted once in the lens lane; the depth lane counts the
    // frames the lens lane hands on (a frame the lens lane skips, e.g. one
    // that reaches it after a newer frame of its camera on a loaded machine,
    // is counted there with its reason and reaches no later lane).
    EXPECT_EQ(r.lens_frames + r.lens_skipped + r.lens_failed, 4u) << r.FinalReport();
    EXPECT_EQ(r.depth_processed + r.depth_skipped + r.depth_failed,
              r.lens_frames + r.lens_failed) << r.FinalReport();
    EXPECT_EQ(r.depth_failed, 0u) << r.FinalReport();
    // Both frames the lane held (camera 1's) are published. Camera 0's frame
    // 1 is published too when the lens lane hands it on before the depth
    // lane takes camera 1's frame 1; handed on later it waits until Finish,
    // which skips what still waits (newest wins: counted as skipped above).
    // Which of the two happens is the lens lane's timing on a busy machine.
    EXPECT_GE(r.depth_processed, 2u) << r.FinalReport();
    pipeline.reset();  // nothing of the lane's left to reach the destroyed nodes
    Drain(bus);
    int previews = 0;
    for (const auto& [serial, ids] : received.preview_frames)
      previews += static_cast<int>(ids.size());
    EXPECT_EQ(static_cast<std::uint64_t>(previews), r.depth_processed);
    EXPECT_EQ(received.preview_frames["101"].size(), 2u) << r.FinalReport();
    std::lock_guard lock(gate.mutex);
    EXPECT_EQ(gate.timed_out, 0);
  }
}

// A registration stage whose Localize of each (camera, trigger) waits until
// the test releases it, recording the order frames began in.
class GatedPoseStage final : public processing::RegistrationStage {
 public:
  // How long a Localize waits for its release at most (then it counts a time-out).
  explicit GatedPoseStage(std::chrono::seconds wait = std::chrono::seconds(5)) : wait_(wait) {}
  std::string name() const override { return "gated-pose"; }
  Expected<std::optional<processing::CameraPose>> Localize(
      const processing::StageFrame& frame) override {
    const std::pair<int, std::int64_t> key{frame.camera_index, frame.trigger_index};
    std::unique_lock lock(mutex_);
    began_.push_back(key);
    cv_.notify_all();
    if (!cv_.wait_for(lock, wait_, [&] { return released_.count(key) > 0; }))
      ++timed_out_;
    processing::CameraPose pose;
    pose.transform = KnownPoseStage::W0FromC(frame.camera_index);
    pose.method = "gated";
    pose.inliers = 42;
    return std::optional<processing::CameraPose>(pose);
  }
  // Until (camera, trigger) began; false after 10 s.
  bool WaitBegan(int camera, std::int64_t trigger) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, std::chrono::seconds(10), [&] {
      return std::find(began_.begin(), began_.end(), std::make_pair(camera, trigger)) !=
             began_.end();
    });
  }
  void Release(int camera, std::int64_t trigger) {
    {
      std::lock_guard lock(mutex_);
      released_.insert({camera, trigger});
    }
    cv_.notify_all();
  }
  void ReleaseAll() {
    {
      std::lock_guard lock(mutex_);
      for (const auto& key : began_) released_.insert(key);
    }
    cv_.notify_all();
  }
  std::vector<std::pair<int, std::int64_t>> Began() {
    std::lock_guard lock(mutex_);
    return began_;
  }
  int timed_out() {
    std::lock_guard lock(mutex_);
    return timed_out_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<std::pair<int, std::int64_t>> began_;
  std::set<std::pair<int, std::int64_t>> released_;
  int timed_out_ = 0;
  std::chrono::seconds wait_;
};

// Under newest_wins with a registration stage, the frame that completes the
// pair of a trigger a worker took last goes first and is not replaced by its
// camera's newer frame: c0_from_cx needs both cameras' poses of one trigger
// (bench_live r32, every frame relocalised: 39 pairs of 248 localised frames
// before, 84 of 146 after). Here camera 1's frame of trigger 1 waits while
// camera 0's is localised and trigger 2's frames arrive; it is localised
// next (trigger 1 becomes extrinsics) and camera 1's trigger 2 waits behind it.
TEST(Pipeline, RegistrationPairsTheCamerasFramesOfATrigger) {
  // A real chain per camera (the stage is called only for a camera with
  // one), on the tiny rig's first frames, given again for every trigger.
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const std::vector<std::string>& serials = rig->serials;
  const std::vector<OwnedImage>& raw = rig->raw;
  ASSERT_EQ(raw.size(), 2u);
  auto processor = DepthProcessor::ForSequence(rig->sequence_dir.string(), serials);
  ASSERT_TRUE(processor.ok()) << processor.error().message;
  lcm::LCM bus("memq://");
  auto stage = std::make_shared<GatedPoseStage>();
  PipelineOptions options;
  options.publisher.bus = &bus;
  options.registration = stage;
  options.skip_when_busy = true;
  options.max_concurrency = 2;
  std::mutex records_mutex;
  std::vector<std::int64_t> extrinsics_triggers;
  options.on_extrinsics = [&](const ExtrinsicsRecord& record) {
    std::lock_guard lock(records_mutex);
    extrinsics_triggers.push_back(record.trigger_index);
  };
  FrameSetAssemblerOptions sync;
  sync.serials = serials;
  sync.trigger.trigger_period_ns = 100'000'000;
  sync.vicon_expected = false;
  auto created = Pipeline::Create(sync, std::move(*processor), options);
  ASSERT_TRUE(created.ok()) << created.error().message;
  std::unique_ptr<Pipeline> pipeline = std::move(*created);
  const auto pool = FramePool::Create(16, raw[0].pixels.size());
  const auto add_set = [&](std::int64_t trigger) {
    pipeline->AddFrameSet(MakeCopiedFrameSet(trigger, serials, *pool, raw));
    pipeline->Poll();
  };
  add_set(0);  // both workers: camera 0 and camera 1 of trigger 0
  ASSERT_TRUE(stage->WaitBegan(0, 0));
  ASSERT_TRUE(stage->WaitBegan(1, 0));
  add_set(1);  // both wait
  stage->Release(0, 0);
  ASSERT_TRUE(stage->WaitBegan(0, 1));  // camera 0 served least recently
  add_set(2);  // camera 1's trigger 1 completes a pair: trigger 2's waits behind it
  stage->Release(1, 0);
  ASSERT_TRUE(stage->WaitBegan(1, 1)) << "camera 1's frame of trigger 1 was replaced";
  // Release what has begun and what begins from here on until everything is in.
  std::atomic<bool> done{false};
  std::thread releaser([&] {
    while (!done) {
      stage->ReleaseAll();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  pipeline->Finish();
  done = true;
  releaser.join();
  const PipelineReport r = pipeline->Report();
  EXPECT_EQ(stage->timed_out(), 0);
  EXPECT_TRUE(r.Accounted()) << r.FinalReport();
  EXPECT_EQ(r.frames_in, 6u) << r.FinalReport();
  std::lock_guard lock(records_mutex);
  std::sort(extrinsics_triggers.begin(), extrinsics_triggers.end());
  // Triggers 0 and 1 paired; trigger 2's frames both localised too (nothing
  // newer came): every localised frame is in a pair.
  EXPECT_EQ(extrinsics_triggers, (std::vector<std::int64_t>{0, 1, 2})) << r.FinalReport();
  EXPECT_EQ(r.skipped, 0u) << r.FinalReport();
}

// Registration first, newest wins: every frame goes to the lens lane as it
// is taken, beside its localisation, so frames the workers hold (a
// relocalisation) and frames they skip (replaced in their slot by their
// camera's newer frame) get their per-lens depth without a pose while the
// workers are busy, and then their dense map in the depth lane; every frame
// taken is counted once in each lane. Here both workers hold trigger 0:
// trigger 0's per-lens depth and dense maps are on LCM before its poses
// (each lane publishes on its own thread: the graph's publishing node runs
// on the workers), then trigger 1's, skipped by the workers for trigger
// 2's. Offered after its pose instead, trigger 0 came to the lens lane
// after trigger 1 and was skipped there (older than a frame it took) while
// the lane had nothing to do.
TEST(Pipeline, LanesPublishTheFramesTheWorkersHoldOrSkipWhileTheWorkersAreHeld) {
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const std::vector<std::string>& serials = rig->serials;
  const std::vector<OwnedImage>& raw = rig->raw;
  ASSERT_EQ(raw.size(), 2u);
  auto processor = DepthProcessor::ForSequence(rig->sequence_dir.string(), serials);
  ASSERT_TRUE(processor.ok()) << processor.error().message;
  lcm::LCM bus("memq://");
  Received received;
  bus.subscribe("LIFMCR_.*", &Received::OnAny, &received);
  auto stage = std::make_shared<GatedPoseStage>(std::chrono::seconds(150));
  PipelineOptions options;
  options.registration = stage;
  auto created = CreateLanesPipeline(serials, std::move(*processor), &bus, options);
  ASSERT_TRUE(created.ok()) << created.error().message;
  std::unique_ptr<Pipeline> pipeline = std::move(*created);
  const auto pool = FramePool::Create(16, raw[0].pixels.size());
  const auto add_set = [&](std::int64_t trigger) {
    pipeline->AddFrameSet(MakeCopiedFrameSet(trigger, serials, *pool, raw));
    pipeline->Poll();
  };
  // Until both lanes published (or failed) `n` frames each: at nice +15 and
  // +19 on a loaded host the lanes wait long for the CPU.
  const auto wait_lanes = [&](std::uint64_t n) {
    const auto done = [n](const PipelineReport& r) {
      return r.lens_frames + r.lens_failed >= n && r.depth_processed + r.depth_failed >= n;
    };
    for (int k = 0; k < 2400 && !done(pipeline->Report()); ++k)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    return pipeline->Report();
  };
  add_set(0);  // both workers, held
  ASSERT_TRUE(stage->WaitBegan(0, 0));
  ASSERT_TRUE(stage->WaitBegan(1, 0));
  const PipelineReport held = wait_lanes(2);
  EXPECT_EQ(held.localized, 0u) << held.FinalReport();
  EXPECT_EQ(held.lens_frames, 2u) << "trigger 0's per-lens depth waited for its poses\n"
                                  << held.FinalReport();
  EXPECT_EQ(held.depth_processed, 2u) << held.FinalReport();
  add_set(1);  // waits for a worker; the lens lane takes it
  const PipelineReport waiting = wait_lanes(4);
  EXPECT_EQ(waiting.lens_frames, 4u) << waiting.FinalReport();
  add_set(2);  // replaces trigger 1's frames in the workers' slots
  const PipelineReport before = wait_lanes(6);
  EXPECT_EQ(before.localized, 0u) << before.FinalReport();
  EXPECT_EQ(before.skipped, 2u) << before.FinalReport();
  EXPECT_EQ(before.lens_frames, 6u) << "the per-lens depth of the frames the workers hold or skip "
                                       "was not published while the workers were busy\n"
                                    << before.FinalReport();
  EXPECT_EQ(before.depth_processed, 6u) << before.FinalReport();
  EXPECT_EQ(before.depth_skipped + before.depth_failed, 0u) << before.FinalReport();
  EXPECT_EQ(before.published_depth, 6u) << before.FinalReport();
  Drain(bus);
  for (const std::string& serial : serials)
    for (const std::int64_t frame_id : {0, 1, 2}) {
      EXPECT_EQ(received.lens_depth.count({serial, frame_id}), 1u)
          << serial << ": no per-lens depth of frame " << frame_id
          << " while the workers were held\n"
          << before.FinalReport();
      EXPECT_EQ(received.depth.count({serial, frame_id}), 1u)
          << serial << ": no dense map of frame " << frame_id << " while the workers were held\n"
          << before.FinalReport();
    }
  std::atomic<bool> done{false};
  std::thread releaser([&] {
    while (!done) {
      stage->ReleaseAll();
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  pipeline->Finish();
  done = true;
  releaser.join();
  const PipelineReport r = pipeline->Report();
  EXPECT_EQ(stage->timed_out(), 0);
  EXPECT_TRUE(r.Accounted()) << r.FinalReport();
  EXPECT_EQ(r.frames_in, 6u) << r.FinalReport();
  EXPECT_EQ(r.processed, 4u) << r.FinalReport();  // triggers 0 and 2 localised
  EXPECT_EQ(r.lens_failed, 0u) << r.last_error;
  EXPECT_EQ(r.lens_frames + r.lens_skipped + r.lens_failed, r.frames_in) << r.FinalReport();
  EXPECT_EQ(r.lens_frames, 6u) << r.FinalReport();
  EXPECT_EQ(r.published_lens_depth, r.lens_frames) << r.FinalReport();
  // Nothing skipped in the lens lane: each frame came to it once, in its
  // camera's order, and none waited there while the lane was busy.
  EXPECT_EQ(r.lens_replaced + r.lens_stale, r.lens_skipped) << r.FinalReport();
  EXPECT_EQ(r.lens_skipped, 0u) << r.FinalReport();
  EXPECT_NE(r.FinalReport().find("lens lane skipped: 0 replaced by a newer frame of its camera "
                                 "while the lane was busy, 0 came after a newer frame"),
            std::string::npos)
      << r.FinalReport();
  // Every frame the lens lane took went on to the depth lane.
  EXPECT_EQ(r.depth_failed, 0u) << r.last_error;
  EXPECT_EQ(r.depth_processed + r.depth_skipped + r.depth_failed, r.lens_frames + r.lens_failed)
      << r.FinalReport();
  EXPECT_EQ(r.published_depth, r.depth_processed) << r.FinalReport();
  Drain(bus);
  EXPECT_EQ(received.depth.size(), r.depth_processed) << r.FinalReport();
  EXPECT_EQ(received.lens_depth.size(), 6u) << r.FinalReport();
}

// The depth processor of a sequence whose ProcessLenses waits until the test
// releases it (bounded: a pipeline that waits for the per-lens depth before
// publishing the pose fails the test instead of hanging it).
class LensGatedProcessor final : public FrameProcessor {
 public:
  explicit LensGatedProcessor(std::unique_ptr<DepthProcessor> inner) : inner_(std::move(inner)) {}
  Expected<ProcessedFrame> Process(const Frame& frame) override { return inner_->Process(frame); }
  Expected<ProcessedFrame> ProcessDense(const Frame& frame,
                                        const ProcessedFrame* lenses) override {
    {
      std::lock_guard lock(mutex_);
      dense_given_lenses_ += lenses != nullptr && lenses->lenses ? 1 : 0;
      // The depth lane's scheduling policy while it computes
      // (PipelineOptions::depth_idle).
      dense_policies_.push_back(sched_getscheduler(0));
    }
    return inner_->ProcessDense(frame, lenses);
  }
  Expected<ProcessedFrame> ProcessLenses(const Frame& frame,
                                         const RegistrationInput* input) override {
    {
      std::unique_lock lock(mutex_);
      ++entered_;
      // The lens lane's thread's nice value (PipelineOptions::lens_nice).
      errno = 0;
      const int nice = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
      if (errno == 0) lens_nice_seen_.push_back(nice);
      cv_.notify_all();
      const bool gated =
          gate_serial_.empty() || (frame.serial == gate_serial_ && frame.frame_id == gate_frame_);
      if (gated && !cv_.wait_for(lock, std::chrono::seconds(20), [&] { return released_; }))
        ++timed_out_;
    }
    return inner_->ProcessLenses(frame, input);
  }
  Expected<RegistrationInput> ForRegistration(const Frame& frame) override {
    return inner_->ForRegistration(frame);
  }
  std::string name() const override { return "lens-gated"; }
  // Only this frame of this camera is held (until Release); by default every frame.
  void GateOnly(const std::string& serial, std::uint64_t frame_id) {
    std::lock_guard lock(mutex_);
    gate_serial_ = serial;
    gate_frame_ = frame_id;
  }
  int entered() {
    std::lock_guard lock(mutex_);
    return entered_;
  }
  // Until `n` frames wait in ProcessLenses; false after 10 s.
  bool WaitEntered(int n) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, std::chrono::seconds(10), [&] { return entered_ >= n; });
  }
  void Release() {
    {
      std::lock_guard lock(mutex_);
      released_ = true;
    }
    cv_.notify_all();
  }
  int timed_out() {
    std::lock_guard lock(mutex_);
    return timed_out_;
  }
  std::vector<int> lens_nice_seen() {
    std::lock_guard lock(mutex_);
    return lens_nice_seen_;
  }
  int dense_given_lenses() {
    std::lock_guard lock(mutex_);
    return dense_given_lenses_;
  }
  std::vector<int> dense_policies() {
    std::lock_guard lock(mutex_);
    return dense_policies_;
  }

 private:
  std::unique_ptr<DepthProcessor> inner_;
  std::mutex mutex_;
  std::condition_variable cv_;
  int entered_ = 0, timed_out_ = 0, dense_given_lenses_ = 0;
  std::vector<int> lens_nice_seen_;
  std::vector<int> dense_policies_;
  bool released_ = false;
  std::string gate_serial_;  // empty: every frame is held
  std::uint64_t gate_frame_ = 0;
};

// Registration first (newest_wins with a stage): a frame's pose, and the
// extrinsics of its trigger, are published as soon as it is localised, while
// the lens lane still holds both frames' per-lens depth; the per-lens depth
// then follows for both frames, and the depth lane seeds its dense map with
// the lens lane's per-lens depth instead of estimating it again.
TEST(Pipeline, PoseIsPublishedBeforeItsFramesPerLensDepth) {
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const std::vector<std::string>& serials = rig->serials;
  const std::vector<OwnedImage>& raw = rig->raw;
  ASSERT_EQ(raw.size(), 2u);
  auto depth = DepthProcessor::ForSequence(rig->sequence_dir.string(), serials);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  auto owned = std::make_unique<LensGatedProcessor>(std::move(*depth));
  LensGatedProcessor* processor = owned.get();
  lcm::LCM bus("memq://");
  Received received;
  bus.subscribe("LIFMCR_.*", &Received::OnAny, &received);
  PipelineOptions options;
  options.lens_nice = 12;  // not the default, so the lane's threads show it
  std::mutex records_mutex;
  std::condition_variable records_cv;
  std::vector<ExtrinsicsRecord> records;
  options.on_extrinsics = [&](const ExtrinsicsRecord& record) {
    {
      std::lock_guard lock(records_mutex);
      records.push_back(record);
    }
    records_cv.notify_all();
  };
  auto created = CreateLanesPipeline(serials, std::move(owned), &bus, options);
  ASSERT_TRUE(created.ok()) << created.error().message;
  std::unique_ptr<Pipeline> pipeline = std::move(*created);
  const auto pool = FramePool::Create(4, raw[0].pixels.size());
  pipeline->AddFrameSet(MakeCopiedFrameSet(0, serials, *pool, raw));
  pipeline->Poll();
  // Both frames wait in ProcessLenses (the lens lane has a thread per
  // camera here; the frames went there as they were taken, beside their
  // localisation): both poses come out all the same, and so do trigger 0's
  // extrinsics.
  ASSERT_TRUE(processor->WaitEntered(2));
  {
    std::unique_lock lock(records_mutex);
    EXPECT_TRUE(records_cv.wait_for(lock, std::chrono::seconds(3), [&] { return !records.empty(); }))
        << "the extrinsics waited for the frames' per-lens depth";
    ASSERT_EQ(records.size(), 1u);
    EXPECT_EQ(records[0].trigger_index, 0);
    EXPECT_EQ(records[0].c0_from_cx.status, "ok");
  }
  // The extrinsics go out inside the second pose's publication, which counts
  // the pose after them.
  for (int k = 0; k < 300 && pipeline->Report().published_poses < 2; ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_EQ(pipeline->Report().published_poses, 2u);
  // The lens lane computes at lens_nice, relative to the thread that made the pipeline.
  const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
  for (const int nice : processor->lens_nice_seen()) EXPECT_EQ(nice, std::min(19, base + 12));
  EXPECT_EQ(processor->lens_nice_seen().size(), 2u);
  processor->Release();
  // The depth lane (lowest priority) takes a frame before the end, which
  // skips the frames still waiting for it.
  for (int k = 0; k < 600 && pipeline->Report().depth_processed == 0; ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  pipeline->Finish();
  const PipelineReport r = pipeline->Report();
  EXPECT_EQ(processor->timed_out(), 0);
  EXPECT_EQ(r.failed + r.lens_failed, 0u) << r.last_error;
  EXPECT_EQ(r.processed, 2u) << r.FinalReport();
  EXPECT_EQ(r.published_lens_depth, 2u) << r.FinalReport();
  EXPECT_EQ(r.lens_frames, 2u) << r.FinalReport();
  // Every dense map the lane made was seeded by the workers' per-lens depth.
  EXPECT_GE(r.depth_processed, 1u) << r.FinalReport();
  EXPECT_EQ(r.depth_seeded_by_lenses, r.depth_processed) << r.FinalReport();
  EXPECT_EQ(processor->dense_given_lenses(), static_cast<int>(r.depth_processed));
  // The dense maps were computed under SCHED_IDLE (depth_idle, the default):
  // only on CPU the workers and the lens lane leave.
  for (const int policy : processor->dense_policies()) EXPECT_EQ(policy, SCHED_IDLE);
  pipeline.reset();
  Drain(bus);
  EXPECT_EQ(received.lens_depth.size(), 2u);
}

// The frame ids of the per-lens depth messages (GEOMETRY_LENS_GRID on
// _DEPTH) by serial, in the order they were published on `bus`.
class LensDepthOrder {
 public:
  explicit LensDepthOrder(lcm::LCM* bus) {
    bus->subscribe("LIFMCR_.*_DEPTH", &LensDepthOrder::On, this);
  }
  std::map<std::string, std::vector<std::int64_t>> Get() {
    std::lock_guard lock(mutex_);
    return order_;
  }

 private:
  void On(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    lifmcr_lcm::depth_image_t m;
    ASSERT_GE(m.decode(rbuf->data, 0, rbuf->data_size), 0);
    if (m.geometry != lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID) return;
    std::lock_guard lock(mutex_);
    order_[m.serial].push_back(m.frame_id);
  }
  std::mutex mutex_;
  std::map<std::string, std::vector<std::int64_t>> order_;
};

// The lens lane held up (both its threads inside ProcessLenses, as when a
// relocalisation at the workers' higher priority takes the CPU) while two
// more triggers come: with lens_queue 2 both wait per camera
// and get their per-lens depth once the lane goes on; a third replaces the
// oldest waiting (newest wins beyond the queue), counted as replaced. With
// lens_queue 1 (newest wins at once) the second trigger already replaces
// the first. The per-lens depth of each camera goes out in its frames' order.
TEST(Pipeline, LensLaneQueueKeepsTheFramesThatCameWhileItWasHeld) {
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const std::vector<std::string>& serials = rig->serials;
  for (const int lens_queue : {2, 1}) {
    SCOPED_TRACE("lens_queue " + std::to_string(lens_queue));
    auto depth = DepthProcessor::ForSequence(rig->sequence_dir.string(), serials);
    ASSERT_TRUE(depth.ok()) << depth.error().message;
    auto owned = std::make_unique<LensGatedProcessor>(std::move(*depth));
    LensGatedProcessor* processor = owned.get();
    lcm::LCM bus("memq://");
    LensDepthOrder lens_order(&bus);
    PipelineOptions options;
    options.lens_queue = lens_queue;
    options.threads = 2;  // two lens-lane threads on any host (one per worker)
    auto created = CreateLanesPipeline(serials, std::move(owned), &bus, options);
    ASSERT_TRUE(created.ok()) << created.error().message;
    std::unique_ptr<Pipeline> pipeline = std::move(*created);
    const auto pool = FramePool::Create(12, rig->raw[0].pixels.size());
    const auto add_set = [&](std::int64_t trigger) {
      pipeline->AddFrameSet(MakeCopiedFrameSet(trigger, serials, *pool, rig->raw));
      pipeline->Poll();
    };
    const auto wait_localised = [&](std::uint64_t n) {
      for (int k = 0; k < 500 && pipeline->Report().localized < n; ++k)
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      return pipeline->Report();
    };
    add_set(0);
    ASSERT_TRUE(processor->WaitEntered(2));  // both lane threads held on trigger 0
    add_set(1);
    wait_localised(4);
    add_set(2);
    const PipelineReport held = wait_localised(6);
    EXPECT_EQ(held.localized, 6u) << held.FinalReport();
    EXPECT_EQ(held.lens_replaced, lens_queue == 2 ? 0u : 2u) << held.FinalReport();
    add_set(3);
    const PipelineReport more = wait_localised(8);
    EXPECT_EQ(more.lens_replaced, lens_queue == 2 ? 2u : 4u) << more.FinalReport();
    processor->Release();
    pipeline->Finish();
    const PipelineReport r = pipeline->Report();
    EXPECT_EQ(processor->timed_out(), 0);
    EXPECT_EQ(r.lens_failed, 0u) << r.last_error;
    EXPECT_EQ(r.lens_stale, 0u) << r.FinalReport();
    EXPECT_EQ(r.lens_frames + r.lens_skipped, r.frames_in) << r.FinalReport();
    EXPECT_EQ(r.lens_frames, lens_queue == 2 ? 6u : 4u) << r.FinalReport();
    pipeline.reset();
    Drain(bus);
    const std::vector<std::int64_t> expected =
        lens_queue == 2 ? std::vector<std::int64_t>{0, 2, 3} : std::vector<std::int64_t>{0, 3};
    auto published = lens_order.Get();
    for (const std::string& serial : serials) EXPECT_EQ(published[serial], expected) << serial;
  }
}

// One lens-lane thread held on a camera's first frame (as when it shares a
// core with a relocalising worker) while five more triggers come: the other
// thread computes both cameras' frames, that camera's next ones too, instead
// of idling while they wait and the oldest is replaced; those wait, computed,
// until the held frame is published, so each camera's per-lens depth still
// goes out in its frames' order and none is replaced.
TEST(Pipeline, LensLaneFreeThreadTakesTheFramesOfACameraHeldOnTheOtherInOrder) {
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const std::vector<std::string>& serials = rig->serials;
  ASSERT_EQ(serials.size(), 2u);
  auto depth = DepthProcessor::ForSequence(rig->sequence_dir.string(), serials);
  ASSERT_TRUE(depth.ok()) << depth.error().message;
  auto owned = std::make_unique<LensGatedProcessor>(std::move(*depth));
  LensGatedProcessor* processor = owned.get();
  processor->GateOnly(serials[0], 0);
  lcm::LCM bus("memq://");
  LensDepthOrder lens_order(&bus);
  PipelineOptions options;  // lens_queue 4: five frames waiting would replace one
  options.threads = 2;       // two lens-lane threads on any host (one per worker)
  auto created = CreateLanesPipeline(serials, std::move(owned), &bus, options);
  ASSERT_TRUE(created.ok()) << created.error().message;
  std::unique_ptr<Pipeline> pipeline = std::move(*created);
  const auto pool = FramePool::Create(32, rig->raw[0].pixels.size());
  // A trigger once both frames of the one before entered ProcessLenses (the
  // first camera's first frame held there), so no queue fills: the old rule
  // (a camera's frames on one thread at a time) never lets them all enter.
  for (int trigger = 0; trigger < 6; ++trigger) {
    pipeline->AddFrameSet(MakeCopiedFrameSet(trigger, serials, *pool, rig->raw));
    pipeline->Poll();
    for (int k = 0; k < 2000 && processor->entered() < 2 * (trigger + 1); ++k)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  // Every frame entered ProcessLenses while the first is held: the second
  // camera's six published, the first camera's five later ones parked.
  for (int k = 0; k < 2000 && (processor->entered() < 12 || pipeline->Report().lens_frames < 6);
       ++k)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const PipelineReport held = pipeline->Report();
  EXPECT_EQ(processor->entered(), 12) << held.FinalReport();
  EXPECT_EQ(held.lens_frames, 6u) << held.FinalReport();
  EXPECT_EQ(held.lens_replaced, 0u) << held.FinalReport();
  processor->Release();
  pipeline->Finish();
  const PipelineReport r = pipeline->Report();
  EXPECT_EQ(processor->timed_out(), 0);
  EXPECT_EQ(r.lens_failed, 0u) << r.last_error;
  EXPECT_EQ(r.lens_skipped, 0u) << r.FinalReport();
  EXPECT_EQ(r.lens_frames, 12u) << r.FinalReport();
  pipeline.reset();
  Drain(bus);
  const std::vector<std::int64_t> expected{0, 1, 2, 3, 4, 5};
  auto published = lens_order.Get();
  for (const std::string& serial : serials) EXPECT_EQ(published[serial], expected) << serial;
}

// DepthProcessor::Warm (what a timed replay does before its cameras start):
// each camera's per-lens estimator and TF sampler made from a frame of it,
// so the lens lane's first frame of the camera computes only its depth; the
// per-lens depth of a frame is the same with and without it, and a camera
// without a chain is an error naming it.
// Two ProcessLenses results of one frame: the same per-lens depth (NaN where
// the other is NaN) and the same TF preview bytes.
void ExpectSameLensProducts(const Expected<ProcessedFrame>& a, const Expected<ProcessedFrame>& b) {
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_TRUE(a->lens_depth && b->lens_depth);
  ASSERT_EQ(a->lens_depth->depth.values.size(), b->lens_depth->depth.values.size());
  for (std::size_t k = 0; k < a->lens_depth->depth.values.size(); ++k) {
    const float x = a->lens_depth->depth.values[k], y = b->lens_depth->depth.values[k];
    ASSERT_EQ(std::isnan(x), std::isnan(y)) << k;
    if (!std::isnan(x)) {
      ASSERT_EQ(x, y) << k;
    }
  }
  EXPECT_EQ(a->tf->bytes, b->tf->bytes);
}

TEST(Pipeline, WarmMakesACamerasSetUpBeforeItsFirstFrameAndChangesNoProduct) {
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  auto warmed = DepthProcessor::ForSequence(rig->sequence_dir.string(), rig->serials);
  auto cold = DepthProcessor::ForSequence(rig->sequence_dir.string(), rig->serials);
  ASSERT_TRUE(warmed.ok() && cold.ok());
  for (std::size_t c = 0; c < rig->serials.size(); ++c) {
    Frame frame;
    frame.serial = rig->serials[c];
    frame.image = rig->raw[c].View();
    ASSERT_TRUE((*warmed)->Warm(frame, /*sampler=*/true).ok());
    processing::CameraChain* camera = (*warmed)->chain().Find(frame.serial);
    ASSERT_NE(camera, nullptr);
    // The camera keeps the estimator Warm made: the lane gets that one.
    auto first = camera->LensEstimator(frame.image);
    auto again = camera->LensEstimator(frame.image);
    ASSERT_TRUE(first.ok() && again.ok());
    EXPECT_EQ(*first, *again);
    auto a = (*warmed)->ProcessLenses(frame);
    auto b = (*cold)->ProcessLenses(frame);
    ExpectSameLensProducts(a, b);
    // The dense map in the workspace Warm used: the cold processor's.
    auto dense_warm = (*warmed)->ProcessDense(frame, &*a);
    auto dense_cold = (*cold)->ProcessDense(frame, &*b);
    ASSERT_TRUE(dense_warm.ok() && dense_cold.ok());
    ASSERT_TRUE(dense_warm->depth && dense_cold->depth);
    EXPECT_EQ(dense_warm->depth->png, dense_cold->depth->png);
    EXPECT_EQ(dense_warm->tf->bytes, dense_cold->tf->bytes);
  }
  Frame unknown;
  unknown.serial = "99999999";
  unknown.image = rig->raw[0].View();
  const Status s = (*warmed)->Warm(unknown, false);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("99999999"), std::string::npos) << s.error().message;
}

// The depth lane renders the TF image of every s-th TF pixel for its
// preview (TfImageStepForPreview): the preview has the size and names the
// source the whole image's preview has, and differs from it by the
// sampling alone (the rendered pixels are the whole image's, byte for
// byte: FrameChain.TfImageStepRendersTheWholeImagesPixelsAtItsPoints); the
// published depth is the same. Process (the block pipeline, whose
// localizer reads the TF image) renders it whole.
// The two JPEG previews against each other: 34.2 dB on this rig (85 x 64
// px, largest difference 29 DN); on `r32` 40.5 dB (docs/processing.md).
constexpr double kPreviewStepPsnrDb = 30.0;
TEST(Pipeline, DepthLaneRendersTheTfImageItsPreviewReads) {
  EXPECT_EQ(TfImageStepForPreview(3280, 2474, 512), 2);  // R32
  EXPECT_EQ(TfImageStepForPreview(1640, 1237, 512), 1);  // medium
  EXPECT_EQ(TfImageStepForPreview(3071, 100, 512), 1);
  EXPECT_EQ(TfImageStepForPreview(100, 3072, 512), 2);
  EXPECT_EQ(TfImageStepForPreview(100000, 100, 512), 16);
  EXPECT_EQ(TfImageStepForPreview(3280, 2474, 0), 1);
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  OwnedImage& raw = rig->raw[0];
  const int tw = raw.width / 2, th = raw.height / 2;
  PreviewOptions preview;
  preview.max_side = std::max(tw, th) / 6;  // step 2
  ASSERT_EQ(TfImageStepForPreview(tw, th, preview.max_side), 2);
  auto processor = DepthProcessor::ForSequence(rig->sequence_dir.string(), rig->serials, preview);
  ASSERT_TRUE(processor.ok()) << processor.error().message;
  Frame frame;
  frame.serial = rig->serials[0];
  frame.image = raw.View();
  auto lenses = (*processor)->ProcessLenses(frame);
  ASSERT_TRUE(lenses.ok()) << lenses.error().message;
  auto dense = (*processor)->ProcessDense(frame, &*lenses);
  auto whole = (*processor)->Process(frame);
  ASSERT_TRUE(dense.ok() && whole.ok());
  ASSERT_TRUE(dense->products && whole->products && dense->tf && whole->tf);
  EXPECT_EQ(dense->products->tf.width, (tw + 1) / 2);
  EXPECT_EQ(dense->products->tf.height, (th + 1) / 2);
  EXPECT_EQ(whole->products->tf.width, tw);
  EXPECT_EQ(whole->products->tf.height, th);
  ASSERT_TRUE(dense->depth && whole->depth);
  EXPECT_EQ(dense->depth->png, whole->depth->png);
  const EncodedImage& a = *dense->tf;
  const EncodedImage& b = *whole->tf;
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.source_width, tw);
  EXPECT_EQ(a.source_height, th);
  EXPECT_EQ(b.source_width, tw);
  EXPECT_EQ(b.source_height, th);
  const cv::Mat da = cv::imdecode(a.bytes, cv::IMREAD_UNCHANGED);
  const cv::Mat db = cv::imdecode(b.bytes, cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(da.empty() || db.empty());
  ASSERT_EQ(da.size(), db.size());
  ASSERT_EQ(da.type(), db.type());
  cv::Mat diff;
  cv::absdiff(da, db, diff);
  const double rms = std::sqrt(cv::mean(diff.mul(diff))[0]);
  double largest = 0;
  cv::minMaxLoc(diff.reshape(1), nullptr, &largest);
  const double psnr = rms > 0 ? 20 * std::log10(255 / rms) : 99.0;
  std::printf("TF preview %dx%d of every 2nd TF pixel against the whole image's: RMS %.2f DN "
              "(PSNR %.2f dB), largest %.0f DN\n",
              a.width, a.height, rms, psnr, largest);
  EXPECT_GE(psnr, kPreviewStepPsnrDb);
}

// DepthProcessor::WarmWithoutFrames (what `record --publish` does before its
// cameras start, no frame yet): a camera with a white image gets its
// per-lens estimator and TF sampler for frames of the white image's size,
// and its products are those of a processor left to the first frame; a
// camera without one (its vignetting estimated from a frame's pixels) is
// left to its first frame and named.
TEST(Pipeline, WarmWithoutFramesMakesTheWhiteImageCamerasSetUpAndChangesNoProduct) {
  test::TempDir dir;
  auto rig = WriteTinyRigFrames(dir.path());
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  ASSERT_EQ(rig->serials.size(), 2u);
  auto setups = LoadSequenceCameras(rig->sequence_dir.string(), rig->serials, {});
  ASSERT_TRUE(setups.ok()) << setups.error().message;
  ASSERT_TRUE((*setups)[0].white && (*setups)[1].white);
  (*setups)[1].white.reset();
  auto chain = processing::ProcessingChain::Create(std::move(*setups), processing::ChainOptions{});
  ASSERT_TRUE(chain.ok()) << chain.error().message;
  DepthProcessor warmed(std::move(*chain), PreviewOptions{}, PixelFormats{});
  auto cold = DepthProcessor::ForSequence(rig->sequence_dir.string(), rig->serials);
  ASSERT_TRUE(cold.ok());
  const int width = rig->raw[0].width, height = rig->raw[0].height;
  processing::CameraChain* with_white = warmed.chain().Find(rig->serials[0]);
  processing::CameraChain* without = warmed.chain().Find(rig->serials[1]);
  ASSERT_TRUE(with_white != nullptr && without != nullptr);
  EXPECT_FALSE(with_white->Prepared(width, height, /*sampler=*/false));
  auto left = warmed.WarmWithoutFrames(/*sampler=*/true);
  ASSERT_TRUE(left.ok()) << left.error().message;
  EXPECT_EQ(*left, std::vector<std::string>{rig->serials[1]});
  EXPECT_TRUE(with_white->Prepared(width, height, /*sampler=*/true));
  EXPECT_FALSE(without->Prepared(width, height, /*sampler=*/false));
  // The first frame of the warmed camera: the same per-lens depth and preview
  // as a processor that builds its estimator from that frame.
  Frame frame;
  frame.serial = rig->serials[0];
  frame.image = rig->raw[0].View();
  auto a = warmed.ProcessLenses(frame);
  auto b = (*cold)->ProcessLenses(frame);
  ExpectSameLensProducts(a, b);
  // The TF sampler made without a frame is the one the registration gets.
  auto sampler = with_white->Sampler(frame.image);
  ASSERT_TRUE(sampler.ok());
  EXPECT_TRUE(with_white->Prepared(width, height, /*sampler=*/true));
}

// Covariance of c0_from_cx to first order: with A = exp(a) A_hat, B =
// exp(b) B_hat, a sampled check against the composition itself.
TEST(Pipeline, ComposedExtrinsicsCarryTheirCovariance) {
  processing::CameraPose c0, cx;
  c0.transform = KnownPoseStage::W0FromC(1);
  cx.transform = KnownPoseStage::W0FromC(3);
  c0.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 1e-4;
  cx.covariance = Eigen::Matrix<double, 6, 6>::Identity() * 4e-4;
  const processing::CameraPose out = processing::ComposeExtrinsics(c0, cx);
  EXPECT_TRUE(out.transform.isApprox(c0.transform.inverse() * cx.transform, 1e-12));
  // The rotation block is R (Sigma_a + Sigma_b)_rr R^T, R = rotation of
  // c0_from_w0: isotropic stays isotropic. The translation block adds the
  // rotation's lever arm: [t]x R Sigma_rr R^T [t]x^T on top of R Sigma_tt R^T.
  const Eigen::Matrix3d rr = out.covariance.bottomRightCorner<3, 3>();
  EXPECT_TRUE(rr.isApprox(5e-4 * Eigen::Matrix3d::Identity(), 1e-9)) << rr;
  const Eigen::Vector3d t = c0.transform.inverse().translation();
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  const Eigen::Matrix3d tt = out.covariance.topLeftCorner<3, 3>();
  EXPECT_TRUE(tt.isApprox(5e-4 * Eigen::Matrix3d::Identity() + 5e-4 * tx * tx.transpose(), 1e-9))
      << tt;
  EXPECT_TRUE(out.covariance.isApprox(out.covariance.transpose(), 1e-12));
  // Unknown covariance on either side: unknown.
  c0.covariance.setZero();
  EXPECT_TRUE(processing::ComposeExtrinsics(c0, cx).covariance.isZero(0));
}

// Record and replay share the grab loop: RigController drives replay
// cameras as fast as the pipeline takes frames (back-pressure, as
// RunReplay runs them) with the recorder beside the pipeline (as `record
// --publish` runs it): every frame is on disk and every frame is published.
TEST(Pipeline, RecordAndReplayShareTheGrabLoopEveryFrameRecordedAndPublished) {
  test::TempDir dir;
  const int frames = 3;
  auto summary = synth::WriteSyntheticDataset(dir / "synth", TinyRig(frames));
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const auto sequence = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(sequence.ok());
  RigConfig rig;
  rig.name = "shared";
  std::vector<std::unique_ptr<Camera>> cameras;
  std::vector<const ReplayCamera*> replay;
  FrameSetAssemblerOptions sync;
  sync.vicon_expected = false;
  sync.trigger.counter_bits = 64;
  sync.trigger.counter_skips_zero = false;
  sync.lateness_ns = 3'600'000'000'000;  // as RunReplay at --rate max
  const std::int64_t clock_start = NowNsForTest();
  for (std::size_t i = 0; i < sequence->cameras.size(); ++i) {
    CameraConfig camera;
    camera.serial = sequence->cameras[i].serial;
    camera.name = "cam" + std::to_string(i);
    camera.driver.kind = DriverKind::kReplay;
    camera.mla_file = layout::MlaXmlPath(summary->calibration_dir, camera.serial);
    rig.cameras.push_back(camera);
    sync.serials.push_back(camera.serial);
    ReplayCameraOptions options;
    options.camera_index = static_cast<int>(i);
    options.pacing = ReplayPacing::kAsFastAsPossible;
    options.pool_buffers = 4;
    options.sequence_clock_start_ns = clock_start;
    auto replay_camera = std::make_unique<ReplayCamera>(sequence->cameras[i].dir, options);
    replay.push_back(replay_camera.get());
    cameras.push_back(std::move(replay_camera));
  }
  rig.vicon.source = ViconSourceKind::kNone;
  RecorderOptions recorder_options;
  recorder_options.root_dir = dir / "rec";
  recorder_options.direct_io = false;
  auto recorder = Recorder::Create(rig, recorder_options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;

  lcm::LCM bus("memq://");
  Received received;
  bus.subscribe("LIFMCR_.*", &Received::OnAny, &received);
  PipelineOptions pipeline_options;
  pipeline_options.publisher.bus = &bus;
  pipeline_options.skip_when_busy = false;
  auto pipeline = Pipeline::Create(sync, std::make_unique<PreviewProcessor>(), pipeline_options);
  ASSERT_TRUE(pipeline.ok()) << pipeline.error().message;
  Pipeline* p = pipeline->get();
  // One assembler: the controller's FrameSets feed the pipeline.
  RigObserver observer;
  observer.on_frame_set = [p](const FrameSet& set) { p->AddFrameSet(set); };
  RigControllerOptions controller_options;
  controller_options.sync = sync;
  controller_options.trigger_hz = 0;
  controller_options.drain = std::chrono::milliseconds(0);
  RigController controller(std::move(cameras), {false, false}, nullptr, recorder->get(),
                           controller_options, observer);
  ASSERT_TRUE(controller.Start().ok());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!controller.CamerasFinished() && std::chrono::steady_clock::now() < deadline) {
    p->Poll();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_TRUE(controller.CamerasFinished());
  controller.Stop();
  (*recorder)->Stop();
  const RigHealth health = controller.Health();
  p->SetSyncDrops(health.sync_drops);
  p->Finish();
  Drain(bus);
  EXPECT_EQ(health.frame_sets, static_cast<std::uint64_t>(frames));
  EXPECT_FALSE(health.FramesLost() > 0) << health.FinalReport();
  for (const CameraHealth& camera : health.cameras)
    EXPECT_EQ(camera.recorder.written, static_cast<std::uint64_t>(frames)) << health.FinalReport();
  const PipelineReport r = p->Report();
  EXPECT_EQ(r.processed, 2u * frames) << r.FinalReport();
  EXPECT_EQ(r.skipped, 0u);
  EXPECT_EQ(r.frame_sets, static_cast<std::uint64_t>(frames));
  EXPECT_EQ(r.sync_lost, 0u) << r.drops;
  for (const auto& camera : sequence->cameras) {
    EXPECT_EQ(received.count[CameraChannel(camera.serial, "PREVIEW")], frames) << camera.serial;
    for (std::int64_t f : camera.frames) {
      // The recording's file number is the trigger_index on LCM.
      EXPECT_TRUE(std::filesystem::exists(layout::RawFramePath(
          (*recorder)->sequence_dir(), camera.serial, f)))
          << camera.serial << " " << f;
      EXPECT_EQ(received.preview_trigger[camera.serial][f], f) << camera.serial;
    }
  }
  for (const ReplayCamera* camera : replay) EXPECT_EQ(camera->Stats().underruns, 0u);
}

// A bad value in the options the grab loop and replay take is an error
// naming the field, returned where they are taken (Start, RunReplay).
TEST(Pipeline, BadGrabLoopAndReplayOptionsNameTheirField) {
  RigControllerOptions controller_options;
  controller_options.frame_timeout = std::chrono::milliseconds(0);
  RigController controller({}, {}, nullptr, nullptr, controller_options);
  const Status started = controller.Start();
  ASSERT_FALSE(started.ok());
  EXPECT_NE(started.error().message.find("frame_timeout"), std::string::npos)
      << started.error().message;
  controller_options = RigControllerOptions{};
  controller_options.vicon_lead_triggers = 1;  // without sync: no Vicon frames per trigger
  EXPECT_NE(controller_options.Check().error().message.find("vicon_lead_triggers: needs sync"),
            std::string::npos);
  controller_options = RigControllerOptions{};
  controller_options.number_files_by_sync = true;  // without sync
  EXPECT_NE(controller_options.Check().error().message.find("number_files_by_sync"),
            std::string::npos);

  ReplayRunOptions replay;
  replay.sequence_dir = "/nonexistent";
  replay.pool_buffers = -1;
  auto result = RunReplay(replay);
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.error().message.find("pool_buffers"), std::string::npos)
      << result.error().message;
  replay.pool_buffers = 8;
  replay.preview.max_side = 4;
  EXPECT_NE(replay.Check().error().message.find("max_side"), std::string::npos);
  replay.preview = PreviewOptions{};
  replay.pipeline.max_concurrency = 0;
  EXPECT_NE(replay.Check().error().message.find("max_concurrency"), std::string::npos);
}

TEST(Pipeline, RateParsing) {
  EXPECT_EQ(ReplayRate::Parse("original")->kind, ReplayRate::Kind::kOriginal);
  EXPECT_EQ(ReplayRate::Parse("max")->kind, ReplayRate::Kind::kMax);
  EXPECT_DOUBLE_EQ(ReplayRate::Parse("2.5")->factor, 2.5);
  EXPECT_FALSE(ReplayRate::Parse("fast").ok());
  EXPECT_FALSE(ReplayRate::Parse("0").ok());
  EXPECT_FALSE(ReplayRate::Parse("-1").ok());
}

// A Bayer camera (rig file pixel_format: BayerRG8): its mosaic frames are
// demosaiced before the preview and the chain, so the preview and the TF
// image go out in colour; without the pixel format they stay grey.
TEST(Pipeline, BayerCameraIsPublishedInColour) {
  test::TempDir dir;
  auto params = synth::MakePreset("small");
  ASSERT_TRUE(params.ok());
  params->camera.bayer = true;
  params->rig.frames = 1;
  params->rig.cameras = 1;
  auto summary = synth::WriteSyntheticDataset(dir / "data", *params);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  auto layout = DiscoverSequence(summary->sequence_dir);
  ASSERT_TRUE(layout.ok());
  const CameraFolder& folder = layout->cameras.at(0);
  auto image = ReadBmp(*folder.FramePath(folder.frames.at(0)));
  ASSERT_TRUE(image.ok());
  ASSERT_EQ(image->format, PixelFormat::kMono8);
  Frame frame;
  frame.serial = folder.serial;
  frame.image = image->View();
  for (const bool bayer : {false, true}) {
    PixelFormats formats;
    if (bayer) formats[folder.serial] = CameraPixelFormat::kBayerRg8;
    auto processor = DepthProcessor::ForSequence(summary->sequence_dir.string(), {folder.serial},
                                                 PreviewOptions{}, formats);
    ASSERT_TRUE(processor.ok()) << processor.error().message;
    auto out = (*processor)->Process(frame);
    ASSERT_TRUE(out.ok()) << out.error().message;
    ASSERT_TRUE(out->preview && out->tf && out->depth);
    EXPECT_EQ(out->preview->channels, bayer ? 3 : 1);
    EXPECT_EQ(out->tf->channels, bayer ? 3 : 1);
    EXPECT_EQ(out->demosaiced != nullptr, bayer);
    EXPECT_GT(out->depth->valid_fraction, 0.2f);
    // The lanes hand a Bayer frame to the lens lane with the registration's
    // demosaiced copy (once localised); any other frame as it is taken.
    auto input = (*processor)->ForRegistration(frame);
    ASSERT_TRUE(input.ok()) << input.error().message;
    EXPECT_EQ((*processor)->SharesRegistrationImage(frame), bayer);
    EXPECT_EQ(input->demosaiced != nullptr, bayer);
    std::printf("%s: depth valid on %.1f %% of the published map\n",
                bayer ? "demosaiced" : "mosaic as grey", 100.0 * out->depth->valid_fraction);
  }
  auto preview_only =
      PreviewProcessor(PreviewOptions{}, {{folder.serial, CameraPixelFormat::kBayerRg8}})
          .Process(frame);
  ASSERT_TRUE(preview_only.ok());
  EXPECT_EQ(preview_only->preview->channels, 3);
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
