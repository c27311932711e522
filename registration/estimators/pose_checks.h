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
//   prediction    (tracked poses only) the pose agrees with the one
//                 predicted from the previous poses within max_jump_mm and
//                 max_jump_deg: tracking that drifted onto wrong matches
//                 jumps.

#include "config/error.h"
#include "config/frames.h"
#include "registration/estimators/pose_covariance.h"

#include <Eigen/Core>

#include <optional>
#include <span>
#include <string>

namespace lifmcr::registration {

struct PoseCheckOptions {
  int min_inliers = 20;         // >= 3
  double min_spread = 0.08;     // of the TF image's shorter side, [0, 1)
  double max_rmse_px = 1.5;     // TF px, > 0
  double max_sigma_mm = 5.0;    // > 0
  double max_sigma_deg = 0.3;   // > 0
  double max_jump_mm = 40.0;    // tracked vs predicted, > 0
  double max_jump_deg = 4.0;    // > 0
  Status Check() const;
};

struct PoseEvidence {
  int inliers = 0;
  std::span<const Eigen::Vector2d> inlier_tf_px;  // the inliers' positions
  int tf_width = 0, tf_height = 0;
  double rmse_px = 0;
  Covariance6 covariance = Covariance6::Zero();  // (t mm, r rad), left perturbation
  Pose w0_from_cam = Pose::Identity();
  std::optional<Pose> predicted_w0_from_cam;  // tracked poses
};

// "ok", or "refused: <reason>" (e.g. "refused: inliers span 3.1 % of the
// image (< 5 %)").
std::string CheckPose(const PoseEvidence& evidence, const PoseCheckOptions& options);

}  // namespace lifmcr::registration
