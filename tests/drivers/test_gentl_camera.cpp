// GenTlCamera through MakeCamera against a real GenTL producer built by the
// tests (tests/drivers/gentl_sim/): loading checks, GenICam features through
// the producer's port, software/timer triggers, drops, incomplete buffers,
// underruns, a device that disappears and comes back, a busy device.

#include "drivers/camera_factory.h"
#include "drivers/gentl_camera.h"
#include "drivers/gentl_producer.h"
#include "tests/drivers/gentl_sim/gentl_sim_xml.h"

#include <dlfcn.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>
#include <vector>

namespace lifmcr {
namespace {

using std::chrono::milliseconds;
namespace fs = std::filesystem;
namespace sim = gentl_sim;

// The test's own handle on the producer keeps it loaded between tests and
// gives the simulator's control entry points.
struct SimControl {
  void* library = dlopen(LIFMCR_GENTL_SIM_CTI, RTLD_NOW | RTLD_LOCAL);
  void (*set_present)(const char*, int) =
      reinterpret_cast<void (*)(const char*, int)>(dlsym(library, "LifmcrGenTlSimSetPresent"));
  void (*set_busy)(const char*, int) =
      reinterpret_cast<void (*)(const char*, int)>(dlsym(library, "LifmcrGenTlSimSetBusy"));
  int (*set_register)(const char*, std::uint64_t, std::uint32_t) =
      reinterpret_cast<int (*)(const char*, std::uint64_t, std::uint32_t)>(
          dlsym(library, "LifmcrGenTlSimSetRegister"));
};
SimControl& Sim() {
  static SimControl control;
  return control;
}

CameraConfig SimConfig(const std::string& serial = "GTLSIM0") {
  CameraConfig config;
  config.serial = serial;
  config.name = "cam0";
  config.driver.kind = DriverKind::kGenTl;
  config.driver.cti = LIFMCR_GENTL_SIM_CTI;
  config.trigger.mode = TriggerMode::kSoftware;
  config.exposure_us = 2000.0;
  config.roi = RoiConfig{16, 8, 256, 128};
  return config;
}

std::unique_ptr<Camera> Make(const CameraConfig& config, CameraFactoryOptions options = {}) {
  EXPECT_NE(Sim().set_present, nullptr);
  auto camera = MakeCamera(config, 0, options);
  EXPECT_TRUE(camera.ok()) << camera.error().message;
  return camera.ok() ? std::move(*camera) : nullptr;
}

CameraFactoryOptions Options(double free_run_rate_hz, int pool_buffers = 16) {
  CameraFactoryOptions options;
  options.free_run_rate_hz = free_run_rate_hz;
  options.pool_buffers = pool_buffers;
  return options;
}

GenTlCamera& AsGenTl(Camera& camera) { return dynamic_cast<GenTlCamera&>(camera); }

std::string Feature(Camera& camera, const char* name) {
  auto value = AsGenTl(camera).FeatureValue(name);
  return value ? *value : "<" + value.error().message + ">";
}

std::string OpenError(const CameraConfig& config) {
  auto camera = MakeCamera(config, 0, {});
  if (!camera) return camera.error().message;
  const Status status = (*camera)->Open();
  return status ? std::string() : status.error().message;
}

TEST(GenTlSim, OpensAndAppliesTheRegionAndFormatThroughThePort) {
  CameraConfig config = SimConfig();
  config.pixel_format = CameraPixelFormat::kBayerRg8;
  auto camera = Make(config);
  ASSERT_TRUE(camera->Open());
  const CameraInfo info = camera->Info();
  EXPECT_EQ(info.width, 256);
  EXPECT_EQ(info.height, 128);
  // The image and the camera's chunk (timestamp, frame id), which the driver enables.
  EXPECT_EQ(info.payload_bytes, 256u * 128u + sim::kChunkBytes);
  EXPECT_EQ(Feature(*camera, "ChunkModeActive"), "true");
  EXPECT_EQ(info.vendor, "lifmcr");
  EXPECT_EQ(info.serial, "GTLSIM0");
  EXPECT_EQ(info.device_id, "SimDev-GTLSIM0");
  EXPECT_EQ(Feature(*camera, "PixelFormat"), "BayerRG8");
  EXPECT_EQ(Feature(*camera, "OffsetX"), "16");
  EXPECT_EQ(Feature(*camera, "OffsetY"), "8");
  EXPECT_EQ(Feature(*camera, "Width"), "256");
  EXPECT_EQ(Feature(*camera, "Height"), "128");
  EXPECT_DOUBLE_EQ(std::stod(Feature(*camera, "ExposureTime")), 2000.0);
  EXPECT_EQ(Feature(*camera, "TriggerSelector"), "FrameStart");
  EXPECT_EQ(Feature(*camera, "TriggerMode"), "On");
  EXPECT_EQ(Feature(*camera, "TriggerSource"), "Software");
  EXPECT_EQ(Feature(*camera, "AcquisitionMode"), "Continuous");
  EXPECT_EQ(Feature(*camera, "DeviceSerialNumber"), "GTLSIM0");
  EXPECT_FALSE(AsGenTl(*camera).FeatureValue("NoSuchFeature").ok());
}

TEST(GenTlSim, SoftwareTriggerDeliversFramesIntoThePoolWithTheirPixels) {
  auto camera = Make(SimConfig());
  ASSERT_TRUE(camera->Open());
  ASSERT_TRUE(camera->Start());
  std::vector<Frame> frames;
  for (int i = 0; i < 6; ++i) {
    ASSERT_TRUE(camera->SoftwareTrigger());
    auto next = camera->NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok()) << next.error().message;
    ASSERT_TRUE(next->has_value()) << "no frame for trigger " << i;
    frames.push_back(std::move(**next));
  }
  ASSERT_TRUE(camera->Stop());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const Frame& frame = frames[i];
    EXPECT_EQ(frame.status, FrameStatus::kOk);
    EXPECT_EQ(frame.serial, "GTLSIM0");
    ASSERT_TRUE(frame.buffer);
    EXPECT_EQ(frame.image.data, frame.buffer->data);  // written by the producer, not copied
    EXPECT_EQ(frame.image.width, 256);
    EXPECT_EQ(frame.image.height, 128);
    // Row y of frame id n holds (n + y) mod 256.
    for (int y : {0, 1, 127})
      EXPECT_EQ(frame.image.data[y * frame.image.stride_bytes + 5], (frame.frame_id + y) & 0xFF);
    if (i > 0) {
      EXPECT_EQ(frames[i - 1].frame_id + 1, frame.frame_id);
      EXPECT_GT(frame.device_ns, frames[i - 1].device_ns);
    }
  }
  const CameraStats stats = camera->Stats();
  EXPECT_EQ(stats.completed, 6u);
  EXPECT_EQ(stats.failed + stats.missing_ids + stats.underruns, 0u);
  EXPECT_EQ(stats.transferred_bytes, 6u * (256u * 128u + sim::kChunkBytes));
}


