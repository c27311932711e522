#pragma once
// Intrinsic calibration of one plenoptic camera and its reference map
// (`lifmcr calibrate`), after LiFCal (notes in processing/camera_model.h)
// without COLMAP:
//
// 1. Frames (calibration_frames.h): SIFT keypoints on the TF image, each a
//    virtual point (x_v, y_v, v) with x_v = 2 tf + 0.5 and v the measured
//    virtual depth; ArUco plate corners, each frame's checked against the
//    plate's planar geometry (plate_corner_check.h): a corner off the
//    homography of its frame's other corners stays out of step 3.
// 2. Initialisation (nominal intrinsics): the first frame that sees the
//    plate is placed by PnP on the plate corners; every keypoint with a
//    virtual depth back-projects to a 3D point (camera_model.h). Each
//    further frame is matched (ratio test + cross-check, approximate
//    neighbours by kd-trees) against the points
//    seen by the frames placed just before it and placed by RANSAC PnP on
//    the TF pinhole (eqs. projX/projY, focal (b_L0 + 2B)/s); matched
//    keypoints join the point's track, the others start new points.
// 3. Plenoptic bundle adjustment (Ceres): frame poses (quaternion on
//    ceres::QuaternionManifold, translation), points of tracks seen at least
//    twice (by inverse depth in the frame of their first observation, so no
//    step puts a point behind the main lens' focal plane there), intrinsics f_L, b_L0, B, c_x, c_y, k1, k2, p1, p2
//    (plenoptic_projection.h). A keypoint observation is reprojected into
//    every micro image that sees it: the observed micro-image position is
//    p_k = l_k + (x_v - l_k) / v (the raw-image position the virtual-depth
//    search matched, l_k with the initial lambda); the residual is the
//    predicted p_k minus it, micro-lens centre adjustment included, Huber
//    loss per observation. Plate corners are points fixed at their known
//    plate coordinates, observed in the micro images in the same way (with
//    the virtual depth at the corner; in the virtual image x_v where the TF
//    depth map has none), each detected corner modelled as moved by one
//    estimated inset towards its marker's centre (near zero with corners
//    from the markers' edges, aruco_plate.h): they fix the
//    metric scale and make the world frame w0 the plate frame; their
//    residuals are weighted by plate_weight. Solves: poses and points under
//    the initial intrinsics, then everything (f_L, b_L0, B bounded to 30 %
//    about their initial values, the principal point to 10 % of the image),
//    then, with observations whose RMS residual exceeds max(outlier_px,
//    3 x the median) dropped,
//    everything again. Recalibration holds f_L and B fixed
//    (ceres::SubsetManifold).
// 4. Standard deviations of the intrinsics from ceres::Covariance, scaled by
//    the residual variance of the solution.
// The principal point has a weak Gaussian prior about its initial value
// (principal_point_prior_px).

#include "config/error.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/features.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/features/plate_corner_check.h"
#include "registration/calibration/plenoptic_projection.h"
#include "registration/map/poses_csv.h"
#include "registration/map/reference_map.h"

#include <functional>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::registration {

