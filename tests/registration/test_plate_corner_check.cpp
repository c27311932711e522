// registration/features/plate_corner_check.h on corners made by a known homography:
// exact and slightly noisy corners all pass, a displaced one is found and
// only it, too few corners are not checked, and a lens' radial distortion
// alone rejects nothing (the threshold relative to the camera's median).

#include "registration/features/plate_corner_check.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

namespace lifmcr::registration {
namespace {

// The `medium` plate (cameras.yaml): four 100 mm markers centred at
// (100|300, 80|200) mm, corners in OpenCV order.
std::vector<PlateCorner> Corners(const Eigen::Matrix3d& tf_from_plate) {
  std::vector<PlateCorner> out;
  const Eigen::Vector2d centres[4] = {{100, 200}, {300, 200}, {100, 80}, {300, 80}};
  const Eigen::Vector2d offsets[4] = {{-50, 50}, {50, 50}, {50, -50}, {-50, -50}};
  for (int m = 0; m < 4; ++m)
    for (int c = 0; c < 4; ++c) {
      const Eigen::Vector2d p = centres[m] + offsets[c];
      const Eigen::Vector2d u = (tf_from_plate * p.homogeneous()).hnormalized();
      out.push_back(PlateCorner{m, c, u, Eigen::Vector3d(p.x(), p.y(), 0)});
    }
  return out;
}

// An oblique view: 2.2 TF px per mm at the near edge, foreshortened along y.
Eigen::Matrix3d Oblique() {
  Eigen::Matrix3d h;
  h << 2.0, 0.3, 400, -0.1, -1.6, 900, 0.0001, 0.0009, 1;
  return h;
}

TEST(PlateCornerCheck, ExactAndNoisyCornersAllPass) {
  std::vector<PlateCorner> corners = Corners(Oblique());
  PlateCornerCheck check = CheckPlateCorners(corners, 0.05);
  EXPECT_TRUE(check.checked);
  EXPECT_TRUE(check.rejected.empty());
  for (const double r : check.residual_tf_px) EXPECT_LT(r, 1e-6);
  // 0.05 TF px of noise per axis (the good frames' leave-one-out residuals
  // are 0.1 TF px or less, docs/calibration.md).
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0, 0.05);
  for (PlateCorner& c : corners) c.tf_px += Eigen::Vector2d(noise(rng), noise(rng));
  check = CheckPlateCorners(corners, 0.05);
  EXPECT_TRUE(check.rejected.empty());
  for (const double r : check.residual_tf_px) EXPECT_LT(r, 0.4);
}

TEST(PlateCornerCheck, DisplacedCornerIsRejectedAlone) {
  std::vector<PlateCorner> corners = Corners(Oblique());
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0, 0.05);
  for (PlateCorner& c : corners) c.tf_px += Eigen::Vector2d(noise(rng), noise(rng));
  corners[14].tf_px += Eigen::Vector2d(-0.35, -1.0);  // marker 3 corner 2
  const PlateCornerCheck check = CheckPlateCorners(corners, 0.05);
  ASSERT_EQ(check.rejected.size(), 1u);
  EXPECT_EQ(check.rejected[0], 14);
  EXPECT_GT(check.rejected_residual_tf_px[0], 0.8);
  EXPECT_GE(check.rejected_residual_tf_px[0], check.threshold_tf_px);
  EXPECT_DOUBLE_EQ(check.threshold_tf_px, 0.5);
  // Without it the others' residuals are those of the noise.
  for (int i = 0; i < 16; ++i) {
    if (i == 14) continue;
    EXPECT_LT(check.residual_tf_px[i], 0.4) << i;
  }
}

TEST(PlateCornerCheck, TwoDisplacedCornersOfOneMarkerAreBothRejected) {
  std::vector<PlateCorner> corners = Corners(Oblique());
  corners[9].tf_px += Eigen::Vector2d(0.8, 0.5);
  corners[10].tf_px += Eigen::Vector2d(-0.2, -1.2);
  const PlateCornerCheck check = CheckPlateCorners(corners, 0.05);
  ASSERT_EQ(check.rejected.size(), 2u);
  EXPECT_TRUE((check.rejected[0] == 9 && check.rejected[1] == 10) ||
              (check.rejected[0] == 10 && check.rejected[1] == 9));
}

TEST(PlateCornerCheck, TooFewCornersAreNotChecked) {
  std::vector<PlateCorner> corners = Corners(Oblique());
  corners.resize(4);  // one marker
  corners[2].tf_px += Eigen::Vector2d(3, 3);
  const PlateCornerCheck check = CheckPlateCorners(corners, 0.05);
  EXPECT_FALSE(check.checked);
  EXPECT_TRUE(check.rejected.empty());
  for (const double r : check.residual_tf_px) EXPECT_TRUE(std::isnan(r));
}

// Radial distortion bends every corner of every frame off one homography
// alike: the camera's median residual (over all frames) raises the
// threshold, so no corner of such frames is rejected, while a frame whose
// corners are displaced among good frames is judged by the good frames.
TEST(PlateCornerCheck, ThresholdFollowsTheCamerasMedianResidual) {
  const Eigen::Vector2d centre(820, 618);
  auto distorted = [&](double k) {
    std::vector<PlateCorner> corners = Corners(Oblique());
    for (PlateCorner& c : corners) {
      const Eigen::Vector2d d = c.tf_px - centre;
      c.tf_px = centre + d * (1 + k * d.squaredNorm());
    }
    return corners;
  };
  const std::vector<std::vector<PlateCorner>> frames = {distorted(5e-8), distorted(6e-8),
                                                        distorted(4e-8)};
  const double reference = MedianPlateCornerResidual(frames);
  double largest = 0;
  for (const std::vector<PlateCorner>& f : frames)
    for (const double r : PlateCornerResiduals(f)) largest = std::max(largest, r);
  std::printf("distorted frames: median residual %.3f TF px, largest %.3f\n", reference, largest);
  EXPECT_GT(largest, 0.5);  // the absolute threshold alone would reject
  for (const std::vector<PlateCorner>& f : frames) {
    const PlateCornerCheck check = CheckPlateCorners(f, reference);
    EXPECT_TRUE(check.rejected.empty());
    EXPECT_GT(check.threshold_tf_px, largest);
  }
  EXPECT_FALSE(CheckPlateCorners(frames[0], 0).rejected.empty());
}

TEST(PlateCornerCheck, OptionsAreChecked) {
  PlateCornerCheckOptions o;
  EXPECT_TRUE(o.Check());
  o.min_corners = 5;
  EXPECT_FALSE(o.Check());
  o = {};
  o.max_residual_tf_px = 0;
  EXPECT_FALSE(o.Check());
  o = {};
  o.max_residual_over_reference = 0.5;
  EXPECT_FALSE(o.Check());
}

}  // namespace
}  // namespace lifmcr::registration
