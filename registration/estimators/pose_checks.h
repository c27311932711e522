#pragma once
// Whether a live pose may be published as `ok`: the checks a user expects
// of a PnP pose before trusting it, each refusal naming its reason. A
// robust estimator finds *some* consensus in any set of matches: a dozen
// wrong matches that happen to agree, all in one corner of the image, or
// a track that slid onto the wrong texture give a pose with a small RMSE
// that is still wrong. What such poses lack, and a right one has:
//   inliers       enough of them (min_inliers);
//   spread        over the image: the inliers' TF positions have a
//                 covariance whose smaller principal standard deviation is
//                 >= min_spread x the TF image's shorter side (a uniform
//                 spread gives 0.29, a square cluster of side a 0.29 a: 0.08
//                 refuses clusters narrower than about 28 % of the image),
//                 so the pose is constrained in every direction;
//   rmse          the inliers' RMS reprojection error <= max_rmse_px;
//   covariance    the pose's 6x6 covariance (left perturbation, (t, r)):
//                 largest translation standard deviation <= max_sigma_mm,
//                 largest rotation one <= max_sigma_deg;
//   depth         a plenoptic observation carries its own depth: the pose
//                 must put each inlier's map point at the virtual depth the
//                 camera measured there. z_i = (v(Z_i) - v_i) / (s_v v_i),
//                 Z_i the map point's depth under the pose, v(Z) the thin
//                 lens (processing/camera_model.h), s_v the relative
//                 virtual-depth noise; at least min_depth_agreement of the
//                 inliers must have |z_i| <= depth_sigmas. A wrong pose from
//                 matches that agree in the image only (a map that covers
//                 the view poorly: few points, one plane, one corner) fits
//                 the image positions but not the depths: it slides the
//                 points along their rays or tilts the scene.
//   depth spread  the inliers' depths Z_i span a range: the interquartile
//                 range of Z_i / their median >= min_depth_spread (0: off).
//   prediction    (tracked poses only) the pose agrees with the one
//                 predicted from the previous poses within max_jump_mm and
//                 max_jump_deg: tracking that drifted onto wrong matches
//                 jumps.

#include "config/error.h"
#include "config/frames.h"
#include "processing/camera_model.h"
#include "registration/estimators/pose_covariance.h"

#include <Eigen/Core>

#include <optional>
#include <span>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct PoseCheckOptions {
  int min_inliers = 20;         // >= 3
  double min_spread = 0.08;     // of the TF image's shorter side, [0, 1)
  double max_rmse_px = 1.5;     // TF px, > 0
  double max_sigma_mm = 5.0;    // > 0
  double max_sigma_deg = 0.3;   // > 0
  double max_jump_mm = 40.0;    // tracked vs predicted, > 0
  double max_jump_deg = 4.0;    // > 0
  // Depth agreement (comment above): an inlier agrees when |z_i| <=
  // depth_sigmas (> 0); min_depth_agreement of them must (in [0, 1]).
  // Off (0) by default: the live localizer relocalises on renders
  // refocused at one virtual depth (registration/live/map_localizer.h), so
  // its keypoints' v_i are the render's depth, not theirs. ForErrorBound
  // (offline, per-pixel depth) asks for half: a right pose has |z_i| <= 3
  // for 96-100 % of its inliers on the fast handheld rig (a wrong one that
  // slides along the rays, a few).
  double depth_sigmas = 3.0;
  double min_depth_agreement = 0.0;
  double min_depth_spread = 0.0;  // interquartile range / median of Z_i, >= 0
  Status Check() const;

  // The defaults above are the live localizer's (its covariance in the
  // convention of registration/live/map_localizer.h, tracked poses with a
  // prediction). Offline registration (`lifmcr register`) promises that an
  // `ok` c0_from_cx lies within max_error_mm / max_error_deg of the truth.
  // c0_from_cx composes two poses against the map (camera 0's and camera
  // X's), so its standard deviation is about sqrt(2) times each pose's; and
  // with a calibrated covariance (registration/estimators/pnp.h,
  // "Covariance") a translation or rotation error (3 degrees of freedom)
  // exceeds sqrt(16.27) = 4.03 times its largest standard deviation with a
  // probability of 0.1 % (chi-square(3), 99.9 %). Hence
  //   max_sigma = max_error / (sqrt(2) x 4.03),
  // 0.88 mm / 0.044 deg for 5 mm / 0.25 deg.
  static PoseCheckOptions ForErrorBound(double max_error_mm, double max_error_deg);
};

struct PoseEvidence {
  int inliers = 0;
  std::span<const Eigen::Vector2d> inlier_tf_px;  // the inliers' positions
  int tf_width = 0, tf_height = 0;
  double rmse_px = 0;
  Covariance6 covariance = Covariance6::Zero();  // (t mm, r rad), left perturbation
  Pose w0_from_cam = Pose::Identity();
  std::optional<Pose> predicted_w0_from_cam;  // tracked poses
  // Per inlier (may be empty: not checked): z_i of the depth check (NaN
  // where the virtual depth is unknown) and the map point's depth Z_i (mm).
  std::span<const double> inlier_depth_z;
  std::span<const double> inlier_depth_mm;
};

// What the checks measured, for reports and for choosing thresholds.
struct PoseCheckFigures {
  double spread = 0;            // smaller principal std. dev. / shorter side
  double sigma_mm = 0;          // largest translation std. dev.
  double sigma_deg = 0;         // largest rotation std. dev.
  double depth_agreement = -1;  // fraction with |z_i| <= depth_sigmas; -1: no depths
  double median_depth_z = 0;    // median z_i (signed)
  double depth_spread = -1;     // IQR / median of Z_i; -1: no depths
};
PoseCheckFigures MeasurePose(const PoseEvidence& evidence, const PoseCheckOptions& options);

// z_i and Z_i of the depth check for map points X_i (w0) seen with virtual
// depths v_i under cam_from_w0; relative virtual-depth noise
// sigma_v_relative.
void InlierDepths(const processing::CameraModel& camera, const Pose& cam_from_w0,
                  std::span<const Eigen::Vector3d> points_in_w0,
                  std::span<const double> virtual_depth, double sigma_v_relative,
                  std::vector<double>* depth_z, std::vector<double>* depth_mm);

// "ok", or "refused: <reason>" (e.g. "refused: inliers span 3.1 % of the
// image (< 5 %)").
std::string CheckPose(const PoseEvidence& evidence, const PoseCheckOptions& options);

}  // namespace lifmcr::registration
