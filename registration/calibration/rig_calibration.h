#pragma once
// Joint calibration of a rig of N plenoptic cameras on a rigid mount
// (`lifmcr calibrate SEQ --rig`): one bundle adjustment over every camera's
// intrinsics, each camera's pose in the rig (c0_from_cx, held constant over
// the sequence), one rig trajectory (camera 0's pose per trigger) and one map
// whose points several cameras observe. The marker plate gives scale and
// frame, as in the single-camera calibration (calibration.h), whose costs,
// initialisation and covariance this reuses.
//
// 1. Camera 0 is calibrated alone (calibration.h; or its calibration is
//    given): its intrinsics, its poses w0_from_c0 per trigger (frame number)
//    and its map.
// 2. Every other camera X: each of its frames whose trigger camera 0 placed
//    is registered against camera 0's map by plenoptic PnP with X's initial
//    intrinsics (frame_registration.h). Each registered frame (one whose
//    pose passed `registration.checks`; when fewer than
//    min_registered_frames pass, every frame PnP gave a pose) gives
//    c0_from_cx = c0_from_w0 w0_from_cx; the initial c0_from_cx is their
//    robust mean (translation: component medians, the frames within
//    max(3 x their median distance to it, 1 mm) averaged; rotation: the
//    normalised sum of those frames' quaternions). PnP's inliers (of every
//    frame PnP placed, also those its checks refused) are X's observations
//    of the shared map points: features matched across the cameras of a
//    trigger and, through the map, across time. X's own tracks across time
//    (calibration.h step 2 on X's frames) add the keypoints that match no
//    map point: a track one of whose keypoints matched a map point observes
//    that point with all its keypoints; a track that matched none becomes a
//    point of X alone (back-projected through the rig at its first frame).
// 3. Bundle adjustment (Ceres, SPARSE_SCHUR; rotations on
//    ceres::QuaternionManifold). Unknowns: per camera its intrinsics
//    (plenoptic_projection.h; the principal point with the single
//    calibration's prior); one plate-corner inset for every camera
//    (`shared_corner_inset`; calibration.h: the detector's, on the same
//    plate); per camera X its
//    c0_from_cx (camera 0's is the identity); per trigger the rig pose
//    c0_from_w0; the map points (mm in w0). Each keypoint observation of
//    camera X at trigger t is reprojected into its micro images through
//      p_in_cx = cx_from_c0 (c0_from_w0(t) p_in_w0)
//    with the single calibration's micro-image cost (calibration_costs.h),
//    each plate corner the same way. Solves: (a) the cameras X alone (their
//    intrinsics and c0_from_cx; camera 0, the shared inset, the trajectory
//    and the map held), (b) everything, (c) with observations above max(outlier_px, 3 x
//    the median RMS) dropped, everything again. A camera's inset of its own
//    trades against its distance to the plate: on the 4-camera `small` rig
//    (no inset rendered) camera 0's calibration alone came to +0.31 TF px and
//    sat 1.5 mm nearer the scene than the truth, cameras 1 and 2 2.1-2.7 mm
//    off; shared, the inset came to -0.008 TF px, camera 0 0.7 mm, cameras 1
//    and 2 1.0 mm (docs/calibration.md). Each camera's plate corners
//    weigh plate_weight in (a); in (b) and (c) (`reweigh_plate_corners`)
//    camera X's weigh plate_weight x min(1, sqrt(s_0 / s_X)), s_c the RMS
//    over camera c's corners of the mean of a corner's micro-image residuals
//    (its position error), measured after (a) and again after (b); camera
//    0's corners, which fix the plate frame, the reference: their cost
//    scaled by the ratio of the standard deviations. A camera X sees the
//    plate from aside and near the image's edge, where its corners are
//    several times less accurate than camera 0's
//    (on the 4-camera `small` rig 0.27-0.34 px against 0.040 px after (b);
//    0.50-0.63 TF px against 0.064 from the truth): weighed as camera 0's
//    they pulled every camera's pose in the plate frame 2-4 mm off. Their
//    inverse variance, (s_0 / s_X)^2, is too little: they are what holds the
//    cameras X against the plate where the keypoints leave a pivot about the
//    scene weakly determined, and the far camera's pose then went 2.1-4.1 mm
//    off (the figures of each weight: docs/calibration.md, "A rig calibrated
//    as one").
// 4. Covariance of the camera parameters by the Schur complement of the
//    points (calibration_covariance.h), scaled by the residual variance:
//    each camera's intrinsics' standard deviations and c0_from_cx's 6 x 6
//    covariance, [rotation (rad, left perturbation in c0: c0_from_cx ->
//    exp(w) c0_from_cx), translation (mm, in c0)]. Like the single
//    calibration's, it treats a keypoint's micro-image residuals as
//    independent, so it is optimistic.
//
// Non-rigid mode (`non_rigid`; `lifmcr calibrate --rig --non-rigid`): the
// cameras move independently (LiFMCR's sequences), so camera X has a pose
// c0_from_cx(t) per trigger instead of one, over the same shared map:
//   p_in_cx = cx_from_c0(t) (c0_from_w0(t) p_in_w0).
// Step 2 then registers the cameras in the order given, each against the
// map grown by the cameras before it: camera 0's points and the points of
// the cameras X before it alone (their tracks across time, back-projected
// at their first frame, with the descriptor of the keypoint that made
// them), so a camera that sees little of camera 0's view joins through its
// neighbours (camera 3 through camera 2's points). Every frame PnP
// estimated a pose for is placed there, also those the pose checks refused:
// the pose is only the start of the bundle adjustment, where several
// cameras' rays fix the points (the refused poses of a far camera are
// several mm off; each point a chained map adds carries the depth bias of
// the one observation that placed it, docs/registration.md). A frame PnP
// could not estimate is left out. Solves (a)-(c) as above, with per-trigger
// poses; after (a) and after (b) every map point is looked for again in
// every placed image by its solved pose (guided_matches.h' projected grid,
// FrameRegistrationOptions' guided radius and ratio, the virtual depth
// within 10 % of the predicted), the cross-camera observations PnP's inliers
// missed. The covariance is per trigger. c0_from_cx of a camera X is then
// the robust mean of its per-trigger poses (a summary, not a mount).

