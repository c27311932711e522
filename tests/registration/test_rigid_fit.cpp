// Weighted Kabsch / Umeyama and the covariance propagation of poses:
// random transforms in, invariants out.
#include "registration/estimators/extrinsics.h"
#include "registration/live/map_localizer.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/estimators/rigid_fit.h"

#include "tests/registration/random_geometry.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <random>

namespace lifmcr::registration {
namespace {

TEST(FitRigid, RecoversRandomTransformsExactly) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-500, 500), w(0.1, 10);
  for (int trial = 0; trial < 200; ++trial) {
    const Pose dst_from_src = test::RandomPose(rng, 2000);
    const int n = 3 + trial % 20;
    std::vector<Eigen::Vector3d> src, dst;
    std::vector<double> weights;
    for (int i = 0; i < n; ++i) {
      src.emplace_back(u(rng), u(rng), u(rng));
      dst.push_back(dst_from_src * src.back());
      weights.push_back(w(rng));
    }
    Pose fitted, weighted;
    ASSERT_TRUE(FitRigid(src, dst, {}, &fitted));
    ASSERT_TRUE(FitRigid(src, dst, weights, &weighted));
    EXPECT_LT(TranslationDifference(fitted, dst_from_src), 1e-8);
    EXPECT_LT(RotationDifferenceDeg(fitted, dst_from_src), 1e-9);
    EXPECT_LT(TranslationDifference(weighted, dst_from_src), 1e-8);
    EXPECT_NEAR(fitted.linear().determinant(), 1.0, 1e-12);
  }
}

TEST(FitRigid, WeightsSelectTheSubsetAndCollinearFails) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-500, 500);
  const Pose a = test::RandomPose(rng, 1000), b = test::RandomPose(rng, 1000);
  std::vector<Eigen::Vector3d> src, dst;
  std::vector<double> weights;
  for (int i = 0; i < 20; ++i) {
    src.emplace_back(u(rng), u(rng), u(rng));
    dst.push_back((i < 10 ? a : b) * src.back());
    weights.push_back(i < 10 ? 1.0 : 0.0);
  }
  Pose fitted;
  ASSERT_TRUE(FitRigid(src, dst, weights, &fitted));
  EXPECT_LT(TranslationDifference(fitted, a), 1e-8);
  const std::vector<int> second = {10, 11, 12, 13};
  ASSERT_TRUE(FitRigidSubset(src, dst, {}, second, &fitted));
  EXPECT_LT(TranslationDifference(fitted, b), 1e-8);
  const std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
  EXPECT_FALSE(FitRigid(line, line, {}, &fitted));
}

TEST(FitRigid, ReflectedDataStillGivesARotation) {
  // Mirror images of a point set: the best proper rotation, never a reflection.
  std::vector<Eigen::Vector3d> src = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 1}}, dst;
  for (const auto& p : src) dst.emplace_back(-p.x(), p.y(), p.z());
  Pose fitted;
  ASSERT_TRUE(FitRigid(src, dst, {}, &fitted));
  EXPECT_NEAR(fitted.linear().determinant(), 1.0, 1e-12);
}

// Numerical Jacobian of pose -> f(pose) in the perturbation convention.
template <typename F>
Covariance6 NumericalJacobian(const Pose& x, F f) {
  Covariance6 j;
  const Pose fx = f(x);
  const double h = 1e-6;
  for (int k = 0; k < 6; ++k) {
    Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
    d[k] = h;
    const Pose moved = f(Perturb(x, d));
    // Recover delta' with moved = Perturb(fx, delta').
    const Eigen::AngleAxisd rot(moved.linear() * fx.linear().transpose());
    j.block<3, 1>(0, k) = (moved.translation() - fx.translation()) / h;
    j.block<3, 1>(3, k) = rot.angle() * rot.axis() / h;
  }
  return j;
}

