// AravisCamera against Aravis's in-process Fake camera ("Fake_1"): the real
// driver code (settings, stream, pooled ArvBuffers, statistics) with no
// network, root or sysctl.

#include "drivers/aravis_camera.h"

#include <gtest/gtest.h>

#include <chrono>
#include <ctime>
#include <vector>

namespace lifmcr {
namespace {

using std::chrono::milliseconds;

std::int64_t NowNs() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

CameraConfig FakeConfig() {
  CameraConfig config;
  config.serial = "FAKE1";
  config.name = "cam0";
  config.driver.kind = DriverKind::kAravis;
  config.driver.address = "Fake_1";
  config.trigger.mode = TriggerMode::kSoftware;
  config.exposure_us = 2000.0;
  config.roi = RoiConfig{16, 8, 256, 128};
  return config;
}

TEST(AravisFake, OpensAndAppliesTheRegionAndFormat) {
  CameraConfig config = FakeConfig();
  config.pixel_format = CameraPixelFormat::kBayerRg8;
  AravisCamera camera(config);
  ASSERT_TRUE(camera.Open()) << "open Fake_1";
  const CameraInfo info = camera.Info();
  EXPECT_EQ(info.width, 256);
  EXPECT_EQ(info.height, 128);
  EXPECT_EQ(info.format, PixelFormat::kMono8);  // Bayer travels as grey
  EXPECT_EQ(info.payload_bytes, 256u * 128u);
  EXPECT_EQ(info.vendor, "Aravis");
  EXPECT_FALSE(info.device_id.empty());
  // What the device itself now holds.
  auto feature = [&camera](const char* name) {
    auto value = camera.FeatureValue(name);
    return value ? *value : "<" + value.error().message + ">";
  };
  EXPECT_EQ(feature("PixelFormat"), "BayerRG8");
  EXPECT_EQ(feature("OffsetX"), "16");
  EXPECT_EQ(feature("OffsetY"), "8");
  EXPECT_EQ(feature("Width"), "256");
  EXPECT_EQ(feature("Height"), "128");
  EXPECT_DOUBLE_EQ(std::stod(feature("ExposureTimeAbs")), 2000.0);
  EXPECT_EQ(feature("TriggerSelector"), "FrameStart");
  EXPECT_EQ(feature("TriggerMode"), "On");
  EXPECT_EQ(feature("TriggerSource"), "Software");
  EXPECT_EQ(feature("AcquisitionMode"), "Continuous");
  EXPECT_FALSE(camera.FeatureValue("NoSuchFeature").ok());
}

TEST(AravisFake, FreeRunTurnsTheTriggerOffAndSetsTheRate) {
  CameraConfig config = FakeConfig();
  config.trigger.mode = TriggerMode::kFreeRun;
  AravisCamera camera(config, AravisCameraOptions{.free_run_rate_hz = 40.0});
  ASSERT_TRUE(camera.Open());
  auto mode = camera.FeatureValue("TriggerMode");
  ASSERT_TRUE(mode.ok());
  EXPECT_EQ(*mode, "Off");
  auto rate = camera.FeatureValue("AcquisitionFrameRate");
  ASSERT_TRUE(rate.ok());
  EXPECT_NEAR(std::stod(*rate), 40.0, 0.5);
}

TEST(AravisFake, SoftwareTriggerDeliversTimestampedFramesWithIncreasingIds) {
  AravisCamera camera(FakeConfig(), AravisCameraOptions{.camera_index = 3});
  ASSERT_TRUE(camera.Open());
  ASSERT_TRUE(camera.Start());
  std::vector<Frame> frames;
  const std::int64_t before_ns = NowNs();
  for (int i = 0; i < 6; ++i) {
    ASSERT_TRUE(camera.SoftwareTrigger());
    auto next = camera.NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok()) << next.error().message;
    ASSERT_TRUE(next->has_value()) << "no frame for trigger " << i;
    frames.push_back(std::move(**next));
  }
  ASSERT_TRUE(camera.Stop());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const Frame& frame = frames[i];
    EXPECT_EQ(frame.status, FrameStatus::kOk);
    EXPECT_EQ(frame.camera_index, 3);
    EXPECT_EQ(frame.serial, "FAKE1");
    EXPECT_EQ(frame.image.width, 256);
    EXPECT_EQ(frame.image.height, 128);
    ASSERT_TRUE(frame.buffer);
    EXPECT_EQ(frame.image.data, frame.buffer->data);  // the pool's memory, not a copy
    EXPECT_GE(frame.host_ns, before_ns - 1'000'000'000);
    EXPECT_LE(frame.host_ns, NowNs());
    EXPECT_GT(frame.device_ns, 0);
    if (i > 0) {
      EXPECT_EQ((frames[i - 1].frame_id + 1) & 0xFFFF, frame.frame_id & 0xFFFF);
      EXPECT_GT(frame.device_ns, frames[i - 1].device_ns);
    }
  }
  const CameraStats stats = camera.Stats();
  EXPECT_EQ(stats.completed, 6u);
  EXPECT_EQ(stats.failed, 0u);
  EXPECT_EQ(stats.missing_ids, 0u);
  EXPECT_EQ(stats.underruns, 0u);
  EXPECT_EQ(stats.reconnects, 0u);
  EXPECT_GE(stats.transferred_bytes, 6u * 256u * 128u);
}

TEST(AravisFake, SixteenBitCounterWrapsWithoutMissingIds) {
  CameraConfig config = FakeConfig();
  config.trigger.mode = TriggerMode::kFreeRun;
  config.roi = RoiConfig{0, 0, 64, 32};
  AravisCamera camera(config, AravisCameraOptions{.free_run_rate_hz = 400.0});
  ASSERT_TRUE(camera.Open());
  ASSERT_TRUE(camera.Start());
  // The fake counter starts near 65400 on purpose; 200 frames cross the wrap.
  bool wrapped = false;
  std::uint64_t previous = 0;
  std::int64_t previous_device_ns = 0;
  for (int i = 0; i < 200; ++i) {
    auto next = camera.NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value()) << "frame " << i;
    const std::uint64_t id = (*next)->frame_id;
    if (i > 0 && id < previous) wrapped = true;
    if (i > 0) {
      EXPECT_GT((*next)->device_ns, previous_device_ns) << "frame " << i;
    }
    previous = id;
    previous_device_ns = (*next)->device_ns;
  }
  ASSERT_TRUE(camera.Stop());
  EXPECT_TRUE(wrapped);
  const CameraStats stats = camera.Stats();
  EXPECT_EQ(stats.completed, 200u);
  EXPECT_EQ(stats.missing_ids, 0u);
}

