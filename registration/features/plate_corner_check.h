#pragma once
// A check of one frame's ArUco plate corners against the plate's planar
// geometry, without the ground truth, before they anchor the calibration.
//
// The plate is a plane and the TF image is a central projection of the
// virtual image (x_v = 2 tf + 0.5 projected from the main lens' centre onto
// the MLA plane; processing/camera_model.h), and the main lens maps a plane
// to a plane: up to the lens' distortion the plate's corners (X, Y) in the
// plate frame and their detected TF positions u are related by one
// homography, u ~ H (X, Y, 1). A corner that the detector displaced (a
// mis-rendered or mis-focused patch of the TF image at a strong depth edge;
// docs/calibration.md) does not fit the homography of the others.
//
// Leave-one-out: for each corner, H is fitted (normalised DLT) to the
// frame's other corners and the corner's residual is |u - H(X, Y)| in TF px.
// The worst corner above the threshold
//   max(max_residual_tf_px, max_residual_over_reference x reference)
// is rejected and the residuals recomputed without it, until none is above
// or fewer than min_corners would remain. The reference is the camera's
// typical residual: the median over every corner of every frame
// (MedianPlateCornerResidual), so that a lens whose distortion bends every
// corner off the homography does not lose them all, while a frame whose
// corners are off together (the orbit's frame 16: eight of its sixteen
// corners 0.5-1.5 TF px off) is judged by the other frames' figures, not by
// its own median. The absolute threshold is justified by the orbit
// sequences (docs/calibration.md): well detected corners 0.1-0.25 TF px or
// less, the displaced ones 1-2.6 TF px.

#include "config/error.h"
#include "registration/features/aruco_plate.h"

#include <vector>

namespace lifmcr::registration {

struct PlateCornerCheckOptions {
  int min_corners = 6;                    // fewer corners in a frame: not checked
  double max_residual_tf_px = 0.5;        // absolute threshold (TF px)
  double max_residual_over_reference = 5.0;  // relative threshold (x the reference residual)
  Status Check() const;
};

struct PlateCornerCheck {
  bool checked = false;                // the frame had min_corners or more
  std::vector<double> residual_tf_px;  // per corner: leave-one-out residual of the last round
  std::vector<int> rejected;           // indices into the corners, in the order rejected
  std::vector<double> rejected_residual_tf_px;   // the residual each had when rejected
  double threshold_tf_px = 0;          // the threshold applied
};

// Leave-one-out residual of each corner (TF px) with none rejected; NaN for
// every corner when there are fewer than min_corners or the layout points
// are degenerate (on a line).
std::vector<double> PlateCornerResiduals(const std::vector<PlateCorner>& corners,
                                         const PlateCornerCheckOptions& options = {});

// The median of PlateCornerResiduals over the corners of every frame given
// (0 when none was checked).
double MedianPlateCornerResidual(const std::vector<std::vector<PlateCorner>>& frames,
                                 const PlateCornerCheckOptions& options = {});

// One frame's check; `reference_tf_px` as above (0: the absolute threshold
// alone). Fewer than min_corners, or a degenerate layout: checked = false,
// nothing rejected.
PlateCornerCheck CheckPlateCorners(const std::vector<PlateCorner>& corners,
                                   double reference_tf_px,
                                   const PlateCornerCheckOptions& options = {});

}  // namespace lifmcr::registration
