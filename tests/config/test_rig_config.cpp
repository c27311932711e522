// The rig configuration: the shipped examples load with the values they
// state, Format -> Parse is the identity (examples and random rigs), and
// every kind of bad input is an error naming the file, the line and column,
// and the key path.

#include "config/rig_config.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

fs::path SourceDir() {
  // tests/data/samples -> the repository root.
  return test::SamplePath("SOURCES.md").parent_path().parent_path().parent_path().parent_path();
}

fs::path ExamplePath(const std::string& name) { return SourceDir() / "config" / "examples" / name; }

fs::path SamplesDir() { return test::SamplePath("SOURCES.md").parent_path(); }

// "<line>:<col>" of the first occurrence of `needle` (1-based), as yaml-cpp
// reports the node that starts there.
std::string PositionOf(const std::string& text, const std::string& needle) {
  const std::size_t at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  const std::size_t line_start = text.rfind('\n', at == 0 ? 0 : at - 1);
  const std::size_t column = line_start == std::string::npos ? at + 1 : at - line_start;
  int line = 1;
  for (std::size_t i = 0; i < at; ++i) line += text[i] == '\n';
  return std::to_string(line) + ":" + std::to_string(column);
}

// A valid two-camera rig; tests break one thing in it at a time.
const std::string kValidRig = R"(rig:
  name: test rig
cameras:
  - serial: "111"
    name: cam0
    role: reference
    driver: {kind: aravis, address: 127.0.0.1}
    mla_file: raytrix_mla_R42_sc2_klein.xml
    exposure_us: 5000
    vicon_object: cam0
  - serial: "222"
    name: cam1
    role: registered
    driver: {kind: replay}
    mla_file: raytrix_mla_R29_Cards2_Processed.xml
    vicon_object: cam1
vicon:
  source: udp
  udp: {address: 127.0.0.1, port: 51001}
)";

Expected<RigConfig> Parse(const std::string& yaml) {
  return ParseRigConfig(yaml, SamplesDir(), "rig.yaml");
}

// Parses `yaml`, expects failure, and returns the message.
std::string ErrorOf(const std::string& yaml) {
  const Expected<RigConfig> rig = Parse(yaml);
  EXPECT_FALSE(rig.ok()) << yaml;
  return rig.ok() ? std::string() : rig.error().message;
}

// ------------------------------------------------------------- examples

TEST(RigConfigExamples, LifmcrTwoR32LoadsWithItsValues) {
  const fs::path file = ExamplePath("lifmcr_two_r32.yaml");
  const Expected<RigConfig> rig = LoadRigConfig(file);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_EQ(rig->name, "lifmcr_two_r32");
  ASSERT_EQ(rig->cameras.size(), 2u);
  EXPECT_EQ(rig->ReferenceIndex(), 0);

  const fs::path calibration =
      fs::absolute(file).parent_path() / "Calibration" / "02_MLA_Calibration";
  const CameraConfig& cam0 = rig->cameras[0];
  EXPECT_EQ(cam0.serial, "40398678");
  EXPECT_EQ(cam0.name, "cam0");
  EXPECT_EQ(cam0.role, CameraRole::kReference);
  EXPECT_EQ(cam0.driver.kind, DriverKind::kGenTl);
  EXPECT_EQ(cam0.driver.cti, fs::path("/opt/framegrabber/lib/gentl/producer_cxp.cti"));
  EXPECT_EQ(cam0.driver.interface_id, "");
  EXPECT_EQ(cam0.driver.device, "40398678");
  EXPECT_EQ(cam0.mla_file, (calibration / "TypeE_40398678_MLA.xml").lexically_normal());
  EXPECT_EQ(cam0.trigger.mode, TriggerMode::kHardware);
  EXPECT_EQ(cam0.trigger.source, "Line1");
  EXPECT_EQ(cam0.trigger.activation, TriggerActivation::kRisingEdge);
  EXPECT_EQ(cam0.exposure_us, 10000.0);
  EXPECT_EQ(cam0.gain_db, 0.0);
  EXPECT_EQ(cam0.pixel_format, CameraPixelFormat::kBgr8);
  EXPECT_EQ(BufferPixelFormat(cam0.pixel_format), PixelFormat::kBgr8);
  EXPECT_FALSE(cam0.roi.has_value());
  EXPECT_EQ(cam0.vicon_object, "cam0");

  const CameraConfig& cam2 = rig->cameras[1];
  EXPECT_EQ(cam2.serial, "40398673");
  EXPECT_EQ(cam2.name, "cam2");
  EXPECT_EQ(cam2.role, CameraRole::kRegistered);
  EXPECT_EQ(cam2.driver.device, "40398673");
  EXPECT_EQ(cam2.mla_file, (calibration / "TypeE_40398673_MLA.xml").lexically_normal());
  EXPECT_EQ(cam2.vicon_object, "cam2");

  // The stand-in MLA files are byte-identical copies of the R42 sample.
  for (const CameraConfig& camera : rig->cameras) {
    EXPECT_EQ(test::ReadFile(camera.mla_file),
              test::ReadFile(test::SamplePath("raytrix_mla_R42_sc2_klein.xml")));
  }

  EXPECT_EQ(rig->vicon.source, ViconSourceKind::kUdp);
  EXPECT_EQ(rig->vicon.udp.address, "0.0.0.0");
  EXPECT_EQ(rig->vicon.udp.port, 51001);
  EXPECT_EQ(rig->vicon.rotation, RotationRepresentation::kHelicalRad);
  EXPECT_EQ(rig->vicon.handedness, Handedness::kLeftFlipY);
  EXPECT_EQ(rig->vicon.plate_object, "plate");
  EXPECT_EQ(rig->vicon.rate_hz, 80.0);
  EXPECT_EQ(rig->vicon.trigger_divider, 8);
  EXPECT_EQ(rig->recorder.writer_threads, 2);
  EXPECT_EQ(rig->recorder.max_memory_mb, 4096);
  EXPECT_TRUE(rig->recorder.direct_io);
  EXPECT_EQ(rig->processing.skip_policy, SkipPolicy::kNewestWins);
  EXPECT_EQ(rig->lcm.url, "udpm://239.255.76.67:7667?ttl=0");
  EXPECT_EQ(rig->lcm.channel_prefix, "LIFMCR");
  EXPECT_TRUE(rig->Check().ok());
}

