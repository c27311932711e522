#pragma once
// Corners of a dark square marker (an ArUco marker's black border) on a
// blurred image, from straight-line fits to its four edges.
//
// Why not OpenCV's cornerSubPix: it finds the point q where the gradients
// g_i of the window are orthogonal to q - p_i. On a blurred corner whose
// angle is not 90 degrees (a marker seen obliquely) the blur rounds the tip
// and the gradients near it no longer point at the true corner: q lies inside
// the square, by about 0.3 TF px on the synthetic TF images and up to 1 px at
// acute corners (measured against the truth, docs/calibration.md). A blurred
// straight edge, in contrast, crosses the half level between its dark and
// light sides exactly on the true edge for any symmetric blur, so
//   1. for each edge q_i -> q_{i+1}, away from both corners, sample profiles
//      along the outward normal n at every pixel of the edge and take the
//      sub-pixel half-level crossing s*: an edge point p + s* n;
//   2. fit a line to the edge points of the half of each edge nearest a
//      corner (total least squares; the nearer half, so that a slightly
//      curved edge of a distorted image bends the fit little at the corner;
//      MarkerEdgeOptions::whole_edges: the whole edge);
//   3. the corner is the intersection of its two lines; repeat from the new
//      corners.
// Profiles stay inside the marker's black border (their inner half-width is
// at most 0.4 of a code cell), so the code bits do not disturb the dark level.

#include "config/error.h"
#include "config/image.h"

#include <Eigen/Core>

#include <array>

namespace lifmcr::registration {

struct MarkerEdgeOptions {
  double max_profile_half_width_px = 3.0;  // profile from -w to +w along the normal
  int cells_per_side = 8;                  // marker side in code cells, border included (6x6 + 2)
  double min_contrast = 20;                // light - dark level (grey levels) of a usable profile
  int min_points_per_half_edge = 5;        // edge points a corner's line needs
  double max_corner_shift_px = 3.0;        // a larger move from the input rejects the refinement
  int iterations = 3;                      // refit from the refined corners
  // Each corner's lines fitted to the whole of its two edges instead of the
  // half nearest it: on the plate rendered at its plane's depth the edges are
  // straight (no distortion in the TF image of a plane seen through an
  // undistorted lens), and the half-edge window's scatter is the larger
  // error there (docs/calibration.md, "Corner lines fitted to whole edges").
  bool whole_edges = false;
  Status Check() const;
};

// Refines the four corners of one marker (any order around the square) on a
// Mono8 image. False, corners untouched, when an edge gives too few profiles
// (out of the image, too little contrast) or a corner would move further
// than max_corner_shift_px.
bool RefineMarkerCorners(ConstImageView grey, const MarkerEdgeOptions& options,
                         std::array<Eigen::Vector2d, 4>* corners);

}  // namespace lifmcr::registration
