// `lifmcr replay SEQ --rate max --reference MAP --extrinsics-csv FILE` end to
// end through the binary, on a small synthetic 2-camera table rig: a reference
// map of camera 0 from the sequence's ground truth (`lifmcr register
// --reference-from-ground-truth`, its OUT/reference), true intrinsics
// (GroundTruth/cameras.yaml), every frame processed from the raw BMPs and
// localised live. A real `lcm-logger` records the EXTRINSICS channel on a
// multicast group of this test's own (loopback route added, as root; the
// LCM part is skipped otherwise); the CSV is read with the reader `lifmcr
// evaluate` uses. Gates (true intrinsics): c0_from_cx median error
// against GroundTruth <= 2 mm / 0.1 deg, >= 95 % of triggers registered.
#include "config/rig_config.h"
#include "tests/acquisition/rig_fixture.h"
#include "lcm_types/safe_decode.h"
#include "evaluation/evaluation_inputs.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/map/poses_csv.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>
#include <lifmcr_lcm/camera_pose_t.hpp>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

// A group of this process's own and a port no other test uses, so no other
// test's (or other checkout's run of this test's) route or logger interferes.
const std::string kGroup = test::MulticastGroupOfThisProcess(71);
const std::string kUrl =
    "udpm://" + kGroup + ":" + std::to_string(test::MulticastPortOfThisProcess()) + "?ttl=0";
constexpr int kFrames = 8;

int Sh(const std::string& command) { return std::system((command + " >/dev/null 2>&1").c_str()); }

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

