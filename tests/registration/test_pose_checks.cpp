// The checks every pose passes (registration/estimators/pose_checks.h) on
// plenoptic PnP poses of random problems with known answers
// (tests/registration/random_geometry.h), and the calibration of PnP's
// covariance that the checks rely on.

#include "registration/estimators/pnp.h"
#include "registration/estimators/pose_checks.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/estimators/tf_projection.h"
#include "tests/registration/random_geometry.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

namespace lifmcr::registration {
namespace {

constexpr double kSigmaVRelative = 0.007;  // PnpOptions::sigma_v_relative

PnpInput InputOf(const test::PnpProblem& p) {
  return {p.points_in_world, p.tf_px, p.virtual_depth};
}

// The evidence CheckPose reads for a PnP result, as frame_registration.cpp
// makes it (covariance of w0_from_cam, depths under the pose).
struct Evidence {
  std::vector<Eigen::Vector2d> tf;
  std::vector<double> depth_z, depth_mm;
  PoseEvidence e;
};
Evidence EvidenceOf(const processing::CameraModel& camera, const test::PnpProblem& p,
                    const PnpResult& r, const Pose& cam_from_w0) {
  Evidence out;
  std::vector<Eigen::Vector3d> points;
  std::vector<double> v;
  for (std::size_t i = 0; i < r.inlier_mask.size(); ++i) {
    if (!r.inlier_mask[i]) continue;
    out.tf.push_back(p.tf_px[i]);
    points.push_back(p.points_in_world[i]);
    v.push_back(p.virtual_depth[i]);
  }
  InlierDepths(camera, cam_from_w0, points, v, kSigmaVRelative, &out.depth_z, &out.depth_mm);
  const PoseWithCovariance w0_from_cam = Inverse(PoseWithCovariance{cam_from_w0, r.covariance});
  out.e.inliers = static_cast<int>(r.num_inliers);
  out.e.inlier_tf_px = out.tf;
  out.e.tf_width = camera.intrinsics().width_px / 2;
  out.e.tf_height = camera.intrinsics().height_px / 2;
  out.e.rmse_px = r.rmse_px;
  out.e.covariance = w0_from_cam.covariance;
  out.e.w0_from_cam = w0_from_cam.pose;
  out.e.inlier_depth_z = out.depth_z;
  out.e.inlier_depth_mm = out.depth_mm;
  return out;
}

// Keeps the matches whose keypoints lie in the image's top-left corner
// (fraction `side` of each side): a map that covers the view poorly.
test::PnpProblem InCorner(const test::PnpProblem& p, double side, int width, int height) {
  test::PnpProblem out;
  out.cam_from_world = p.cam_from_world;
  for (std::size_t i = 0; i < p.tf_px.size(); ++i) {
    if (p.tf_px[i].x() > side * width || p.tf_px[i].y() > side * height) continue;
    out.points_in_world.push_back(p.points_in_world[i]);
    out.points_in_cam.push_back(p.points_in_cam[i]);
    out.tf_px.push_back(p.tf_px[i]);
    out.virtual_depth.push_back(p.virtual_depth[i]);
    out.is_outlier.push_back(p.is_outlier[i]);
  }
  return out;
}

TEST(PoseChecks, RightPosePasses) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  std::mt19937_64 rng(30);
  for (int trial = 0; trial < 10; ++trial) {
    test::PnpProblem p = test::MakePnpProblem(rng, camera, 400, 0.3, 0.3, 0.0);
    for (double& v : p.virtual_depth) v *= 1 + kSigmaVRelative * std::normal_distribution<>()(rng);
    const PnpResult r = EstimatePlenopticPnp(camera, InputOf(p), PnpOptions{});
    ASSERT_TRUE(r.success) << r.BriefReport();
    const Evidence ev = EvidenceOf(camera, p, r, r.cam_from_world);
    EXPECT_EQ(CheckPose(ev.e, PoseCheckOptions{}), "ok");
    EXPECT_EQ(CheckPose(ev.e, PoseCheckOptions::ForErrorBound(5.0, 0.25)), "ok");
    EXPECT_GT(MeasurePose(ev.e, PoseCheckOptions{}).depth_agreement, 0.95);
  }
}

TEST(PoseChecks, WrongPoseFromPoorlyCoveringMapIsRefusedWithItsReason) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  const int tf_width = camera.intrinsics().width_px / 2;
  const int tf_height = camera.intrinsics().height_px / 2;
  std::mt19937_64 rng(31);
  int refused_sigma = 0, trials = 0;
  for (int trial = 0; trial < 10; ++trial) {
    // The map covers the top-left 30 % of the view only: 30 or so matches.
    const test::PnpProblem all = test::MakePnpProblem(rng, camera, 400, 0.0, 0.7, 0.0);
    const test::PnpProblem p = InCorner(all, 0.3, tf_width, tf_height);
    const PnpResult r = EstimatePlenopticPnp(camera, InputOf(p), PnpOptions{});
    if (!r.success) continue;
    ++trials;
    const Evidence ev = EvidenceOf(camera, p, r, r.cam_from_world);
    const std::string verdict = CheckPose(ev.e, PoseCheckOptions::ForErrorBound(5.0, 0.25));
    EXPECT_NE(verdict, "ok") << r.BriefReport();
    if (verdict.find("sigma") != std::string::npos || verdict.find("span") != std::string::npos)
      ++refused_sigma;

    // The pose slid along the viewing direction by 15 % of the scene's
    // depth (the direction a small patch of map constrains least): the
    // inliers' map points are no longer at their measured virtual depths,
    // and the depth check names it.
    Pose wrong = r.cam_from_world;
    double mean_z = 0;
    for (const Eigen::Vector3d& x : p.points_in_cam) mean_z += x.z();
    mean_z /= static_cast<double>(p.points_in_cam.size());
    wrong.translation().z() += 0.15 * mean_z;
    const Evidence bad = EvidenceOf(camera, p, r, wrong);
    PoseCheckOptions depth_only;  // the corner's spread refuses it too: left out here
    depth_only.min_spread = 0;
    depth_only.min_depth_agreement = 0.5;
    depth_only.max_sigma_mm = depth_only.max_sigma_deg = 1e9;
    const std::string depth_verdict = CheckPose(bad.e, depth_only);
    EXPECT_NE(depth_verdict.find("at their measured virtual depth"), std::string::npos)
        << depth_verdict;
  }
  EXPECT_GE(trials, 5);
  EXPECT_EQ(refused_sigma, trials);
}