TEST(AravisFake, HeldBuffersExhaustThePoolAndCountUnderruns) {
  CameraConfig config = FakeConfig();
  config.trigger.mode = TriggerMode::kFreeRun;
  config.roi = RoiConfig{0, 0, 64, 32};
  AravisCamera camera(config, AravisCameraOptions{.pool_buffers = 4, .free_run_rate_hz = 200.0});
  ASSERT_TRUE(camera.Open());
  ASSERT_TRUE(camera.Start());
  std::vector<Frame> held;
  while (held.size() < 4) {
    auto next = camera.NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value());
    held.push_back(std::move(**next));
  }
  // Every buffer is held: the camera has nowhere to put its frames.
  auto none = camera.NextFrame(milliseconds(300));
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  EXPECT_GT(camera.Stats().underruns, 10u);
  held.clear();  // back to the pool; the next call queues them again
  auto again = camera.NextFrame(milliseconds(1000));
  ASSERT_TRUE(again.ok() && again->has_value());
  EXPECT_EQ((*again)->status, FrameStatus::kOk);
  // The Fake camera does not count the frames it could not deliver, so
  // there is no id gap; nothing is counted twice.
  EXPECT_EQ(camera.Stats().missing_ids, 0u);
  ASSERT_TRUE(camera.Stop());
}

TEST(AravisFake, RegionOutsideTheSensorIsAnErrorNamingTheCamera) {
  CameraConfig config = FakeConfig();
  config.roi = RoiConfig{2000, 0, 256, 128};
  AravisCamera camera(config);
  const Status status = camera.Open();
  ASSERT_FALSE(status);
  EXPECT_NE(status.error().message.find("cam0"), std::string::npos) << status.error().message;
  EXPECT_NE(status.error().message.find("roi"), std::string::npos) << status.error().message;
}

TEST(AravisFake, HardwareTriggerOnALineTheCameraLacksIsAnError) {
  CameraConfig config = FakeConfig();
  config.trigger.mode = TriggerMode::kHardware;
  config.trigger.source = "Line1";  // the fake camera has Line0 only
  AravisCamera camera(config);
  const Status status = camera.Open();
  ASSERT_FALSE(status);
  EXPECT_NE(status.error().message.find("TriggerSource"), std::string::npos)
      << status.error().message;
}

TEST(AravisFake, UnknownDeviceIsAnErrorNamingIt) {
  CameraConfig config = FakeConfig();
  config.driver.address = "Fake_no_such_camera_xyz";
  AravisCamera camera(config);
  const Status status = camera.Open();
  ASSERT_FALSE(status);
  EXPECT_NE(status.error().message.find("Fake_no_such_camera_xyz"), std::string::npos)
      << status.error().message;
}

TEST(AravisFake, SoftwareTriggerBeforeOpenIsAnError) {
  AravisCamera camera(FakeConfig());
  EXPECT_FALSE(camera.SoftwareTrigger());
  EXPECT_FALSE(camera.NextFrame(milliseconds(1)).ok());
}

}  // namespace
}  // namespace lifmcr
