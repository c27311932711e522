// Plenoptic PnP: exact without noise, graceful with noise, right at 50-80 %
// outliers; the projection agrees with processing's camera model.
#include "registration/estimators/pnp.h"

#include "registration/estimators/tf_projection.h"
#include "tests/registration/random_geometry.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cstdio>
#include <random>

namespace lifmcr::registration {
namespace {

PnpInput InputOf(const test::PnpProblem& p) {
  return {p.points_in_world, p.tf_px, p.virtual_depth};
}

TEST(TfProjection, AgreesWithTheCameraModel) {
  processing::CameraIntrinsics k = test::SmallCameraIntrinsics();
  for (const bool distorted : {false, true}) {
    if (distorted) {
      k.k1 = 2e-3;
      k.k2 = -1e-5;
      k.p1 = 3e-4;
      k.p2 = -2e-4;
    }
    const processing::CameraModel camera(k);
    const TfProjection projection = TfProjection::Of(camera);
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<double> u(-300, 300), z(200, 4000);
    for (int i = 0; i < 100; ++i) {
      const Eigen::Vector3d p(u(rng), u(rng), z(rng));
      double tf[2];
      ASSERT_TRUE(projection(p.data(), tf));
      const Eigen::Vector3d virtual_px = camera.Project(p);
      const Eigen::Vector2d expected = processing::CameraModel::TfOfRaw(virtual_px.head<2>());
      EXPECT_NEAR(tf[0], expected.x(), 1e-9);
      EXPECT_NEAR(tf[1], expected.y(), 1e-9);
    }
    // The Jacobian against central differences.
    const Eigen::Vector3d p(120, -80, 900);
    Eigen::Vector2d tf0;
    Eigen::Matrix<double, 2, 3> jacobian;
    ASSERT_TRUE(projection.WithJacobian(p, &tf0, &jacobian));
    for (int a = 0; a < 3; ++a) {
      Eigen::Vector3d step = Eigen::Vector3d::Zero();
      step[a] = 1e-4;
      double plus[2], minus[2];
      const Eigen::Vector3d pp = p + step, pm = p - step;
      ASSERT_TRUE(projection(pp.data(), plus) && projection(pm.data(), minus));
      EXPECT_NEAR(jacobian(0, a), (plus[0] - minus[0]) / 2e-4, 1e-6);
      EXPECT_NEAR(jacobian(1, a), (plus[1] - minus[1]) / 2e-4, 1e-6);
    }
    const Eigen::Vector3d at_focus(0, 0, k.main_focal_length_mm);
    double tf[2];
    EXPECT_FALSE(projection(at_focus.data(), tf));
  }
}

TEST(PlenopticPnp, RecoversRandomPosesExactlyWithoutNoise) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const test::PnpProblem p = test::MakePnpProblem(rng, camera, 100, 0.0, 0.0, 0.0);
    const PnpResult r = EstimatePlenopticPnp(camera, InputOf(p), PnpOptions{});
    ASSERT_TRUE(r.success) << r.BriefReport();
    EXPECT_EQ(r.num_inliers, 100u);
    EXPECT_LT(TranslationDifference(r.cam_from_world, p.cam_from_world), 1e-6);
    EXPECT_LT(RotationDifferenceDeg(r.cam_from_world, p.cam_from_world), 1e-7);
    EXPECT_LT(r.rmse_px, 1e-6);
  }
}

TEST(PlenopticPnp, DegradesGracefullyWithNoiseAndTheCovarianceSaysHowMuch) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  double previous_error = 0;
  for (const double sigma : {0.25, 0.5, 1.0}) {
    std::mt19937_64 rng(8);
    double sum_t = 0, sum_r = 0, sum_mahalanobis = 0;
    const int trials = 20;
    for (int trial = 0; trial < trials; ++trial) {
      // Noise on the virtual depth too: only the hypotheses use it.
      const test::PnpProblem p = test::MakePnpProblem(rng, camera, 300, 0.0, sigma, 0.05);
      PnpOptions options;
      options.ransac.max_error = 4 * sigma;  // keeps 99.97 % of the inliers
      const PnpResult r = EstimatePlenopticPnp(camera, InputOf(p), options);
      ASSERT_TRUE(r.success) << r.BriefReport();
      EXPECT_GT(r.num_inliers, 295u);
      EXPECT_NEAR(r.rmse_px, sigma * std::sqrt(2.0), 0.3 * sigma);
      sum_t += TranslationDifference(r.cam_from_world, p.cam_from_world);
      sum_r += RotationDifferenceDeg(r.cam_from_world, p.cam_from_world);
      sum_mahalanobis += test::PoseErrorMahalanobis(p.cam_from_world, r.cam_from_world, r.covariance);
    }
    const double mean_t = sum_t / trials;
    // Pose error grows with noise, about in proportion: graceful, not abrupt.
    EXPECT_LT(mean_t, 8.0 * sigma) << "sigma " << sigma;
    EXPECT_LT(sum_r / trials, 0.1 * sigma) << "sigma " << sigma;
    if (previous_error > 0) {
      EXPECT_LT(mean_t, 4.0 * previous_error);
    }
    previous_error = mean_t;
    // The 6x6 covariance is consistent: E[chi^2_6] = 6.
    EXPECT_GT(sum_mahalanobis / trials, 2.0);
    EXPECT_LT(sum_mahalanobis / trials, 15.0);
  }
}