TEST(PoseCovariance, InverseAndComposeMatchNumericalJacobians) {
  std::mt19937_64 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    const Pose a_from_b = test::RandomPose(rng, 1000), b_from_c = test::RandomPose(rng, 1000);
    Covariance6 random = Covariance6::Random();
    const Covariance6 cov = random * random.transpose();
    const Covariance6 j_inv = NumericalJacobian(a_from_b, [](const Pose& p) { return p.inverse(); });
    const PoseWithCovariance inv = Inverse({a_from_b, cov});
    EXPECT_TRUE(inv.pose.isApprox(a_from_b.inverse(), 1e-12));
    const Covariance6 expected_inv = j_inv * cov * j_inv.transpose();
    EXPECT_LT((inv.covariance - expected_inv).norm(), 1e-5 * expected_inv.norm());

    const Covariance6 j1 = NumericalJacobian(a_from_b, [&](const Pose& p) { return p * b_from_c; });
    const Covariance6 j2 = NumericalJacobian(b_from_c, [&](const Pose& p) { return a_from_b * p; });
    const PoseWithCovariance ac = Compose({a_from_b, cov}, {b_from_c, 2 * cov});
    const Covariance6 expected = j1 * cov * j1.transpose() + j2 * (2 * cov) * j2.transpose();
    EXPECT_LT((ac.covariance - expected).norm(), 1e-5 * expected.norm());
  }
}

}  // namespace
}  // namespace lifmcr::registration

namespace lifmcr::registration {
namespace {

// A point seen by both cameras: c0_from_cx must carry its cx coordinates to
// its c0 coordinates, whatever the frames in between.
TEST(Extrinsics, ComposeInTheOrderTheNamesSay) {
  std::mt19937_64 rng(15);
  for (int trial = 0; trial < 100; ++trial) {
    const Pose w0_from_c0 = test::RandomPose(rng, 1000), w0_from_wx = test::RandomPose(rng, 1000),
               wx_from_cx = test::RandomPose(rng, 1000);
    const Eigen::Vector3d p_in_cx = test::RandomPose(rng, 1000).translation();
    const Eigen::Vector3d p_in_w0 = w0_from_wx * (wx_from_cx * p_in_cx);
    const Eigen::Vector3d p_in_c0 = w0_from_c0.inverse() * p_in_w0;
    const PoseWithCovariance by_3d = C0FromCxBy3d({w0_from_c0}, {w0_from_wx}, {wx_from_cx});
    EXPECT_LT((by_3d.pose * p_in_cx - p_in_c0).norm(), 1e-9);
    const PoseWithCovariance by_pnp = C0FromCxByPnp({w0_from_c0}, {w0_from_wx * wx_from_cx});
    EXPECT_LT((by_pnp.pose * p_in_cx - p_in_c0).norm(), 1e-9);
    // Uncertainty of either input reaches the result.
    Covariance6 cov = Covariance6::Identity();
    EXPECT_GT(C0FromCxByPnp({w0_from_c0, cov}, {w0_from_wx}).covariance.trace(), 5.9);
    EXPECT_GT(C0FromCxByPnp({w0_from_c0}, {w0_from_wx, cov}).covariance.trace(), 5.9);
  }
}

}  // namespace
}  // namespace lifmcr::registration

namespace lifmcr::registration {
namespace {

// The stage's perturbation T = exp(xi) T_hat, xi = (rho, phi): to first
// order t = t_hat + rho + phi x t_hat, so rho = dt - phi x t = dt + [t]x phi.
TEST(MapLocalizer, CovarianceConventionMatchesTheStagesLeftPerturbation) {
  std::mt19937_64 rng(16);
  const Pose pose = test::RandomPose(rng, 1000);
  for (int k = 0; k < 6; ++k) {
    Eigen::Matrix<double, 6, 1> delta = Eigen::Matrix<double, 6, 1>::Zero();
    delta[k] = 1e-6;
    const Pose moved = Perturb(pose, delta);
    const Eigen::AngleAxisd rotation(moved.linear() * pose.linear().transpose());
    const Eigen::Vector3d phi = rotation.angle() * rotation.axis();
    const Eigen::Vector3d rho = moved.translation() - rotation * pose.translation();
    // A delta = xi: check through a covariance with one non-zero entry.
    Covariance6 single = Covariance6::Zero();
    single(k, k) = 1;
    const Covariance6 mapped = ToLeftPerturbationCovariance({pose, single});
    Eigen::Matrix<double, 6, 1> xi;
    xi << rho, phi;
    const Covariance6 expected = (xi / 1e-6) * (xi / 1e-6).transpose();
    EXPECT_LT((mapped - expected).norm(), 1e-3 * (1 + expected.norm())) << "component " << k;
  }
}

}  // namespace
}  // namespace lifmcr::registration
