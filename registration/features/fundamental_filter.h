#pragma once
// The paper's outlier filter before PnP relocalisation (section 3: "outliers
// in the 2D-2D correspondences are first removed using robust fundamental
// matrix estimation between the reference and query views"). The 2D-2D
// pairs are a query keypoint and the same map point's keypoint in one
// reference keyframe of the map (RegisterFrame picks the keyframe that saw
// most of the matched map points). A pair agrees with a fundamental matrix F
// when x_ref^T F x_query ~ 0 (x homogeneous TF pixels); F is estimated by
// OpenCV's USAC (USAC_ACCURATE: GC-RANSAC with local optimisation, 7-point
// minimal samples, degeneracy checks), so no camera model is needed: the two
// views may be different cameras. Pairs beyond the threshold (Sampson
// distance, px) are outliers.

#include "config/error.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace lifmcr::registration {

struct FundamentalFilterOptions {
  bool enabled = false;        // RegisterFrame (PnP) filters its matches first
  double threshold_px = 2.0;   // epipolar (Sampson) distance of an inlier, > 0
  double confidence = 0.999;   // of USAC's stopping rule, in (0, 1)
  int max_iterations = 1000;   // USAC's, >= 1
  int min_pairs = 30;          // fewer pairs with the keyframe: not filtered, >= 8
  Status Check() const;
};

struct FundamentalFilterResult {
  bool applied = false;  // false: too few pairs, or no F found (nothing removed)
  int pairs = 0;
  int outliers = 0;
  std::vector<char> inlier;  // per pair (all 1 when not applied)
  std::string Report() const;  // "F filter: 37 of 412 pairs outliers"
};

FundamentalFilterResult FilterByFundamental(const std::vector<Eigen::Vector2d>& query_px,
                                            const std::vector<Eigen::Vector2d>& reference_px,
                                            const FundamentalFilterOptions& options);

}  // namespace lifmcr::registration
