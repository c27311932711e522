#pragma once
// One LO-RANSAC for every robust estimator of lifmcr (the plenoptic PnP and
// the rigid 3D-3D registration), after the shape of PoseLib's and COLMAP's
// cores: an estimator concept, a seedable generator, an adaptive number of
// trials, MSAC scoring and local optimisation by non-linear refinement.
//
// Scoring (MSAC, Torr & Zisserman 2000): a model's cost is
//   C(M) = sum_i min(r_i(M)^2, t^2),
// r_i the residual of datum i in the estimator's units and t the inlier
// threshold; datum i is an inlier when r_i^2 < t^2. Lower is better.
//
// Trials: after the best model so far has inlier ratio w, the probability
// that none of k samples of size s is all-inlier is (1 - w^s)^k; requiring it
// below 1 - confidence gives
//   k = multiplier * log(1 - confidence) / log(1 - w^s),
// clamped to [min_trials, max_trials]. A multiplier above 1 (PoseLib and
// COLMAP use 3) pays for w being an estimate; lifmcr's w comes from the
// locally optimised model, whose inlier count is close to the true one, so
// it defaults to 1.
//
// Early bail-out (Capel 2005): the core scores a minimal model on the data
// in one random order fixed per call. A model at least as good as the best
// so far, of inlier ratio w, has after k data about w k inliers with
// standard deviation sqrt(k w (1 - w)); a model with fewer than
//   w k - 3 sqrt(k w (1 - w)) - 1
// is dropped there (checked every 16 data from k = 32). Most minimal models
// are bad, and they cost k ~ 50 data instead of all of them; a model as good
// as the best survives with probability > 99.8 %. Until a model with at
// least min_inlier_ratio is found, w = min_inlier_ratio (the ratio below
// which the problem is not expected to be solved, as COLMAP's option of that
// name): the random models of the first trials are dropped after ~230 data
// at 0.05 instead of running through all of them.
//
// Local optimisation: whenever a minimal model has more inliers than every
// minimal model before it, the estimator refines it non-linearly over all
// data (Estimator::Refine minimises the truncated loss, so outliers do not
// pull it); the refined model replaces the best one when its MSAC cost is
// lower. The best model is refined once more at the end unless it is the
// outcome of a refinement already (refining it again would only repeat the
// converged solve).
//
// Samples of the best model's inliers: once the best model is the outcome
// of a local optimisation, a sample whose data are all its inliers is not
// solved. Its minimal model would fit data the refinement already fitted
// all together, and could only come out as a noisier copy of the best,
// scored through nearly all data (a model as good as the best neither fails
// the bail-out nor the cost bound until near the end). Such a sample still
// counts as a trial: what the trial count guards against is never having
// drawn an all-inlier sample, and this one is all-inlier for the best. At
// 50 % outliers about 8 of 69 samples are all-inlier, and after the first
// one each of the others cost a full scoring of the data (bench_pnp).
//
// Allocation: the sample, the scoring order, the model list and the inlier
// mask are sized once per call; no trial allocates (the estimator keeps its
// own scratch).

#include "config/error.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <span>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct RansacOptions {
  double max_error = 1.0;        // inlier threshold t, in the estimator's residual units (> 0)
  double confidence = 0.9999;    // probability of drawing one all-inlier sample, in (0, 1)
  double trials_multiplier = 1;  // multiplier of the adaptive trial count (>= 1)
  int min_trials = 50;           // trials run even when the count is reached earlier (>= 0)
  int max_trials = 100000;       // hard cap (>= min_trials, >= 1)
  bool local_optimisation = true;  // refine each new best minimal model (LO-RANSAC)
  bool bail_out = true;          // drop hopeless minimal models early (comment above)
  bool skip_samples_of_best = true;  // leave samples of the best's inliers unsolved (above)
  double min_inlier_ratio = 0.05;  // the bail-out's least w, in [0, 1)
  std::uint64_t seed = 0;        // the generator's seed: the same seed gives the same result

  // Every field in range; the message names the field.
  Status Check() const;
};