TEST(RigConfigExamples, FakeGigeTwoCamerasLoadsWithItsValues) {
  const Expected<RigConfig> rig = LoadRigConfig(ExamplePath("fake_gige_two_cameras.yaml"));
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  ASSERT_EQ(rig->cameras.size(), 2u);
  const char* const addresses[] = {"127.0.0.1", "127.0.0.2"};
  for (int i = 0; i < 2; ++i) {
    const CameraConfig& camera = rig->cameras[i];
    EXPECT_EQ(camera.driver.kind, DriverKind::kAravis);
    EXPECT_EQ(camera.driver.address, addresses[i]);
    EXPECT_EQ(camera.trigger.mode, TriggerMode::kSoftware);
    EXPECT_EQ(camera.pixel_format, CameraPixelFormat::kMono8);
    ASSERT_TRUE(camera.roi.has_value());
    EXPECT_EQ(*camera.roi, (RoiConfig{0, 0, 512, 512}));
    EXPECT_EQ(camera.socket_buffer_bytes, 0);  // auto
    EXPECT_EQ(camera.packet_size_bytes, 0);
  }
  EXPECT_EQ(rig->cameras[0].serial, "GV01");
  EXPECT_EQ(rig->cameras[1].serial, "GV02");
  EXPECT_EQ(rig->ReferenceIndex(), 0);
  EXPECT_EQ(rig->vicon.udp.address, "127.0.0.1");
  EXPECT_EQ(rig->vicon.rotation, RotationRepresentation::kHelicalRad);  // default
  EXPECT_EQ(rig->vicon.handedness, Handedness::kLeftFlipY);             // default
  EXPECT_FALSE(rig->recorder.direct_io);
  EXPECT_EQ(rig->processing.skip_policy, SkipPolicy::kBlock);
  EXPECT_EQ(rig->lcm.channel_prefix, "LIFMCR_TEST");
}

TEST(RigConfigExamples, FormatParsesBackEqual) {
  for (const char* name : {"lifmcr_two_r32.yaml", "fake_gige_two_cameras.yaml",
                           "gentl_simulator_two_cameras.yaml"}) {
    const Expected<RigConfig> rig = LoadRigConfig(ExamplePath(name));
    ASSERT_TRUE(rig.ok()) << rig.error().message;
    const std::string text = FormatRigConfig(*rig);
    // Resolved paths: the copy loads equal from any folder.
    const Expected<RigConfig> back = ParseRigConfig(text, "/somewhere/else", "copy.yaml");
    ASSERT_TRUE(back.ok()) << back.error().message << "\n" << text;
    EXPECT_TRUE(*back == *rig) << text;
  }
}

// ------------------------------------------------------------- defaults

