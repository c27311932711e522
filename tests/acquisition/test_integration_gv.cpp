// Integration: two GigE Vision simulators (arv-fake-gv-camera-0.8) on
// loopback addresses of this test process's own (ProcessLoopbackAddress), acquired through
// the real Aravis driver, plus the Vicon UDP test sender; the rig controller
// with the sync assembler and the recorder write a real sequence, which is
// read back through the dataset layer. Faults: packet loss (-r), a simulator
// killed and restarted mid-recording. Needs root (loopback addresses).
#include "acquisition/recorder.h"
#include "acquisition/rig_controller.h"
#include "drivers/camera_factory.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/vicon_csv.h"
#include "tests/acquisition/rig_fixture.h"
#include "tests/drivers/gv_simulator.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <unistd.h>

namespace lifmcr {
namespace {

using std::chrono::milliseconds;

#define REQUIRE_ROOT() \
  if (geteuid() != 0) GTEST_SKIP() << "needs root: adds 127.1xx.x.x addresses to lo"

std::string UniqueSerial(const char* tag) {
  return std::string("REC") + tag + std::to_string(getpid() % 100000);
}

struct GvRig {
  GvRig(const std::string& address_a, const std::string& address_b, int loss_b_per_thousand)
      : loopback_a(address_a),
        loopback_b(address_b),
        serial_a(UniqueSerial("A")),
        serial_b(UniqueSerial("B")),
        simulator_a(address_a, serial_a),
        simulator_b(address_b, serial_b, loss_b_per_thousand) {
    rig = test::TwoCameraRig();
    // The simulator sends a triggered frame at its next 40 ms tick, 20-42 ms
    // after the trigger (the simulator's frame period), stamped on that tick: two
    // cameras' frames of one trigger can be 40 ms apart. At 80 Hz / 16 = 5 Hz
    // that is 0.2 trigger periods, inside the assembler's 0.25 grid
    // tolerance, also on a loaded machine; at 10 Hz it is 0.4 and frames fall
    // off the grid.
    rig.vicon.trigger_divider = 16;
    const std::string addresses[2] = {address_a, address_b};
    const std::string serials[2] = {serial_a, serial_b};
    for (int i = 0; i < 2; ++i) {
      CameraConfig& camera = rig.cameras[i];
      camera.serial = serials[i];
      camera.driver.kind = DriverKind::kAravis;
      camera.driver.address = addresses[i];
      camera.exposure_us = 1000.0;
      camera.roi = RoiConfig{0, 0, 256, 256};
    }
  }
  test::LoopbackAddress loopback_a, loopback_b;
  std::string serial_a, serial_b;
  test::GvSimulator simulator_a, simulator_b;
  RigConfig rig;
};

struct RecordRun {
  std::unique_ptr<Recorder> recorder;
  std::unique_ptr<RigController> controller;
  ViconUdpSource* vicon = nullptr;
};

RecordRun StartRun(const RigConfig& rig, const std::filesystem::path& out) {
  RecordRun run;
  RecorderOptions options = RecorderOptions::FromRig(rig.recorder);
  options.root_dir = out;
  auto recorder = Recorder::Create(rig, options);
  EXPECT_TRUE(recorder.ok()) << recorder.error().message;
  if (!recorder.ok()) return run;
  run.recorder = std::move(*recorder);
  std::vector<std::unique_ptr<Camera>> cameras;
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    CameraFactoryOptions factory;
    factory.pool_buffers = rig.recorder.queue_frames + 4;
    factory.trigger_period = TriggerPeriod(rig.vicon);
    auto camera = MakeCamera(rig.cameras[i], static_cast<int>(i), factory);
    EXPECT_TRUE(camera.ok()) << camera.error().message;
    if (!camera.ok()) return run;
    cameras.push_back(std::move(*camera));
  }
  auto vicon = std::make_unique<ViconUdpSource>(ViconUdpSourceOptions::FromRig(rig));
  run.vicon = vicon.get();
  RigControllerOptions controller_options;
  controller_options.trigger_hz = rig.vicon.rate_hz / rig.vicon.trigger_divider;
  controller_options.sync = FrameSetAssemblerOptions::FromRig(rig);
  run.controller =
      std::make_unique<RigController>(std::move(cameras), std::vector<bool>{true, true},
                                      std::move(vicon), run.recorder.get(), controller_options);
  const Status started = run.controller->Start();
  EXPECT_TRUE(started.ok()) << (started.ok() ? "" : started.error().message);
  if (!started.ok()) run.controller.reset();
  return run;
}

// Per camera: every software trigger gave a frame on disk or a counted loss
// (a trigger that could not even be sent, while the camera was lost, is
// counted as skipped). Across a reconnect the missed triggers are estimated
// from host time, which may be one off.
void ExpectEveryTriggerAccountedFor(const RigHealth& health) {
  ASSERT_TRUE(health.has_sync);  // the assembler ran beside (its figures are in the report)
  for (const CameraHealth& camera : health.cameras) {
    const std::uint64_t accounted = camera.recorder.written + camera.Lost();
    const std::uint64_t slack = camera.counter_restarts;
    EXPECT_LE(accounted, camera.triggers + slack) << camera.serial;
    EXPECT_GE(accounted + camera.triggers_skipped + slack, camera.triggers) << camera.serial;
  }
}

void ExpectSequenceMatches(const std::filesystem::path& seq, const RigHealth& health) {
  auto sequence = DiscoverSequence(seq);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  for (const CameraFolder& folder : sequence->cameras) {
    const auto& disk =
        health.recorder.cameras[folder.serial == health.recorder.cameras[0].serial ? 0 : 1];
    EXPECT_EQ(folder.frames.size(), disk.written) << folder.serial;
    for (const std::string& file : folder.frame_files) {
      auto image = ReadBmp(folder.dir / file);
      ASSERT_TRUE(image.ok()) << image.error().message;
      EXPECT_EQ(image->width, 256);
    }
  }
  auto csv = ReadViconCsv(layout::ViconCsvPath(seq, 1));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_EQ(csv->blocks.at(0).num_rows(), health.recorder.vicon_written);
}

TEST(RecordGv, TwoSimulatorsAndViconEveryTriggerAccountedFor) {
  REQUIRE_ROOT();
  GvRig gv(test::ProcessLoopbackAddress(21), test::ProcessLoopbackAddress(22), 0);
  ASSERT_TRUE(gv.loopback_a.ok() && gv.loopback_b.ok());
  ASSERT_TRUE(gv.simulator_a.Start() && gv.simulator_b.Start());
  test::TempDir out;
  RecordRun run = StartRun(gv.rig, out.path());
  ASSERT_TRUE(run.controller);
  test::ViconStreamer streamer(gv.rig, run.vicon->BoundPort(), gv.rig.vicon.rate_hz);
  std::this_thread::sleep_for(milliseconds(3000));
  run.controller->Stop();
  run.recorder->Stop();
  const RigHealth health = run.controller->Health();
  SCOPED_TRACE(health.FinalReport());
  ExpectEveryTriggerAccountedFor(health);
  EXPECT_FALSE(health.AnythingLost());
  for (const auto& disk : health.recorder.cameras) EXPECT_GE(disk.written, 13u) << disk.serial;
  EXPECT_TRUE(health.vicon_f0.has_value());
  EXPECT_GT(health.recorder.vicon_written, 150u);
  ExpectSequenceMatches(run.recorder->sequence_dir(), health);
}

TEST(RecordGv, PacketLossIsCountedAndTheRecordingContinues) {
  REQUIRE_ROOT();
  GvRig gv(test::ProcessLoopbackAddress(23), test::ProcessLoopbackAddress(24), 10);  // 1 % of B's packets lost, no resend
  ASSERT_TRUE(gv.loopback_a.ok() && gv.loopback_b.ok());
  ASSERT_TRUE(gv.simulator_a.Start() && gv.simulator_b.Start());
  test::TempDir out;
  RecordRun run = StartRun(gv.rig, out.path());
  ASSERT_TRUE(run.controller);
  test::ViconStreamer streamer(gv.rig, run.vicon->BoundPort(), gv.rig.vicon.rate_hz);
  std::this_thread::sleep_for(milliseconds(3000));
  run.controller->Stop();
  run.recorder->Stop();
  const RigHealth health = run.controller->Health();
  SCOPED_TRACE(health.FinalReport());
  ExpectEveryTriggerAccountedFor(health);
  const CameraHealth& b = health.cameras[1];
  EXPECT_GT(b.driver.failed + b.driver.missing_ids, 0u);
  EXPECT_GT(b.Lost(), 0u);
  EXPECT_TRUE(health.AnythingLost());
  EXPECT_GE(health.recorder.cameras[0].written, 13u);  // A unaffected
  ExpectSequenceMatches(run.recorder->sequence_dir(), health);
}

TEST(RecordGv, KilledSimulatorReconnectsAndTheGapIsReported) {
  REQUIRE_ROOT();
  GvRig gv(test::ProcessLoopbackAddress(25), test::ProcessLoopbackAddress(26), 0);
  ASSERT_TRUE(gv.loopback_a.ok() && gv.loopback_b.ok());
  ASSERT_TRUE(gv.simulator_a.Start() && gv.simulator_b.Start());
  test::TempDir out;
  RecordRun run = StartRun(gv.rig, out.path());
  ASSERT_TRUE(run.controller);
  test::ViconStreamer streamer(gv.rig, run.vicon->BoundPort(), gv.rig.vicon.rate_hz);
  std::this_thread::sleep_for(milliseconds(1500));
  gv.simulator_b.Kill();
  std::this_thread::sleep_for(milliseconds(1500));
  ASSERT_TRUE(gv.simulator_b.Start());
  std::this_thread::sleep_for(milliseconds(3000));
  run.controller->Stop();
  run.recorder->Stop();
  const RigHealth health = run.controller->Health();
  SCOPED_TRACE(health.FinalReport());
  ExpectEveryTriggerAccountedFor(health);
  const CameraHealth& b = health.cameras[1];
  EXPECT_GE(b.driver.reconnects, 1u);
  EXPECT_GE(b.missing_in_gaps, 4u);  // the gap, counted
  EXPECT_EQ(b.counter_restarts, 1u);
  EXPECT_TRUE(health.AnythingLost());
  // B recorded again after the restart: its last file is near the end of the run.
  EXPECT_GE(health.recorder.cameras[1].last_frame + 8, static_cast<std::int64_t>(b.triggers));
  ExpectSequenceMatches(run.recorder->sequence_dir(), health);
}

}  // namespace
}  // namespace lifmcr