struct RansacReport {
  bool success = false;        // a model with at least sample-size inliers was found
  int trials = 0;              // samples drawn
  int models = 0;              // minimal models scored
  int bailed_out = 0;          // of which dropped early
  int skipped = 0;             // samples of the best model's inliers, left unsolved
  int refinements = 0;         // local optimisations run (including the final one)
  int required_trials = 0;     // the adaptive count when the loop stopped
  std::size_t num_data = 0;
  std::size_t num_inliers = 0;
  double cost = std::numeric_limits<double>::infinity();  // MSAC cost of the model
  double time_ms = 0;
  std::vector<char> inlier_mask;  // 1 for inliers of the returned model

  double InlierRatio() const {
    return num_data ? static_cast<double>(num_inliers) / static_cast<double>(num_data) : 0.0;
  }
  // "LO-RANSAC ok: 812/2000 inliers (40.6 %), 152 trials of 152 needed,
  //  6 refinements, cost 1.2e+03, 1.84 ms".
  std::string BriefReport() const;
};

// The adaptive trial count of the comment above for inlier ratio w.
int RequiredTrials(double inlier_ratio, int sample_size, const RansacOptions& options);

// What LO-RANSAC needs of an estimator. `Model` is its hypothesis type.
//   kSampleSize       data per minimal sample.
//   NumData()         number of data.
//   Generate(sample, models)  appends the minimal models of the sampled data
//                     (may append none, e.g. a degenerate sample); `models`
//                     is cleared by the caller and keeps its capacity.
//   Score(model, t^2, bound, &inliers)  MSAC cost; may stop early and
//                     return any value >= bound once the cost exceeds it.
//   SquaredResidual(model, i)  r_i^2.
//   Refine(model, t)  non-linear refinement of *model over the data,
//                     robust to outliers beyond t; false when it failed
//                     (the model is then left as it was).
template <typename E>
concept RansacEstimator = requires(E e, const E ce, typename E::Model m,
                                   std::span<const int> sample,
                                   std::vector<typename E::Model>* models, std::size_t* n) {
  { E::kSampleSize } -> std::convertible_to<int>;
  { ce.NumData() } -> std::convertible_to<std::size_t>;
  e.Generate(sample, models);
  { ce.Score(m, 1.0, 1.0, n) } -> std::convertible_to<double>;
  { ce.SquaredResidual(m, std::size_t{0}) } -> std::convertible_to<double>;
  { e.Refine(&m, 1.0) } -> std::convertible_to<bool>;
};

