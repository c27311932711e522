#pragma once
// The virtual depths of the plate's corners from the plate plane instead of
// the TF depth map's pixel under each corner. A corner lies on a marker's
// edge, where the map's virtual depth scatters about +-1 % per frame; but
// the plate is a plane, and a thin lens images a plane into a plane: in
// (x_v, y_v, v) the plate's virtual image satisfies v = a + b x + c y (x, y
// on the TF grid; v = (b_L - b_L0) / B is affine in b_L, and the lateral
// virtual coordinates are (x_v - c) s). So one plane fitted to the measured
// (not filled) TF depths inside the detected markers (robustly: points more
// than 3 robust sigmas off are left out and the plane fitted again) gives
// every corner's v from thousands of pixels instead of one.

#include "registration/features/aruco_plate.h"

#include <vector>

namespace lifmcr::registration {

struct PlateDepthOptions {
  double shrink = 0.8;   // a marker's quad scaled by this about its centre (clear of its edges)
  int min_pixels = 200;  // measured pixels for a plane, else the pixel under each corner
};

// Per corner: the plate plane's virtual depth at the corner, or (too few
// measured pixels in the markers) the TF depth map's nearest pixel, NaN
// where that is empty. `tf_sigma_z` is NaN where the TF depth was filled,
// not measured (processing/total_focus.h).
std::vector<float> PlateCornerDepths(const std::vector<PlateCorner>& corners,
                                     const std::vector<float>& tf_virtual_depth,
                                     const std::vector<float>& tf_sigma_z, int width, int height,
                                     const PlateDepthOptions& options = {});

}  // namespace lifmcr::registration
