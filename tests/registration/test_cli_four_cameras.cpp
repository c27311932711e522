// A rig of four cameras through `lifmcr synth -> register -> evaluate` at
// `small` (three triggers, keypoints and depth from the ground truth): the
// two cameras next to camera 0 register against camera 0's map; the far
// camera (three baselines away) does through the map extended by the
// cameras registered before it (`register --chain`,
// registration/map/map_extension.h); evaluate writes a row per camera.
#include "registration/estimators/pose_covariance.h"
#include "registration/map/poses_csv.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include "evaluation/evaluation_inputs.h"
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

TEST(CliFourCameras, TheFarCameraRegistersThroughTheChainedMap) {
  test::TempDir dir;
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + (dir / "data").string() + " --preset small --frames 3 --cameras 4 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  // Camera 0 is the first in cameras.yaml; the truth of every camera.
  std::map<std::string, std::map<std::int64_t, Pose>> truth;
  for (const auto& entry : fs::directory_iterator(seq / "GroundTruth")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("poses_", 0) != 0) continue;
    Expected<std::vector<registration::FramePose>> poses = registration::ReadPosesCsv(entry.path());
    ASSERT_TRUE(poses) << poses.error().message;
    for (const auto& p : *poses)
      truth[name.substr(6, name.size() - 10)][p.frame] = p.world_from_cam;
  }
  ASSERT_EQ(truth.size(), 4u);

  // Per camera X: (ok rows, median c0_from_cx error mm, deg).
  struct Summary {
    int ok = 0, rows = 0;
    double t_mm = 0, r_deg = 0;
  };
  std::string zero;
  auto run = [&](const std::string& extra, const fs::path& out) {
    const test::CommandResult r =
        test::RunLifmcr("register " + seq.string() +
                        " --reference-from-ground-truth --observations ground-truth "
                        "--method pnp " +
                        extra + " --out " + out.string());
    EXPECT_EQ(r.exit_code, 0) << r.err;
    std::map<std::string, Summary> summary;
    Expected<RegistrationTable> table = ReadRegistrationCsv(out / "registration.csv");
    EXPECT_TRUE(table) << (table ? "" : table.error().message);
    if (!table) return summary;
    EXPECT_EQ(table->rows.size(), 9u);  // three cameras X, three frames
    for (const auto& [serial, poses] : truth)
      if (std::none_of(table->rows.begin(), table->rows.end(),
                       [&](const RegistrationRow& row) { return row.camera == serial; }))
        zero = serial;
    std::map<std::string, std::vector<double>> t, rot;
    for (const RegistrationRow& row : table->rows) {
      ++summary[row.camera].rows;
      if (row.status != "ok") continue;
      const Pose expected = truth[zero][row.frame].inverse() * truth[row.camera][row.frame];
      t[row.camera].push_back(registration::TranslationDifference(row.c0_from_cx, expected));
      rot[row.camera].push_back(registration::RotationDifferenceDeg(row.c0_from_cx, expected));
      ++summary[row.camera].ok;
    }
    for (auto& [serial, s] : summary) {
      s.t_mm = Median(t[serial]);
      s.r_deg = Median(rot[serial]);
      std::printf("%s %s: %d/%d ok, median %.3f mm / %.4f deg\n", extra.c_str(), serial.c_str(),
                  s.ok, s.rows, s.t_mm, s.r_deg);
    }
    return summary;
  };
  const std::map<std::string, Summary> alone = run("", dir / "alone");
  const std::map<std::string, Summary> chained = run("--chain", dir / "chained");
  ASSERT_EQ(chained.size(), 3u);
  // The far camera: the last in cameras.yaml order is the one three
  // baselines from camera 0 (lifmcr synth); registration.csv keeps that order.
  Expected<RegistrationTable> table = ReadRegistrationCsv(dir / "chained" / "registration.csv");
  ASSERT_TRUE(table);
  const std::string far = table->rows.back().camera;
  // Against camera 0's map alone the far camera sees too little of it for
  // the pose checks (fewer frames registered than with the chain).
  EXPECT_LT(alone.at(far).ok, 3);
  // Through the chain: every frame of every camera, the gate
  // (2 mm / 0.1 deg median) for each.
  for (const auto& [serial, s] : chained) {
    EXPECT_EQ(s.ok, 3) << serial;
    EXPECT_LE(s.t_mm, 2.0) << serial;
    EXPECT_LE(s.r_deg, 0.1) << serial;
  }

  // evaluate: a table row and a hand-eye per camera.
  const test::CommandResult evaluation = test::RunLifmcr(
      "evaluate " + seq.string() + " --registration " +
      (dir / "chained" / "registration.csv").string() + " --out " + (dir / "evaluation").string() +
      " --hand-eye truth --split none --no-plots --quiet");
  ASSERT_EQ(evaluation.exit_code, 0) << evaluation.err;
  for (const auto& [serial, s] : chained)
    EXPECT_NE(evaluation.out.find("pnp " + serial + "           absolute, hand-eye"),
              std::string::npos)
        << evaluation.out;
}

