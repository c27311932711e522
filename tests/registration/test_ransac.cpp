// LO-RANSAC core on a problem whose answer is known: a 2D line y = a x + b
// with outliers (the core does not know it is a line).
#include "registration/estimators/ransac.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/LU>

#include <cmath>
#include <random>

namespace lifmcr::registration {
namespace {

struct LineEstimator {
  using Model = Eigen::Vector2d;  // (a, b)
  static constexpr int kSampleSize = 2;
  std::vector<Eigen::Vector2d> points;
  int refine_calls = 0;

  std::size_t NumData() const { return points.size(); }
  void Generate(std::span<const int> s, std::vector<Model>* models) {
    const Eigen::Vector2d p = points[s[0]], q = points[s[1]];
    if (std::abs(q.x() - p.x()) < 1e-12) return;
    const double a = (q.y() - p.y()) / (q.x() - p.x());
    models->push_back({a, p.y() - a * p.x()});
  }
  double SquaredResidual(const Model& m, std::size_t i) const {
    const double r = points[i].y() - (m[0] * points[i].x() + m[1]);
    return r * r;
  }
  double Score(const Model& m, double t2, double bound, std::size_t* inliers) const {
    double cost = 0;
    *inliers = 0;
    for (std::size_t i = 0; i < points.size() && cost < bound; ++i) {
      const double r2 = SquaredResidual(m, i);
      if (r2 < t2) ++*inliers;
      cost += std::min(r2, t2);
    }
    return cost;
  }
  // Least squares over the inliers.
  bool Refine(Model* m, double t) {
    ++refine_calls;
    Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (SquaredResidual(*m, i) >= t * t) continue;
      const Eigen::Vector2d row(points[i].x(), 1);
      a += row * row.transpose();
      b += row * points[i].y();
    }
    if (std::abs(a.determinant()) < 1e-12) return false;
    *m = a.ldlt().solve(b);
    return true;
  }
};
static_assert(RansacEstimator<LineEstimator>);

LineEstimator MakeLine(std::uint64_t seed, int count, double outliers, double noise) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> x(-10, 10), y(-40, 40), unit(0, 1);
  std::normal_distribution<double> n(0, noise);
  LineEstimator e;
  for (int i = 0; i < count; ++i) {
    const double xi = x(rng);
    e.points.emplace_back(xi, unit(rng) < outliers ? y(rng) : 2.0 * xi - 3.0 + n(rng));
  }
  return e;
}

TEST(Ransac, RecoversALineAtEightyPercentOutliers) {
  LineEstimator e = MakeLine(1, 1000, 0.8, 0.05);
  Eigen::Vector2d line;
  const RansacReport r = Ransac(RansacOptions{.max_error = 0.2, .seed = 3}, e, &line);
  ASSERT_TRUE(r.success) << r.BriefReport();
  EXPECT_NEAR(line[0], 2.0, 0.01);
  EXPECT_NEAR(line[1], -3.0, 0.02);
  EXPECT_NEAR(r.InlierRatio(), 0.2, 0.04);
  EXPECT_EQ(r.inlier_mask.size(), 1000u);
  EXPECT_GT(r.refinements, 0);
  EXPECT_NE(r.BriefReport().find("LO-RANSAC ok"), std::string::npos) << r.BriefReport();
}

TEST(Ransac, SameSeedSameResultOtherSeedStillRight) {
  LineEstimator e = MakeLine(2, 400, 0.5, 0.05);
  Eigen::Vector2d a, b, c;
  const RansacReport ra = Ransac(RansacOptions{.max_error = 0.2, .seed = 7}, e, &a);
  const RansacReport rb = Ransac(RansacOptions{.max_error = 0.2, .seed = 7}, e, &b);
  const RansacReport rc = Ransac(RansacOptions{.max_error = 0.2, .seed = 8}, e, &c);
  EXPECT_EQ(a, b);
  EXPECT_EQ(ra.trials, rb.trials);
  EXPECT_EQ(ra.inlier_mask, rb.inlier_mask);
  EXPECT_NEAR(c[0], 2.0, 0.01);
}