TEST(RigConfig, OmittedKeysTakeTheStructDefaults) {
  const Expected<RigConfig> rig = Parse(kValidRig);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  const CameraConfig defaults;
  const CameraConfig& cam1 = rig->cameras[1];
  EXPECT_EQ(cam1.trigger, defaults.trigger);
  EXPECT_EQ(cam1.exposure_us, defaults.exposure_us);
  EXPECT_EQ(cam1.gain_db, defaults.gain_db);
  EXPECT_EQ(cam1.pixel_format, defaults.pixel_format);
  EXPECT_EQ(cam1.socket_buffer_bytes, defaults.socket_buffer_bytes);
  EXPECT_EQ(rig->recorder, RecorderConfig{});
  EXPECT_EQ(rig->processing, ProcessingConfig{});
  EXPECT_EQ(rig->lcm, LcmConfig{});
  EXPECT_EQ(rig->vicon.rotation, RotationRepresentation::kHelicalRad);
  EXPECT_EQ(rig->vicon.handedness, Handedness::kLeftFlipY);
  EXPECT_EQ(rig->vicon.plate_object, "plate");
  EXPECT_EQ(rig->vicon.rate_hz, 80.0);
  EXPECT_EQ(rig->vicon.trigger_divider, 8);
  EXPECT_EQ(rig->cameras[0].exposure_us, 5000.0);
  EXPECT_EQ(rig->cameras[0].serial, "111");
}

TEST(RigConfig, RelativePathsResolveAgainstTheRigFolder) {
  const Expected<RigConfig> rig = ParseRigConfig(
      test::ReplaceFirst(test::ReplaceFirst(kValidRig, "mla_file: raytrix_mla_R42_sc2_klein.xml",
                                            "mla_file: ./sub/../raytrix_mla_R42_sc2_klein.xml"),
                         "vicon:\n", "recorder: {out_dir: out/run1}\nvicon:\n"),
      SamplesDir(), "rig.yaml");
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_EQ(rig->cameras[0].mla_file, test::SamplePath("raytrix_mla_R42_sc2_klein.xml"));
  EXPECT_EQ(rig->recorder.out_dir, SamplesDir() / "out" / "run1");
}

TEST(RigConfig, SerialsKeepLeadingZeros) {
  const Expected<RigConfig> rig =
      Parse(test::ReplaceFirst(kValidRig, "serial: \"111\"", "serial: 0042"));
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_EQ(rig->cameras[0].serial, "0042");
}

TEST(RigConfig, CheckWorksOnConfigsBuiltInCode) {
  RigConfig rig;
  rig.name = "code";
  CameraConfig camera;
  camera.serial = "1";
  camera.name = "a";
  camera.role = CameraRole::kReference;
  camera.mla_file = "/x.xml";
  rig.cameras.push_back(camera);
  EXPECT_TRUE(rig.Check().ok()) << rig.Check().error().message;
  rig.cameras[0].exposure_us = 0.0;
  const Status status = rig.Check();
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message,
            "rig 'code': /cameras/0/exposure_us: expected a number > 0 and <= 1e7 (microseconds), got 0");
}

// ------------------------------------------------------------- round trip

std::string RandomText(std::mt19937& rng, int min_length) {
  static const std::vector<std::string> kPieces = {
      "a", "Z", "7", " ", "\"", "\\", "'", ":", "#", "-", "[",    "]", "{",    "}",    ",",
      "&", "*", "!", "|", ">",  "%",  "@", "`", "?", "ü", "日本", "~", "null", "true", "1e3"};
  std::uniform_int_distribution<int> length(min_length, 12);
  std::uniform_int_distribution<std::size_t> piece(0, kPieces.size() - 1);
  std::string text;
  for (int i = length(rng); i > 0; --i) text += kPieces[piece(rng)];
  return text;
}

std::string RandomIdentifier(std::mt19937& rng) {
  static const std::string kChars = "abcXYZ0123456789_-";
  std::uniform_int_distribution<std::size_t> pick(0, kChars.size() - 1);
  std::string text;
  for (int i = std::uniform_int_distribution<int>(1, 8)(rng); i > 0; --i) text += kChars[pick(rng)];
  return text;
}

fs::path RandomAbsolutePath(std::mt19937& rng, const std::string& extension) {
  static const std::string kChars = "ab XY09_#:'\"\\";
  std::uniform_int_distribution<std::size_t> pick(0, kChars.size() - 1);
  fs::path path = "/";
  for (int part = std::uniform_int_distribution<int>(1, 3)(rng); part > 0; --part) {
    std::string name = "d";
    for (int i = std::uniform_int_distribution<int>(0, 6)(rng); i > 0; --i)
      name += kChars[pick(rng)];
    path /= name;
  }
  return path.string() + extension;
}

template <typename T>
T Pick(std::mt19937& rng, std::initializer_list<T> values) {
  std::uniform_int_distribution<std::size_t> pick(0, values.size() - 1);
  return *(values.begin() + pick(rng));
}

