#pragma once
// A diagnostic for synthetic sequences, not a method (`lifmcr calibrate
// --substitute-truth LIST`): one group of the calibration's observations
// replaced by the renderer's truth before the calibration, so that the
// calibration shows which observations carry a bias (the principal point,
// B and the poses that move when a group is made exact).
//
// Every substitute is in the geometry of the processed frame (lambda0 and
// c0 of the initial intrinsics, calibration_gates.h ProcessedGeometry), as
// the measured observations are:
//   keypoint-depth   each keypoint's virtual depth the true one at its
//                    position (the true point behind the keypoint's
//                    processed position, SurfaceDepthMm); keypoints where
//                    the truth has no depth lose theirs
//   keypoints        the keypoints SIFT finds on the renderer's all-in-focus
//                    image (the true TF grid), each at the true virtual
//                    point taken into the processed geometry: positions and
//                    depths exact, the detector's own error aside
//   corners          each plate corner at the true projection of its plate
//                    point (true intrinsics and pose), with the true depth
//   corner-depth     only the plate corners' virtual depths true
//   no-corner-depth  the plate corners without a virtual depth (each enters
//                    by its position at the depth of its projection)
// Needs SEQ/GroundTruth (cameras.yaml, poses_<serial>.csv, depth/,
// all_in_focus/ for `keypoints`).

#include "config/error.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/features.h"

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::registration {

// The groups named above (at most one of each line).
struct TruthSubstitution {
  bool keypoint_depth = false, keypoints = false;
  bool corners = false, corner_depth = false, no_corner_depth = false;
  bool any() const { return keypoint_depth || keypoints || corners || corner_depth || no_corner_depth; }
};

// A comma-separated list of the names above; an error names the unknown one
// and the conflicting pairs (keypoint-depth with keypoints; more than one of
// the corner groups).
Expected<TruthSubstitution> ParseTruthSubstitution(std::string_view list);

// The frames' observations replaced as `what` says. `lambda0` and `c0_px`
// are what the frames were processed with; `features` the detector's
// options (for `keypoints`). Returns a line per group: how many were
// replaced.
Expected<std::string> SubstituteTruth(const TruthSubstitution& what,
                                      const std::filesystem::path& sequence_dir,
                                      const std::string& serial, double lambda0,
                                      const Eigen::Vector2d& c0_px,
                                      const FeatureOptions& features,
                                      std::vector<CalibrationFrame>* frames);

}  // namespace lifmcr::registration
