// `lifmcr register` end to end on a small synthetic rig (two cameras, three
// frames): a reference map from camera 0's ground truth, keypoints and depth
// from the ground truth, both methods. registration.csv is read back with
// the reader `lifmcr evaluate` uses and compared with GroundTruth/poses.
#include "evaluation/evaluation_inputs.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/map/poses_csv.h"
#include "replay/layout.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

TEST(CliRegister, BothMethodsRegisterCameraXAgainstAGroundTruthMap) {
  test::TempDir dir;
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + (dir / "data").string() + " --preset small --frames 3 --cameras 2 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  const test::CommandResult r = test::RunLifmcr(
      "register " + seq.string() + " --reference-from-ground-truth --observations ground-truth "
      "--method both --out " + (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // Progress and a summary line per camera and method on stderr; errors on stdout.
  EXPECT_NE(r.err.find("pnp: camera"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("ransac: camera"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("difference pnp - ransac"), std::string::npos) << r.out;
  // PnP's c0_from_cx against its own covariance (registration/estimators/pnp.h,
  // "Covariance"): the share of ok rows within the 95 % chi-square(6) bound,
  // printed; all but at most one of the three.
  {
    const std::size_t at = r.out.find("pnp checks");
    ASSERT_NE(at, std::string::npos) << r.out;
    int beyond = -1, within = -1, rows = -1;
    ASSERT_EQ(std::sscanf(r.out.c_str() + at,
                          "pnp checks %d ok rows beyond 5 mm / 0.25 deg; %d of %d", &beyond,
                          &within, &rows),
              3)
        << r.out.substr(at, 200);
    std::printf("PnP c0_from_cx: %d of %d ok rows within the 95 %% chi-square(6) bound\n", within,
                rows);
    EXPECT_EQ(beyond, 0);
    EXPECT_EQ(rows, 3);
    EXPECT_GE(within, rows - 1);
  }
  Expected<RegistrationTable> table = ReadRegistrationCsv(dir / "out" / "registration.csv");
  ASSERT_TRUE(table) << table.error().message;
  ASSERT_EQ(table->rows.size(), 6u);  // camera X, 3 frames, 2 methods
  const std::string x = table->rows.front().camera;
  // Camera X's inliers at the true pose: residual variance over the pose's
  // own s^2 per component near 1 (the independent part of the noise model;
  // camera 0's keypoints here are the map's own).
  {
    const std::size_t at = r.out.find("pnp inliers of " + x + " at the true pose");
    ASSERT_NE(at, std::string::npos) << r.out;
    double vx = 0, vy = 0;
    ASSERT_EQ(std::sscanf(r.out.c_str() + r.out.find("residual variance", at),
                          "residual variance / the pose's s^2 x %lf, y %lf", &vx, &vy),
              2)
        << r.out.substr(at, 200);
    EXPECT_GT(vx + vy, 1.0);
    EXPECT_LT(vx + vy, 3.0);
  }
  std::string zero;
  std::map<std::string, std::map<std::int64_t, Pose>> truth;
  for (const auto& entry : fs::directory_iterator(seq / "GroundTruth")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("poses_", 0) != 0) continue;
    const std::string serial = name.substr(6, name.size() - 10);
    if (serial != x) zero = serial;
    Expected<std::vector<registration::FramePose>> poses = registration::ReadPosesCsv(entry.path());
    ASSERT_TRUE(poses) << poses.error().message;
    for (const auto& p : *poses) truth[serial][p.frame] = p.world_from_cam;
  }
  ASSERT_FALSE(zero.empty());
  for (const RegistrationRow& row : table->rows) {
    ASSERT_EQ(row.status, "ok") << "frame " << row.frame << " " << row.method;
    EXPECT_GE(row.inliers, 12);
    EXPECT_GT(row.rmse_px, 0.0);
    EXPECT_LT(row.rmse_px, 2.0);
    // c0_from_cx = world_from_c0^-1 world_from_cx; loose bounds here, the
    // gates are measured on larger runs (docs/registration.md).
    const Pose expected = truth[zero][row.frame].inverse() * truth[x][row.frame];
    EXPECT_LT(registration::TranslationDifference(row.c0_from_cx, expected), 15.0)
        << row.method << " frame " << row.frame;
    EXPECT_LT(registration::RotationDifferenceDeg(row.c0_from_cx, expected), 0.5);
  }
  for (const std::string method : {"pnp", "ransac"})
    for (const std::string& serial : {zero, x})
      EXPECT_TRUE(fs::exists(dir / "out" / ("trajectory_" + serial + "_" + method + ".tum")));
  EXPECT_TRUE(fs::exists(dir / "out" / "reference" / "descriptors.bin"));

  // The written map read back as a calibration's would be: each camera's own
  // error against the truth (w0 is the world here), parsed from its line;
  // within the loose bounds above.
  const test::CommandResult again = test::RunLifmcr(
      "register " + seq.string() + " --reference " + (dir / "out" / "reference").string() +
      " --observations ground-truth --out " + (dir / "again").string());
  ASSERT_EQ(again.exit_code, 0) << again.err;
  for (const std::string& serial : {zero, x}) {
    const std::string label = "pnp w0_from_cam " + serial;
    const std::size_t at = again.out.find(label);
    ASSERT_NE(at, std::string::npos) << again.out;
    double t[3], r[3];
    int n = 0;
    ASSERT_EQ(std::sscanf(again.out.c_str() + again.out.find("mean in its own frame", at),
                          "mean in its own frame: position x %lf y %lf z %lf mm, rotation x %lf "
                          "y %lf z %lf deg (n=%d)",
                          &t[0], &t[1], &t[2], &r[0], &r[1], &r[2], &n),
              7)
        << again.out.substr(at, 200);
    std::printf("%s: position %.3f %.3f %.3f mm, rotation %.4f %.4f %.4f deg\n", label.c_str(),
                t[0], t[1], t[2], r[0], r[1], r[2]);
    EXPECT_EQ(n, 3);
    EXPECT_LT(std::sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]), 15.0);
    EXPECT_LT(std::sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]), 0.5);
  }
}