#include "config/error.h"
#include "config/frames.h"
#include "registration/calibration/calibration.h"
#include "registration/map/frame_registration.h"
#include "registration/map/reference_map.h"

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct RigCalibrationOptions {
  // Camera 0's calibration (step 1) and the costs of the joint solve
  // (Huber scale, outlier threshold, plate weight, micro images per
  // observation, which intrinsics are estimated, the principal point's
  // prior, iterations, threads). `recalibrate` holds every camera's f_L and
  // B at their initial values (camera 0's b_L0 starts from the plate,
  // calibration.h; the others' from their initial values).
  CalibrationOptions calibration;
  // Step 2: the cameras X against camera 0's map. A frame counts as
  // registered (RigCameraResult::registered) under `lifmcr register`'s
  // checks, the 5 mm / 0.25 deg promise of an `ok` row with the depth
  // checks on (pose_checks.h, ForErrorBound): the live localizer's defaults
  // passed far-camera poses 15-38 mm off against a grown map.
  FrameRegistrationOptions registration = [] {
    FrameRegistrationOptions o;
    o.checks = PoseCheckOptions::ForErrorBound(5.0, 0.25);
    return o;
  }();
  // Frames of a camera X registered, else an error (non_rigid: frames
  // placed, refused poses counted; rigid: when fewer pass the checks, the
  // robust mean of every pose PnP estimated starts c0_from_cx, as a refused
  // pose starts a non-rigid frame).
  int min_registered_frames = 3;
  bool non_rigid = false;         // per-trigger c0_from_cx (above)
  // Step 3 (b), (c): camera X's plate corners weighed by their scatter
  // against camera 0's (above); false: every camera's at
  // calibration.plate_weight.
  bool reweigh_plate_corners = true;
  // Step 3: one plate-corner inset for every camera (the detector's, on the
  // same plate), camera 0's from its calibration; false: one per camera X,
  // from 0.
  bool shared_corner_inset = true;
  Status Check() const;
};

struct RigCameraResult {
  std::string serial;
  CameraCalibration calibration;   // the joint solve's intrinsics
  IntrinsicsVector initial{};      // where they started (camera 0: its own calibration's)
  IntrinsicsVector std_dev{};      // NaN where not estimated or not available
  Pose c0_from_cx = Pose::Identity();          // joint solve (camera 0: identity)
  Pose c0_from_cx_initial = Pose::Identity();  // robust mean of the registrations (step 2)
  // [rotation rad (left, in c0), translation mm]; zero for camera 0 and when
  // not computed (RigCalibrationResult::covariance_computed).
  Eigen::Matrix<double, 6, 6> c0_from_cx_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  // Step 2, per registered frame of camera X: c0_from_cx = c0_from_w0
  // w0_from_cx (FramePose::world_from_cam holds c0_from_cx).
  std::vector<FramePose> registered;
  // Rigid mode: the frames c0_from_cx_initial is the robust mean of
  // (`registered`, or every pose PnP estimated when fewer than
  // min_registered_frames passed; as `registered`). Empty in the non-rigid
  // mode and for camera 0.
  std::vector<FramePose> start;
  // Non-rigid mode, per trigger camera X was placed at (FramePose::
  // world_from_cam holds c0_from_cx(t)): the joint solve, where step 2
  // started it (PnP's pose, also when its checks refused it), and the joint
  // solve's covariance (as c0_from_cx_covariance; zero when not computed).
  // Empty in the rigid mode and for camera 0.
  std::vector<FramePose> per_trigger;
  std::vector<FramePose> per_trigger_initial;
  std::vector<Eigen::Matrix<double, 6, 6>> per_trigger_covariance;
  int frames = 0;                  // frames given
  long long observations = 0;      // keypoint observations in the final solve
  int plate_corners = 0;           // plate corners in the solve
  // Step 3: the RMS of the plate corners' position residuals after solve
  // (b) (px of the micro images; NaN without corners) and the corners'
  // weight in solve (c).
  double plate_corner_rms_px = NAN;
  double plate_weight = 0;
  double corner_inset_tf_px = 0;   // its plate corners' inset (shared: camera 0's)
  double rmse_px = 0;              // its micro-image residuals in the final solve
};

