// The metrics against hand-computed values (notes: identity -> 0, a pure
// offset -> its known APE, a constant offset X with rotating motion -> the
// RPE it causes).
#include "evaluation/trajectory_metrics.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace lifmcr {
namespace {

constexpr double kDeg = M_PI / 180.0;

Pose Make(double angle_deg, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  Pose p = Pose::Identity();
  p.linear() = Eigen::AngleAxisd(angle_deg * kDeg, axis.normalized()).toRotationMatrix();
  p.translation() = t;
  return p;
}

// A camera turning about its y axis by 10 degrees per frame while moving.
FramePoses RotatingTrajectory(int frames) {
  FramePoses poses;
  for (int i = 0; i < frames; ++i)
    poses[i] = Make(10.0 * i, Eigen::Vector3d::UnitY(), Eigen::Vector3d(5.0 * i, 0, 300));
  return poses;
}

TEST(ErrorStats, HandComputed) {
  const std::vector<double> v{1, 2, 3, 4};
  const ErrorStats s = ErrorStats::Of(v);
  EXPECT_EQ(s.count, 4u);
  EXPECT_NEAR(s.rmse, std::sqrt(30.0 / 4.0), 1e-12);
  EXPECT_NEAR(s.mean, 2.5, 1e-12);
  EXPECT_NEAR(s.median, 2.5, 1e-12);
  EXPECT_NEAR(s.sd, std::sqrt(1.25), 1e-12);  // population SD, as evo
  EXPECT_EQ(s.min, 1);
  EXPECT_EQ(s.max, 4);
  EXPECT_EQ(ErrorStats::Of(std::vector<double>{}).count, 0u);
}

TEST(TrajectoryMetrics, IdentityGivesZero) {
  const FramePoses truth = RotatingTrajectory(20);
  const ErrorSummary ape = SummarizeErrors(AbsolutePoseErrors(truth, truth));
  const ErrorSummary rpe = SummarizeErrors(RelativePoseErrors(truth, truth));
  EXPECT_EQ(ape.translation_mm.count, 20u);
  EXPECT_EQ(rpe.translation_mm.count, 19u);
  EXPECT_NEAR(ape.translation_mm.max, 0, 1e-9);
  EXPECT_NEAR(ape.rotation_deg.max, 0, 1e-6);
  EXPECT_NEAR(rpe.translation_mm.max, 0, 1e-9);
  EXPECT_NEAR(rpe.rotation_deg.max, 0, 1e-6);
}

TEST(TrajectoryMetrics, PureOffsetGivesItsApeAndNoRpeWithoutRotation) {
  // Translating camera (no rotation), estimate shifted by (3, -4, 12) mm in
  // the world: APE |t| = 13 mm in every frame; RPE 0 (the shift cancels).
  FramePoses truth, estimate;
  for (int i = 0; i < 10; ++i) {
    truth[i] = Make(0, Eigen::Vector3d::UnitZ(), Eigen::Vector3d(10.0 * i, 0, 0));
    estimate[i] = truth[i];
    estimate[i].translation() += Eigen::Vector3d(3, -4, 12);
  }
  const PoseErrors ape = AbsolutePoseErrors(estimate, truth);
  const ErrorSummary s = SummarizeErrors(ape);
  EXPECT_NEAR(s.translation_mm.rmse, 13.0, 1e-9);
  EXPECT_NEAR(s.translation_mm.mean, 13.0, 1e-9);
  EXPECT_NEAR(s.translation_mm.sd, 0.0, 1e-9);
  // E = P^-1 Q: the truth seen from the estimate, per axis -(3, -4, 12).
  EXPECT_NEAR(s.translation_axis_mm[0].mean, -3.0, 1e-9);
  EXPECT_NEAR(s.translation_axis_mm[1].mean, 4.0, 1e-9);
  EXPECT_NEAR(s.translation_axis_mm[2].mean, -12.0, 1e-9);
  EXPECT_NEAR(s.translation_axis_mm[2].rmse, 12.0, 1e-9);
  EXPECT_NEAR(s.rotation_deg.max, 0, 1e-9);
  EXPECT_NEAR(SummarizeErrors(RelativePoseErrors(estimate, truth)).translation_mm.max, 0, 1e-9);
}

TEST(TrajectoryMetrics, RotationOffsetGivesItsAngle) {
  const FramePoses truth = RotatingTrajectory(8);
  FramePoses estimate;
  const Pose offset = Make(5.0, Eigen::Vector3d(1, 2, 3), Eigen::Vector3d::Zero());
  for (const auto& [f, q] : truth) estimate[f] = q * offset;
  const ErrorSummary s = SummarizeErrors(AbsolutePoseErrors(estimate, truth));
  EXPECT_NEAR(s.rotation_deg.rmse, 5.0, 1e-9);
  EXPECT_NEAR(s.translation_mm.max, 0, 1e-9);
  // Per axis: the rotation vector of offset^-1, -5 deg about (1, 2, 3)/|.|.
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 3).normalized();
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.rotation_axis_deg[k].mean, -5.0 * axis[k], 1e-9);
}