RigConfig RandomRig(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto coin = [&] { return unit(rng) < 0.5; };
  const auto integer = [&](int lo, int hi) {
    return std::uniform_int_distribution<int>(lo, hi)(rng);
  };
  RigConfig rig;
  rig.name = RandomText(rng, 1);
  const int n = integer(1, 4);
  const int reference = integer(0, n - 1);
  for (int i = 0; i < n; ++i) {
    CameraConfig camera;
    camera.serial = RandomIdentifier(rng) + std::to_string(i);
    camera.name = RandomIdentifier(rng) + "_" + std::to_string(i);
    camera.role = i == reference ? CameraRole::kReference : CameraRole::kRegistered;
    camera.driver.kind = Pick(rng, {DriverKind::kAravis, DriverKind::kGenTl, DriverKind::kReplay});
    if (camera.driver.kind == DriverKind::kAravis && coin())
      camera.driver.address = RandomText(rng, 1);
    if (camera.driver.kind == DriverKind::kGenTl) {
      if (coin()) camera.driver.cti = RandomAbsolutePath(rng, ".cti");
      if (coin()) camera.driver.interface_id = RandomText(rng, 1);
      if (coin()) camera.driver.device = RandomText(rng, 1);
    }
    camera.mla_file = test::SamplePath(Pick<std::string>(
        rng, {"raytrix_mla_R42_sc2_klein.xml", "raytrix_mla_R29_Cards2_Processed.xml",
              "raytrix_mla_frog1_tree_Calibration_rot90.xml"}));
    camera.trigger.mode =
        Pick(rng, {TriggerMode::kHardware, TriggerMode::kSoftware, TriggerMode::kFreeRun});
    camera.trigger.source = Pick<std::string>(rng, {"Line0", "Line1", "Line3", "CxpTrigger0"});
    camera.trigger.activation =
        Pick(rng, {TriggerActivation::kRisingEdge, TriggerActivation::kFallingEdge});
    camera.exposure_us = 1e6 * unit(rng) + 1e-9;
    camera.gain_db = coin() ? 0.0 : 48.0 * unit(rng);
    camera.pixel_format = Pick(rng, {CameraPixelFormat::kMono8, CameraPixelFormat::kBgr8,
                                     CameraPixelFormat::kBayerRg8, CameraPixelFormat::kBayerGr8,
                                     CameraPixelFormat::kBayerGb8, CameraPixelFormat::kBayerBg8});
    if (coin())
      camera.roi = RoiConfig{integer(0, 100), integer(0, 100), integer(1, 7000), integer(1, 5000)};
    if (camera.driver.kind == DriverKind::kAravis) {
      camera.packet_size_bytes = coin() ? 0 : integer(576, 65535);
      camera.socket_buffer_bytes = coin() ? 0 : std::int64_t{integer(1, 1 << 30)} * 8;
    }
    camera.vicon_object = coin() ? "" : "obj" + std::to_string(i) + RandomText(rng, 0);
    camera.device_clock = coin() ? "" : "ptp" + RandomText(rng, 0);
    rig.cameras.push_back(camera);
  }
  ViconConfig& vicon = rig.vicon;
  vicon.source = Pick(rng, {ViconSourceKind::kNone, ViconSourceKind::kUdp, ViconSourceKind::kCsv});
  vicon.udp.address = std::to_string(integer(0, 255)) + "." + std::to_string(integer(0, 255)) +
                      "." + std::to_string(integer(0, 255)) + "." + std::to_string(integer(0, 255));
  vicon.udp.port = integer(1, 65535);
  if (vicon.source == ViconSourceKind::kCsv || coin())
    vicon.csv = test::SamplePath("vicon_nexus_trajectories_pyomeca_markers_first135frames.csv");
  vicon.rotation =
      Pick(rng, {RotationRepresentation::kHelicalRad, RotationRepresentation::kHelicalDeg,
                 RotationRepresentation::kEulerXyzDeg, RotationRepresentation::kEulerXyzRad});
  vicon.handedness = Pick(rng, {Handedness::kRight, Handedness::kLeftFlipX, Handedness::kLeftFlipY,
                                Handedness::kLeftFlipZ});
  vicon.plate_object = "plate" + RandomText(rng, 0);
  vicon.rate_hz = 1.0 + 999.0 * unit(rng);
  vicon.trigger_divider = integer(1, 16);
  if (coin()) vicon.vsk = test::SamplePath("vicon_tracker_object_go2_body.vsk");
  if (coin()) rig.recorder.out_dir = RandomAbsolutePath(rng, "");
  rig.recorder.queue_frames = integer(1, 4096);
  rig.recorder.writer_threads = integer(1, 64);
  rig.recorder.direct_io = coin();
  rig.recorder.direct_io_min_kb = integer(0, 1 << 22);
  rig.recorder.max_memory_mb = integer(0, 1 << 20);
  rig.processing.enabled = coin();
  rig.processing.threads = integer(0, 1024);
  rig.processing.skip_policy = Pick(rng, {SkipPolicy::kNewestWins, SkipPolicy::kBlock});
  rig.processing.preview_max_px = integer(16, 8192);
  // Every provider's form (config/rig_config.h, LcmUrlProblem); the log
  // file's path carries the characters YAML must quote.
  rig.lcm.url = Pick<std::string>(rng, {"udpm://", "udpm://239.255.76.67:7667?ttl=0",
                                        "udpm://224.0.0.1:1?ttl=255&recv_buf_size=4194304", "memq://",
                                        "tcpq://", "tcpq://localhost:7700",
                                        "file://" + RandomAbsolutePath(rng, ".log").string() +
                                            "?mode=w&speed=0.5"});
  rig.lcm.channel_prefix = Pick<std::string>(rng, {"LIFMCR", "A", "RIG_2", "X_Y_Z9"});
  rig.lcm.publish_previews = coin();
  return rig;
}

