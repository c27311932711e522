// A rig of four cameras live: `lifmcr replay --rate max --reference MAP` of a
// synthetic 4-camera `small` rig (three triggers; cameras moving
// independently), the map camera 0's ground-truth map extended by the other
// cameras (`register --chain`, so the far camera, three baselines from
// camera 0, has points it sees). A stock `lcm-logger` records every channel
// and `lifmcr monitor` watches the bus beside it. Every camera publishes its
// per-lens depth, TF image and pose for every trigger, every camera X its
// c0_from_cx (within the 2 mm / 0.1 deg, median), and the monitor
// shows a row per camera and each camera X's extrinsics. Then the same rig as
// hardware: `lifmcr record --rig --replay --publish --reference` records every
// camera's frames and publishes each camera X's c0_from_cx. As root (loopback
// multicast); skipped with the reason otherwise.
#include "config/rig_config.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/map/poses_csv.h"
#include "replay/layout.h"
#include "tests/apps/synthetic_rig_file.h"
#include "tests/child_process.h"
#include "tests/lcm_log_marker.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include "evaluation/evaluation_inputs.h"
#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <unistd.h>
#include <vector>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

const std::string kGroup = test::MulticastGroupOfThisProcess(81);
const std::string kUrl =
    "udpm://" + kGroup + ":" + std::to_string(test::MulticastPortOfThisProcess()) + "?ttl=0";
constexpr int kFrames = 3;
constexpr int kCameras = 4;

int Sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