TEST(CliRegister, TheMapIndexRegistersAsTheExactMatcherDoes) {
  // The default matching (the map's kd-forest, features.h) against brute
  // force on the same rig and map: every frame registered by both, c0_from_cx
  // within a small fraction of the registration's own error (the gate is
  // 2 mm / 0.1 deg; docs/registration.md measures both on larger runs).
  test::TempDir dir;
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + (dir / "data").string() + " --preset small --frames 3 --cameras 2 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  std::map<std::string, std::vector<RegistrationRow>> rows;
  for (const std::string matching : {"exact", "approximate"}) {
    const fs::path out = dir / ("out_" + matching);
    const test::CommandResult r = test::RunLifmcr(
        "register " + seq.string() + " --reference-from-ground-truth --observations ground-truth "
        "--method pnp --matching " + matching + " --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err.find("map index: kd-forest") != std::string::npos, matching == "approximate")
        << r.err;
    Expected<RegistrationTable> table = ReadRegistrationCsv(out / "registration.csv");
    ASSERT_TRUE(table) << table.error().message;
    rows[matching] = table->rows;
  }
  ASSERT_EQ(rows["exact"].size(), 3u);
  ASSERT_EQ(rows["approximate"].size(), 3u);
  // The true c0_from_cx of each frame (camera 0 listed first in cameras.yaml).
  const std::string x = rows["exact"].front().camera;
  std::map<std::string, std::map<std::int64_t, Pose>> truth;
  std::string zero;
  for (const auto& entry : fs::directory_iterator(seq / "GroundTruth")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("poses_", 0) != 0) continue;
    const std::string serial = name.substr(6, name.size() - 10);
    if (serial != x) zero = serial;
    Expected<std::vector<registration::FramePose>> poses = registration::ReadPosesCsv(entry.path());
    ASSERT_TRUE(poses) << poses.error().message;
    for (const auto& p : *poses) truth[serial][p.frame] = p.world_from_cam;
  }
  double error_exact = 0, error_approximate = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    const RegistrationRow& e = rows["exact"][i];
    const RegistrationRow& a = rows["approximate"][i];
    ASSERT_EQ(e.status, "ok");
    ASSERT_EQ(a.status, "ok");
    const double t = registration::TranslationDifference(e.c0_from_cx, a.c0_from_cx);
    const double r = registration::RotationDifferenceDeg(e.c0_from_cx, a.c0_from_cx);
    std::printf("frame %lld: exact %lld inliers, approximate %lld; c0_from_cx differs by %.4f mm "
                "/ %.5f deg\n",
                static_cast<long long>(e.frame), static_cast<long long>(e.inliers),
                static_cast<long long>(a.inliers), t, r);
    EXPECT_LT(t, 0.25);
    EXPECT_LT(r, 0.01);
    EXPECT_GE(a.inliers, 0.95 * static_cast<double>(e.inliers));
    ASSERT_EQ(e.frame, a.frame);
    const Pose expected = truth[zero][e.frame].inverse() * truth[x][e.frame];
    error_exact += registration::TranslationDifference(e.c0_from_cx, expected) / 3;
    error_approximate += registration::TranslationDifference(a.c0_from_cx, expected) / 3;
  }
  // Against the truth, no worse on the mean than by a fraction of the exact
  // matcher's own error (about 0.3 mm at small, docs/registration.md).
  std::printf("mean c0_from_cx error: exact %.3f mm, approximate %.3f mm\n", error_exact,
              error_approximate);
  EXPECT_LT(error_approximate, error_exact + 0.1);
  const test::CommandResult bad = test::RunLifmcr(
      "register " + seq.string() + " --reference-from-ground-truth --matching magic --out " +
      (dir / "bad").string());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--matching magic: expected approximate or exact"), std::string::npos)
      << bad.err;
}

