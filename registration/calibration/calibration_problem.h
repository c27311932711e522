#pragma once
// Internal to calibration: the tracks and frame poses that initialisation
// builds and the bundle adjustment refines (calibration.h states the method).

#include "registration/calibration/calibration.h"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <cmath>
#include <vector>

namespace lifmcr::registration::internal {

struct Observation {
  int frame = 0;     // index into CalibrationInput::frames
  int keypoint = 0;  // index into that frame's keypoints
  bool inlier = true;
};

struct Track {
  Eigen::Vector3d p_in_w_mm = Eigen::Vector3d::Zero();
  std::vector<Observation> observations;
};

struct FrameState {
  bool placed = false;
  std::string how;
  Pose w0_from_c = Pose::Identity();
  std::vector<int> track_of_keypoint;  // -1 where the keypoint starts no track
};

struct InitialMap {
  std::vector<FrameState> frames;
  std::vector<Track> tracks;
};

// Recalibration's start for b_L0 (f_L and B held): each frame that sees the
// plate is placed on its corners (the virtual image is a pinhole of focal
// b_L(Z) / s with b_L = f_L Z / (Z - f_L), which needs f_L, not b_L0), and
// every corner with a measured virtual depth v gives b_L0 = b_L(Z) - v B;
// the median over all of them. An error when no corner has a virtual depth.
Expected<double> MlaDistanceFromPlate(const CalibrationInput& input,
                                      const processing::CameraIntrinsics& nominal,
                                      const CalibrationOptions& options);

// Step 2 of calibration.h with the nominal intrinsics.
Expected<InitialMap> Initialise(const CalibrationInput& input,
                                const processing::CameraIntrinsics& nominal,
                                const CalibrationOptions& options,
                                const ProgressFn& progress);

// The TF pinhole pixel (reference_map.h: distortion corrected, eqs.
// projX/projY, TF grid) of a virtual point under the intrinsics vector k;
// `model` gives the distortion model (its own intrinsics' values are not
// used for c, b_L0, B).
Eigen::Vector2d TfPinholePx(const IntrinsicsVector& k, const processing::CameraModel& model,
                            const Eigen::Vector3d& virtual_px);

// The virtual point of keypoint k of a frame (raw pixels, measured v).
inline Eigen::Vector3d VirtualPoint(const CalibrationFrame& frame, int k) {
  const Eigen::Vector2f& tf = frame.features.keypoints[k].xy_px;
  return {2.0 * tf.x() + 0.5, 2.0 * tf.y() + 0.5, frame.virtual_depth[k]};
}

// The range of the measured virtual depth over keypoint k's support
// (CalibrationFrame::virtual_depth_range); NaN where the frame has none.
inline double KeypointDepthRange(const CalibrationFrame& frame, int k) {
  return static_cast<std::size_t>(k) < frame.virtual_depth_range.size()
             ? frame.virtual_depth_range[k]
             : std::nan("");
}

// The weight of a keypoint's depth for the range of its support
// (CalibrationOptions::keypoint_depth_sigma_rel, _per_range):
// sigma_0 / sqrt(sigma_0^2 + (slope range)^2); 1 without a range.
inline double KeypointDepthWeight(double range, double sigma_rel, double per_range) {
  if (!(range >= 0)) return 1;
  const double r = per_range * range / sigma_rel;
  return 1 / std::sqrt(1 + r * r);
}

}  // namespace lifmcr::registration::internal
