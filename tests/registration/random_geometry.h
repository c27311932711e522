#pragma once
// Random poses and synthetic registration problems with known answers, for
// the property tests of registration/ (Sophus style: many random samples,
// invariants asserted). Deterministic for a given generator seed.

#include "config/frames.h"
#include "processing/camera_model.h"

#include <Eigen/Core>

#include <random>
#include <vector>

namespace lifmcr::test {

// A uniformly random rotation and a translation with coordinates in
// [-translation_mm, translation_mm].
Pose RandomPose(std::mt19937_64& rng, double translation_mm);

// The `small` synth preset's camera (1024 x 768 raw, f_L 25 mm).
processing::CameraIntrinsics SmallCameraIntrinsics();

// Matches of a plenoptic camera at cam_from_world against world points:
// keypoints uniform over the TF image, virtual depths uniform in [v_min,
// v_max] (0.63 to 2.5 m for the small camera), the world point
// back-projected from them. Then Gaussian noise of sigma_tf_px on each
// keypoint and sigma_v on each virtual depth; a fraction of outliers gets a
// keypoint and a virtual depth drawn anew (its world point stays).
// delta^T Sigma^-1 delta for the delta with truth = Perturb(estimate, delta)
// (registration/estimators/pose_covariance.h): chi-square with 6 degrees of freedom
// when `covariance` describes the estimate's error.
double PoseErrorMahalanobis(const Pose& truth, const Pose& estimate,
                            const Eigen::Matrix<double, 6, 6>& covariance);

struct PnpProblem {
  Pose cam_from_world;
  std::vector<Eigen::Vector3d> points_in_world;
  std::vector<Eigen::Vector3d> points_in_cam;  // noise-free, outliers included
  std::vector<Eigen::Vector2d> tf_px;
  std::vector<double> virtual_depth;
  std::vector<char> is_outlier;
};
PnpProblem MakePnpProblem(std::mt19937_64& rng, const processing::CameraModel& camera, int count,
                          double outlier_fraction, double sigma_tf_px, double sigma_v,
                          double v_min = 2.5, double v_max = 5.5);

}  // namespace lifmcr::test