// `synth --cameras 4 --rigid`: one rig whose cameras move together, so every
// camera's c0_from_cx is the same at every trigger; without it each camera
// has its own trajectory (LiFMCR's sequences) and c0_from_cx changes.
TEST(CliFourCameras, SynthRigidKeepsEveryCameraOnItsMount) {
  test::TempDir dir;
  for (const bool rigid : {true, false}) {
    const fs::path out = dir / (rigid ? "rigid" : "free");
    const test::CommandResult synth = test::RunLifmcr(
        "synth --out " + out.string() +
        " --preset small --frames 5 --cameras 4 --no-images --quiet" + (rigid ? " --rigid" : ""));
    ASSERT_EQ(synth.exit_code, 0) << synth.err;
    const fs::path truth = out / "00_Synthetic" / "Sequence_00" / "GroundTruth";
    std::map<std::string, std::vector<registration::FramePose>> poses;
    for (const auto& entry : fs::directory_iterator(truth)) {
      const std::string name = entry.path().filename().string();
      if (name.rfind("poses_", 0) != 0) continue;
      Expected<std::vector<registration::FramePose>> p = registration::ReadPosesCsv(entry.path());
      ASSERT_TRUE(p) << p.error().message;
      ASSERT_EQ(p->size(), 5u);
      poses[name.substr(6, name.size() - 10)] = *p;
    }
    ASSERT_EQ(poses.size(), 4u);
    const std::vector<registration::FramePose>& zero = poses.begin()->second;
    double largest_change_mm = 0, largest_change_deg = 0;
    for (const auto& [serial, p] : poses) {
      const Pose first = zero[0].world_from_cam.inverse() * p[0].world_from_cam;
      for (std::size_t f = 1; f < p.size(); ++f) {
        const Pose c0_from_cx = zero[f].world_from_cam.inverse() * p[f].world_from_cam;
        largest_change_mm =
            std::max(largest_change_mm, registration::TranslationDifference(c0_from_cx, first));
        largest_change_deg =
            std::max(largest_change_deg, registration::RotationDifferenceDeg(c0_from_cx, first));
      }
    }
    std::printf("%s: c0_from_cx changes by up to %.6f mm / %.6f deg over 5 triggers\n",
                rigid ? "--rigid" : "independent", largest_change_mm, largest_change_deg);
    if (rigid) {
      EXPECT_LT(largest_change_mm, 1e-3);
      EXPECT_LT(largest_change_deg, 1e-4);
    } else {
      EXPECT_GT(largest_change_mm, 1.0);
    }
  }
}

// `calibrate --rig` on cameras whose ground truth moves them independently
// (synth without --rigid) refuses before processing a frame and names
// --non-rigid (apps/cmd_calibrate.cpp).
TEST(CliFourCameras, CalibrateRigRefusesCamerasMovingIndependentlyWithoutNonRigid) {
  test::TempDir dir;
  const test::CommandResult synth =
      test::RunLifmcr("synth --out " + (dir / "data").string() +
                      " --preset small --frames 2 --cameras 2 --no-images --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  const std::string common = "calibrate " + seq.string() +
                             " --rig --cameras 40398678,40398673 --initial " +
                             (seq / "GroundTruth" / "cameras.yaml").string() + " --quiet --out " +
                             (dir / "rig").string();
  const test::CommandResult rigid = test::RunLifmcr(common);
  EXPECT_EQ(rigid.exit_code, 2) << rigid.err;
  EXPECT_NE(rigid.err.find("the mount is not rigid"), std::string::npos) << rigid.err;
  EXPECT_NE(rigid.err.find("--rig --non-rigid"), std::string::npos) << rigid.err;
}

}  // namespace
}  // namespace lifmcr
