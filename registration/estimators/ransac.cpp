#include "registration/estimators/ransac.h"

#include <cstdio>

namespace lifmcr::registration {
namespace {

Error FieldError(const std::string& field, const std::string& what) {
  return Error{"ransac options: " + field + ": " + what};
}

}  // namespace

Status RansacOptions::Check() const {
  if (!(max_error > 0) || !std::isfinite(max_error))
    return FieldError("max_error", "expected a finite number > 0");
  if (!(confidence > 0 && confidence < 1)) return FieldError("confidence", "expected 0 < c < 1");
  if (!(trials_multiplier >= 1) || !std::isfinite(trials_multiplier))
    return FieldError("trials_multiplier", "expected a finite number >= 1");
  if (min_trials < 0) return FieldError("min_trials", "expected >= 0");
  if (!(min_inlier_ratio >= 0 && min_inlier_ratio < 1))
    return FieldError("min_inlier_ratio", "expected 0 <= ratio < 1");
  if (max_trials < 1 || max_trials < min_trials)
    return FieldError("max_trials", "expected >= 1 and >= min_trials");
  return Status::Ok();
}

int RequiredTrials(double inlier_ratio, int sample_size, const RansacOptions& options) {
  const double all_inlier = std::pow(inlier_ratio, sample_size);
  if (all_inlier >= 1.0 - 1e-12) return options.min_trials;
  if (all_inlier <= 0.0) return options.max_trials;
  const double k = options.trials_multiplier * std::log(1.0 - options.confidence) /
                   std::log1p(-all_inlier);
  if (!(k < static_cast<double>(options.max_trials))) return options.max_trials;
  return std::max(options.min_trials, static_cast<int>(std::ceil(k)));
}

std::string RansacReport::BriefReport() const {
  char line[320];
  std::snprintf(line, sizeof line,
                "LO-RANSAC %s: %zu/%zu inliers (%.1f %%), %d trials of %d needed (%d of the best's "
                "inliers, unsolved), %d models (%d bailed out), %d refinements, cost %.3g, %.2f ms",
                success ? "ok" : "failed", num_inliers, num_data, 100.0 * InlierRatio(), trials,
                required_trials, skipped, models, bailed_out, refinements, cost, time_ms);
  return line;
}

}  // namespace lifmcr::registration
