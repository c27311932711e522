#pragma once
// Hand-eye calibration in the robot-world form A_i X = Z B_i: the offset X
// between a tracked body and a camera on it, together with a fixed transform
// Z between the two "world" frames (notes: Shah 2013, Li 2010; OpenCV's
// calibrateRobotWorldHandEye).
//
// lifmcr uses it in two shapes (evaluation/evaluation.h):
//   per camera pair   A_i = marker0_from_markerX (Vicon),  B_i = c0_from_cx
//                     (registration),  X = markerX_from_camX,  Z = marker0_from_cam0;
//   per camera        A_i = vicon_from_marker (Vicon),  B_i = w0_from_cam (map
//                     poses),  X = marker_from_cam,  Z = vicon_from_w0.
// Both read: "the tracked frame composed with the offset equals the other
// world composed with the camera".
//
// Method:
//  1. Observability. Eliminating Z gives A_j^-1 A_i X = X B_j^-1 B_i: X is
//     determined only when the B_i rotate about at least two different axes
//     (with rotations about one axis, the rotation about it and the
//     translation along it are free). The rotation vectors Log(R̄^T R_Bi)
//     around the chordal mean R̄ are decomposed by SVD; the RMS spread about
//     the second principal axis must reach min_rotation_spread_deg, otherwise
//     the solve is refused with a message that names the spreads.
//  2. Closed form: Shah's Kronecker solution (as cv::calibrateRobotWorldHandEye,
//     extended to several X sharing one Z): with column-major vec,
//     R_A R_Xk R_B^T = R_Z reads (R_B ⊗ R_A) vec(R_Xk) - vec(R_Z) = 0; the
//     stacked system's null vector (smallest eigenvector of MᵀM) gives every
//     R_Xk and R_Z up to one scale, fixed by det(R_Z) = 1, each block then
//     projected onto SO(3). The translations follow linearly from
//     R_A t_Xk - t_Z = R_Z t_B - t_A. Repeated once without the observations
//     whose residual is beyond 5 robust sigmas (gross registration failures).
//  3. Refinement (Ceres, Levenberg-Marquardt, ceres::EigenQuaternionManifold):
//        min_{X,Z} sum_i rho(|r_i|^2),  E_i = (Z B_i)^-1 A_i X,
//        r_i = [t(E_i) / sigma_t ; Log(R(E_i)) / sigma_r],
//     rho = Huber at huber_threshold. sigma_t and sigma_r start from the
//     options and are re-estimated from the residuals (1.4826 MAD, per
//     camera in the joint solve) before a second solve, so the weights
//     follow the data.
//  4. Uncertainty: the covariance of X and Z from ceres::Covariance at the
//     optimum, scaled by the variance factor of the inliers' normalised
//     residuals, sum r^2 / (m - 12) over their m components.
//     Rotation standard deviations are about the axes of the frame X (or Z)
//     maps into (the manifold perturbs on the left).

#include "config/error.h"
#include "config/frames.h"

#include <Eigen/Core>

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace lifmcr {

struct HandEyeOptions {
  // Refuse when the rotations spread less than this (deg, RMS) about the
  // second principal axis: they turn about one axis only.
  double min_rotation_spread_deg = 1.0;
  // Starting residual scales of the refinement (re-estimated from the data).
  double translation_sigma_mm = 1.0;
  double rotation_sigma_deg = 0.1;
  // Huber threshold, in sigmas of the normalised residual.
  double huber_threshold = 3.0;
  // Levenberg-Marquardt iterations per solve.
  int max_iterations = 100;
  // At least this many observations.
  int min_observations = 10;

  Status Check() const;
};

struct HandEyeResult {
  bool success = false;
  std::string message;  // the reason when it failed
  Pose x = Pose::Identity();
  Pose z = Pose::Identity();
  Pose x_closed_form = Pose::Identity();
  Pose z_closed_form = Pose::Identity();
  // Standard deviations: translation per axis of the frame X (Z) maps into
  // (mm), rotation about those axes (deg).
  Eigen::Vector3d x_translation_sd_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d x_rotation_sd_deg = Eigen::Vector3d::Zero();
  Eigen::Vector3d z_translation_sd_mm = Eigen::Vector3d::Zero();
  Eigen::Vector3d z_rotation_sd_deg = Eigen::Vector3d::Zero();
  std::size_t observations = 0;
  std::size_t inliers = 0;            // normalised residual within the Huber threshold
  double translation_rms_mm = 0;      // residual of the inliers after refinement
  double rotation_rms_deg = 0;
  double translation_sigma_mm = 0;    // the robust scales the final solve used
  double rotation_sigma_deg = 0;
  Eigen::Vector3d rotation_spread_deg = Eigen::Vector3d::Zero();  // descending
  int iterations = 0;

  // "hand-eye: 200 obs, 198 inliers, residual 0.9 mm / 0.05 deg, X t=(..) mm ± (..)".
  std::string BriefReport() const;
};

// RMS spread (deg) of the rotations of `poses` about their three principal
// axes, descending (step 1 above).
Eigen::Vector3d RotationSpreadDeg(std::span<const Pose> poses);

// Solves A_i X = Z B_i for X and Z (a.size() == b.size()). Never throws on
// data: a degenerate or too small input gives success = false and a message.
HandEyeResult SolveRobotWorldHandEye(std::span<const Pose> a, std::span<const Pose> b,
                                     const HandEyeOptions& options = {});

// Several bodies seen in one pair of worlds: A_ki X_k = Z B_ki for cameras
// k with their own offsets X_k and ONE shared Z (the map-frame hand-eye of
// a rig: every camera's marker_from_cam and one correction of the plate
// alignment). Each camera's observations must determine its X_k (step 1 on
// its B_ki; the refusal names the camera) and number min_observations.
struct HandEyeObservations {
  std::string name;  // the camera, for messages
  std::vector<Pose> a, b;
};
struct JointHandEyeResult {
  bool success = false;
  std::string message;  // the reason when it failed
  // Per camera, in input order: x, its uncertainty and residuals; z and its
  // uncertainty are the shared Z in each.
  std::vector<HandEyeResult> cameras;
  Pose z = Pose::Identity();
  // "joint hand-eye of 2 cameras: Z t=(..) mm, r=(..) deg; 0: ...; X: ...".
  std::string BriefReport() const;
};
// A measurement of Z made apart from the motions (the plate alignment's:
// Z = identity within its residual). With it the refinement adds the
// residual [t(Z0^-1 Z) / sd_t ; Log(R(Z0^-1 Z)) / sd_r] (no robust loss) and
// starts from Z = Z0 and X_k = the chordal mean of A_ki^-1 Z0 B_ki: a
// sequence whose rotations spread a few degrees determines Z and the X_k
// together only to several mm (each X's translation along a turning axis
// trades against Z's), while Z0 with a fraction of a mm pins them.
struct HandEyePrior {
  Pose z = Pose::Identity();
  double translation_sd_mm = 1.0;  // > 0
  double rotation_sd_deg = 0.1;    // > 0
  Status Check() const;
};
JointHandEyeResult SolveJointRobotWorldHandEye(std::span<const HandEyeObservations> cameras,
                                               const HandEyeOptions& options = {},
                                               const std::optional<HandEyePrior>& z_prior = {});

}  // namespace lifmcr