TEST(TrajectoryMetrics, ConstantOffsetWithRotatingMotionCausesRpe) {
  // Estimate = truth · X with X a translation t = (100, 0, 0) mm
  // perpendicular to the rotation axis (y). The estimated motion between
  // frames is X^-1 Q_rel X, so E = Q_rel^-1 X^-1 Q_rel X = [I | t - R^T t],
  // |t - R^T t| = 2 |t| sin(theta / 2) with theta = 10 deg per frame:
  // 17.431148549 mm, and no rotation error. The APE is |t| = 100 mm.
  const FramePoses truth = RotatingTrajectory(12);
  FramePoses estimate;
  const Pose x = Make(0, Eigen::Vector3d::UnitZ(), Eigen::Vector3d(100, 0, 0));
  for (const auto& [f, q] : truth) estimate[f] = q * x;
  const ErrorSummary rpe = SummarizeErrors(RelativePoseErrors(estimate, truth));
  EXPECT_EQ(rpe.translation_mm.count, 11u);
  EXPECT_NEAR(rpe.translation_mm.rmse, 2 * 100 * std::sin(5 * kDeg), 1e-9);
  EXPECT_NEAR(rpe.translation_mm.rmse, 17.431148549, 1e-6);
  EXPECT_NEAR(rpe.translation_mm.sd, 0, 1e-9);
  EXPECT_NEAR(rpe.rotation_deg.max, 0, 1e-9);
  const ErrorSummary ape = SummarizeErrors(AbsolutePoseErrors(estimate, truth));
  EXPECT_NEAR(ape.translation_mm.rmse, 100, 1e-9);
  EXPECT_NEAR(ape.translation_axis_mm[0].mean, -100, 1e-9);
}

TEST(TrajectoryMetrics, RpePairsOnlyConsecutiveFrames) {
  FramePoses truth = RotatingTrajectory(6);
  truth.erase(3);
  FramePoses estimate = truth;
  estimate.erase(1);
  // Frames in both: 0, 2, 4, 5: the only consecutive pair is (4, 5).
  const PoseErrors rpe = RelativePoseErrors(estimate, truth);
  ASSERT_EQ(rpe.size(), 1u);
  EXPECT_EQ(rpe.frames[0], 4);
  EXPECT_EQ(AbsolutePoseErrors(estimate, truth).size(), 4u);
}

TEST(TrajectoryMetrics, RotationAngleNearZeroAndHalfTurn) {
  EXPECT_NEAR(RotationAngleDeg(Eigen::AngleAxisd(1e-7, Eigen::Vector3d::UnitX()).toRotationMatrix()),
              1e-7 / kDeg, 1e-12);
  EXPECT_NEAR(RotationAngleDeg(Eigen::AngleAxisd(M_PI - 1e-6, Eigen::Vector3d(1, 1, 0).normalized())
                                   .toRotationMatrix()),
              180.0 - 1e-6 / kDeg, 1e-6);
}

}  // namespace
}  // namespace lifmcr