TEST(RigConfig, RandomConfigsRoundTripThroughFormatAndParse) {
  std::mt19937 rng(20240611);
  for (int i = 0; i < 300; ++i) {
    const RigConfig rig = RandomRig(rng);
    const auto issue = rig.FindIssue();
    ASSERT_FALSE(issue.has_value()) << issue->path << ": " << issue->what;
    const std::string text = FormatRigConfig(rig);
    const Expected<RigConfig> back = ParseRigConfig(text, "/unrelated", "random.yaml");
    ASSERT_TRUE(back.ok()) << back.error().message << "\n" << text;
    ASSERT_TRUE(*back == rig) << "rig " << i << "\n" << text << "\n" << FormatRigConfig(*back);
  }
}

// ------------------------------------------------------------- bad input

// cameras[].device_clock: cameras naming one clock; "" (omitted) is the driver's.
TEST(RigConfig, DeviceClockIsReadAndControlCharactersAreRefused) {
  const std::string yaml =
      test::ReplaceFirst(kValidRig, "    vicon_object: cam0\n",
                         "    vicon_object: cam0\n    device_clock: ptp domain 0\n");
  const Expected<RigConfig> rig = Parse(yaml);
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_EQ(rig->cameras[0].device_clock, "ptp domain 0");
  EXPECT_EQ(rig->cameras[1].device_clock, "");
  const std::string message = ErrorOf(test::ReplaceFirst(
      kValidRig, "    vicon_object: cam0\n", "    vicon_object: cam0\n    device_clock: \"a\\tb\"\n"));
  EXPECT_NE(message.find("/cameras/0/device_clock"), std::string::npos) << message;
}

TEST(RigConfigErrors, UnknownTopLevelKey) {
  const std::string yaml = kValidRig + "cameraz: []\n";
  EXPECT_EQ(ErrorOf(yaml), "rig.yaml:" + PositionOf(yaml, "cameraz") +
                               ": /cameraz: unknown key 'cameraz', expected one of: rig, "
                               "cameras, vicon, recorder, processing, lcm, registration");
}

TEST(RigConfigErrors, UnknownNestedKey) {
  const std::string yaml = test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure: 5000");
  const std::string message = ErrorOf(yaml);
  EXPECT_EQ(message.rfind("rig.yaml:" + PositionOf(yaml, "exposure:") +
                              ": /cameras/0/exposure: unknown key 'exposure', expected one of: "
                              "serial, name, role, driver,",
                          0),
            0u)
      << message;
  EXPECT_NE(message.find("exposure_us"), std::string::npos) << message;

  const std::string in_driver =
      test::ReplaceFirst(kValidRig, "{kind: replay}", "{kind: replay, ip: 1}");
  EXPECT_EQ(ErrorOf(in_driver).rfind("rig.yaml:" + PositionOf(in_driver, "ip: 1") +
                                         ": /cameras/1/driver/ip: unknown key 'ip'",
                                     0),
            0u)
      << ErrorOf(in_driver);
}

TEST(RigConfigErrors, WrongTypeForExposure) {
  const std::string yaml = test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure_us: fast");
  EXPECT_EQ(ErrorOf(yaml), "rig.yaml:" + PositionOf(yaml, "fast") +
                               ": /cameras/0/exposure_us: expected a finite number, got 'fast'");
  const std::string quoted =
      test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure_us: \"5000\"");
  EXPECT_EQ(ErrorOf(quoted),
            "rig.yaml:" + PositionOf(quoted, "\"5000\"") +
                ": /cameras/0/exposure_us: expected a finite number, got the string \"5000\"");
  const std::string map = test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure_us: {a: 1}");
  EXPECT_EQ(ErrorOf(map), "rig.yaml:" + PositionOf(map, "{a: 1}") +
                              ": /cameras/0/exposure_us: expected a number, got a map");
}

