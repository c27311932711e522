#include "registration/features/fundamental_filter.h"

#include <opencv2/calib3d.hpp>

#include <cmath>
#include <cstdio>

namespace lifmcr::registration {

Status FundamentalFilterOptions::Check() const {
  if (!(threshold_px > 0) || !std::isfinite(threshold_px))
    return Error{"fundamental filter: threshold_px: expected a finite number > 0"};
  if (!(confidence > 0 && confidence < 1))
    return Error{"fundamental filter: confidence: expected in (0, 1)"};
  if (max_iterations < 1) return Error{"fundamental filter: max_iterations: expected >= 1"};
  if (min_pairs < 8) return Error{"fundamental filter: min_pairs: expected >= 8"};
  return Status::Ok();
}

std::string FundamentalFilterResult::Report() const {
  char line[128];
  if (!applied)
    std::snprintf(line, sizeof line, "F filter: not applied (%d pairs)", pairs);
  else
    std::snprintf(line, sizeof line, "F filter: %d of %d pairs outliers", outliers, pairs);
  return line;
}

FundamentalFilterResult FilterByFundamental(const std::vector<Eigen::Vector2d>& query_px,
                                            const std::vector<Eigen::Vector2d>& reference_px,
                                            const FundamentalFilterOptions& options) {
  FundamentalFilterResult result;
  const std::size_t n = std::min(query_px.size(), reference_px.size());
  result.pairs = static_cast<int>(n);
  result.inlier.assign(n, 1);
  if (!options.Check() || result.pairs < options.min_pairs) return result;
  std::vector<cv::Point2f> q(n), r(n);
  for (std::size_t i = 0; i < n; ++i) {
    q[i] = {static_cast<float>(query_px[i].x()), static_cast<float>(query_px[i].y())};
    r[i] = {static_cast<float>(reference_px[i].x()), static_cast<float>(reference_px[i].y())};
  }
  std::vector<std::uint8_t> mask;
  cv::Mat f;
  try {
    f = cv::findFundamentalMat(q, r, cv::USAC_ACCURATE, options.threshold_px, options.confidence,
                               options.max_iterations, mask);
  } catch (const cv::Exception&) {
    return result;  // degenerate input: nothing removed
  }
  if (f.empty() || mask.size() != n) return result;
  result.applied = true;
  for (std::size_t i = 0; i < n; ++i) {
    result.inlier[i] = mask[i] ? 1 : 0;
    result.outliers += mask[i] ? 0 : 1;
  }
  return result;
}

}  // namespace lifmcr::registration
