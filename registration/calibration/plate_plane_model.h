#pragma once
// The marker plate's virtual plane as a calibration predicts it, and the
// plate corners placed again on the plate rendered at that plane
// (`lifmcr calibrate --plate-model-passes N`).
//
// Why: the corners are placed on the plate rendered at a plane fitted to the
// measured virtual depths inside the markers (plate_plane.h), and that plane
// is 4-5 % flatter than the plate on `medium` smooth and handheld
// (processing/'s depth bias inside the high-contrast markers). A TF pixel
// rendered at F times its virtual depth v has its content moved along the
// main-lens ray,
//   x' - c = (x - c) (lambda + F v (1 - lambda)) / (lambda + v (1 - lambda)),
// so each corner moves by a part that changes across the tilted plate, which
// the principal point absorbs (docs/calibration.md, "Where the corners'
// offset along the slant comes from"). The plate's geometry is known: under
// a calibration's intrinsics and a frame's pose its points project
// (plenoptic_projection.h) to virtual points on a plane, which, taken into
// the geometry the frame was processed in (lambda0 and c0 of the initial
// intrinsics, calibration_gates.h ProcessedGeometry), is
//   v'(u, w) = a + b u + c w     (TF coordinates u, w; x' = 2 u + 1/2)
// to within the distortion's bend (least squares over the frame's corners).
// A pass: the plane of every placed frame predicted from the last solve, the
// plate rendered at it and its corners placed again (marker_edges.h,
// CalibrationFrameLoader::PlaceCornersAtPlane), optionally their virtual
// depths from the same plane, and the calibration run again.

#include "config/error.h"
#include "config/frames.h"
#include "registration/calibration/calibration.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/marker_edges.h"
#include "registration/features/plate_plane.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace lifmcr::registration {

struct PlateModelOptions {
  int passes = 0;  // corners placed again and calibrated again this many times; 0: off
  // Each corner's virtual depth the predicted plane's at the corner (the
  // depth its position was found at) instead of the depth measured at the
  // corner pixel by the first processing.
  bool corner_depth_from_plane = true;
  MarkerEdgeOptions edges;  // the corner lines (whole_edges: the plate's edges are straight)
  Status Check() const;
};

// The plane of the plate points `p_in_w_mm` (at least 3, not collinear) in
// a frame processed with lambda0 and principal point c0 (raw px), under the
// intrinsics `k` (pixel size `pixel_size_mm`) and the pose `cam_from_w`. An
// error when a point lies in front of the main lens' focal length or the
// points do not span a plane.
Expected<PlatePlane> PredictPlatePlane(const IntrinsicsVector& k, double pixel_size_mm,
                                       const Pose& cam_from_w,
                                       const std::vector<Eigen::Vector3d>& p_in_w_mm,
                                       double lambda0, const Eigen::Vector2d& c0);

// What a pass did to the corners.
struct PlateModelPass {
  int frames = 0;           // frames whose corners were placed again
  int corners = 0;          // corners placed again
  int corners_lost = 0;     // corners whose marker's edges no longer fitted (left out)
  double mean_shift_tf_px = 0;  // mean move of the corners placed again
  double mean_dy_tf_px = 0;     // its mean along y
  double mean_depth_change_rel = 0;  // mean of v_new / v_old - 1 where both are known
  std::string Summary() const;
};

// One pass over `frames` (those with a pose in `result` and plate corners):
// each frame's markers (its corners grouped by marker, the four in order)
// placed again on the plate rendered at the plane `result` predicts
// (`result.frames_lambda`, `result.frames_principal_point_px`: the
// geometry the frames were processed in); frames without a pose keep theirs.
Expected<PlateModelPass> PlaceCornersAtModelPlane(const CalibrationResult& result,
                                                  const PlateModelOptions& options,
                                                  CalibrationFrameLoader* loader,
                                                  std::vector<CalibrationFrame>* frames);

}  // namespace lifmcr::registration
