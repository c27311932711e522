#pragma once
// How far a keypoint's virtual depth can be trusted, from the measured TF
// depth map alone (no ground truth): the relative range of the virtual depth
// over the keypoint's support, a disc of `support_radius_tf_px` about it,
//   range = (max v - min v) / (median v)   over the disc's pixels with a depth.
// SIFT keypoints sit on corners and edges, often on a depth edge, where
// processing/'s virtual depth is 2-30 % wrong on the foreground side
// (docs/processing.md, "Systematic error of the virtual depth"); those errors
// grow with v and pull a calibration's B. A support that straddles an edge
// (or lies on such a wrong strip) shows it as a range of several percent,
// while one surface seen through the map's noise ranges about 1 %
// (docs/calibration.md measures it per keypoint: `bench_keypoint_depth`).

#include <Eigen/Core>

#include <vector>

namespace lifmcr::registration {

struct KeypointDepthSupport {
  int radius_tf_px = 8;  // the disc's radius (TF pixels)
};

// The relative range of `tf_virtual_depth` (width x height, NaN where
// empty) over the disc of `radius_tf_px` about `tf_px`; NaN where fewer than
// half of the disc's pixels have a depth.
float VirtualDepthRange(const std::vector<float>& tf_virtual_depth, int width, int height,
                        const Eigen::Vector2f& tf_px, int radius_tf_px);

}  // namespace lifmcr::registration
