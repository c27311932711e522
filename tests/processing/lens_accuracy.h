#pragma once
// The per-lens depth against the truth reduced per lens (the tests of
// processing/lens_depth.h): coverage, median |dv|/v and outliers (> 10 %)
// over the lenses the estimator calls textured and whose truth is known.

#include "processing/lens_depth.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace lifmcr::processing::testing {

struct LensAccuracy {
  long long textured = 0, estimated = 0, outliers = 0;
  double coverage = 0, median = 1;
};

// Over the cells `use(c)` keeps.
template <typename Use>
LensAccuracy MeasureLensDepth(const LensDepthMap& depth, const std::vector<float>& truth, Use use) {
  LensAccuracy a;
  std::vector<double> rel;
  for (std::size_t c = 0; c < truth.size(); ++c) {
    if (!use(c) || !depth.textured[c] || !std::isfinite(truth[c])) continue;
    ++a.textured;
    const float v = depth.virtual_depth[c];
    if (!std::isfinite(v)) continue;
    ++a.estimated;
    rel.push_back(std::abs(v - truth[c]) / truth[c]);
    if (rel.back() > 0.10) ++a.outliers;
  }
  if (a.textured == 0 || rel.empty()) return a;
  std::nth_element(rel.begin(), rel.begin() + rel.size() / 2, rel.end());
  a.coverage = static_cast<double>(a.estimated) / a.textured;
  a.median = rel[rel.size() / 2];
  return a;
}

inline LensAccuracy MeasureLensDepth(const LensDepthMap& depth, const std::vector<float>& truth) {
  return MeasureLensDepth(depth, truth, [](std::size_t) { return true; });
}

}  // namespace lifmcr::processing::testing