TEST(CliFourCamerasLive, ReplayAndRecordPublishEveryCameraAndTheMonitorShowsEach) {
  if (getuid() != 0 || Sh("command -v lcm-logger") != 0 || Sh("ip link set lo multicast on") != 0)
    GTEST_SKIP() << "needs root (loopback multicast) and lcm-logger";
  test::TempDir dir;
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + (dir / "data").string() + " --preset small --frames " +
      std::to_string(kFrames) + " --cameras " + std::to_string(kCameras) + " --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  const test::CommandResult chain = test::RunLifmcr(
      "register " + seq.string() +
      " --reference-from-ground-truth --observations ground-truth --method pnp --chain --out " +
      (dir / "register").string());
  ASSERT_EQ(chain.exit_code, 0) << chain.err;
  const fs::path map = dir / "register" / "chained_reference";
  ASSERT_TRUE(fs::is_directory(map)) << chain.out;

  // Each camera's truth, camera 0 the one the table's rows are related to.
  std::map<std::string, std::map<std::int64_t, Pose>> truth;
  for (const auto& entry : fs::directory_iterator(seq / "GroundTruth")) {
    const std::string name = entry.path().filename().string();
    if (!name.starts_with("poses_")) continue;
    auto poses = registration::ReadPosesCsv(entry.path());
    ASSERT_TRUE(poses) << poses.error().message;
    for (const auto& p : *poses)
      truth[name.substr(6, name.size() - 10)][p.frame] = p.world_from_cam;
  }
  ASSERT_EQ(truth.size(), static_cast<std::size_t>(kCameras));

  const bool added_route = Sh("ip route add " + kGroup + "/32 dev lo") == 0;
  const fs::path log_path = dir / "run.lcmlog";
  test::Child logger("", {"lcm-logger", "--lcm-url=" + kUrl, log_path.string()},
                     dir / "logger.txt");
  test::Child monitor("", test::LifmcrArgv({"monitor", "--lcm", kUrl}), dir / "monitor.txt");
  ASSERT_TRUE(test::PublishUntilLogged(kUrl, log_path.string(), "TEST_MARK_BEFORE"))
      << "lcm-logger did not start: " << logger.Log();
  const fs::path csv = dir / "extrinsics.csv";
  const test::CommandResult replay =
      test::RunLifmcr("replay " + seq.string() + " --rate max --lcm " + kUrl + " --reference " +
                      map.string() + " --extrinsics-csv " + csv.string());
  const bool logged = test::PublishUntilLogged(kUrl, log_path.string(), "TEST_MARK_AFTER");
  // The monitor's view needs a refresh after the last message (twice a second).
  std::this_thread::sleep_for(std::chrono::seconds(1));
  logger.Signal(SIGINT);
  monitor.Signal(SIGINT);
  EXPECT_EQ(logger.Wait(std::chrono::seconds(30)), 0) << logger.Log();
  EXPECT_EQ(monitor.Wait(std::chrono::seconds(30)), 0) << monitor.Log();
  if (added_route) Sh("ip route del " + kGroup + "/32 dev lo");
  ASSERT_EQ(replay.exit_code, 0) << replay.out << replay.err;
  ASSERT_TRUE(logged);

  // The table: a row per camera X and trigger, each camera X within the gate.
  Expected<RegistrationTable> table = ReadRegistrationCsv(csv);
  ASSERT_TRUE(table) << table.error().message;
  EXPECT_EQ(table->rows.size(), static_cast<std::size_t>((kCameras - 1) * kFrames));
  std::string zero;
  for (const auto& [serial, poses] : truth)
    if (std::none_of(table->rows.begin(), table->rows.end(),
                     [&](const RegistrationRow& row) { return row.camera == serial; }))
      zero = serial;
  ASSERT_FALSE(zero.empty());
  std::map<std::string, std::vector<double>> t_mm, r_deg;
  for (const RegistrationRow& row : table->rows) {
    if (row.status != "ok") continue;
    const Pose expected = truth[zero][row.frame].inverse() * truth[row.camera][row.frame];
    t_mm[row.camera].push_back(registration::TranslationDifference(row.c0_from_cx, expected));
    r_deg[row.camera].push_back(registration::RotationDifferenceDeg(row.c0_from_cx, expected));
  }
  for (const auto& [serial, poses] : truth) {
    if (serial == zero) continue;
    std::printf("live %s: %zu/%d ok, median %.3f mm / %.4f deg (gate 2 mm / 0.1 deg)\n",
                serial.c_str(), t_mm[serial].size(), kFrames, Median(t_mm[serial]),
                Median(r_deg[serial]));
    EXPECT_GE(t_mm[serial].size(), 2u) << serial;
    EXPECT_LE(Median(t_mm[serial]), 2.0) << serial;
    EXPECT_LE(Median(r_deg[serial]), 0.1) << serial;
  }

  // The log: every camera's products for every trigger, extrinsics per camera X.
  std::map<std::string, int> channels;
  lcm::LogFile log(log_path.string(), "r");
  ASSERT_TRUE(log.good());
  while (const lcm::LogEvent* event = log.readNextEvent()) ++channels[event->channel];
  for (const auto& [serial, poses] : truth) {
    const std::string prefix = "LIFMCR_" + serial + "_";
    EXPECT_GE(channels[prefix + "DEPTH"], kFrames) << serial;
    EXPECT_GE(channels[prefix + "TF"], kFrames) << serial;
    EXPECT_EQ(channels[prefix + "POSE"], kFrames) << serial;
    EXPECT_EQ(channels[prefix + "EXTRINSICS"], serial == zero ? 0 : kFrames) << serial;
  }
  std::printf("lcm-logger: %zu channels\n", channels.size());

  // The monitor: a row per camera, and each camera X's extrinsics.
  const std::string view = monitor.Log();
  for (const auto& [serial, poses] : truth) {
    EXPECT_NE(view.find("\n" + serial + " "), std::string::npos) << serial << "\n" << view;
    if (serial != zero) {
      EXPECT_NE(view.find(zero + " <- " + serial), std::string::npos) << serial << "\n" << view;
    }
  }

  // The same rig recorded as if from its cameras (replay driver, hardware
  // trigger), published and registered live against the same map.
  std::vector<std::string> serials;
  for (const auto& [serial, poses] : truth) serials.push_back(serial);
  const RigConfig rig = test::SyntheticReplayRig("four_cameras", dir / "data", seq, serials, zero);
  test::WriteFile(dir / "rig.yaml", FormatRigConfig(rig));
  const fs::path recorded_csv = dir / "recorded_extrinsics.csv";
  const test::CommandResult record = test::RunLifmcr(
      "record --rig " + (dir / "rig.yaml").string() + " --replay " + seq.string() + " --out " +
      (dir / "rec").string() + " --duration 120 --publish --lcm memq:// --reference " +
      map.string() + " --extrinsics-csv " + recorded_csv.string());
  ASSERT_EQ(record.exit_code, 0) << record.out << record.err;
  for (const auto& [serial, poses] : truth) {
    int frames = 0;
    for (const auto& entry : fs::directory_iterator(dir / "rec" / "00_Recording" / "seq" /
                                                    layout::CameraFolderName(serial)))
      frames += entry.is_regular_file() ? 1 : 0;
    EXPECT_EQ(frames, kFrames) << serial << " recorded\n" << record.out;
  }
  Expected<RegistrationTable> recorded = ReadRegistrationCsv(recorded_csv);
  ASSERT_TRUE(recorded) << recorded.error().message;
  std::map<std::string, int> recorded_ok;
  for (const RegistrationRow& row : recorded->rows) {
    if (row.status != "ok") continue;
    const Pose expected = truth[zero][row.frame].inverse() * truth[row.camera][row.frame];
    EXPECT_LE(registration::TranslationDifference(row.c0_from_cx, expected), 5.0) << row.camera;
    ++recorded_ok[row.camera];
  }
  for (const auto& [serial, poses] : truth) {
    if (serial == zero) continue;
    std::printf("record --publish %s: %d ok c0_from_cx\n", serial.c_str(), recorded_ok[serial]);
    EXPECT_GE(recorded_ok[serial], 1) << serial << "\n" << record.out;
  }
}

}  // namespace
}  // namespace lifmcr
