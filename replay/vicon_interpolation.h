#pragma once
// Vicon poses between Vicon samples: SE(3) interpolation as rotation slerp
// plus linear translation (the usual "split" interpolation; for the 12.5 ms
// between 80 Hz samples it is indistinguishable from the screw motion).
//
//   Interpolate(a, b, s): R = slerp(R_a, R_b, s)   (the shorter arc),
//                         t = (1 - s) t_a + s t_b,   s in [0, 1].
// At a fractional Vicon frame f between samples f_a <= f <= f_b,
// s = (f - f_a) / (f_b - f_a).
//
// In the dataset layer (not sync/) so that offline evaluation
// (registration/) uses the same interpolation as the live pipeline.

#include "config/frames.h"
#include "replay/vicon_poses.h"

#include <optional>
#include <span>

namespace lifmcr {

// a at s = 0, b at s = 1; s outside [0, 1] extrapolates along the same arc.
Pose InterpolatePose(const Pose& a, const Pose& b, double s);

// The pose at `vicon_frame` (fractional) from samples sorted by frame
// number: the sample itself at an integer frame, else the interpolation of
// the two samples around it. nullopt when `vicon_frame` is outside the
// samples, when a sample around it is untracked, or when the two samples
// are more than `max_gap_frames` apart (do not bridge occlusions).
std::optional<Pose> PoseAtViconFrame(std::span<const ViconPoseSample> samples, double vicon_frame,
                                     int max_gap_frames = 1);

}  // namespace lifmcr
