#pragma once
// A non-rigid rig calibration (rig_calibration.h, `non_rigid`) against a
// synthetic rig's truth: per camera its intrinsics' errors and, per frame,
// the error of c0_from_cx(t) as the joint solve gives it, as step 2 started
// it (PnP against the map of the cameras before it, also where its checks
// refused the pose), and as camera X's frame registered alone against
// camera 0's map gives it (the baseline; RegisterAgainstCamera0). For
// camera 0 the rows are its pose in the plate frame, w0_from_c0: the joint
// solve's and (as `start`) its calibration alone's; `alone` is empty.
//
// Camera 0's own error in the plate frame (its calibration's) moves every
// c0_from_cx alike; what is left of camera X's is its joint pose in the
// plate frame, w0_from_cx(t) = w0_from_c0(t) c0_from_cx(t), against the
// truth (`plate` below). And the joint covariance of c0_from_cx(t)
// (rig_calibration.h, step 4) against the error: the squared Mahalanobis
// distance (pose_covariance.h), chi-square(6) when the covariance is right,
// and the share of frames within its 95 % bound (12.59).

#include "config/error.h"
#include "config/frames.h"
#include "registration/calibration/rig_calibration.h"

#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct RigPerFrameTruth {
  struct Row {
    std::int64_t frame = 0;
    double joint_mm = NAN, joint_deg = NAN;  // NaN: not placed
    double start_mm = NAN, start_deg = NAN;  // NaN: PnP estimated no pose
    bool start_passed = false;               // the start passed the pose checks
    double alone_mm = NAN, alone_deg = NAN;  // NaN: not registered against camera 0's map
    double plate_mm = NAN, plate_deg = NAN;  // joint w0_from_cx(t) vs truth (camera X)
    double chi2 = NAN;  // joint c0_from_cx(t)'s squared Mahalanobis distance; NaN: no covariance
  };
  struct Camera {
    std::string serial;
    double f_l_rel = 0, b_l0_rel = 0, b_rel = 0;  // (estimate - truth) / truth
    double principal_point_px = 0;
    std::vector<Row> rows;  // camera X's frames with a true pose (empty for camera 0)
    int placed = 0, alone_registered = 0;
    double joint_max_mm = NAN, joint_max_deg = NAN;  // over the placed frames
    double joint_median_mm = NAN, joint_median_deg = NAN;
    double alone_median_mm = NAN, alone_median_deg = NAN;
    double plate_median_mm = NAN, plate_median_deg = NAN;
    int with_covariance = 0, within_chi2_95 = 0;  // frames with a covariance, of them within 12.59
  };
  std::vector<Camera> cameras;
  // Per camera one line (intrinsics, the joint poses' median and worst
  // error, the baseline's), then a table of its frames.
  std::string Report() const;
  // Every frame of every camera X placed, each within max_mm / max_deg.
  bool AllWithin(double max_mm, double max_deg) const;
};

// c0_from_cx_truth[c]: frame -> true c0_from_cx of result.cameras[c]
// (c0_from_cx_truth[0]: the true w0_from_c0, the plate frame's);
// registered_alone[c]: RegisterAgainstCamera0 of that camera (may be empty).
Expected<RigPerFrameTruth> CompareNonRigidWithTruth(
    const RigCalibrationResult& result, const std::vector<CameraCalibration>& truth,
    const std::vector<std::map<std::int64_t, Pose>>& c0_from_cx_truth,
    const std::vector<std::vector<FramePose>>& registered_alone);

}  // namespace lifmcr::registration
