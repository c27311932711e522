// The recorder and the rig controller with real threads, real files and a
// real Vicon UDP stream on loopback: what is recorded reads back through the
// dataset layer, and every trigger is either on disk or counted as lost.
#include "acquisition/memory_camera.h"
#include "acquisition/recorder.h"
#include "acquisition/rig_controller.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "tests/acquisition/rig_fixture.h"
#include "tests/cpu_hogs.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <optional>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

std::unique_ptr<MemoryCamera> MakeCamera(const std::string& serial, PixelFormat format, int width,
                                         int height, int pool = 8) {
  MemoryCameraOptions options;
  options.serial = serial;
  options.format = format;
  options.width = width;
  options.height = height;
  options.pool_frames = pool;
  return std::make_unique<MemoryCamera>(options);
}

// Every frame file of the sequence is a valid BMP of the camera's size.
void ExpectEveryFrameReads(const SequenceLayout& sequence) {
  for (const CameraFolder& camera : sequence.cameras) {
    for (const std::string& file : camera.frame_files) {
      auto image = ReadBmp(camera.dir / file);
      ASSERT_TRUE(image.ok()) << image.error().message;
    }
  }
}

TEST(Recorder, TwoCamerasAndViconEveryTriggerAccountedFor) {
  test::TempDir out;
  RigConfig rig = test::TwoCameraRig();
  RecorderOptions options = RecorderOptions::FromRig(rig.recorder);
  options.root_dir = out.path();
  options.scene = "00_Test";
  options.sequence = "seq_a";
  auto recorder = Recorder::Create(rig, options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;

  std::vector<std::unique_ptr<Camera>> cameras;
  cameras.push_back(MakeCamera("MEMA", PixelFormat::kMono8, 64, 48));
  cameras.push_back(MakeCamera("MEMB", PixelFormat::kBgr8, 61, 40));
  auto vicon = std::make_unique<ViconUdpSource>(ViconUdpSourceOptions::FromRig(rig));
  ViconUdpSource* vicon_source = vicon.get();
  RigControllerOptions controller_options;
  controller_options.trigger_hz = 40.0;
  RigController controller(std::move(cameras), {true, true}, std::move(vicon), recorder->get(),
                           controller_options);
  ASSERT_TRUE(controller.Start().ok());
  test::ViconStreamer streamer(rig, vicon_source->BoundPort(), 320.0);
  ASSERT_TRUE(streamer.ok());
  std::this_thread::sleep_for(milliseconds(1000));
  controller.Stop();
  (*recorder)->Stop();
  const RigHealth health = controller.Health();
  SCOPED_TRACE(health.FinalReport());

  ASSERT_GE(health.triggers_fired, 30u);
  ASSERT_EQ(health.cameras.size(), 2u);
  for (const CameraHealth& camera : health.cameras) {
    // Every trigger: on disk or counted.
    EXPECT_EQ(camera.recorder.written + camera.Lost(), camera.triggers) << camera.serial;
    EXPECT_EQ(camera.Lost(), 0u) << camera.serial;
  }
  EXPECT_FALSE(health.AnythingLost());
  EXPECT_GT(health.recorder.vicon_written, 200u);
  EXPECT_EQ(health.recorder.vicon_written, health.vicon.frames);

  const fs::path seq = out.path() / "00_Test" / "seq_a";
  auto sequence = DiscoverSequence(seq);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  ASSERT_EQ(sequence->cameras.size(), 2u);
  for (std::size_t c = 0; c < 2; ++c) {
    const CameraFolder& folder = sequence->cameras[c];
    const CameraHealth& camera = health.cameras[folder.serial == "MEMA" ? 0 : 1];
    EXPECT_EQ(folder.frames.size(), camera.recorder.written);
    EXPECT_EQ(folder.missing_count, 0);
    EXPECT_EQ(folder.frames.front(), 0);
  }
  ExpectEveryFrameReads(*sequence);
  auto first = ReadBmp(layout::RawFramePath(seq, "MEMB", 0));
  ASSERT_TRUE(first.ok());
  EXPECT_EQ(first->format, PixelFormat::kBgr8);
  EXPECT_EQ(first->width, 61);

  auto csv = ReadViconCsv(layout::ViconCsvPath(seq, 1));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_EQ(csv->blocks.at(0).num_rows(), health.recorder.vicon_written);
  auto cam1 = ExtractSubjectPoses(*csv, "cam1");
  ASSERT_TRUE(cam1.ok()) << cam1.error().message;
  for (const ViconPoseSample& sample : *cam1) {
    ASSERT_TRUE(sample.vicon_from_marker.has_value());
    EXPECT_NEAR(sample.vicon_from_marker->translation().x(),
                static_cast<double>(sample.vicon_frame), 1e-9);
  }
  auto calibration = DiscoverCalibration(out.path() / "Calibration");
  ASSERT_TRUE(calibration.ok()) << calibration.error().message;
  EXPECT_EQ(calibration->mla_xml.size(), 2u);
  EXPECT_TRUE(calibration->mla_xml.count("MEMA"));

  // The same folder again is refused: a recording never overwrites one.
  auto again = Recorder::Create(rig, options);
  ASSERT_FALSE(again.ok());
  EXPECT_NE(again.error().message.find("seq_a"), std::string::npos);
}

// The same through the sync assembler: files are numbered by trigger, every
// trigger is one FrameSet, and each camera's frame of it is on disk or counted.
TEST(Recorder, ThroughSyncEveryTriggerIsOneFrameSetOnDiskOrCounted) {
  test::TempDir out;
  RigConfig rig = test::TwoCameraRig();  // 80 Hz Vicon, a trigger every 8th frame: 10 Hz
  RecorderOptions options;
  options.root_dir = out.path();
  auto recorder = Recorder::Create(rig, options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;
  std::vector<std::unique_ptr<Camera>> cameras;
  cameras.push_back(MakeCamera("MEMA", PixelFormat::kMono8, 64, 48));
  cameras.push_back(MakeCamera("MEMB", PixelFormat::kBgr8, 64, 48));
  auto vicon = std::make_unique<ViconUdpSource>(ViconUdpSourceOptions::FromRig(rig));
  ViconUdpSource* vicon_source = vicon.get();
  RigControllerOptions controller_options;
  controller_options.trigger_hz = rig.vicon.rate_hz / rig.vicon.trigger_divider;
  controller_options.sync = FrameSetAssemblerOptions::FromRig(rig);
  controller_options.number_files_by_sync = true;
  RigController controller(std::move(cameras), {true, true}, std::move(vicon), recorder->get(),
                           controller_options);
  ASSERT_TRUE(controller.Start().ok());
  test::ViconStreamer streamer(rig, vicon_source->BoundPort(), rig.vicon.rate_hz);
  std::this_thread::sleep_for(milliseconds(2000));
  controller.Stop();
  (*recorder)->Stop();
  const RigHealth health = controller.Health();
  SCOPED_TRACE(health.FinalReport());
  ASSERT_TRUE(health.has_sync);
  EXPECT_GE(health.frame_sets, 15u);
  EXPECT_GE(health.frame_sets + 1, health.triggers_fired);
  EXPECT_TRUE(health.vicon_f0.has_value());
  EXPECT_GE(health.complete_frame_sets + 1, health.frame_sets);
  ASSERT_EQ(health.sync_cameras.size(), 2u);
  for (std::size_t c = 0; c < 2; ++c) {
    const CameraSyncStats& sync = health.sync_cameras[c];
    const RecorderCameraStats& disk = health.recorder.cameras[c];
    EXPECT_EQ(disk.written + disk.lost() + sync.missed_triggers + sync.failed, health.frame_sets)
        << sync.serial;
    EXPECT_EQ(disk.written, sync.in_sets - sync.failed);
  }
  auto sequence = DiscoverSequence((*recorder)->sequence_dir());
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  for (const CameraFolder& folder : sequence->cameras) {
    EXPECT_EQ(folder.frames.front(), 0) << folder.serial;
    EXPECT_EQ(folder.missing_count, 0) << folder.serial;
  }
  ExpectEveryFrameReads(*sequence);
}

// Two memory cameras, MEMA and MEMB (32x32 Mono8), and a recorder writing
// into a fresh folder, for a rig without Vicon: the placement tests' rig.
struct TwoMemoryCameraRig {
  TwoMemoryCameraRig() {
    rig.vicon.source = ViconSourceKind::kNone;
    RecorderOptions options;
    options.root_dir = out.path();
    auto created = Recorder::Create(rig, options);
    EXPECT_TRUE(created.ok()) << created.error().message;
    if (created.ok()) recorder = std::move(*created);
    auto a = MakeCamera("MEMA", PixelFormat::kMono8, 32, 32);
    auto b = MakeCamera("MEMB", PixelFormat::kMono8, 32, 32);
    camera_a = a.get();
    camera_b = b.get();
    cameras.push_back(std::move(a));
    cameras.push_back(std::move(b));
  }
  test::TempDir out;
  RigConfig rig = test::TwoCameraRig();
  std::unique_ptr<Recorder> recorder;
  std::vector<std::unique_ptr<Camera>> cameras;  // moved into the controller
  MemoryCamera* camera_a = nullptr;
  MemoryCamera* camera_b = nullptr;
};

// A camera whose first frame comes three triggers after the rig's first
// (armed later on a running trigger) starts at frame 3, not 0, and the three
// triggers it missed are counted. Here the two cameras' device clocks are
// declared apart, so host time places it (the fallback).
TEST(Recorder, ALateCameraIsPlacedOnTheRigsTriggerCountByHostTime) {
  TwoMemoryCameraRig setup;
  ASSERT_TRUE(setup.recorder != nullptr);
  MemoryCamera* late_camera = setup.camera_b;
  RigControllerOptions controller_options;
  controller_options.trigger_hz = 5.0;  // 200 ms: host-time jitter is far below half a period
  controller_options.device_clocks = {"clock of A", "clock of B"};
  // Only A is triggered by the controller; the test triggers B from the 4th trigger on.
  RigController controller(std::move(setup.cameras), {true, false}, nullptr, setup.recorder.get(),
                           controller_options);
  ASSERT_TRUE(controller.Start().ok());
  // Timed from the controller's schedule, not from Start's return: on a
  // loaded host Start returns tens of milliseconds after it (its trigger
  // threads take its CPU as it wakes them).
  ASSERT_TRUE(controller.ScheduleStart().has_value());
  const auto start = *controller.ScheduleStart();
  for (int k = 3; k < 8; ++k) {
    // 20 ms after the controller's k-th trigger: a frame arrives after its trigger.
    std::this_thread::sleep_until(start + milliseconds(200 * k + 20));
    ASSERT_TRUE(late_camera->SoftwareTrigger().ok());
  }
  std::this_thread::sleep_until(start + milliseconds(200 * 8 - 50));
  controller.Stop();
  setup.recorder->Stop();
  const RigHealth health = controller.Health();
  SCOPED_TRACE(health.FinalReport());
  const RecorderCameraStats& b = health.recorder.cameras[1];
  EXPECT_EQ(b.written, 5u);
  EXPECT_EQ(b.first_frame, 3);
  EXPECT_EQ(b.last_frame, 7);
  EXPECT_EQ(health.cameras[1].missing_by_id, 3u);
  EXPECT_EQ(health.recorder.cameras[0].first_frame, 0);
  EXPECT_EQ(health.cameras[1].first_placement,
            "trigger 3 by host time (no camera on its device clock \"clock of B\" placed yet)");
}

// A hardware-triggered rig has no software-trigger schedule: the rig's first
// frame is trigger 0 however long after Start the trigger line begins (the
// schedule a controller with trigger_hz set would otherwise assume put it
// on trigger 3 here).
TEST(Recorder, AHardwareTriggeredRigCountsFromItsFirstFrameNotFromStart) {
  TwoMemoryCameraRig setup;
  ASSERT_TRUE(setup.recorder != nullptr);
  MemoryCamera* cameras_on_the_line[2] = {setup.camera_a, setup.camera_b};
  RigControllerOptions controller_options;
  controller_options.trigger_hz = 10.0;  // the rig's rate; the line is not ours to fire
  controller_options.device_clocks = {"clock of A", "clock of B"};  // host time places both
  RigController controller(std::move(setup.cameras), {false, false}, nullptr, setup.recorder.get(),
                           controller_options);
  const auto start = std::chrono::steady_clock::now();
  ASSERT_TRUE(controller.Start().ok());
  for (int k = 0; k < 4; ++k) {
    std::this_thread::sleep_until(start + milliseconds(350 + 100 * k));
    for (MemoryCamera* camera : cameras_on_the_line) ASSERT_TRUE(camera->SoftwareTrigger().ok());
  }
  std::this_thread::sleep_until(start + milliseconds(350 + 400));
  controller.Stop();
  setup.recorder->Stop();
  const RigHealth health = controller.Health();
  SCOPED_TRACE(health.FinalReport());
  EXPECT_EQ(health.triggers_fired, 0u);
  for (int c = 0; c < 2; ++c) {
    EXPECT_EQ(health.recorder.cameras[c].written, 4u);
    EXPECT_EQ(health.recorder.cameras[c].first_frame, 0);
    EXPECT_EQ(health.recorder.cameras[c].last_frame, 3);
  }
}

// The same on one device clock (memory cameras stamp CLOCK_REALTIME at the
// trigger), at the rig's 10 Hz, with two busy threads taking both cores:
// the late camera's first frame is placed by device time against the
// other camera's frame of that trigger (the controller's own placement,
// without sync), and says so. (With the sync assembler the memory cameras'
// software triggers, fired late by the hogs, move their device times off
// the grid themselves; the assembler's placement under hogs is shown on
// exact device times by RecordPublish.FirstFramesPlacedByDeviceTimeUnderTwoCpuHogs.)
TEST(Recorder, ALateCameraOnTheSameClockIsPlacedByDeviceTimeUnderTwoCpuHogs) {
  TwoMemoryCameraRig setup;
  ASSERT_TRUE(setup.recorder != nullptr);
  MemoryCamera* late_camera = setup.camera_b;
  RigControllerOptions controller_options;
  controller_options.trigger_hz = 10.0;
  test::CpuHogs hogs(2);
  RigController controller(std::move(setup.cameras), {true, false}, nullptr, setup.recorder.get(),
                           controller_options);
  ASSERT_TRUE(controller.Start().ok());
  // Timed from the controller's schedule (Start returns after it, later
  // still beside the hogs).
  ASSERT_TRUE(controller.ScheduleStart().has_value());
  const auto start = *controller.ScheduleStart();
  for (int k = 3; k < 8; ++k) {
    // On the controller's k-th trigger, as a shared trigger line would.
    std::this_thread::sleep_until(start + milliseconds(100 * k));
    ASSERT_TRUE(late_camera->SoftwareTrigger().ok());
  }
  std::this_thread::sleep_until(start + milliseconds(100 * 8 - 50));
  controller.Stop();
  setup.recorder->Stop();
  const RigHealth health = controller.Health();
  SCOPED_TRACE(health.FinalReport());
  const RecorderCameraStats& b = health.recorder.cameras[1];
  EXPECT_EQ(b.written, 5u);
  EXPECT_EQ(b.first_frame, 3);
  EXPECT_EQ(b.last_frame, 7);
  EXPECT_EQ(health.recorder.cameras[0].first_frame, 0);
  EXPECT_EQ(health.cameras[1].first_placement.rfind("trigger 3 by device time against camera 0", 0),
            0u)
      << health.cameras[1].first_placement;
}

TEST(Recorder, ViconStreamStopsFramesStillRecorded) {
  test::TempDir out;
  RigConfig rig = test::TwoCameraRig();
  RecorderOptions options;
  options.root_dir = out.path();
  auto recorder = Recorder::Create(rig, options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;
  std::vector<std::unique_ptr<Camera>> cameras;
  cameras.push_back(MakeCamera("MEMA", PixelFormat::kMono8, 32, 32));
  cameras.push_back(MakeCamera("MEMB", PixelFormat::kMono8, 32, 32));
  auto vicon = std::make_unique<ViconUdpSource>(ViconUdpSourceOptions::FromRig(rig));
  ViconUdpSource* vicon_source = vicon.get();
  RigControllerOptions controller_options;
  controller_options.trigger_hz = 50.0;
  RigController controller(std::move(cameras), {true, true}, std::move(vicon), recorder->get(),
                           controller_options);
  ASSERT_TRUE(controller.Start().ok());
  test::ViconStreamer streamer(rig, vicon_source->BoundPort(), 200.0);
  std::this_thread::sleep_for(milliseconds(300));
  streamer.Pause(true);  // the Vicon keeps counting, nothing arrives
  std::this_thread::sleep_for(milliseconds(300));
  const std::uint64_t written_during_pause_start = (*recorder)->Stats().vicon_written;
  std::this_thread::sleep_for(milliseconds(200));
  streamer.Pause(false);
  std::this_thread::sleep_for(milliseconds(300));
  controller.Stop();
  (*recorder)->Stop();
  const RigHealth health = controller.Health();
  SCOPED_TRACE(health.FinalReport());
  for (const CameraHealth& camera : health.cameras) {
    EXPECT_EQ(camera.Lost(), 0u);
    EXPECT_EQ(camera.recorder.written, health.triggers_fired);
  }
  EXPECT_GT(written_during_pause_start, 0u);
  // The frames the Vicon counted while the stream was silent are a reported gap.
  EXPECT_GT(health.vicon.gaps, 0u);
  EXPECT_TRUE(health.AnythingLost());
  auto csv = ReadViconCsv(layout::ViconCsvPath((*recorder)->sequence_dir(), 1));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_EQ(csv->blocks.at(0).num_rows(), health.recorder.vicon_written);
}

// Small frames go through the page cache, frames of direct_io_min_bytes and
// more with O_DIRECT (recorder.h says why): a 5 KiB O_DIRECT file took up to
// 880 ms on this machine's virtual disk, which a pool of 8 at 50 Hz (160 ms)
// cannot wait out (Recorder.ViconStreamStopsFramesStillRecorded lost frames).
TEST(Recorder, SmallFramesGoThroughThePageCacheLargeOnesWithODirect) {
  test::TempDir out;
  RigConfig rig = test::TwoCameraRig();
  rig.vicon.source = ViconSourceKind::kNone;
  RecorderOptions options;
  options.root_dir = out.path();
  options.direct_io_min_bytes = 1 << 20;
  auto recorder = Recorder::Create(rig, options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;
  auto small = MakeCamera("MEMA", PixelFormat::kMono8, 64, 48);    // 3 KiB
  auto large = MakeCamera("MEMB", PixelFormat::kMono8, 1024, 1024);  // 1 MiB: not under it
  for (MemoryCamera* camera : {small.get(), large.get()}) {
    ASSERT_TRUE(camera->Open().ok());
    ASSERT_TRUE(camera->Start().ok());
  }
  constexpr int kFrames = 3;
  for (int i = 0; i < kFrames; ++i) {
    for (int c = 0; c < 2; ++c) {
      MemoryCamera* camera = c == 0 ? small.get() : large.get();
      ASSERT_TRUE(camera->SoftwareTrigger().ok());
      auto frame = camera->NextFrame(milliseconds(1000));
      ASSERT_TRUE(frame.ok() && frame->has_value());
      ASSERT_TRUE((*recorder)->SubmitFrame(c, i, std::move(**frame)));
    }
  }
  (*recorder)->Stop();
  const RecorderStats stats = (*recorder)->Stats();
  SCOPED_TRACE(stats.OneLine());
  EXPECT_EQ(stats.FramesWritten(), 2u * kFrames);
  EXPECT_EQ(stats.small_buffered_files, static_cast<std::uint64_t>(kFrames));
  // The large frames: O_DIRECT, or buffered where this file system refuses it.
  EXPECT_EQ(stats.direct_files + (stats.buffered_files - stats.small_buffered_files),
            static_cast<std::uint64_t>(kFrames));
  if (stats.direct_files == 0)
    std::printf("O_DIRECT refused by the file system of %s\n", out.path().c_str());
  auto sequence = DiscoverSequence((*recorder)->sequence_dir());
  ASSERT_TRUE(sequence.ok());
  for (const auto& camera : sequence->cameras) EXPECT_EQ(camera.frames.size(), 3u);
  ExpectEveryFrameReads(*sequence);

  RecorderOptions bad = options;
  bad.direct_io_min_bytes = -1;
  const Status checked = bad.Check();
  ASSERT_FALSE(checked.ok());
  EXPECT_NE(checked.error().message.find("direct_io_min_bytes"), std::string::npos);
}

TEST(Recorder, QueueFullDropsAreCountedAndNeverBlock) {
  test::TempDir out;
  RigConfig rig = test::TwoCameraRig();
  rig.cameras.resize(1);
  rig.vicon.source = ViconSourceKind::kNone;
  RecorderOptions options;
  options.root_dir = out.path();
  options.queue_frames = 2;
  options.direct_io = false;
  auto recorder = Recorder::Create(rig, options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;
  auto camera = MakeCamera("MEMA", PixelFormat::kMono8, 1024, 1024, 16);
  ASSERT_TRUE(camera->Open().ok());
  ASSERT_TRUE(camera->Start().ok());
  constexpr int kFrames = 200;
  std::uint64_t accepted = 0;
  auto slowest = std::chrono::nanoseconds(0);
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(camera->SoftwareTrigger().ok());
    auto frame = camera->NextFrame(milliseconds(1000));
    ASSERT_TRUE(frame.ok() && frame->has_value());
    const auto before = std::chrono::steady_clock::now();
    accepted += (*recorder)->SubmitFrame(0, i, std::move(**frame)) ? 1 : 0;
    slowest = std::max(slowest, std::chrono::steady_clock::now() - before);
  }
  (*recorder)->Stop();
  const RecorderStats stats = (*recorder)->Stats();
  SCOPED_TRACE(stats.OneLine());
  EXPECT_LT(accepted, static_cast<std::uint64_t>(kFrames));
  EXPECT_GT(stats.cameras[0].dropped_queue_full, 0u);
  EXPECT_EQ(stats.cameras[0].written, accepted);
  EXPECT_EQ(stats.cameras[0].written + stats.cameras[0].dropped_queue_full,
            static_cast<std::uint64_t>(kFrames));
  EXPECT_LE(stats.cameras[0].queue_high_water, 2u);
  // Drops above already show it never waits for the disk; this bounds scheduling noise.
  EXPECT_LT(slowest, milliseconds(200)) << "SubmitFrame waited on the disk";
  EXPECT_EQ(stats.buffered_files, stats.cameras[0].written);
  auto sequence = DiscoverSequence((*recorder)->sequence_dir());
  ASSERT_TRUE(sequence.ok());
  EXPECT_EQ(sequence->cameras.at(0).frames.size(), accepted);
  EXPECT_EQ(camera->Stats().underruns, 0u);
}

// A small tmpfs as the disk: the recording stops by itself when it is full,
// and what is on it reads back.
class SmallTmpfs {
 public:
  explicit SmallTmpfs(const fs::path& dir) : dir_(dir) {
    fs::create_directories(dir_);
    mounted_ = ::mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=1m") == 0;
  }
  ~SmallTmpfs() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }

 private:
  fs::path dir_;
  bool mounted_ = false;
};

TEST(Recorder, DiskFullStopsCleanlyWithValidFiles) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root: mounts a 1 MiB tmpfs";
  test::TempDir out;
  SmallTmpfs disk(out / "disk");
  if (!disk.mounted()) GTEST_SKIP() << "cannot mount tmpfs here: " << std::strerror(errno);
  RigConfig rig = test::TwoCameraRig();
  RecorderOptions options;
  options.root_dir = out / "disk";
  auto recorder = Recorder::Create(rig, options);
  ASSERT_TRUE(recorder.ok()) << recorder.error().message;
  auto a = MakeCamera("MEMA", PixelFormat::kMono8, 128, 100);  // 16.9 kB files
  auto b = MakeCamera("MEMB", PixelFormat::kMono8, 128, 100);
  for (auto* camera : {a.get(), b.get()}) {
    ASSERT_TRUE(camera->Open().ok());
    ASSERT_TRUE(camera->Start().ok());
  }
  int submitted = 0;
  for (int i = 0; i < 200 && !(*recorder)->failed(); ++i) {
    for (int c = 0; c < 2; ++c) {
      MemoryCamera* camera = c == 0 ? a.get() : b.get();
      // A writer starved of CPU can hold all 8 of a camera's buffers; the
      // camera then underruns (counted in its stats, as a real one would)
      // and the trigger is repeated once the writer gave a buffer back: this
      // test is about the full disk, not about the writer's speed.
      std::optional<Frame> frame;
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (!frame && std::chrono::steady_clock::now() < deadline) {
        ASSERT_TRUE(camera->SoftwareTrigger().ok());
        auto next = camera->NextFrame(milliseconds(1000));
        ASSERT_TRUE(next.ok()) << next.error().message;
        frame = std::move(*next);
        if (!frame) std::this_thread::sleep_for(milliseconds(5));
      }
      ASSERT_TRUE(frame.has_value()) << "no buffer came back from the writer within 5 s";
      (*recorder)->SubmitFrame(c, i, std::move(*frame));
      ++submitted;
    }
    ViconFrame vicon;
    vicon.vicon_frame = 1 + 8 * i;
    vicon.objects.push_back({"cam0", Pose::Identity()});
    (*recorder)->SubmitVicon(vicon);
    std::this_thread::sleep_for(milliseconds(2));  // let the writer keep up: no queue drops
  }
  (*recorder)->Stop();
  const RecorderStats stats = (*recorder)->Stats();
  SCOPED_TRACE(stats.OneLine());
  ASSERT_TRUE((*recorder)->failed());
  ASSERT_TRUE(stats.stop_reason.has_value());
  EXPECT_NE(stats.stop_reason->find("disk full"), std::string::npos) << *stats.stop_reason;
  EXPECT_GT(stats.FramesWritten(), 10u);
  EXPECT_GT(stats.FramesLost(), 0u);
  EXPECT_EQ(stats.FramesWritten() + stats.FramesLost(), static_cast<std::uint64_t>(submitted));
  auto sequence = DiscoverSequence((*recorder)->sequence_dir());
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  std::uint64_t on_disk = 0;
  for (const CameraFolder& camera : sequence->cameras) on_disk += camera.frames.size();
  EXPECT_EQ(on_disk, stats.FramesWritten());
  ExpectEveryFrameReads(*sequence);
  auto csv = ReadViconCsv(layout::ViconCsvPath((*recorder)->sequence_dir(), 1));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_EQ(csv->blocks.at(0).num_rows(), stats.vicon_written);
}

// A file-size limit (RLIMIT_FSIZE) in a child process: the Vicon CSV hits it
// first, the write fails with EFBIG, the recording stops, and the CSV is
// complete up to its last line.
TEST(Recorder, FileSizeLimitStopsCleanlyAndTheCsvEndsWithACompleteLine) {
  test::TempDir out;
  RigConfig rig = test::TwoCameraRig();
  rig.cameras.resize(1);
  RecorderOptions options;
  options.root_dir = out.path();
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{20000, 20000};
    setrlimit(RLIMIT_FSIZE, &limit);
    auto recorder = Recorder::Create(rig, options);
    if (!recorder.ok()) _exit(10);
    auto camera = MakeCamera("MEMA", PixelFormat::kMono8, 32, 32);
    if (!camera->Open().ok() || !camera->Start().ok()) _exit(11);
    for (int i = 0; i < 2000 && !(*recorder)->failed(); ++i) {
      if (i % 8 == 0) {
        (void)camera->SoftwareTrigger();
        auto frame = camera->NextFrame(milliseconds(1000));
        if (frame.ok() && frame->has_value())
          (*recorder)->SubmitFrame(0, i / 8, std::move(**frame));
      }
      ViconFrame vicon;
      vicon.vicon_frame = 1 + i;
      vicon.objects.push_back({"cam0", Pose::Identity()});
      (*recorder)->SubmitVicon(vicon);
      // Far faster than 80 Hz, yet slow enough that the writer keeps up.
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    }
    (*recorder)->Stop();
    const RecorderStats stats = (*recorder)->Stats();
    if (!stats.stop_reason || stats.stop_reason->find("disk full") == std::string::npos) _exit(12);
    if (stats.vicon_lost == 0) _exit(13);
    if (stats.FramesWritten() + stats.FramesLost() != camera->Stats().completed) _exit(14);
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0);
  const fs::path seq = out.path() / "00_Recording" / "seq";
  const std::string text = test::ReadFile(layout::ViconCsvPath(seq, 1));
  ASSERT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n');
  EXPECT_LE(text.size(), 20000u);
  auto csv = ReadViconCsv(layout::ViconCsvPath(seq, 1));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_GT(csv->blocks.at(0).num_rows(), 50u);
  auto sequence = DiscoverSequence(seq);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  EXPECT_GT(sequence->cameras.at(0).frames.size(), 5u);
  ExpectEveryFrameReads(*sequence);
}

}  // namespace
}  // namespace lifmcr
