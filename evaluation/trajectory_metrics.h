#pragma once
// Trajectory error metrics, as evo (M. Grupp) and the TUM RGB-D benchmark
// define them, so that `evo_ape` / `evo_rpe` on the TUM files `lifmcr
// evaluate` writes reproduce the figures.
//
// A trajectory is a pose per frame number (FramePoses). Estimate P_i and
// reference (ground truth) Q_i are associated by frame number; frames present
// in only one of them are left out (and counted by the caller).
//
// APE (absolute pose error, evo's "Kümmerle notation"):
//   E_i = P_i^-1 Q_i
// RPE (relative pose error, TUM RGB-D, Δ = 1 frame):
//   E_i = (Q_i^-1 Q_{i+1})^-1 (P_i^-1 P_{i+1})
// for every frame i where frames i and i+1 are both in both trajectories; a
// pair across a missing frame is not formed (evo pairs consecutive entries
// of its lists instead, so the two agree when no frame is missing).
// Per pose error:
//   translation_mm = |t(E_i)|
//   rotation_deg   = angle of R(E_i) (the angle of its axis-angle form)
// Per axis (the paper's supplementary table): the components of t(E_i) and of
// the rotation vector Log(R(E_i)) (deg). For APE, t(E_i) is the offset of the
// true camera centre seen from the estimated camera: it is expressed in the
// (estimated) camera frame, x right, y down, z along the optical axis.
//
// Statistics (evo's): rmse = sqrt(mean e^2), mean, median, sd = population
// standard deviation (divide by n), min, max. For per-axis values they are
// taken over the signed components: rmse measures the offset and the spread
// together, mean the constant offset, sd the spread around it.

#include "config/frames.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace lifmcr {

using FramePoses = std::map<std::int64_t, Pose>;

struct ErrorStats {
  std::size_t count = 0;
  double rmse = 0, mean = 0, median = 0, sd = 0, min = 0, max = 0;

  // Over `values`; all zero (count 0) for no values.
  static ErrorStats Of(std::span<const double> values);
  // "rmse 1.23 mean 1.10 median 1.05 sd 0.40 (n=99) mm"
  std::string BriefReport(const std::string& unit) const;
};

struct PoseErrors {
  std::vector<std::int64_t> frames;  // APE: frame i; RPE: the first frame of the pair
  std::vector<double> translation_mm;
  std::vector<double> rotation_deg;
  std::vector<Eigen::Vector3d> translation_axes_mm;  // components of t(E_i)
  std::vector<Eigen::Vector3d> rotation_axes_deg;    // components of Log(R(E_i)), deg
  std::size_t size() const { return frames.size(); }
};

struct ErrorSummary {
  ErrorStats translation_mm;
  ErrorStats rotation_deg;
  std::array<ErrorStats, 3> translation_axis_mm;  // x, y, z
  std::array<ErrorStats, 3> rotation_axis_deg;    // about x, y, z
};

// Angle (deg, in [0, 180]) of a rotation matrix.
double RotationAngleDeg(const Eigen::Matrix3d& rotation);
// Rotation vector (axis * angle, rad) of a rotation matrix.
Eigen::Vector3d RotationLog(const Eigen::Matrix3d& rotation);
// The rotation nearest to `m` in the Frobenius norm (SVD, det +1): the
// chordal mean of rotations is NearestRotation of their sum.
Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m);

// The error of one estimate against its reference: E = estimate^-1 reference.
Pose PoseError(const Pose& estimate, const Pose& reference);

PoseErrors AbsolutePoseErrors(const FramePoses& estimate, const FramePoses& reference);
PoseErrors RelativePoseErrors(const FramePoses& estimate, const FramePoses& reference);

ErrorSummary SummarizeErrors(const PoseErrors& errors);

// Only the frames in [first, last] (both inclusive) of a trajectory.
FramePoses FramesBetween(const FramePoses& poses, std::int64_t first, std::int64_t last);

}  // namespace lifmcr
