// SE(3) interpolation (slerp + linear): endpoints, geodesic rotation, the
// shorter arc, and the pose at fractional Vicon frames with untracked
// samples and gaps.
#include "sync/pose_interpolation.h"
#include "tests/drivers/vicon_test_poses.h"

#include <gtest/gtest.h>

#include <random>

namespace lifmcr {
namespace {

double AngleBetween(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

TEST(PoseInterpolation, SlerpIsTheGeodesicAndTranslationIsLinear) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    const Pose a = test::RandomPose(rng);
    const Pose b = test::RandomPose(rng);
    EXPECT_TRUE(test::PosesNear(InterpolatePose(a, b, 0.0), a, 1e-9));
    EXPECT_TRUE(test::PosesNear(InterpolatePose(a, b, 1.0), b, 1e-9));
    const double s = unit(rng);
    const Pose p = InterpolatePose(a, b, s);
    // The rotation moves along the shorter arc at constant speed.
    const double total = AngleBetween(a.linear(), b.linear());
    EXPECT_LE(total, M_PI + 1e-9);
    EXPECT_NEAR(AngleBetween(a.linear(), p.linear()), s * total, 1e-7);
    EXPECT_NEAR(AngleBetween(p.linear(), b.linear()), (1 - s) * total, 1e-7);
    // Same axis: a^-1 p is a rotation about the axis of a^-1 b.
    if (total > 1e-3) {
      const Eigen::AngleAxisd ab(a.linear().transpose() * b.linear());
      const Eigen::AngleAxisd ap(a.linear().transpose() * p.linear());
      if (s * total > 1e-3) {
        EXPECT_NEAR(ab.axis().dot(ap.axis()), 1.0, 1e-6);
      }
    }
    EXPECT_TRUE(((1 - s) * a.translation() + s * b.translation() - p.translation()).norm() < 1e-9);
    EXPECT_NEAR(p.linear().determinant(), 1.0, 1e-12);
  }
}

TEST(PoseInterpolation, HalfwayAboutOneAxis) {
  Pose a = Pose::Identity();
  Pose b = Pose::Identity();
  b.linear() = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  b.translation() = Eigen::Vector3d(10, 20, 30);
  const Pose mid = InterpolatePose(a, b, 0.5);
  EXPECT_TRUE(mid.linear().isApprox(
      Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-12));
  EXPECT_TRUE(mid.translation().isApprox(Eigen::Vector3d(5, 10, 15)));
}

TEST(PoseInterpolation, PoseAtFractionalViconFrames) {
  std::mt19937 rng(5);
  std::vector<ViconPoseSample> samples;
  for (int f = 100; f <= 110; ++f) {
    if (f == 106) continue;  // a frame never received
    samples.push_back({f, f == 103 ? std::nullopt : std::optional(test::RandomPose(rng))});
  }
  const Pose& p100 = *samples[0].vicon_from_marker;
  const Pose& p101 = *samples[1].vicon_from_marker;
  EXPECT_TRUE(test::PosesNear(*PoseAtViconFrame(samples, 100.0), p100, 1e-12));
  EXPECT_TRUE(test::PosesNear(*PoseAtViconFrame(samples, 100.25), InterpolatePose(p100, p101, 0.25),
                              1e-12));
  EXPECT_FALSE(PoseAtViconFrame(samples, 99.5).has_value());     // before the first
  EXPECT_FALSE(PoseAtViconFrame(samples, 110.5).has_value());    // after the last
  EXPECT_FALSE(PoseAtViconFrame(samples, 103.0).has_value());    // untracked
  EXPECT_FALSE(PoseAtViconFrame(samples, 102.5).has_value());    // next to untracked
  EXPECT_FALSE(PoseAtViconFrame(samples, 105.5).has_value());    // 105 -> 107: a gap
  EXPECT_TRUE(PoseAtViconFrame(samples, 105.5, 2).has_value());  // bridged when allowed
  EXPECT_FALSE(PoseAtViconFrame({}, 1.0).has_value());
}

TEST(PoseInterpolation, ObjectPoseAndViconFrameAt) {
  ViconFrame frame;
  frame.objects = {{"plate", Pose::Identity()}, {"cam0", std::nullopt}};
  EXPECT_TRUE(ObjectPose(frame, "plate").has_value());
  EXPECT_FALSE(ObjectPose(frame, "cam0").has_value());
  EXPECT_FALSE(ObjectPose(frame, "cam1").has_value());
  EXPECT_DOUBLE_EQ(ViconFrameAt(800, 1'000'000'000, 1'006'250'000, 80.0), 800.5);
}

}  // namespace
}  // namespace lifmcr