TEST(GenTlSim, TimerTriggerDeliversOnTheLinePeriod) {
  CameraConfig config = SimConfig();
  config.trigger.mode = TriggerMode::kHardware;
  config.trigger.source = "Line1";
  auto camera = Make(config);
  ASSERT_TRUE(camera->Open());
  EXPECT_EQ(Feature(*camera, "TriggerSource"), "Line1");
  EXPECT_EQ(Feature(*camera, "TriggerActivation"), "RisingEdge");
  constexpr std::int64_t kPeriodNs = 20'000'000;
  ASSERT_EQ(Sim().set_register("GTLSIM0", sim::kLinePeriodUs, kPeriodNs / 1000), 0);
  ASSERT_TRUE(camera->Start());
  std::vector<Frame> frames;
  while (frames.size() < 8) {
    auto next = camera->NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value());
    frames.push_back(std::move(**next));
  }
  ASSERT_TRUE(camera->Stop());
  // The device time is the camera's chunk timestamp, the pulse itself; the
  // producer's own buffer timestamp is the arrival, exposure + 1 ms later.
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].device_ns % kPeriodNs, 0) << "pulse " << i << " off the line's grid";
    EXPECT_LT(frames[i].device_ns, frames[i].host_ns);
    if (i > 0) {
      EXPECT_EQ(frames[i].frame_id, frames[i - 1].frame_id + 1);
      EXPECT_EQ(frames[i].device_ns - frames[i - 1].device_ns, kPeriodNs);
    }
  }
}

TEST(GenTlSim, FreeRunTurnsTheTriggerOffAndSetsTheRate) {
  CameraConfig config = SimConfig();
  config.trigger.mode = TriggerMode::kFreeRun;
  auto camera = Make(config, Options(40.0));
  ASSERT_TRUE(camera->Open());
  EXPECT_EQ(Feature(*camera, "TriggerMode"), "Off");
  EXPECT_NEAR(std::stod(Feature(*camera, "AcquisitionFrameRate")), 40.0, 1e-9);
}

