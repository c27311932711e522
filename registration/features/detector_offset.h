#pragma once
// The keypoint detector's own offset, measured without a ground truth: SIFT
// on an image and on the same image turned by 180 degrees. A feature at x
// lies at W - 1 - x in the turned image (per axis, W the image's extent); a
// detector that reports it b off reports r = x + b on the image and
// r' = W - 1 - x + b on the turned one, so b = (r + r' - (W - 1)) / 2 for each
// pair. bench_keypoint_position prints it by octave; test_keypoint_depth
// bounds it (DetectSift puts keypoints on the pixel grid, features.h).

#include "config/error.h"
#include "config/image.h"
#include "registration/features/features.h"

#include <Eigen/Core>

#include <vector>

namespace lifmcr::registration {

// For each keypoint of `a`, the index of the nearest of `b_xy` (b's keypoints'
// positions in a's image, in b's order) within `radius_px` whose size is
// within 20 % of a's; -1 where none.
std::vector<int> PairByPosition(const Features& a, const std::vector<Eigen::Vector2f>& b_xy,
                                const Features& b, float radius_px);

struct DetectorOffset {
  int keypoint = -1;            // index into the image's keypoints
  Eigen::Vector2f offset_px{};  // b, in the image's pixels
};

// b for every keypoint of `on_image` (DetectSift of `image` with `options`)
// that pairs within 1 px with one on the turned image (the pair's 2b is below
// that). The turned image is one new buffer of the image's size.
Expected<std::vector<DetectorOffset>> DetectorOffsetsByTurning(ConstImageView image,
                                                               const Features& on_image,
                                                               const FeatureOptions& options);

}  // namespace lifmcr::registration