TEST(RigConfigErrors, OutOfRangeValues) {
  const std::string port = test::ReplaceFirst(kValidRig, "port: 51001", "port: 70000");
  EXPECT_EQ(ErrorOf(port), "rig.yaml:" + PositionOf(port, "70000") +
                               ": /vicon/udp/port: expected a port in 1..65535, got 70000");
  const std::string exposure =
      test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure_us: -1");
  EXPECT_EQ(ErrorOf(exposure),
            "rig.yaml:" + PositionOf(exposure, "-1") +
                ": /cameras/0/exposure_us: expected a number > 0 and <= 1e7 (microseconds), got -1");
  // Values no real camera, Vicon or sensor can have (issue 17).
  const std::string huge = test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure_us: 1e300");
  EXPECT_NE(ErrorOf(huge).find("/cameras/0/exposure_us: expected a number > 0 and <= 1e7"),
            std::string::npos);
  const std::string rate = kValidRig + "  rate_hz: 1e9\n";
  EXPECT_NE(ErrorOf(rate).find("/vicon/rate_hz: expected a number 1 .. 10000 (Hz)"),
            std::string::npos)
      << ErrorOf(rate);
}

TEST(RigConfigErrors, BadEnumListsTheAllowedValues) {
  const std::string yaml = test::ReplaceFirst(kValidRig, "role: reference", "role: master");
  EXPECT_EQ(ErrorOf(yaml), "rig.yaml:" + PositionOf(yaml, "master") +
                               ": /cameras/0/role: expected one of reference|registered, got "
                               "'master'");
  const std::string handedness = kValidRig + "  handedness: left\n";
  EXPECT_EQ(ErrorOf(handedness), "rig.yaml:" + PositionOf(handedness, "left\n") +
                                     ": /vicon/handedness: expected one of "
                                     "right|left_flip_x|left_flip_y|left_flip_z, got 'left'");
}

TEST(RigConfigErrors, MissingRequiredKey) {
  const std::string yaml =
      test::ReplaceFirst(kValidRig, "serial: \"222\"\n    name: cam1", "name: cam1");
  EXPECT_EQ(ErrorOf(yaml), "rig.yaml:" + PositionOf(yaml, "name: cam1") +
                               ": /cameras/1/serial: missing required key 'serial'");
  const std::string no_cameras = "rig: {name: x}\n";
  EXPECT_EQ(ErrorOf(no_cameras), "rig.yaml:1:1: /cameras: missing required key 'cameras'");
}

TEST(RigConfigErrors, DuplicateSerials) {
  const std::string yaml = test::ReplaceFirst(kValidRig, "serial: \"222\"", "serial: \"111\"");
  EXPECT_EQ(ErrorOf(yaml), "rig.yaml:" + PositionOf(yaml, "\"111\"\n    name: cam1") +
                               ": /cameras/1/serial: serial '111' is already used by /cameras/0");
  const std::string names = test::ReplaceFirst(kValidRig, "name: cam1", "name: cam0");
  EXPECT_EQ(ErrorOf(names), "rig.yaml:" + PositionOf(names, "cam0\n    role: registered") +
                                ": /cameras/1/name: name 'cam0' is already used by /cameras/0");
}

TEST(RigConfigErrors, ExactlyOneReference) {
  const std::string two = test::ReplaceFirst(kValidRig, "role: registered", "role: reference");
  EXPECT_EQ(ErrorOf(two),
            "rig.yaml:" + PositionOf(two, "reference\n    driver: {kind: replay}") +
                ": /cameras/1/role: expected exactly one camera with role reference, found a "
                "second one (the first is /cameras/0)");
  const std::string none = test::ReplaceFirst(kValidRig, "role: reference", "role: registered");
  EXPECT_EQ(ErrorOf(none), "rig.yaml:" + PositionOf(none, "- serial") +
                               ": /cameras: expected exactly one camera with role reference, "
                               "found none");
}

TEST(RigConfigErrors, MissingMlaFile) {
  const std::string yaml =
      test::ReplaceFirst(kValidRig, "raytrix_mla_R29_Cards2_Processed.xml", "nope.xml");
  EXPECT_EQ(ErrorOf(yaml), "rig.yaml:" + PositionOf(yaml, "nope.xml") +
                               ": /cameras/1/mla_file: expected an existing MLA calibration file: " +
                               (SamplesDir() / "nope.xml").string() + ": no such file or folder");
}

TEST(RigConfigErrors, MalformedYamlNamesTheLine) {
  const std::string yaml = test::ReplaceFirst(kValidRig, "{address: 127.0.0.1, port: 51001}",
                                              "[address: 127.0.0.1, port: 51001");
  const std::string message = ErrorOf(yaml);
  EXPECT_EQ(message.rfind("rig.yaml:", 0), 0u) << message;
  EXPECT_NE(message.find("malformed YAML"), std::string::npos) << message;
  // yaml-cpp notices the missing ']' at the end of the document: line 20.
  EXPECT_NE(message.find("rig.yaml:20:"), std::string::npos) << message;
}