// Every frame id between the first and the last is delivered, failed,
// missing or an underrun: nothing unaccounted for.
void ExpectEveryIdAccountedFor(const CameraStats& stats, std::uint64_t first_id,
                               std::uint64_t last_id) {
  EXPECT_EQ(stats.completed + stats.failed + stats.missing_ids + stats.underruns,
            last_id - first_id + 1)
      << "completed " << stats.completed << " failed " << stats.failed << " missing "
      << stats.missing_ids << " underruns " << stats.underruns;
}

TEST(GenTlSim, FramesLostInTransportAreMissingIds) {
  CameraConfig config = SimConfig();
  config.trigger.mode = TriggerMode::kFreeRun;
  config.roi = RoiConfig{0, 0, 64, 32};
  auto camera = Make(config, Options(200.0));
  ASSERT_TRUE(camera->Open());
  ASSERT_EQ(Sim().set_register("GTLSIM0", sim::kDropEvery, 5), 0);
  ASSERT_TRUE(camera->Start());
  std::uint64_t first = 0, last = 0;
  for (int i = 0; i < 24; ++i) {
    auto next = camera->NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value());
    if (i == 0) first = (*next)->frame_id;
    last = (*next)->frame_id;
    EXPECT_NE(last % 5, 0u) << "a dropped id was delivered";
  }
  ASSERT_TRUE(camera->Stop());
  const CameraStats stats = camera->Stats();
  EXPECT_EQ(stats.completed, 24u);
  EXPECT_GE(stats.missing_ids, 5u);
  EXPECT_EQ(stats.underruns, 0u);
  ExpectEveryIdAccountedFor(stats, first, last);
}

TEST(GenTlSim, IncompleteBuffersAreDeliveredAsIncomplete) {
  CameraConfig config = SimConfig();
  config.trigger.mode = TriggerMode::kFreeRun;
  config.roi = RoiConfig{0, 0, 64, 32};
  auto camera = Make(config, Options(200.0));
  ASSERT_TRUE(camera->Open());
  ASSERT_EQ(Sim().set_register("GTLSIM0", sim::kIncompleteEvery, 3), 0);
  ASSERT_TRUE(camera->Start());
  std::uint64_t incomplete = 0, first = 0, last = 0;
  for (int i = 0; i < 12; ++i) {
    auto next = camera->NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value());
    const Frame& frame = **next;
    if (i == 0) first = frame.frame_id;
    last = frame.frame_id;
    EXPECT_EQ(frame.status, frame.frame_id % 3 == 0 ? FrameStatus::kIncomplete : FrameStatus::kOk)
        << "frame id " << frame.frame_id;
    incomplete += frame.status == FrameStatus::kIncomplete;
  }
  ASSERT_TRUE(camera->Stop());
  const CameraStats stats = camera->Stats();
  EXPECT_EQ(stats.failed, incomplete);
  EXPECT_GE(incomplete, 3u);
  ExpectEveryIdAccountedFor(stats, first, last);
}

TEST(GenTlSim, HeldBuffersExhaustThePoolAndCountUnderrunsOnce) {
  CameraConfig config = SimConfig();
  config.trigger.mode = TriggerMode::kFreeRun;
  config.roi = RoiConfig{0, 0, 64, 32};
  auto camera = Make(config, Options(200.0, 4));
  ASSERT_TRUE(camera->Open());
  ASSERT_TRUE(camera->Start());
  std::vector<Frame> held;
  while (held.size() < 4) {
    auto next = camera->NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value());
    held.push_back(std::move(**next));
  }
  const std::uint64_t first = held.front().frame_id;
  auto none = camera->NextFrame(milliseconds(300));
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  EXPECT_GT(camera->Stats().underruns, 10u);
  held.clear();  // back to the pool; the next call queues them again
  auto again = camera->NextFrame(milliseconds(1000));
  ASSERT_TRUE(again.ok() && again->has_value());
  EXPECT_EQ((*again)->status, FrameStatus::kOk);
  const CameraStats stats = camera->Stats();
  EXPECT_EQ(stats.missing_ids, 0u);  // the ids the underruns skipped are not counted twice
  ExpectEveryIdAccountedFor(stats, first, (*again)->frame_id);
  ASSERT_TRUE(camera->Stop());
}