TEST(Ransac, AdaptiveTrialCountFollowsTheInlierRatio) {
  // log(1 - 0.9999) / log(1 - 0.5^2) = 32.0...; 33 trials at w = 0.5, 97 with multiplier 3.
  const RansacOptions o{.max_error = 1, .min_trials = 10};
  EXPECT_EQ(RequiredTrials(0.5, 2, o), 33);
  EXPECT_EQ(RequiredTrials(0.5, 2, RansacOptions{.max_error = 1, .trials_multiplier = 3}), 97);
  EXPECT_EQ(RequiredTrials(1.0, 2, o), 10);
  EXPECT_EQ(RequiredTrials(0.0, 2, o), o.max_trials);
  EXPECT_LT(RequiredTrials(0.9, 3, o), RequiredTrials(0.5, 3, o));
  // Clean data stops at min_trials, noisy data runs longer.
  LineEstimator clean = MakeLine(4, 300, 0.0, 0.01), dirty = MakeLine(4, 300, 0.7, 0.01);
  Eigen::Vector2d line;
  const RansacReport rc = Ransac(RansacOptions{.max_error = 0.1, .min_trials = 10}, clean, &line);
  const RansacReport rd = Ransac(RansacOptions{.max_error = 0.1, .min_trials = 10}, dirty, &line);
  EXPECT_EQ(rc.trials, 10);
  EXPECT_GT(rd.trials, 50);
  EXPECT_LE(rd.trials, rd.required_trials);
}

TEST(Ransac, StopsAtMaxTrialsAndFailsOnTooLittleData) {
  LineEstimator e = MakeLine(5, 300, 0.95, 0.01);
  Eigen::Vector2d line;
  const RansacReport r = Ransac(RansacOptions{.max_error = 0.1, .min_trials = 0, .max_trials = 20}, e, &line);
  EXPECT_EQ(r.trials, 20);
  LineEstimator one = MakeLine(5, 1, 0, 0);
  const RansacReport f = Ransac(RansacOptions{}, one, &line);
  EXPECT_FALSE(f.success);
  EXPECT_NE(f.BriefReport().find("failed"), std::string::npos);
}

TEST(Ransac, WithoutLocalOptimisationOnlyTheFinalRefinementRuns) {
  LineEstimator e = MakeLine(6, 400, 0.5, 0.05);
  Eigen::Vector2d line;
  const RansacReport r =
      Ransac(RansacOptions{.max_error = 0.2, .local_optimisation = false, .seed = 1}, e, &line);
  EXPECT_EQ(r.refinements, 1);
  EXPECT_EQ(e.refine_calls, 1);
}

TEST(Ransac, SamplesOfTheBestsInliersAreLeftUnsolvedAndTheLineStaysRight) {
  // Once LO has fitted the best model, a sample of its inliers is not solved
  // (ransac.h): fewer models, the same draws and trial count, and the line
  // as right as when every sample is solved (there a noisier minimal model
  // of lower MSAC cost may end up the best, so the two need not be equal).
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    LineEstimator with = MakeLine(10 + seed, 600, 0.5, 0.05);
    LineEstimator without = with;
    Eigen::Vector2d a, b;
    const RansacReport ra = Ransac(RansacOptions{.max_error = 0.2, .seed = seed}, with, &a);
    const RansacReport rb = Ransac(
        RansacOptions{.max_error = 0.2, .skip_samples_of_best = false, .seed = seed}, without, &b);
    ASSERT_TRUE(ra.success && rb.success);
    EXPECT_GT(ra.skipped, 0) << ra.BriefReport();
    EXPECT_EQ(rb.skipped, 0);
    EXPECT_LT(ra.models, rb.models) << ra.BriefReport() << "\n" << rb.BriefReport();
    EXPECT_EQ(ra.trials, rb.trials);
    EXPECT_NEAR(a[0], 2.0, 0.01);
    EXPECT_NEAR(a[1], -3.0, 0.02);
    EXPECT_NEAR(b[0], 2.0, 0.01);
    EXPECT_NEAR(static_cast<double>(ra.num_inliers), static_cast<double>(rb.num_inliers), 6);
    EXPECT_NE(ra.BriefReport().find("of the best's inliers, unsolved"), std::string::npos);
  }
}

TEST(RansacOptions, CheckNamesTheField) {
  EXPECT_TRUE(RansacOptions{}.Check().ok());
  const auto message = [](RansacOptions o) { return o.Check().error().message; };
  EXPECT_NE(message({.max_error = 0}).find("max_error"), std::string::npos);
  EXPECT_NE(message({.confidence = 1}).find("confidence"), std::string::npos);
  EXPECT_NE(message({.trials_multiplier = 0.5}).find("trials_multiplier"), std::string::npos);
  EXPECT_NE(message({.min_trials = -1}).find("min_trials"), std::string::npos);
  EXPECT_NE(message({.min_trials = 10, .max_trials = 5}).find("max_trials"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr::registration
