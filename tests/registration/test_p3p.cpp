// Lambda Twist P3P: random poses and points, exact recovery.
#include "registration/estimators/p3p.h"

#include "registration/estimators/pose_covariance.h"
#include "tests/registration/random_geometry.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

namespace lifmcr::registration {
namespace {

TEST(SolveMonicCubic, FindsRandomRoots) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-10, 10);
  for (int trial = 0; trial < 1000; ++trial) {
    double r[3] = {u(rng), u(rng), u(rng)};
    std::sort(r, r + 3);
    // (x - r0)(x - r1)(x - r2)
    const double b = -(r[0] + r[1] + r[2]);
    const double c = r[0] * r[1] + r[0] * r[2] + r[1] * r[2];
    const double d = -r[0] * r[1] * r[2];
    double roots[3];
    const int n = SolveMonicCubic(b, c, d, roots);
    // Nearly double roots may come out as one.
    if (n == 3) {
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(roots[k], r[k], 1e-6 * (1 + std::abs(r[k])));
    } else {
      ASSERT_EQ(n, 1);
      const double x = roots[0];
      EXPECT_NEAR(((x + b) * x + c) * x + d, 0, 1e-6);
    }
  }
  // One real root: (x - 2)(x^2 + 1).
  double roots[3];
  ASSERT_EQ(SolveMonicCubic(-2, 1, -2, roots), 1);
  EXPECT_NEAR(roots[0], 2, 1e-12);
}

TEST(SolveP3P, RecoversRandomPosesExactly) {
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> lateral(-1, 1), depth(300, 3000);
  int found = 0;
  const int trials = 2000;
  std::vector<Pose> solutions;
  solutions.reserve(4);
  for (int trial = 0; trial < trials; ++trial) {
    const Pose cam_from_world = test::RandomPose(rng, 1000);
    std::array<Eigen::Vector3d, 3> bearings, points;
    for (int k = 0; k < 3; ++k) {
      const double z = depth(rng);
      const Eigen::Vector3d p_in_cam(lateral(rng) * z * 0.5, lateral(rng) * z * 0.4, z);
      bearings[k] = p_in_cam * (0.5 + trial % 3);  // not normalised on purpose
      points[k] = cam_from_world.inverse() * p_in_cam;
    }
    solutions.clear();
    const int n = SolveP3P(bearings, points, &solutions);
    ASSERT_EQ(n, static_cast<int>(solutions.size()));
    ASSERT_LE(n, 4);
    double best = 1e9;
    for (const Pose& s : solutions) {
      best = std::min(best, TranslationDifference(s, cam_from_world) +
                                1e3 * RotationDifferenceDeg(s, cam_from_world));
      // Every solution explains the three bearings.
      for (int k = 0; k < 3; ++k)
        EXPECT_GT((s * points[k]).normalized().dot(bearings[k].normalized()), 1 - 1e-8);
    }
    found += best < 1e-5;
  }
  // Near-degenerate configurations may lose a little precision, never most.
  EXPECT_GE(found, trials * 995 / 1000) << found << " of " << trials;
}

TEST(SolveP3P, DegenerateSamplesGiveNothing) {
  std::vector<Pose> solutions;
  const std::array<Eigen::Vector3d, 3> bearings = {Eigen::Vector3d(0, 0, 1), Eigen::Vector3d(0.1, 0, 1),
                                                   Eigen::Vector3d(0.2, 0, 1)};
  // Collinear world points.
  const std::array<Eigen::Vector3d, 3> collinear = {Eigen::Vector3d(0, 0, 1000), Eigen::Vector3d(100, 0, 1000),
                                                    Eigen::Vector3d(200, 0, 1000)};
  EXPECT_EQ(SolveP3P(bearings, collinear, &solutions), 0);
  EXPECT_TRUE(solutions.empty());
}

}  // namespace
}  // namespace lifmcr::registration
