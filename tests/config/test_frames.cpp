// Property tests of the conventions in config/frames.h: random rotations in,
// invariants out (Sophus style).

#include "config/frames.h"
#include "config/mla.h"

#include <gtest/gtest.h>

#include <random>

namespace lifmcr {
namespace {

Eigen::Matrix3d RandomRotation(std::mt19937& rng, double max_angle) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
  axis.normalize();
  const double angle = std::abs(unit(rng)) * max_angle;
  return Eigen::AngleAxisd(angle, axis).toRotationMatrix();
}

TEST(RotationRepresentation, NamesRoundTrip) {
  for (const char* name : {"helical_rad", "helical_deg", "euler_xyz_deg", "euler_xyz_rad"}) {
    const auto parsed = ParseRotationRepresentation(name);
    ASSERT_TRUE(parsed.has_value()) << name;
    EXPECT_EQ(ToString(*parsed), name);
  }
  EXPECT_FALSE(ParseRotationRepresentation("quaternion").has_value());
  EXPECT_EQ(RotationRepresentationNames(), "helical_rad|helical_deg|euler_xyz_deg|euler_xyz_rad");
}

TEST(RotationRepresentation, EveryRepresentationRoundTripsRandomRotations) {
  std::mt19937 rng(7);
  for (const auto repr :
       {RotationRepresentation::kHelicalRad, RotationRepresentation::kHelicalDeg,
        RotationRepresentation::kEulerXyzDeg, RotationRepresentation::kEulerXyzRad}) {
    for (int i = 0; i < 200; ++i) {
      const Eigen::Matrix3d rotation = RandomRotation(rng, 3.1);
      const Eigen::Vector3d r = RotationToVicon(repr, rotation);
      const Eigen::Matrix3d back = RotationFromVicon(repr, r);
      EXPECT_LT((back - rotation).norm(), 1e-9) << ToString(repr) << " sample " << i;
    }
  }
}

TEST(RotationRepresentation, HelicalIsAxisTimesAngle) {
  const Eigen::Matrix3d r =
      RotationFromVicon(RotationRepresentation::kHelicalDeg, Eigen::Vector3d(0, 0, 90));
  EXPECT_LT((r * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-12);
  EXPECT_TRUE(
      RotationFromVicon(RotationRepresentation::kHelicalRad, Eigen::Vector3d::Zero()).isIdentity());
}

TEST(RotationRepresentation, EulerXyzComposesXThenYThenZFromTheLeft) {
  const Eigen::Matrix3d r =
      RotationFromVicon(RotationRepresentation::kEulerXyzDeg, Eigen::Vector3d(90, 0, 90));
  // Rx(90) * Rz(90) maps x to Rx(90) * y = z.
  EXPECT_LT((r * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
}

TEST(Handedness, ConversionIsAnInvolutionAndKeepsRotationsProper) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> mm(-2000.0, 2000.0);
  for (const auto h : {Handedness::kRight, Handedness::kLeftFlipX, Handedness::kLeftFlipY,
                       Handedness::kLeftFlipZ}) {
    EXPECT_EQ(ParseHandedness(ToString(h)), h);
    for (int i = 0; i < 100; ++i) {
      Pose pose = Pose::Identity();
      pose.linear() = RandomRotation(rng, 3.1);
      pose.translation() = Eigen::Vector3d(mm(rng), mm(rng), mm(rng));
      Eigen::Matrix3d rotation;
      Eigen::Vector3d translation;
      RightHandedToVicon(h, pose, &rotation, &translation);
      const auto back = ViconToRightHanded(h, rotation, translation);
      ASSERT_TRUE(back.ok()) << back.error().message;
      EXPECT_LT((back->matrix() - pose.matrix()).norm(), 1e-9);
      EXPECT_NEAR(back->linear().determinant(), 1.0, 1e-12);
    }
  }
}

TEST(Handedness, MirroredPointsStayConsistent) {
  // A point seen in the left-handed frame maps through the converted pose to
  // the mirrored image of where the left-handed pose puts it.
  const Eigen::Matrix3d s = ReflectionOf(Handedness::kLeftFlipY);
  std::mt19937 rng(3);
  const Eigen::Matrix3d r_lh = RandomRotation(rng, 2.0);
  const Eigen::Vector3d t_lh(10, -20, 30);
  const auto pose = ViconToRightHanded(Handedness::kLeftFlipY, r_lh, t_lh);
  ASSERT_TRUE(pose.ok());
  const Eigen::Vector3d p_lh(1, 2, 3);
  EXPECT_LT((*pose * (s * p_lh) - s * (r_lh * p_lh + t_lh)).norm(), 1e-12);
}

TEST(Handedness, ANonRotationIsAnError) {
  Eigen::Matrix3d reflection = Eigen::Matrix3d::Identity();
  reflection(2, 2) = -1;
  const auto result =
      ViconToRightHanded(Handedness::kLeftFlipY, reflection, Eigen::Vector3d::Zero());
  ASSERT_FALSE(result.ok());
  EXPECT_NE(result.error().message.find("not a rotation"), std::string::npos);
  EXPECT_FALSE(ParseHandedness("left").has_value());
}

TEST(MlaCalibration, ReferenceCentreMatchesLiFCalFormula) {
  MlaCalibration mla;
  mla.offset_px = Eigen::Vector2d(12.25, -7.5);
  const int w = 6560, h = 4948;
  const Eigen::Vector2d c = mla.ReferenceLensCenterPx(w, h);
  EXPECT_DOUBLE_EQ(c.x(), w / 2.0 - 0.5 + 12.25);
  EXPECT_DOUBLE_EQ(c.y(), h / 2.0 - 0.5 + 7.5);  // y up in the file, down in pixels
}

}  // namespace
}  // namespace lifmcr