TEST(RigConfigErrors, DuplicateKey) {
  const std::string yaml = test::ReplaceFirst(kValidRig, "exposure_us: 5000",
                                              "exposure_us: 5000\n    exposure_us: 6000");
  EXPECT_EQ(ErrorOf(yaml), "rig.yaml:" + PositionOf(yaml, "exposure_us: 6000") +
                               ": /cameras/0/exposure_us: duplicate key 'exposure_us' (first "
                               "given at line 9)");
}

TEST(RigConfigErrors, DriverFieldsMustMatchTheKind) {
  // A gentl camera without a cti searches GENICAM_GENTL64_PATH.
  const std::string gentl = test::ReplaceFirst(kValidRig, "{kind: replay}", "{kind: gentl}");
  EXPECT_TRUE(Parse(gentl).ok()) << gentl;
  const std::string device =
      test::ReplaceFirst(kValidRig, "{kind: replay}", "{kind: replay, device: X1}");
  EXPECT_EQ(ErrorOf(device), "rig.yaml:" + PositionOf(device, "X1") +
                                 ": /cameras/1/driver/device: only the gentl driver takes a "
                                 "device, kind is replay");
  const std::string cti =
      test::ReplaceFirst(kValidRig, "{kind: replay}", "{kind: replay, cti: a.cti}");
  EXPECT_EQ(ErrorOf(cti), "rig.yaml:" + PositionOf(cti, "a.cti") +
                              ": /cameras/1/driver/cti: only the gentl driver takes a cti, kind is "
                              "replay");
}

TEST(RigConfigErrors, EmptyAndNullValues) {
  const std::string null_value = test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure_us:");
  const std::string message = ErrorOf(null_value);
  EXPECT_EQ(message.rfind("rig.yaml:" + PositionOf(null_value, "exposure_us:") +
                              ": /cameras/0/exposure_us: expected a number, got nothing (null)",
                          0),
            0u)
      << message;
  EXPECT_EQ(ErrorOf(""), "rig.yaml:1:1: /: expected a map, got nothing (null)");
  EXPECT_EQ(ErrorOf("- 1\n"), "rig.yaml:1:1: /: expected a map, got a list");
}

// Found by tests/fuzz/fuzz_rig_yaml: yaml-cpp 0.7's LoadAll loops forever,
// allocating, on a document that starts with ','; the reader must answer.
TEST(RigConfigErrors, CommaAtTheStartOfADocumentIsAnErrorNotAHang) {
  for (const std::string& yaml : {std::string(","), std::string(",i\n\n\x7f\xff\x7f\xff\xff"),
                                 std::string("rig: {name: x}\n ,   role: registered\n"),
                                 std::string("a: 1\n---\n,\n")}) {
    const Expected<RigConfig> rig = Parse(yaml);
    ASSERT_FALSE(rig.ok()) << yaml;
    EXPECT_EQ(rig.error().message.rfind("rig.yaml", 0), 0u) << rig.error().message;
  }
}

// LCM opens only what its providers take; a rig file naming anything else
// must fail here, at its line, not when the publisher starts.
TEST(RigConfigErrors, LcmUrlThatLcmCannotOpen) {
  const auto error_of_url = [](const std::string& url) {
    return ErrorOf(kValidRig + "lcm:\n  url: \"" + url + "\"\n");
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"nonsense", "expected an LCM URL: udpm://GROUP:PORT"},
      {"http://239.255.76.67:7667", "expected an LCM URL"},
      {"udpm://nonsense!!:abc", "udpm:// group 'nonsense!!' is not a multicast IPv4 address"},
      {"udpm://10.0.0.1:7667", "udpm:// group '10.0.0.1' is not a multicast IPv4 address"},
      {"udpm://239.255.76.67:99999", "udpm:// port '99999' is not a port 1..65535"},
      {"udpm://239.255.76.67:7667?ttl=1000", "option 'ttl' of udpm://: expected 0..255"},
      {"udpm://239.255.76.67:7667?ttl", "option 'ttl' is not KEY=VALUE"},
      {"udpm://239.255.76.67:7667?bogus=1", "option 'bogus' of udpm://: unknown"},
      {"udpm://239.255.76.67:7667?transmit_only=yes", "expected true or false"},
      {"memq://x", "memq:// takes no address or options"},
      {"tcpq://host name:7700", "tcpq:// host 'host name' is not a host name"},
      {"tcpq://localhost:0", "tcpq:// port '0' is not a port 1..65535"},
      {"file://", "file:// names no log file"},
      {"file:///tmp/x.log?mode=z", "option 'mode' of file://: expected r, w or a"},
  };
  for (const auto& [url, expected] : cases) {
    const std::string message = error_of_url(url);
    EXPECT_NE(message.find("/lcm/url: "), std::string::npos) << url << ": " << message;
    EXPECT_NE(message.find(expected), std::string::npos) << url << ": " << message;
  }
  for (const std::string url :
       {"udpm://239.255.76.67:7667?ttl=0", "udpm://", "udpm://224.0.0.1", "memq://",
        "udpm://239.255.76.67:7713?ttl=0&recv_buf_size=4194304&transmit_only=false",
        "tcpq://", "tcpq://127.0.0.1:7700", "file:///tmp/log.lcm?mode=w&speed=2"}) {
    const Expected<RigConfig> rig = Parse(kValidRig + "lcm:\n  url: \"" + url + "\"\n");
    EXPECT_TRUE(rig.ok()) << url << ": " << (rig.ok() ? "" : rig.error().message);
  }
}