// The fraction of PnP poses within the 95 % chi-square(6) bound (12.59) of
// their own covariance over 200 random problems (150 matches, 20 %
// outliers, 0.5 px keypoint noise), each problem's keypoints also moved by
// a common shift, scale and rotation about the principal point drawn with
// standard deviations shift_px, scale and rotation_rad (pnp.h,
// "Covariance"), the estimator told `options`.
double Chi2Fraction(double shift_px, double scale, double rotation_rad, const PnpOptions& options,
                    std::uint64_t seed) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  const TfProjection projection = TfProjection::Of(camera);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  int within = 0, n = 0;
  for (int trial = 0; trial < 200; ++trial) {
    test::PnpProblem p = test::MakePnpProblem(rng, camera, 150, 0.2, 0.5, 0.0);
    const Eigen::Vector2d shift(shift_px * normal(rng), shift_px * normal(rng));
    const double k = scale * normal(rng), w = rotation_rad * normal(rng);
    const Eigen::Vector2d c(projection.tf_cx, projection.tf_cy);
    for (Eigen::Vector2d& tf : p.tf_px) {
      const Eigen::Vector2d u = tf - c;
      tf += shift + k * u + w * Eigen::Vector2d(-u.y(), u.x());
    }
    const PnpResult r = EstimatePlenopticPnp(camera, InputOf(p), options);
    if (!r.success) continue;
    const double d2 = SquaredMahalanobis({r.cam_from_world, r.covariance}, p.cam_from_world);
    ++n;
    if (d2 <= 12.5916) ++within;
  }
  EXPECT_GE(n, 190);
  return static_cast<double>(within) / std::max(n, 1);
}

// Independent keypoint noise only, and a covariance without the common
// terms: s^2 (J^T J)^-1 alone is calibrated.
TEST(PoseCovariance, PnpCovarianceIsCalibratedForIndependentNoise) {
  PnpOptions options;
  options.common_shift_sigma_px = options.common_scale_sigma = 0;
  options.common_rotation_sigma_rad = 0;
  const double fraction = Chi2Fraction(0, 0, 0, options, 32);
  std::printf("independent noise: %.1f %% within the 95 %% chi-square(6) bound\n", 100 * fraction);
  EXPECT_GE(fraction, 0.90);
  EXPECT_LE(fraction, 0.99);  // not inflated either
}

// Keypoints that also share a frame's common shift, scale and rotation of the
// default sizes: without the common terms the covariance is too small;
// with them (the defaults) it is calibrated.
TEST(PoseCovariance, PnpCovarianceIsCalibratedForCommonErrors) {
  const PnpOptions defaults;
  PnpOptions independent_only = defaults;
  independent_only.common_shift_sigma_px = independent_only.common_scale_sigma = 0;
  independent_only.common_rotation_sigma_rad = 0;
  const double without =
      Chi2Fraction(defaults.common_shift_sigma_px, defaults.common_scale_sigma,
                   defaults.common_rotation_sigma_rad, independent_only, 33);
  const double with = Chi2Fraction(defaults.common_shift_sigma_px, defaults.common_scale_sigma,
                                   defaults.common_rotation_sigma_rad, defaults, 33);
  std::printf("common shift %.2f px, scale %.1e, rotation %.1e rad: %.1f %% within the 95 %% "
              "chi-square(6) bound without the common terms, %.1f %% with them\n",
              defaults.common_shift_sigma_px, defaults.common_scale_sigma,
              defaults.common_rotation_sigma_rad, 100 * without, 100 * with);
  EXPECT_LT(without, 0.85);
  EXPECT_GE(with, 0.90);
  EXPECT_LE(with, 0.99);
}

}  // namespace
}  // namespace lifmcr::registration
