// The files evaluation reads (round trips, errors naming file and line) and
// the association of camera frames with Vicon samples.
#include "evaluation/evaluation_inputs.h"
#include "evaluation/vicon_ground_truth.h"
#include "tests/test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace lifmcr {
namespace {

Pose Make(double angle_rad, const Eigen::Vector3d& t) {
  Pose p = Pose::Identity();
  p.linear() = Eigen::AngleAxisd(angle_rad, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  p.translation() = t;
  return p;
}

TEST(EvaluationInputs, RegistrationCsvRoundTripKeepsFailures) {
  test::TempDir dir;
  std::vector<RegistrationRow> rows(2);
  rows[0] = {4, "40398673", "pnp", Make(0.3, {1, 2, 3}), 120, 0.45, "ok", 0};
  rows[1] = {5, "40398673", "pnp", Pose::Identity(), 3, 0, "too few inliers, 3", 0};
  test::WriteFile(dir / "r.csv", FormatRegistrationCsv(rows));
  Expected<RegistrationTable> table = ReadRegistrationCsv(dir / "r.csv");
  ASSERT_TRUE(table) << table.error().message;
  ASSERT_EQ(table->rows.size(), 2u);
  EXPECT_EQ(table->rows[0].frame, 4);
  EXPECT_EQ(table->rows[0].inliers, 120);
  EXPECT_TRUE(table->rows[0].c0_from_cx.isApprox(rows[0].c0_from_cx, 1e-6));
  EXPECT_EQ(table->rows[1].status, "too few inliers, 3");  // quoted: it holds a comma
  test::WriteFile(dir / "bad.csv", "frame,camera,method,tx_mm\n1,2,pnp,3\n");
  Expected<RegistrationTable> bad = ReadRegistrationCsv(dir / "bad.csv");
  ASSERT_FALSE(bad);
  test::ExpectMessageHas(bad.error(), {"bad.csv", "ty_mm"});
}

TEST(EvaluationInputs, FrameTumAndHandEyeYaml) {
  test::TempDir dir;
  test::WriteFile(dir / "t.tum",
                  "# TUM trajectory of w0_from_cam: frame tx_mm ty_mm tz_mm qx qy qz qw\n"
                  "3 1 2 3 0 0 0 1\n7 4 5 6 0 0 0.7071067811865476 0.7071067811865476\n");
  Expected<FramePoses> poses = ReadFrameTum(dir / "t.tum");
  ASSERT_TRUE(poses) << poses.error().message;
  ASSERT_EQ(poses->size(), 2u);
  EXPECT_NEAR(poses->at(7).translation().z(), 6, 1e-12);
  EXPECT_NEAR(RotationAngleDeg(poses->at(7).linear()), 90, 1e-9);
  test::WriteFile(dir / "bad.tum", "3 1 2 3 0 0 0\n");
  Expected<FramePoses> bad = ReadFrameTum(dir / "bad.tum");
  ASSERT_FALSE(bad);
  test::ExpectMessageHas(bad.error(), {"bad.tum:1", "8 numbers"});

  HandEyeOffsets offsets{{"40398678", Make(0.05, {3, -70, -40})}, {"40398673", Make(-0.02, {1, 2, 3})}};
  test::WriteFile(dir / "h.yaml", FormatHandEyeYaml(offsets, "test"));
  Expected<HandEyeOffsets> back = ReadHandEyeYaml(dir / "h.yaml");
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->size(), 2u);
  EXPECT_TRUE(back->at("40398678").isApprox(offsets.at("40398678"), 1e-6));
}

TEST(ViconGroundTruth, TriggersTakeTheirSampleInterpolateAndCountUntracked) {
  // Vicon frames 1..40; the camera fires every 8th from frame 1 (image 0).
  std::vector<ViconPoseSample> samples;
  for (int f = 1; f <= 40; ++f)
    samples.push_back({f, Pose(Make(0, Eigen::Vector3d(10.0 * f, 0, 0)))});
  samples[16].vicon_from_marker.reset();  // Vicon frame 17 = image frame 2: occluded
  FrameAssociationOptions options;
  const std::vector<std::int64_t> frames{0, 1, 2, 3, 4, 5};
  AssociatedPoses a = AssociateFrames(samples, frames, options);
  EXPECT_EQ(a.vicon_from_marker.size(), 4u);
  EXPECT_EQ(a.untracked, (std::vector<std::int64_t>{2, 5}));  // occluded; beyond the samples
  EXPECT_NEAR(a.vicon_from_marker.at(3).translation().x(), 250, 1e-9);  // Vicon frame 25
  // A trigger latency of half a Vicon frame: interpolated between samples.
  options.vicon_frame_offset = 0.5;
  a = AssociateFrames(samples, frames, options);
  EXPECT_NEAR(a.vicon_from_marker.at(1).translation().x(), 95, 1e-9);
  EXPECT_EQ(a.untracked, (std::vector<std::int64_t>{2, 5}));  // 17.5 borders 17; 41.5 beyond
  EXPECT_EQ(FramesCoveredBy(samples, FrameAssociationOptions{}),
            (std::vector<std::int64_t>{0, 1, 2, 3, 4}));
}

}  // namespace
}  // namespace lifmcr