struct CalibrationOptions {
  int min_frames = 3;               // frames placed, else an error
  int min_features = 50;            // keypoints with a virtual depth per frame, else rejected
  int min_plate_corners = 4;        // corners for a plate pose
  MatchOptions match = MapMatching();  // frame to map matching (kd-forest, features.h)
  int match_window = 4;             // a frame is matched against points seen by this many placed frames
  double pnp_threshold_px = 6.0;    // RANSAC inlier threshold (raw pixels of the TF pinhole)
  int pnp_iterations = 5000;        // RANSAC trials
  int min_pnp_inliers = 20;         // else the frame falls back to the plate, or is rejected
  double huber_px = 1.0;            // Huber scale per micro-image residual (raw pixels)
  double outlier_px = 1.5;          // observations above max(this, 3 x median) RMS residual are dropped
  double plate_weight = 5.0;        // plate corner residuals count this much more (the metric anchor)
  // Frames whose plate corners enter the bundle adjustment (empty: every
  // frame's). The initialisation still places frames on the plate.
  std::vector<std::int64_t> plate_frames;
  // Each frame's plate corners are checked against the plate's planar
  // geometry before the bundle adjustment (plate_corner_check.h); a corner
  // that fails is left out of the plate terms and reported
  // (CalibrationResult::rejected_corners). Off: every corner enters, the
  // residuals are still reported.
  bool reject_plate_corners = true;
  PlateCornerCheckOptions plate_corner_check;
  // A point enters the reference map when at least min_map_observations
  // frames kept their observation of it (all points with two take part in
  // the solve) and those observations agree: each frame's back-projection of
  // its keypoint (TF position and virtual depth, final intrinsics and pose)
  // lies within the 99 % chi-square(3) bound of the point under that
  // observation's plenoptic covariance (registration/estimators/
  // plenoptic_point_noise.h: sigma_v = map_sigma_v_rel v along the ray,
  // map_sigma_tf_px across it). Only agreeing observations count, however
  // small the baseline between their frames: a plenoptic observation
  // measures the depth itself. The point's uncertainty (MapPoint::sigma_mm)
  // is that of the agreeing observations fused, or their spread about the
  // point where larger. min_map_angle_deg > 0 also asks the rays to meet at
  // that angle (the largest over pairs of frames): the triangulated depth is
  // then about (lateral error) / sin(angle) instead of the plenoptic depth's.
  int min_map_observations = 2;
  double min_map_angle_deg = 0;
  double map_sigma_v_rel = 0.015;  // sigma of a keypoint's virtual depth, share of v
  // Of its TF position (TF pixels), with the pose's and the point's own
  // lateral error: SIFT keypoints alone are better than 0.3 TF px.
  double map_sigma_tf_px = 1.0;
  int max_lenses = 12;              // micro images per observation (the most central)
  // A keypoint whose measured virtual depth ranges more than this (share of
  // v) over its support (CalibrationFrame::virtual_depth_range, a disc of
  // FrameLoaderOptions::keypoint_support about it) enters by its position
  // only (calibration_costs.h, MicroImageCost::depth_from_estimate): its
  // support straddles a depth edge or lies on the strip next to one, where
  // processing/'s virtual depth is 2-30 % off and pulls B (on handheld frames
  // 5, 20, 32 the keypoints within 1 % at radius 8 TF px pull B +0.13 %, all
  // of them +1.67 %: bench_keypoint_depth). A keypoint without a range keeps
  // its depth. Off (infinite) by default: at 0.01 B comes within 0.12 % on
  // smooth, handheld and orbit (`medium`, 40 frames), but handheld's and
  // orbit's principal points move from 0.81 to 1.26 px and 0.44 to 1.04 px
  // and camera X through the handheld map from 0.51 to 0.65 mm
  // (docs/calibration.md, "The keypoints' y offset").
  double max_keypoint_depth_range = std::numeric_limits<double>::infinity();
  // Each keypoint's virtual depth enters with the weight sigma_0 / sigma of
  // its depth part (calibration_costs.h, MicroImageCost::depth_weight; its
  // position keeps full weight), sigma = sqrt(sigma_0^2 + (slope range)^2)
  // with `range` its support's (above): the keypoints' virtual-depth error
  // against the truth grows so with the range (bench_keypoint_depth, handheld
  // frames 5, 20, 32, radius 8 TF px: median |error| 0.19, 0.44, 0.81, 1.19,
  // 2.40 % at ranges 0-1, 1-2, 2-3, 3-5, > 5 %, i.e. sqrt(0.19^2 +
  // (0.3 range)^2) %; sigma = 1.48 median |error|, so slope 0.44). Only
  // slope / sigma_0 matters; slope 0: every depth at full weight. A keypoint
  // without a range keeps full weight. Off (0) by default: at 0.44 B came
  // within 0.1 % on handheld and smooth `medium` (from +0.41 / +0.48 %) and
  // moved little on orbit, but on six `small` frames from 1.8 m, where the
  // depths are what determine B, it went from +7.5 to +15.1 % (smooth) and
  // +13.8 to +20.9 % (handheld) (docs/calibration.md).
  double keypoint_depth_sigma_rel = 0.0028;         // sigma_0, share of v
  double keypoint_depth_sigma_per_range = 0;        // slope (measured: 0.44)
  // After the first full solve, each keypoint's depth weight is divided by
  // sqrt(1 + (e / s)^2) (Cauchy), e its measured virtual depth's
  // disagreement with its point (a share of v), s this factor times the
  // robust sigma of every e (1.4826 median |e|); the last solve keeps these
  // weights (one reweighting step: the depths of every keypoint still
  // determine B together). 2.385 is Cauchy's 95 %-efficiency constant.
  // 0: none. Off (0) by default: at 2.385 B comes 0.02-0.17 % nearer the
  // truth on `medium` (handheld +0.27 %, smooth +0.31 %, orbit +0.50 %) and
  // 1.0-1.2 % on six `small` smooth and handheld frames, but camera X
  // registered through the handheld map goes from 0.43 to 0.52 mm
  // (docs/calibration.md).
  double keypoint_depth_robust = 0;
  // Each keypoint observation's residuals in units of its standard
  // deviation sigma = max(1, size / keypoint_sigma_size_tf_px), `size` its
  // SIFT region's diameter (TF px): the usual bundle adjustment weighting by
  // scale (ORB-SLAM's per-octave sigma), the smallest SIFT regions (about
  // 1.8 TF px) at unit. 0: every keypoint at unit.
  double keypoint_sigma_size_tf_px = 0;
  int max_iterations = 100;         // Ceres iterations per solve (twice that for the last)
  bool recalibrate = false;         // hold f_L and B fixed (LiFCal recalib)
  bool estimate_principal_point = true;
  // Gaussian prior of the principal point about its initial value (sigma in
  // raw px; 0: none): a real lens' axis meets the sensor within tens of
  // pixels of the centre, and views that do not determine c keep it there.
  double principal_point_prior_px = 20;
  bool estimate_distortion = true;   // radial k1, k2 (and p1, p2 when the next is set)
  // Tangential p1, p2 (with estimate_distortion). Off by default: a
  // decentering term is nearly a principal point shift; on 40 `medium` frames
  // with a distortion-free lens p2 came out at 13 of its standard deviations
  // and took the principal point 2.6 px off (0.75 px with p1, p2 held).
  bool estimate_tangential_distortion = false;
  bool inverse_depth = true;          // points by inverse depth in their anchor frame
  bool estimate_corner_inset = true;  // the plate corners' detection inset (calibration.cpp)
  bool covariance = true;           // standard deviations of the intrinsics
  int threads = 2;
  Status Check() const;
};