// The fast handheld rig (5x the default speed), where camera X's view is
// far from camera 0's map: matching each PnP pose's map points again around
// their projections (--guided-rounds, registration/map/frame_registration.h)
// finds many more of camera X's keypoints than the descriptor search alone,
// and no row marked ok is beyond the 5 mm / 0.25 deg bound either way.
TEST(CliRegister, GuidedRematchingFindsMoreInliersOnTheFastRig) {
  test::TempDir dir;
  test::WriteFile(dir / "fast.yaml", "rig: {speed_scale: 5}\n");
  const test::CommandResult synth = test::RunLifmcr(
      "synth --out " + (dir / "data").string() + " --preset small --config " +
      (dir / "fast.yaml").string() + " --frames 3 --cameras 2 --motion handheld --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.err;
  const fs::path seq = dir / "data" / "00_Synthetic" / "Sequence_00";
  std::map<int, std::vector<RegistrationRow>> rows;
  std::map<int, std::string> progress;  // stderr: each frame's inliers, refused poses' too
  for (const int rounds : {0, 2}) {
    const fs::path out = dir / ("out_" + std::to_string(rounds));
    const test::CommandResult r = test::RunLifmcr(
        "register " + seq.string() + " --reference-from-ground-truth --observations ground-truth "
        "--method pnp --guided-rounds " + std::to_string(rounds) + " --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.err.find("guided matches") != std::string::npos, rounds > 0) << r.err;
    const std::size_t at = r.out.find("pnp checks");
    ASSERT_NE(at, std::string::npos) << r.out;
    int beyond = -1;
    ASSERT_EQ(std::sscanf(r.out.c_str() + at, "pnp checks %d ok rows beyond", &beyond), 1);
    EXPECT_EQ(beyond, 0) << rounds << " rounds";
    Expected<RegistrationTable> table = ReadRegistrationCsv(out / "registration.csv");
    ASSERT_TRUE(table) << table.error().message;
    rows[rounds] = table->rows;
    progress[rounds] = r.err;
  }
  ASSERT_EQ(rows[0].size(), 3u);
  ASSERT_EQ(rows[2].size(), 3u);
  // Camera X's inliers per frame from the progress lines ("camera X frame
  // F: ... pnp STATUS: N inliers of M matches").
  const std::string x = rows[0].front().camera;
  const auto inliers_of = [&](const std::string& err) {
    std::vector<long> n;
    for (std::size_t at = err.find("camera " + x + " frame "); at != std::string::npos;
         at = err.find("camera " + x + " frame ", at + 1)) {
      const std::size_t end = err.find('\n', at);
      const std::string line = err.substr(at, end - at);
      const std::size_t of = line.find(" inliers of ");
      if (of == std::string::npos) continue;
      const std::size_t begin = line.rfind(' ', of - 1) + 1;
      n.push_back(std::stol(line.substr(begin, of - begin)));
    }
    return n;
  };
  const std::vector<long> alone = inliers_of(progress[0]), guided = inliers_of(progress[2]);
  ASSERT_EQ(alone.size(), 3u) << progress[0];
  ASSERT_EQ(guided.size(), 3u) << progress[2];
  long sum_alone = 0, sum_guided = 0;
  int ok_alone = 0, ok_guided = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    std::printf("frame %lld: %ld inliers (%s) alone, %ld (%s) guided\n",
                static_cast<long long>(rows[0][i].frame), alone[i], rows[0][i].status.c_str(),
                guided[i], rows[2][i].status.c_str());
    sum_alone += alone[i];
    sum_guided += guided[i];
    ok_alone += rows[0][i].status == "ok";
    ok_guided += rows[2][i].status == "ok";
  }
  EXPECT_GT(sum_guided, sum_alone + sum_alone / 4);
  EXPECT_GE(ok_guided, ok_alone);
}

TEST(CliRegister, UsageErrorsSayWhatIsExpected) {
  test::TempDir dir;
  const test::CommandResult method =
      test::RunLifmcr("register " + dir.path().string() + " --reference " + dir.path().string() +
                      " --method magic --out " + (dir / "out").string());
  EXPECT_EQ(method.exit_code, 2);
  EXPECT_NE(method.err.find("--method magic: expected pnp, ransac or both"), std::string::npos)
      << method.err;
  const test::CommandResult neither =
      test::RunLifmcr("register " + dir.path().string() + " --out " + (dir / "out").string());
  EXPECT_EQ(neither.exit_code, 2);
  EXPECT_NE(neither.err.find("--reference MAP_DIR or --reference-from-ground-truth"),
            std::string::npos)
      << neither.err;
}

}  // namespace
}  // namespace lifmcr
