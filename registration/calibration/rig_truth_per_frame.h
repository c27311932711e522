#pragma once
// A non-rigid rig calibration (rig_calibration.h, `non_rigid`) against a
// synthetic rig's truth: per camera its intrinsics' errors and, per frame,
// the error of c0_from_cx(t) as the joint solve gives it, as step 2 started
// it (PnP against the map of the cameras before it, also where its checks
// refused the pose), and as camera X's frame registered alone against
// camera 0's map gives it (the baseline; RegisterAgainstCamera0). For
// camera 0 the rows are its pose in the plate frame, w0_from_c0: the joint
// solve's and (as `start`) its calibration alone's; `alone` is empty.

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