struct CalibrationInput {
  std::string serial;
  CameraCalibration initial;  // nominal values (and the sensor: size, pixel size)
  const MicroImages* micro_images = nullptr;
  std::vector<CalibrationFrame> frames;
  double frames_lambda = 0;  // lambda the frames were processed with (0: the initial intrinsics')
};

struct FrameReport {
  std::int64_t frame = 0;
  bool placed = false;
  std::string how;       // "plate", "pnp", or why it was rejected
  int keypoints = 0;     // with a virtual depth
  int plate_corners = 0;
  int observations = 0;  // in the final solve
  double rmse_px = 0;    // micro-image residuals of this frame
  // Largest leave-one-out homography residual of its plate corners (TF px,
  // plate_corner_check.h); NaN when not checked (too few corners).
  double plate_corner_residual_max_tf_px = 0;
  int plate_corners_rejected = 0;
};

// A plate corner left out of the bundle adjustment by the planar check.
struct RejectedPlateCorner {
  std::int64_t frame = 0;
  int marker_id = 0;
  int corner = 0;
  Eigen::Vector2d tf_px = Eigen::Vector2d::Zero();
  double residual_tf_px = 0;   // leave-one-out homography residual
  double threshold_tf_px = 0;  // what it was above
};

struct CalibrationResult {
  CameraCalibration calibration;
  IntrinsicsVector initial{};
  IntrinsicsVector std_dev{};  // NaN where not estimated or not available
  std::string weakest_direction;  // of the covariance, e.g. "(1.1e-06: principal_point_y_px -0.55, ...)"
  std::vector<FramePose> poses;     // w0_from_c0 of the placed frames
  std::vector<FrameReport> frames;  // every input frame
  std::vector<RejectedPlateCorner> rejected_corners;  // by the planar check
  ReferenceMap map;
  double rmse_px = 0;               // all micro-image residuals of the final solve
  double plate_rmse_px = 0;         // plate corners
  double corner_inset_tf_px = 0;    // estimated inset of the detected plate corners
  long long observations = 0, micro_observations = 0, rejected_observations = 0;
  // Keypoint observations entered by their position only (max_keypoint_depth_range).
  long long position_only_observations = 0;
  int points = 0;
  double initial_cost = 0, final_cost = 0, solver_seconds = 0, total_seconds = 0;
  int iterations = 0;
  // How the frames' TF images and virtual depths were made (l_k = c + (c_k -
  // c) lambda): the geometry their keypoints are in (calibration_gates.h).
  double frames_lambda = 1;
  Eigen::Vector2d frames_principal_point_px = Eigen::Vector2d::Zero();
  bool usable = false;              // Ceres: solution usable, and no flag below
  std::string termination;          // Ceres termination type
  std::vector<std::string> flags;   // problems a user should know (report flags)
  std::string BriefReport() const;  // one line, Ceres BriefReport style
};

using ProgressFn = std::function<void(std::string_view line)>;

Expected<CalibrationResult> Calibrate(const CalibrationInput& input,
                                      const CalibrationOptions& options,
                                      const ProgressFn& progress = {});

// calibration_report.md: parameter table with standard deviations, RMSE per
// frame and overall, what was rejected, the flags.
std::string FormatCalibrationReport(const CalibrationResult& result, const std::string& serial);

}  // namespace lifmcr::registration
