#pragma once
// Camera motion of the synthetic rig: each camera has its own smooth
// trajectory in front of the scene, as a pose world_from_cam at any time, so
// images (at triggers) and Vicon samples (at every Vicon frame) come from
// the same motion.
//
// Kinds (--motion): smooth (sums of slow sines of random phase on the eye
// position, the look-at point and the roll), handheld (smooth plus tremor:
// 1-3 Hz, a few mm and tenths of a degree), axis (one axis at a time:
// translate x, y, z, then yaw, pitch, roll, each back and forth), circle (an
// arc of 90 degrees around the plate at constant height and distance), orbit
// (for calibration: over the sequence the camera sweeps 30 degrees of azimuth
// around the target once, from one side to the other, while its elevation
// runs through one cycle of 26..54 degrees, its distance +-8 %, its roll
// +-4.6 degrees and its look-at point +-30 mm, so that the views of a
// sequence differ by more than 20 degrees about two axes; the cameras of a
// rig keep their lateral offsets and differ by a small phase of the cycle, so
// they see common structure throughout).

#include "config/frames.h"

#include <Eigen/Core>

#include <cstdint>
#include <limits>
#include <string>

namespace lifmcr::synth {

// Camera looking from `eye` at `target`, image y down along -up (world z).
Pose LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, double roll_rad = 0.0);

struct TrajectoryParams {
  std::string motion = "smooth";
  Eigen::Vector3d target_mm = Eigen::Vector3d::Zero();  // what the rig looks at
  double distance_mm = 700;                             // eye to target
  double elevation_rad = 0.7;                           // above the table plane
  double lateral_offset_mm = 0;                         // this camera's place in the rig (along x)
  double duration_s = 1.0;                              // sequence length (for axis/circle)
  double amplitude_scale = 1.0;
  std::uint64_t seed = 1;  // per camera
  // A rigid rig (SynthRigParams::rigid): every camera follows the rig's
  // trajectory (lateral offset 0, the rig's seed) and sits at rig_from_cam on
  // it; from knock_time_s on at rig_from_cam * knock (the camera moved on its
  // mount). Defaults: the camera is the trajectory's.
  Pose rig_from_cam = Pose::Identity();
  double knock_time_s = std::numeric_limits<double>::infinity();
  Pose knock = Pose::Identity();
};

class CameraTrajectory {
 public:
  explicit CameraTrajectory(const TrajectoryParams& params);
  Pose WorldFromCam(double t_s) const;

 private:
  Pose RigWorldFromCam(double t_s) const;  // the trajectory itself
  struct Wave {
    double amplitude, frequency_hz, phase;
  };
  double Sum(const Wave* waves, int count, double t_s) const;
  TrajectoryParams p_;
  Wave eye_[3][3];
  Wave target_[3][2];
  Wave roll_[2];
  Wave tremor_[6][2];
  double orbit_phase_ = 0;  // rad, per camera
};

}  // namespace lifmcr::synth