TEST(PlenopticPnp, StaysRightAtFiftyToEightyPercentOutliers) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  for (const double outliers : {0.5, 0.8}) {
    std::mt19937_64 rng(9);
    for (int trial = 0; trial < 5; ++trial) {
      const test::PnpProblem p = test::MakePnpProblem(rng, camera, 1000, outliers, 0.5, 0.05);
      PnpOptions options;
      options.ransac.seed = trial;
      const PnpResult r = EstimatePlenopticPnp(camera, InputOf(p), options);
      ASSERT_TRUE(r.success) << r.BriefReport();
      EXPECT_LT(TranslationDifference(r.cam_from_world, p.cam_from_world), 5.0) << r.BriefReport();
      EXPECT_LT(RotationDifferenceDeg(r.cam_from_world, p.cam_from_world), 0.1);
      // Inliers found are the true inliers (an outlier may land near its true place by chance).
      std::size_t true_inliers = 0, wrong = 0;
      for (std::size_t i = 0; i < p.is_outlier.size(); ++i) {
        true_inliers += !p.is_outlier[i];
        wrong += r.inlier_mask[i] && p.is_outlier[i];
      }
      EXPECT_GT(r.num_inliers, true_inliers * 95 / 100);
      EXPECT_LT(wrong, 5u);
    }
  }
}

// The sample check (pnp.h): at 80 % outliers it leaves nearly every sample
// with an outlier unsolved, and the pose is the one found without it; with
// no outliers and the depth noise it assumes, it leaves almost no sample
// unsolved (each would be an all-inlier draw lost).
TEST(PlenopticPnp, SampleCheckSkipsSamplesWithOutliersNotThoseWithout) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 3; ++trial) {
    // Virtual-depth noise 0.7 % of v at v = 4, the check's default.
    const test::PnpProblem p = test::MakePnpProblem(rng, camera, 1000, 0.8, 0.5, 0.028);
    PnpOptions with, without;
    with.ransac.seed = without.ransac.seed = trial;
    without.sample_check = false;
    const PnpResult a = EstimatePlenopticPnp(camera, InputOf(p), with);
    const PnpResult b = EstimatePlenopticPnp(camera, InputOf(p), without);
    ASSERT_TRUE(a.success) << a.BriefReport();
    ASSERT_TRUE(b.success) << b.BriefReport();
    std::printf("80 %% outliers: %s\n  without the check: %s\n", a.BriefReport().c_str(),
                b.BriefReport().c_str());
    // 99.2 % of the samples hold an outlier; the check leaves most unsolved.
    EXPECT_GT(a.samples_rejected, a.ransac.trials * 9 / 10);
    EXPECT_EQ(b.samples_rejected, 0);
    EXPECT_LT(a.ransac.models, b.ransac.models / 5);
    EXPECT_LT(TranslationDifference(a.cam_from_world, b.cam_from_world), 0.05);
    EXPECT_LT(RotationDifferenceDeg(a.cam_from_world, b.cam_from_world), 0.002);
    EXPECT_EQ(a.num_inliers, b.num_inliers);

    const test::PnpProblem clean = test::MakePnpProblem(rng, camera, 1000, 0.0, 0.5, 0.028);
    PnpOptions all_trials;
    all_trials.ransac.min_trials = 2000;  // many draws, all of them all-inlier
    all_trials.ransac.seed = trial;
    const PnpResult c = EstimatePlenopticPnp(camera, InputOf(clean), all_trials);
    ASSERT_TRUE(c.success) << c.BriefReport();
    EXPECT_LT(c.samples_rejected, c.ransac.trials / 200) << c.BriefReport();
  }
  PnpOptions bad;
  bad.sample_check_sigmas = 0;
  EXPECT_NE(bad.Check().error().message.find("sample_check_sigmas"), std::string::npos);
  bad = PnpOptions{};
  bad.sigma_v_relative = -1;
  EXPECT_NE(bad.Check().error().message.find("sigma_v_relative"), std::string::npos);
}