struct RigCalibrationResult {
  bool non_rigid = false;                 // RigCalibrationOptions::non_rigid
  CalibrationResult camera0;              // step 1
  std::vector<RigCameraResult> cameras;   // camera 0 first
  std::vector<FramePose> trajectory;      // w0_from_c0 per trigger (joint solve)
  // The shared map: camera 0's images (with the joint solve's poses and
  // pinhole positions), camera 0's points at their joint positions, then the
  // points of a camera X alone; each point's track lists camera 0's
  // observations (ReferenceMap holds one camera), `observers` (same order as
  // map.points) every camera's.
  ReferenceMap map;
  struct Observer {
    int camera = 0;  // index into cameras
    std::int64_t frame = 0;
    int keypoint = 0;  // index into that camera's frame's keypoints
  };
  std::vector<std::vector<Observer>> observers;  // per map point
  int shared_points = 0;  // points observed by more than one camera
  int own_points = 0;     // points of one camera X alone (its tracks across time)
  bool covariance_computed = false;
  std::string weakest_direction;  // of the covariance (calibration_covariance.h)
  long long rejected_observations = 0;
  double rmse_px = 0;
  double initial_cost = 0, final_cost = 0, solver_seconds = 0, total_seconds = 0;
  int iterations = 0;
  bool usable = false;
  std::string termination;
  std::vector<std::string> flags;
  // "Rig calibration: 3 cameras, 30 triggers, 18236 points (9120 shared),
  // 160233 observations, RMSE 0.118 px; Ceres 61 iterations ..., CONVERGENCE".
  std::string BriefReport() const;
  // One line per camera: intrinsics and c0_from_cx with standard deviations.
  std::string CameraReport() const;
};

// `cameras[0]` is camera 0. `camera0`, when given, is camera 0's existing
// calibration of the same frames (step 1 skipped): its map's keypoints must
// be those of cameras[0].frames. Errors: options, inputs, too few frames of
// a camera X registered, a failed solve.
Expected<RigCalibrationResult> CalibrateRig(const std::vector<CalibrationInput>& cameras,
                                            const RigCalibrationOptions& options,
                                            const CalibrationResult* camera0 = nullptr,
                                            const ProgressFn& progress = {});

// A CalibrationResult made from a calibration written by `lifmcr calibrate`
// (its intrinsics and reference map), to be given as CalibrateRig's camera0.
CalibrationResult CalibrationResultOf(const CameraCalibration& calibration, ReferenceMap map);

// Step 2 alone with other intrinsics (the baseline: camera X registered
// against camera 0's map with its true intrinsics): c0_from_cx = c0_from_w0
// w0_from_cx of every frame PnP registers, c0_from_w0 from camera 0's
// calibration (FramePose::world_from_cam holds c0_from_cx).
std::vector<FramePose> RegisterAgainstCamera0(const CalibrationResult& camera0,
                                              const CalibrationInput& camera,
                                              const processing::CameraIntrinsics& intrinsics,
                                              const FrameRegistrationOptions& options);

// The joint solve against a synthetic rig's truth, beside camera X registered
// alone (step 2). c0_from_cx_truth[i] for cameras[i].
struct RigTruthComparison {
  struct Camera {
    std::string serial;
    double f_l_rel = 0, b_l0_rel = 0, b_rel = 0;  // (estimate - truth) / truth
    double principal_point_px = 0;                // distance
    double joint_mm = 0, joint_deg = 0;           // c0_from_cx of the joint solve
    double mean_mm = 0, mean_deg = 0;             // c0_from_cx_initial (robust mean)
    double median_mm = 0, median_deg = 0;         // median over its frames (start)
    int start_frames = 0;                         // RigCameraResult::start
    int registered = 0;                           // of them, passing the pose checks
    // Registered alone with the true intrinsics (RegisterAgainstCamera0);
    // NaN when not given.
    double true_mean_mm = NAN, true_mean_deg = NAN, true_median_mm = NAN, true_median_deg = NAN;
    int true_registered = 0;
  };
  std::vector<Camera> cameras;
  // One line per camera, the gates (f_L, b_L0, B 0.3 %, principal point
  // 0.5 px, c0_from_cx 0.2 mm / 0.01 deg and better than registered alone).
  std::string Report() const;
  bool GatesMet() const;
};

// `registered_with_truth`: per camera RegisterAgainstCamera0 with its true
// intrinsics (empty: not given).
Expected<RigTruthComparison> CompareRigWithTruth(
    const RigCalibrationResult& result, const std::vector<CameraCalibration>& truth,
    const std::vector<Pose>& c0_from_cx_truth,
    const std::vector<std::vector<FramePose>>& registered_with_truth = {});

}  // namespace lifmcr::registration