TEST(GenTlSim, DisappearanceIsReportedAndTheReturnCounted) {
  CameraConfig config = SimConfig("GTLSIM1");
  config.trigger.mode = TriggerMode::kFreeRun;
  config.roi = RoiConfig{0, 0, 64, 32};
  auto camera = Make(config, Options(100.0));
  ASSERT_TRUE(camera->Open());
  ASSERT_TRUE(camera->Start());
  for (int i = 0; i < 3; ++i) {
    auto next = camera->NextFrame(milliseconds(1000));
    ASSERT_TRUE(next.ok() && next->has_value());
  }
  Sim().set_present("GTLSIM1", 0);
  bool reported = false;
  for (int i = 0; i < 40 && !reported; ++i) {
    auto next = camera->NextFrame(milliseconds(100));
    if (!next.ok()) {
      reported = true;
      EXPECT_NE(next.error().message.find("device lost"), std::string::npos)
          << next.error().message;
    }
  }
  ASSERT_TRUE(reported) << "the loss was not reported within 4 s";
  EXPECT_TRUE(AsGenTl(*camera).IsLost());
  EXPECT_FALSE(camera->SoftwareTrigger());
  Sim().set_present("GTLSIM1", 1);
  std::optional<Frame> back;
  for (int i = 0; i < 40 && !back; ++i) {
    auto next = camera->NextFrame(milliseconds(100));
    ASSERT_TRUE(next.ok()) << next.error().message;
    if (next->has_value()) back = std::move(**next);
  }
  ASSERT_TRUE(back) << "no frame within 4 s of the device's return";
  EXPECT_EQ(back->status, FrameStatus::kOk);
  EXPECT_EQ(camera->Stats().reconnects, 1u);
  const std::vector<CameraGap> gaps = AsGenTl(*camera).Gaps();
  ASSERT_EQ(gaps.size(), 1u);
  EXPECT_TRUE(gaps[0].had_frame_before);
  EXPECT_TRUE(gaps[0].had_frame_after);
  EXPECT_EQ(gaps[0].first_frame_id_after, back->frame_id);
  EXPECT_GT(gaps[0].FramelessNs(), 0);
  EXPECT_NE(gaps[0].Describe().find("lost"), std::string::npos) << gaps[0].Describe();
  ASSERT_TRUE(camera->Stop());
}

TEST(GenTlSim, ASecondOpenOfTheDeviceIsBusy) {
  auto first = Make(SimConfig());
  ASSERT_TRUE(first->Open());
  const std::string message = OpenError(SimConfig());
  EXPECT_NE(message.find("busy"), std::string::npos) << message;
  EXPECT_NE(message.find("IFOpenDevice"), std::string::npos) << message;
  EXPECT_NE(message.find("GC_ERR_RESOURCE_IN_USE"), std::string::npos) << message;
}

TEST(GenTlSim, ADeviceAnotherProcessHoldsIsBusy) {
  // Held loaded, so the simulator's cameras exist and keep their state.
  auto producer = GenTlProducer::Load(LIFMCR_GENTL_SIM_CTI);
  ASSERT_TRUE(producer.ok()) << producer.error().message;
  Sim().set_busy("GTLSIM0", 1);
  const std::string message = OpenError(SimConfig());
  Sim().set_busy("GTLSIM0", 0);
  EXPECT_NE(message.find("device SimDev-GTLSIM0 busy: busy (opened by another process or host)"),
            std::string::npos)
      << message;
}

TEST(GenTlSim, UnknownDeviceNamesItAndListsTheDevices) {
  CameraConfig config = SimConfig();
  config.driver.device = "NOPE";
  const std::string message = OpenError(config);
  EXPECT_NE(message.find("'NOPE'"), std::string::npos) << message;
  EXPECT_NE(message.find("SimDev-GTLSIM0 (serial GTLSIM0)"), std::string::npos) << message;
  config.driver.device = "SimDev-GTLSIM1";  // by device id
  auto camera = Make(config);
  ASSERT_TRUE(camera->Open());
  EXPECT_EQ(camera->Info().serial, "GTLSIM1");
}

TEST(GenTlSim, RegionOutsideTheSensorIsAnErrorNamingTheCamera) {
  CameraConfig config = SimConfig();
  config.roi = RoiConfig{2000, 0, 256, 128};
  const std::string message = OpenError(config);
  EXPECT_NE(message.find("cam0"), std::string::npos) << message;
  EXPECT_NE(message.find("roi"), std::string::npos) << message;
}