TEST(PlenopticPnp, DistortedCameraAndSeedDeterminism) {
  processing::CameraIntrinsics k = test::SmallCameraIntrinsics();
  k.k1 = 2e-3;
  k.p2 = 1e-4;
  const processing::CameraModel camera(k);
  std::mt19937_64 rng(10);
  const test::PnpProblem p = test::MakePnpProblem(rng, camera, 500, 0.5, 0.0, 0.0);
  const PnpResult a = EstimatePlenopticPnp(camera, InputOf(p), PnpOptions{});
  const PnpResult b = EstimatePlenopticPnp(camera, InputOf(p), PnpOptions{});
  ASSERT_TRUE(a.success) << a.BriefReport();
  EXPECT_LT(TranslationDifference(a.cam_from_world, p.cam_from_world), 1e-5);
  EXPECT_TRUE(a.cam_from_world.isApprox(b.cam_from_world, 0));
  EXPECT_EQ(a.ransac.trials, b.ransac.trials);
}

TEST(PlenopticPnp, CeresRefinementConvergesFromFarOnTheQuaternionChart) {
  // The refinement's chart (pnp_refinement.cpp) turns the rotation by
  // Exp(2 d): from 20 mm and ~3 deg off it takes several steps with d far
  // from 0, where the left Jacobian of SO(3) matters; noise-free data give
  // the truth back, with and without a start-cost hint, with distortion
  // (its Jacobian by automatic differentiation) and without.
  for (const bool distorted : {false, true}) {
    processing::CameraIntrinsics k = test::SmallCameraIntrinsics();
    if (distorted) {
      k.k1 = 2e-3;
      k.p2 = 1e-4;
    }
    const processing::CameraModel camera(k);
    std::mt19937_64 rng(11);
    const test::PnpProblem p = test::MakePnpProblem(rng, camera, 300, 0.0, 0.0, 0.0);
    const std::vector<char> all(300, 1);
    Eigen::Matrix<double, 6, 1> delta;
    delta << 20, -10, 5, 0.04, -0.03, 0.02;  // (dt mm, dr rad), pose_covariance.h
    for (const double start_cost : {-1.0, 1e3}) {
      Pose pose = Perturb(p.cam_from_world, delta);
      const int iterations = RefinePnpCeres(camera, InputOf(p), all, PnpLoss::kHuber, 1.0, 50, &pose,
                                            start_cost);
      EXPECT_GT(iterations, 2);
      EXPECT_LT(TranslationDifference(pose, p.cam_from_world), 1e-6) << distorted;
      EXPECT_LT(RotationDifferenceDeg(pose, p.cam_from_world), 1e-7) << distorted;
    }
  }
}

TEST(PlenopticPnp, FailuresSayWhy) {
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  std::mt19937_64 rng(11);
  const test::PnpProblem p = test::MakePnpProblem(rng, camera, 5, 0.0, 0.0, 0.0);
  const PnpResult few = EstimatePlenopticPnp(camera, InputOf(p), PnpOptions{});
  EXPECT_FALSE(few.success);
  EXPECT_NE(few.status.find("too few matches"), std::string::npos) << few.status;
  // Without virtual depths no hypothesis can be made.
  const test::PnpProblem q = test::MakePnpProblem(rng, camera, 50, 0.0, 0.0, 0.0);
  const PnpResult no_depth = EstimatePlenopticPnp(camera, {q.points_in_world, q.tf_px, {}}, PnpOptions{});
  EXPECT_FALSE(no_depth.success);
  EXPECT_NE(no_depth.BriefReport().find("no pose hypothesis"), std::string::npos);
  PnpOptions bad;
  bad.loss_scale_px = 0;
  EXPECT_NE(bad.Check().error().message.find("loss_scale_px"), std::string::npos);
  bad = PnpOptions{};
  bad.ransac.confidence = 2;
  EXPECT_NE(bad.Check().error().message.find("confidence"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr::registration