// A Vicon rate no system has, or a trigger period of minutes, is a typo.
TEST(RigConfigErrors, AbsurdlySmallRates) {
  EXPECT_NE(ErrorOf(kValidRig + "  rate_hz: 1e-300\n")
                .find("/vicon/rate_hz: expected a number 1 .. 10000 (Hz), got 1e-300"),
            std::string::npos);
  EXPECT_NE(ErrorOf(kValidRig + "  rate_hz: 0.08\n").find("/vicon/rate_hz"), std::string::npos);
  const std::string period = ErrorOf(kValidRig + "  rate_hz: 80\n  trigger_divider: 8000\n");
  EXPECT_NE(period.find("/vicon/trigger_divider: gives camera triggers every 100 s (rate_hz 80 / "
                        "trigger_divider 8000); expected a trigger at least every 60 s"),
            std::string::npos)
      << period;
  EXPECT_TRUE(Parse(kValidRig + "  rate_hz: 1\n  trigger_divider: 60\n").ok());
}

// yaml-cpp's depth guard says "bad file"; the message says what is wrong.
TEST(RigConfigErrors, YamlNestedTooDeep) {
  const std::string deep = "rig: " + std::string(100000, '[') + std::string(100000, ']') + "\n";
  const std::string message = ErrorOf(deep);
  EXPECT_EQ(message.rfind("rig.yaml:1:", 0), 0u) << message;
  EXPECT_NE(message.find("levels deep here, more than the YAML reader takes"), std::string::npos)
      << message;
  EXPECT_EQ(message.find("bad file"), std::string::npos) << message;
}

// 1e-400 is a finite number: it reads as 0 where a number is expected.
TEST(RigConfig, UnderflowReadsAsZero) {
  const Expected<RigConfig> rig = Parse(test::ReplaceFirst(kValidRig, "exposure_us: 5000",
                                                           "exposure_us: 5000\n    gain_db: 1e-400"));
  ASSERT_TRUE(rig.ok()) << rig.error().message;
  EXPECT_EQ(rig->cameras[0].gain_db, 0.0);
  EXPECT_NE(ErrorOf(test::ReplaceFirst(kValidRig, "exposure_us: 5000", "exposure_us: 1e400"))
                .find("/cameras/0/exposure_us: expected a finite number, got '1e400'"),
            std::string::npos);
}

TEST(RigConfigErrors, UnreadableFile) {
  const Expected<RigConfig> rig = LoadRigConfig("/nonexistent/rig.yaml");
  ASSERT_FALSE(rig.ok());
  EXPECT_EQ(rig.error().message.rfind("/nonexistent/rig.yaml: no such file or folder; expected a rig file", 0), 0u)
      << rig.error().message;
}

TEST(RigConfigErrors, RandomlyMutatedFilesNeverCrash) {
  std::mt19937 rng(99);
  const std::string base = FormatRigConfig(*LoadRigConfig(ExamplePath("lifmcr_two_r32.yaml")));
  static const std::string kInsert = "[]{}:-\"'\\#&*!|>%@`? \n\t0a";
  for (int i = 0; i < 400; ++i) {
    std::string text = base;
    for (int m = std::uniform_int_distribution<int>(1, 4)(rng); m > 0; --m) {
      if (text.empty()) break;
      const std::size_t at = std::uniform_int_distribution<std::size_t>(0, text.size() - 1)(rng);
      switch (std::uniform_int_distribution<int>(0, 2)(rng)) {
        case 0:
          text.erase(at, 1);
          break;
        case 1:
          text.insert(
              at, 1,
              kInsert[std::uniform_int_distribution<std::size_t>(0, kInsert.size() - 1)(rng)]);
          break;
        default:
          text.resize(at);
      }
    }
    const Expected<RigConfig> rig = ParseRigConfig(text, "/", "mutated.yaml");
    if (!rig.ok()) {
      EXPECT_EQ(rig.error().message.rfind("mutated.yaml:", 0), 0u) << rig.error().message;
    }
  }
}

}  // namespace
}  // namespace lifmcr