TEST(CliLiveRegistration, ReplayWithAReferenceMapPublishesAccurateExtrinsicsPerTrigger) {
  test::TempDir dir;
  const test::CommandResult synth =
      test::RunLifmcr("synth --out " + (dir / "data").string() + " --preset small --frames " +
                      std::to_string(kFrames) + " --cameras 2 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  // The map only: camera 0's frames 0-2 from the ground truth.
  const test::CommandResult map =
      test::RunLifmcr("register " + seq.string() +
                      " --reference-from-ground-truth --observations ground-truth --frames 1 "
                      "--out " + (dir / "map").string());
  ASSERT_EQ(map.exit_code, 0) << map.err;
  const fs::path reference = dir / "map" / "reference";

  // The logger on our own group, when we may route multicast over loopback.
  const bool multicast = getuid() == 0 && Sh("command -v lcm-logger") == 0 &&
                         Sh("ip link set lo multicast on") == 0;
  const bool added_route = multicast && Sh("ip route add " + kGroup + "/32 dev lo") == 0;
  const std::string log_path = (dir / "run.lcmlog").string();
  pid_t logger = -1;
  if (multicast) {
    logger = fork();
    ASSERT_GE(logger, 0);
    if (logger == 0) {
      std::freopen("/dev/null", "w", stdout);  // its once-a-second summary
      execlp("lcm-logger", "lcm-logger", ("--lcm-url=" + kUrl).c_str(),
             "--channel=.*_EXTRINSICS", log_path.c_str(), nullptr);
      _exit(127);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
  }
  const fs::path csv = dir / "extrinsics.csv";
  const test::CommandResult replay = test::RunLifmcr(
      "replay " + seq.string() + " --rate max --lcm " + (multicast ? kUrl : std::string("memq://")) +
      " --reference " + reference.string() + " --extrinsics-csv " + csv.string());
  if (multicast) {
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
    kill(logger, SIGINT);
    int status = 0;
    waitpid(logger, &status, 0);
    if (added_route) Sh("ip route del " + kGroup + "/32 dev lo");
  }
  ASSERT_EQ(replay.exit_code, 0) << replay.out << replay.err;
  EXPECT_NE(replay.out.find(std::to_string(kFrames) + " extrinsics"), std::string::npos)
      << replay.out;
  EXPECT_NE(replay.out.find("rows in " + csv.string()), std::string::npos) << replay.out;
  EXPECT_NE(replay.out.find(" relocalised ("), std::string::npos) << replay.out;

  // Ground truth: c0_from_cx = world_from_c0^-1 world_from_cx per frame.
  Expected<RegistrationTable> table = ReadRegistrationCsv(csv);
  ASSERT_TRUE(table) << table.error().message;
  ASSERT_EQ(table->rows.size(), static_cast<std::size_t>(kFrames));
  const std::string x = table->rows.front().camera;
  std::string zero;
  std::map<std::string, std::map<std::int64_t, Pose>> truth;
  for (const auto& entry : fs::directory_iterator(seq / "GroundTruth")) {
    const std::string name = entry.path().filename().string();
    if (!name.starts_with("poses_")) continue;
    const std::string serial = name.substr(6, name.size() - 10);
    if (serial != x) zero = serial;
    auto poses = registration::ReadPosesCsv(entry.path());
    ASSERT_TRUE(poses) << poses.error().message;
    for (const auto& p : *poses) truth[serial][p.frame] = p.world_from_cam;
  }
  std::vector<double> t_mm, r_deg;
  std::map<std::int64_t, Pose> by_trigger;
  for (const RegistrationRow& row : table->rows) {
    EXPECT_EQ(row.method, "pnp");
    if (row.status != "ok") continue;
    const Pose expected = truth[zero][row.frame].inverse() * truth[x][row.frame];
    t_mm.push_back(registration::TranslationDifference(row.c0_from_cx, expected));
    r_deg.push_back(registration::RotationDifferenceDeg(row.c0_from_cx, expected));
    by_trigger[row.frame] = row.c0_from_cx;
  }
  const double registered = static_cast<double>(t_mm.size()) / kFrames;
  std::printf("live c0_from_cx vs GroundTruth: median %.3f mm / %.4f deg, max %.3f mm / %.4f deg, "
              "registered %zu/%d (%.0f %%) (gates 2 mm / 0.1 deg, 95 %%)\n",
              Median(t_mm), Median(r_deg), *std::max_element(t_mm.begin(), t_mm.end()),
              *std::max_element(r_deg.begin(), r_deg.end()), t_mm.size(), kFrames,
              100 * registered);
  EXPECT_LE(Median(t_mm), 2.0);
  EXPECT_LE(Median(r_deg), 0.1);
  EXPECT_GE(registered, 0.95);

  if (!multicast) GTEST_SKIP() << "the LCM part needs root (loopback multicast) and lcm-logger";
  // What the logger received: one message per trigger, as in the CSV.
  lcm::LogFile log(log_path, "r");
  ASSERT_TRUE(log.good());
  std::set<std::int64_t> triggers;
  std::set<std::string> localisations;
  int messages = 0;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    ASSERT_EQ(event->channel, "LIFMCR_" + x + "_EXTRINSICS");
    auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::camera_extrinsics_t>(event->data,
                                                                      event->datalen);
    ASSERT_TRUE(m);
    ++messages;
    EXPECT_EQ(m->reference_serial, zero);
    EXPECT_EQ(m->serial, x);
    EXPECT_EQ(m->method, "pnp");
    EXPECT_EQ(m->status, "ok");
    EXPECT_GE(m->inliers, 12);
    EXPECT_GT(m->rmse_px, 0.0);
    EXPECT_LT(m->rmse_px, 2.0);
    EXPECT_GT(m->covariance[0][0], 0.0);  // carried, in mm^2
    EXPECT_GT(m->covariance[5][5], 0.0);
    EXPECT_EQ(m->change_state, lifmcr_lcm::camera_extrinsics_t::CHANGE_OFF);
    localisations.insert(m->localisation);
    triggers.insert(m->trigger_index);
    ASSERT_TRUE(by_trigger.count(m->trigger_index));
    const Pose& row = by_trigger[m->trigger_index];
    EXPECT_NEAR(m->t_mm[0], row.translation().x(), 1e-3);
    EXPECT_NEAR(m->t_mm[2], row.translation().z(), 1e-3);
  }
  EXPECT_EQ(messages, kFrames);
  EXPECT_EQ(triggers.size(), static_cast<std::size_t>(kFrames));
  // The first frame of each camera is relocalised, the following ones tracked.
  EXPECT_TRUE(localisations.count("relocalised")) << "localisations seen: " << localisations.size();
  EXPECT_TRUE(localisations.count("tracked"));
  std::printf("lcm-logger: %d EXTRINSICS messages, triggers 0..%lld\n", messages,
              static_cast<long long>(*triggers.rbegin()));
}

// A timed replay (`--rate original`: newest wins, registration first) with
// live registration, recorded by a stock lcm-logger: every frame a worker
// took has a POSE message (tracked, relocalised or passed through); every
// frame taken (the workers' and the ones they skipped) goes to the lens
// lane, whose per-lens depth (_DEPTH, GEOMETRY_LENS_GRID) and TF image of it
// are in the log unless a newer frame of its camera replaced it there (the
// report counts those; a small frame's per-lens depth costs a fraction of
// the 100 ms between frames, so none is expected without load); the
// report's per-lens count is the log's.
TEST(CliLiveRegistration, TimedReplayAccountsForThePerLensDepthOfEveryFrameTaken) {
  if (getuid() != 0 || Sh("command -v lcm-logger") != 0 || Sh("ip link set lo multicast on") != 0)
    GTEST_SKIP() << "needs root (loopback multicast) and lcm-logger";
  test::TempDir dir;
  const test::CommandResult synth =
      test::RunLifmcr("synth --out " + (dir / "data").string() + " --preset small --frames " +
                      std::to_string(kFrames) + " --cameras 2 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  const test::CommandResult map =
      test::RunLifmcr("register " + seq.string() +
                      " --reference-from-ground-truth --observations ground-truth --frames 1 "
                      "--out " + (dir / "map").string());
  ASSERT_EQ(map.exit_code, 0) << map.err;
  const bool added_route = Sh("ip route add " + kGroup + "/32 dev lo") == 0;
  const std::string log_path = (dir / "run.lcmlog").string();
  const pid_t logger = fork();
  ASSERT_GE(logger, 0);
  if (logger == 0) {
    std::freopen("/dev/null", "w", stdout);
    // Above the replay's priority, with a large receive buffer: a starved
    // logger drops messages, which is not the pipeline's loss.
    (void)setpriority(PRIO_PROCESS, 0, -10);
    execlp("lcm-logger", "lcm-logger", ("--lcm-url=" + kUrl + "&recv_buf_size=4194304").c_str(),
           "--channel=LIFMCR_.*_(POSE|DEPTH|TF)", log_path.c_str(), nullptr);
    _exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  const test::CommandResult replay =
      test::RunLifmcr("replay " + seq.string() + " --rate original --lcm " + kUrl +
                      " --reference " + (dir / "map" / "reference").string());
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  kill(logger, SIGINT);
  int status = 0;
  waitpid(logger, &status, 0);
  if (added_route) Sh("ip route del " + kGroup + "/32 dev lo");
  ASSERT_EQ(replay.exit_code, 0) << replay.out << replay.err;

  using Key = std::pair<std::string, std::int64_t>;  // serial, frame_id
  std::set<Key> posed, lens_depth, tf;
  lcm::LogFile log(log_path, "r");
  ASSERT_TRUE(log.good());
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    const std::string& channel = event->channel;
    if (channel.ends_with("_POSE")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::camera_pose_t>(event->data, event->datalen);
      ASSERT_TRUE(m);
      posed.insert({m->serial, m->frame_id});
    } else if (channel.ends_with("_DEPTH")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::depth_image_t>(event->data, event->datalen);
      ASSERT_TRUE(m);
      if (m->geometry == lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID)
        lens_depth.insert({m->serial, m->frame_id});
    } else if (channel.ends_with("_TF")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::preview_image_t>(event->data, event->datalen);
      ASSERT_TRUE(m);
      tf.insert({m->serial, m->frame_id});
    }
  }
  ASSERT_FALSE(posed.empty()) << replay.out;
  // Each per-lens depth with its TF image (of a frame the workers localised
  // or of one they skipped: the lens lane takes every frame).
  std::map<std::string, int> per_camera;
  for (const Key& key : lens_depth) {
    EXPECT_TRUE(tf.count(key)) << key.first << " frame " << key.second << ": no TF image";
    ++per_camera[key.first];
  }
  EXPECT_EQ(per_camera.size(), 2u);
  EXPECT_NE(replay.out.find("depth messages: " + std::to_string(lens_depth.size()) + " per-lens"),
            std::string::npos)
      << replay.out;
  // Every frame taken is accounted for: its per-lens depth in the log, or
  // replaced in the lens lane by its camera's newer frame.
  const std::string lane = "lens lane: processed " + std::to_string(lens_depth.size()) + " skipped ";
  const auto at = replay.out.find(lane);
  ASSERT_NE(at, std::string::npos) << replay.out;
  const long skipped = std::strtol(replay.out.c_str() + at + lane.size(), nullptr, 10);
  const std::string in = "frames in: ";
  const auto in_at = replay.out.find(in);
  ASSERT_NE(in_at, std::string::npos) << replay.out;
  const long frames_in = std::strtol(replay.out.c_str() + in_at + in.size(), nullptr, 10);
  EXPECT_GE(static_cast<std::size_t>(frames_in), posed.size()) << replay.out;
  EXPECT_EQ(lens_depth.size() + static_cast<std::size_t>(skipped),
            static_cast<std::size_t>(frames_in))
      << replay.out;
  EXPECT_NE(replay.out.find(lane + std::to_string(skipped) + " failed 0,"), std::string::npos)
      << replay.out;
  // Each skipped frame with its reason: replaced while the lane was busy, or
  // older than a frame the lane had taken (a localised frame comes with its pose).
  const std::string why = "lens lane skipped: ";
  const auto why_at = replay.out.find(why);
  ASSERT_NE(why_at, std::string::npos) << replay.out;
  char* after = nullptr;
  const long replaced = std::strtol(replay.out.c_str() + why_at + why.size(), &after, 10);
  const std::string busy = " replaced by a newer frame of its camera while the lane was busy, ";
  ASSERT_EQ(std::string(after, busy.size()), busy) << replay.out;
  const long stale = std::strtol(after + busy.size(), nullptr, 10);
  EXPECT_EQ(replaced + stale, skipped) << replay.out;
  for (const auto& [serial, n] : per_camera)
    std::printf("camera %s: per-lens depth and TF of %d of %d frames (%ld frames taken replaced "
                "in the lens lane, both cameras)\n",
                serial.c_str(), n, kFrames, skipped);
}

// Extrinsic change detection end to end, short: a rigid synthetic rig
// (`synth --config` rig: {rigid: true, knock_frame: 7}) whose last camera is
// knocked 5 mm / 0.5 deg from trigger 7 on, recorded from its replay with
// `record --publish --reference MAP` and a rig file saying
// registration: {rigid_mount: true, settle_triggers: 4} (the default settles
// over 10 triggers; the gates over 200 triggers are the unit test's,
// tests/registration/test_extrinsics_monitor.cpp). The extrinsics go to an
// LCM log file (the rig's lcm.url).
TEST(CliLiveRegistration, RecordFlagsACameraKnockedOnARigidMount) {
  constexpr int kTriggers = 11, kKnock = 7;
  test::TempDir dir;
  // The file is checked on its own before --frames applies: frames in it too.
  test::WriteFile(dir / "synth.yaml", "rig:\n  rigid: true\n  frames: " +
                                          std::to_string(kTriggers) + "\n  knock_frame: " +
                                          std::to_string(kKnock) + "\n");
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + (dir / "data").string() + " --preset small --frames " +
      std::to_string(kTriggers) + " --cameras 2 --quiet --config " + (dir / "synth.yaml").string());
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  const test::CommandResult map =
      test::RunLifmcr("register " + seq.string() +
                      " --reference-from-ground-truth --observations ground-truth --frames 1 "
                      "--out " + (dir / "map").string());
  ASSERT_EQ(map.exit_code, 0) << map.err;
  const auto sequence = DiscoverSequence(seq);
  ASSERT_TRUE(sequence.ok());

  RigConfig rig = test::TwoCameraRig();
  rig.vicon.source = ViconSourceKind::kNone;
  rig.vicon.rate_hz = 160;  // 20 Hz triggers
  rig.vicon.udp.port = 51003;
  for (int c = 0; c < 2; ++c) {
    rig.cameras[c].serial = sequence->cameras[c].serial;
    rig.cameras[c].mla_file =
        layout::MlaXmlPath(dir / "data" / "Calibration", rig.cameras[c].serial);
    rig.cameras[c].trigger.mode = TriggerMode::kHardware;
  }
  const fs::path log = dir / "run.lcmlog";
  rig.processing.skip_policy = SkipPolicy::kBlock;  // every trigger registered
  rig.lcm.url = "file://" + log.string() + "?mode=w";
  rig.registration.rigid_mount = true;
  rig.registration.settle_triggers = 4;
  const fs::path rig_path = dir / "rig.yaml";
  test::WriteFile(rig_path, FormatRigConfig(rig));
  const test::CommandResult record = test::RunLifmcr(
      "record --rig " + rig_path.string() + " --replay " + seq.string() + " --out " +
      (dir / "rec").string() + " --duration 300 --publish --reference " +
      (dir / "map" / "reference").string() + " --extrinsics-csv " + (dir / "x.csv").string());
  ASSERT_EQ(record.exit_code, 0) << record.out << record.err;
  EXPECT_NE(record.out.find("rows in"), std::string::npos) << record.out;
  // Both cameras (white images in the sequence) warmed before they start.
  EXPECT_NE(record.err.find("per-lens estimators and TF samplers of 2 camera(s) made before the "
                            "cameras start"),
            std::string::npos)
      << record.err;

  lcm::LogFile file(log.string(), "r");
  ASSERT_TRUE(file.good());
  std::map<std::int64_t, lifmcr_lcm::camera_extrinsics_t> by_trigger, fused;
  while (const lcm::LogEvent* event = file.readNextEvent()) {
    const bool is_fused = event->channel.ends_with("_EXTRINSICS_FUSED");
    if (!event->channel.ends_with("_EXTRINSICS") && !is_fused) continue;
    auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::camera_extrinsics_t>(event->data,
                                                                      event->datalen);
    ASSERT_TRUE(m);
    (is_fused ? fused : by_trigger)[m->trigger_index] = *m;
  }
  // The fused estimate beside each trigger's (docs/lcm.md): the running
  // estimate as the pose, its covariance, the triggers fused.
  ASSERT_FALSE(fused.empty());
  for (const auto& [trigger, f] : fused) {
    ASSERT_TRUE(by_trigger.count(trigger)) << trigger;
    const lifmcr_lcm::camera_extrinsics_t& m = by_trigger.at(trigger);
    EXPECT_EQ(f.method, "fused");
    EXPECT_EQ(f.localisation, "fused");
    EXPECT_EQ(f.status, "ok");
    EXPECT_GE(f.inliers, 1);
    EXPECT_GT(f.covariance[0][0], 0.0);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(f.t_mm[k], m.running_t_mm[k]);
    EXPECT_EQ(f.change_state, m.change_state);
  }
  ASSERT_GE(by_trigger.size(), static_cast<std::size_t>(kTriggers - 1)) << record.out;
  std::int64_t first_changed = -1;
  for (const auto& [trigger, m] : by_trigger) {
    std::printf("trigger %2lld: %s t = (%.2f, %.2f, %.2f) mm, change_state %d, departure %.1f, "
                "%d in a row\n",
                static_cast<long long>(trigger), m.status.c_str(), m.t_mm[0], m.t_mm[1], m.t_mm[2],
                m.change_state, m.departure, m.departures_in_row);
    EXPECT_NE(m.change_state, lifmcr_lcm::camera_extrinsics_t::CHANGE_OFF);
    if (trigger < kKnock) {
      EXPECT_NE(m.change_state, lifmcr_lcm::camera_extrinsics_t::CHANGE_CHANGED)
          << "false alarm at trigger " << trigger;
    }
    if (m.change_state == lifmcr_lcm::camera_extrinsics_t::CHANGE_CHANGED && first_changed < 0)
      first_changed = trigger;
  }
  ASSERT_GE(first_changed, kKnock) << "the knock was not flagged";
  EXPECT_LT(first_changed, kKnock + 5) << "flagged later than 5 triggers after the knock";
  std::printf("knocked at trigger %d, flagged at trigger %lld (%lld triggers)\n", kKnock,
              static_cast<long long>(first_changed),
              static_cast<long long>(first_changed - kKnock + 1));
}

}  // namespace
}  // namespace lifmcr