TEST(GenTlProducerLoad, MissingFileWrongArchitectureAndMissingSymbolsAreNamed) {
  CameraConfig config = SimConfig();
  config.driver.cti = "/nonexistent/vendor_producer.cti";
  std::string message = OpenError(config);
  EXPECT_NE(message.find("/nonexistent/vendor_producer.cti: no such file"), std::string::npos)
      << message;

  const fs::path elf32 = fs::temp_directory_path() / "lifmcr_test_elf32.cti";
  {
    std::ofstream file(elf32, std::ios::binary);
    const unsigned char header[20] = {0x7f, 'E', 'L', 'F', 1, 1, 1, 0, 0, 0,
                                      0,    0,   0,   0,   0, 0, 3, 0, 3, 0};
    file.write(reinterpret_cast<const char*>(header), sizeof(header));
  }
  config.driver.cti = elf32;
  message = OpenError(config);
  EXPECT_NE(message.find("wrong architecture"), std::string::npos) << message;
  EXPECT_NE(message.find("32-bit"), std::string::npos) << message;
  fs::remove(elf32);

#if defined(__x86_64__)
  {
    // A 64-bit producer for another machine (ARM, e_machine 183).
    std::ofstream file(elf32, std::ios::binary);
    const unsigned char header[20] = {0x7f, 'E', 'L', 'F', 2, 1, 1, 0, 0, 0,
                                      0,    0,   0,   0,   0, 0, 3, 0, 183, 0};
    file.write(reinterpret_cast<const char*>(header), sizeof(header));
  }
  message = OpenError(config);
  EXPECT_NE(message.find("wrong architecture, built for aarch64, this host is x86-64"),
            std::string::npos)
      << message;
  fs::remove(elf32);
#endif

  config.driver.cti = LIFMCR_GENTL_INCOMPLETE_CTI;
  message = OpenError(config);
  EXPECT_NE(message.find("missing symbols"), std::string::npos) << message;
  EXPECT_NE(message.find("GCReadPort"), std::string::npos) << message;
  EXPECT_NE(message.find("DSAnnounceBuffer"), std::string::npos) << message;
}

TEST(GenTlProducerLoad, GenicamGentl64PathFindsTheProducerWithTheDevice) {
  // The folder also holds the incomplete producer, which the search skips.
  const std::string dir = fs::path(LIFMCR_GENTL_SIM_CTI).parent_path().string();
  ASSERT_EQ(setenv("GENICAM_GENTL64_PATH", ("/nonexistent:" + dir).c_str(), 1), 0);
  CameraConfig config = SimConfig();
  config.driver.cti.clear();
  auto camera = Make(config);
  ASSERT_TRUE(camera->Open());
  EXPECT_EQ(camera->Info().device_id, "SimDev-GTLSIM0");
  unsetenv("GENICAM_GENTL64_PATH");
}

TEST(GenTlProducerLoad, ErrorCodesHaveTheirStandardNames) {
  EXPECT_EQ(gentl::ErrorName(gentl::GC_ERR_RESOURCE_IN_USE), "GC_ERR_RESOURCE_IN_USE");
  EXPECT_EQ(gentl::ErrorName(-1011), "GC_ERR_TIMEOUT");
  EXPECT_EQ(gentl::ErrorName(-1022), "GC_ERR_BUSY");
  EXPECT_EQ(gentl::ErrorName(-10007), "GC_ERR_CUSTOM_ID-7");
  EXPECT_EQ(gentl::ErrorName(-5), "GC_ERROR(-5)");
}

TEST(GenTlProducerLoad, DiscoveryListsInterfacesAndDevices) {
  auto producer = GenTlProducer::Load(LIFMCR_GENTL_SIM_CTI);
  ASSERT_TRUE(producer.ok()) << producer.error().message;
  const GenTlProducerInfo info = (*producer)->Info();
  EXPECT_EQ(info.vendor, "lifmcr");
  EXPECT_EQ(info.tl_type, "CXP");
  EXPECT_EQ(info.gentl_version, "1.5");
  auto devices = (*producer)->Devices("", milliseconds(100));
  ASSERT_TRUE(devices.ok()) << devices.error().message;
  ASSERT_EQ(devices->size(), 2u);
  EXPECT_EQ((*devices)[0].interface_id, "SimIF0");
  EXPECT_EQ((*devices)[0].serial, "GTLSIM0");
  EXPECT_EQ((*devices)[1].id, "SimDev-GTLSIM1");
  auto wrong = (*producer)->Devices("NoSuchIF", milliseconds(100));
  ASSERT_FALSE(wrong.ok());
  EXPECT_NE(wrong.error().message.find("SimIF0"), std::string::npos) << wrong.error().message;
}

}  // namespace
}  // namespace lifmcr