// Runs LO-RANSAC. `*model` receives the best model when the report says
// success; `options` must pass Check() (a broken precondition, not a user
// error: the callers check options where the user sets them).
template <RansacEstimator Estimator>
RansacReport Ransac(const RansacOptions& options, Estimator& estimator,
                    typename Estimator::Model* model) {
  using Model = typename Estimator::Model;
  constexpr int kS = Estimator::kSampleSize;
  const auto start = std::chrono::steady_clock::now();
  RansacReport report;
  const std::size_t n = estimator.NumData();
  report.num_data = n;
  report.required_trials = options.max_trials;
  if (n < static_cast<std::size_t>(kS)) return report;

  const double t2 = options.max_error * options.max_error;
  std::mt19937_64 rng(options.seed);
  std::vector<int> sample(kS);
  std::vector<std::size_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = i;
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<Model> models;
  models.reserve(8);
  Model best{};
  std::size_t best_minimal_inliers = 0;
  bool best_is_refined = false;
  // The inliers of `best` whenever it is refined and the skip is on (the
  // refinement's scoring pass records them, try_refine below).
  std::vector<char> best_mask(options.skip_samples_of_best ? n : 0);
  const auto sample_of_best = [&] {
    if (!options.skip_samples_of_best || !best_is_refined) return false;
    for (int k = 0; k < kS; ++k)
      if (!best_mask[sample[k]]) return false;
    return true;
  };
  int required = options.max_trials;

  // MSAC cost of a minimal model in `order`, or +inf once it cannot beat the
  // best (cost bound) or fails the bail-out test.
  auto score_minimal = [&](const Model& model, std::size_t* inliers) {
    const double w = std::max(report.InlierRatio(), options.min_inlier_ratio);
    const bool bail = options.bail_out && w > 0;
    const double spread = 3.0 * std::sqrt(w * (1.0 - w));
    double cost = 0;
    std::size_t count = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double r2 = estimator.SquaredResidual(model, order[k]);
      if (r2 < t2) {
        ++count;
        cost += r2;
      } else {
        cost += t2;
      }
      if (cost >= report.cost) return std::numeric_limits<double>::infinity();
      if (bail && k >= 31 && (k + 1) % 16 == 0) {
        const double seen = static_cast<double>(k + 1);
        if (static_cast<double>(count) < w * seen - spread * std::sqrt(seen) - 1) {
          ++report.bailed_out;
          return std::numeric_limits<double>::infinity();
        }
      }
    }
    *inliers = count;
    return cost;
  };

  // A refined model is scored through all data anyway (it is rarely
  // worse than the best); with the skip on, the same pass records its
  // inliers, the mask the skip needs if it becomes the best.
  std::vector<char> refined_mask(best_mask.size());
  auto try_refine = [&](Model candidate) {
    ++report.refinements;
    if (!estimator.Refine(&candidate, options.max_error)) return;
    std::size_t inliers = 0;
    double cost = 0;
    if (options.skip_samples_of_best) {
      for (std::size_t i = 0; i < n; ++i) {
        const double r2 = estimator.SquaredResidual(candidate, i);
        refined_mask[i] = r2 < t2;
        inliers += refined_mask[i];
        cost += r2 < t2 ? r2 : t2;
      }
    } else {
      cost = estimator.Score(candidate, t2, report.cost, &inliers);
    }
    if (cost < report.cost) {
      report.cost = cost;
      report.num_inliers = inliers;
      best = candidate;
      best_is_refined = true;
      best_mask.swap(refined_mask);
    }
  };

  for (report.trials = 0; report.trials < options.max_trials; ++report.trials) {
    if (report.trials >= options.min_trials && report.trials >= required) break;
    // Uniform sample of kS distinct indices (rejection: kS << n).
    for (int k = 0; k < kS; ++k) {
      int index;
      bool repeated;
      do {
        index = static_cast<int>(rng() % n);
        repeated = std::find(sample.begin(), sample.begin() + k, index) != sample.begin() + k;
      } while (repeated);
      sample[k] = index;
    }
    if (sample_of_best()) {
      ++report.skipped;
      continue;
    }
    models.clear();
    estimator.Generate(std::span<const int>(sample), &models);
    int new_minimal_best = -1;
    for (std::size_t m = 0; m < models.size(); ++m) {
      ++report.models;
      std::size_t inliers = 0;
      const double cost = score_minimal(models[m], &inliers);
      if (cost >= report.cost) continue;
      report.cost = cost;
      report.num_inliers = inliers;
      best = models[m];
      best_is_refined = false;
      if (inliers > best_minimal_inliers) {
        best_minimal_inliers = inliers;
        new_minimal_best = static_cast<int>(m);
      }
    }
    if (new_minimal_best < 0) continue;
    if (options.local_optimisation && best_minimal_inliers >= static_cast<std::size_t>(kS)) {
      try_refine(models[new_minimal_best]);
    }
    required = RequiredTrials(report.InlierRatio(), kS, options);
  }
  report.required_trials = required;
  if (report.num_inliers >= static_cast<std::size_t>(kS)) {
    if (!best_is_refined) try_refine(best);
    report.success = true;
    *model = best;
    if (best_is_refined && options.skip_samples_of_best) {
      report.inlier_mask.assign(best_mask.begin(), best_mask.end());
    } else {
      report.inlier_mask.assign(n, 0);
      for (std::size_t i = 0; i < n; ++i)
        report.inlier_mask[i] = estimator.SquaredResidual(best, i) < t2;
    }
    report.num_inliers = 0;
    for (const char inlier : report.inlier_mask) report.num_inliers += inlier != 0;
  }
  report.time_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return report;
}

}  // namespace lifmcr::registration
