// 3D RANSAC: exact without noise, the plenoptic noise model weighted right,
// right at 50-80 % outliers.
#include "registration/estimators/rigid_3d.h"

#include "registration/estimators/rigid_fit.h"
#include "tests/registration/random_geometry.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>

#include <random>

namespace lifmcr::registration {
namespace {

// Camera points of a PnP problem as a 3D-3D problem: src = measured points in
// the camera (with the plenoptic noise of their covariance), dst = world.
struct Problem3d {
  Pose world_from_cam;
  std::vector<Eigen::Vector3d> src, dst;
  std::vector<Eigen::Matrix3d> covariance;
  std::vector<char> is_outlier;
};

Problem3d MakeProblem(std::mt19937_64& rng, const processing::CameraModel& camera, int count,
                      double outliers, double sigma_v, double sigma_tf) {
  const test::PnpProblem p = test::MakePnpProblem(rng, camera, count, 0.0, 0.0, 0.0);
  Problem3d q;
  q.world_from_cam = p.cam_from_world.inverse();
  std::normal_distribution<double> n(0, 1);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int i = 0; i < count; ++i) {
    const Eigen::Matrix3d c = PlenopticPointCovariance(camera, p.points_in_cam[i], sigma_v, sigma_tf);
    const bool outlier = unit(rng) < outliers;
    // An outlier is matched to another random map point.
    const int j = outlier ? static_cast<int>(rng() % count) : i;
    const Eigen::Vector3d noise = c.llt().matrixL() * Eigen::Vector3d(n(rng), n(rng), n(rng));
    q.src.push_back(p.points_in_cam[i] + noise);
    q.dst.push_back(p.points_in_world[j]);
    q.covariance.push_back(c);
    q.is_outlier.push_back(outlier && j != i);
  }
  return q;
}

TEST(PlenopticPointCovariance, GrowsQuadraticallyAlongTheRay) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  const Eigen::Vector3d near(100, 50, 700), far = near * 2;
  const Eigen::Matrix3d c_near = PlenopticPointCovariance(camera, near, 0.02, 0.3);
  const Eigen::Matrix3d c_far = PlenopticPointCovariance(camera, far, 0.02, 0.3);
  const Eigen::Vector3d ray = (far - Eigen::Vector3d(0, 0, 25)).normalized();
  // Variance along the ray ~ (Z - f)^4: about 2^4 for twice the distance.
  const double ratio = ray.dot(c_far * ray) / ray.dot(c_near * ray);
  EXPECT_GT(ratio, 14.0);
  EXPECT_LT(ratio, 20.0);
  // Strongly anisotropic: along the ray >> across it.
  const Eigen::Vector3d across = ray.cross(Eigen::Vector3d::UnitX()).normalized();
  EXPECT_GT(ray.dot(c_far * ray), 100 * across.dot(c_far * across));
  // sigma_Z = B (Z - f)^2 / f^2 sigma_v on the axis.
  const Eigen::Matrix3d axis = PlenopticPointCovariance(camera, {0, 0, 1025}, 0.01, 0);
  EXPECT_NEAR(std::sqrt(axis(2, 2)), 0.2042 * 1000.0 * 1000.0 / 625.0 * 0.01, 1e-9);
}

TEST(Rigid3d, RecoversRandomPosesExactlyWithoutNoise) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 20; ++trial) {
    const Problem3d q = MakeProblem(rng, camera, 60, 0.0, 0.0, 0.0);
    const Rigid3dResult r = EstimateRigid3d({q.src, {}, q.dst}, Rigid3dOptions{});
    ASSERT_TRUE(r.success) << r.BriefReport();
    EXPECT_EQ(r.num_inliers, 60u);
    EXPECT_LT(TranslationDifference(r.dst_from_src, q.world_from_cam), 1e-6);
    EXPECT_LT(RotationDifferenceDeg(r.dst_from_src, q.world_from_cam), 1e-7);
  }
}

TEST(Rigid3d, UncertaintyWeightingBeatsPlainUmeyamaAndDegradesGracefully) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  double previous = 0;
  for (const double sigma_v : {0.01, 0.02, 0.04}) {
    std::mt19937_64 rng(13);
    double weighted = 0, plain = 0, mahalanobis = 0;
    const int trials = 20;
    for (int trial = 0; trial < trials; ++trial) {
      const Problem3d q = MakeProblem(rng, camera, 300, 0.0, sigma_v, 0.3);
      Rigid3dOptions options;
      options.map_sigma_mm = 0;  // the map points of this problem are exact
      options.ransac.max_error = 4;
      const Rigid3dResult r = EstimateRigid3d({q.src, q.covariance, q.dst}, options);
      ASSERT_TRUE(r.success) << r.BriefReport();
      EXPECT_GT(r.num_inliers, 295u);
      EXPECT_NEAR(r.rmse_sigma, std::sqrt(3.0), 0.3);
      Pose umeyama;
      ASSERT_TRUE(FitRigid(q.src, q.dst, {}, &umeyama));
      weighted += TranslationDifference(r.dst_from_src, q.world_from_cam);
      plain += TranslationDifference(umeyama, q.world_from_cam);
      mahalanobis += test::PoseErrorMahalanobis(q.world_from_cam, r.dst_from_src, r.covariance);
    }
    EXPECT_LT(weighted, 0.5 * plain) << "sigma_v " << sigma_v;
    if (previous > 0) {
      EXPECT_LT(weighted, 4.0 * previous);
    }
    previous = weighted;
    EXPECT_GT(mahalanobis / trials, 2.0);
    EXPECT_LT(mahalanobis / trials, 15.0) << "sigma_v " << sigma_v;
  }
}

TEST(Rigid3d, StaysRightAtFiftyToEightyPercentOutliers) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  for (const double outliers : {0.5, 0.8}) {
    std::mt19937_64 rng(14);
    for (int trial = 0; trial < 5; ++trial) {
      const Problem3d q = MakeProblem(rng, camera, 1000, outliers, 0.02, 0.3);
      Rigid3dOptions options;
      options.ransac.seed = trial;
      const Rigid3dResult r = EstimateRigid3d({q.src, q.covariance, q.dst}, options);
      ASSERT_TRUE(r.success) << r.BriefReport();
      EXPECT_LT(TranslationDifference(r.dst_from_src, q.world_from_cam), 5.0) << r.BriefReport();
      EXPECT_LT(RotationDifferenceDeg(r.dst_from_src, q.world_from_cam), 0.2) << r.BriefReport();
      std::size_t true_inliers = 0;
      for (const char o : q.is_outlier) true_inliers += !o;
      EXPECT_GT(r.num_inliers, true_inliers * 90 / 100) << r.BriefReport();
      // The prefilter removes outliers, not inliers.
      EXPECT_LT(r.num_prefiltered, q.src.size());
      EXPECT_GE(r.num_prefiltered, true_inliers * 90 / 100);
    }
  }
}

TEST(Rigid3d, FailuresAndOptionsSayWhy) {
  std::vector<Eigen::Vector3d> a(5, Eigen::Vector3d::Zero());
  const Rigid3dResult r = EstimateRigid3d({a, {}, a}, Rigid3dOptions{});
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.status.find("too few matches"), std::string::npos);
  Rigid3dOptions bad;
  bad.prefilter_keep_ratio = 0;
  EXPECT_NE(bad.Check().error().message.find("prefilter_keep_ratio"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr::registration
