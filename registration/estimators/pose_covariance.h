#pragma once
// Poses with a 6x6 covariance, and how the covariance follows the two
// operations registration needs (inverse and composition).
//
// Convention (the order of lcm_types/camera_extrinsics_t.lcm): the covariance
// is that of delta = (dt_x, dt_y, dt_z [mm], dr_x, dr_y, dr_z [rad]) in the
// perturbation
//   a_from_b = (exp([dr]x) R, t + dt)
// of the estimate (R, t): a rotation perturbed on the left, in a's frame, and
// the translation additively. To first order:
//   inverse:  b_from_a = (R^T, -R^T t) moves by
//             dt' = -R^T dt - R^T [t]x dr,   dr' = -R^T dr;
//   compose:  a_from_c = a_from_b b_from_c moves, for a perturbed a_from_b, by
//             dt' = dt - [R_ab t_bc]x dr,     dr' = dr,
//             and for a perturbed b_from_c by
//             dt' = R_ab dt,                  dr' = R_ab dr.
// Independent estimates add: Sigma_ac = J1 Sigma_ab J1^T + J2 Sigma_bc J2^T.

#include "config/frames.h"

#include <Eigen/Core>

namespace lifmcr::registration {

using Covariance6 = Eigen::Matrix<double, 6, 6>;

struct PoseWithCovariance {
  Pose pose = Pose::Identity();
  Covariance6 covariance = Covariance6::Zero();
};

// [v]x, the matrix of v x (.).
inline Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

PoseWithCovariance Inverse(const PoseWithCovariance& a_from_b);
// a_from_c of two independent estimates a_from_b and b_from_c.
PoseWithCovariance Compose(const PoseWithCovariance& a_from_b,
                           const PoseWithCovariance& b_from_c);

// The pose moved by delta as in the convention above (for tests and
// numerical Jacobians).
Pose Perturb(const Pose& a_from_b, const Eigen::Matrix<double, 6, 1>& delta);

// The perturbation delta of the convention above that moves `truth` to
// estimate.pose (dt = t_est - t_true, dr = log(R_est R_true^T)), and its
// squared Mahalanobis distance delta^T Sigma^-1 delta under the estimate's
// own covariance: chi-square with 6 degrees of freedom when the covariance
// is right (infinite when it is singular).
Eigen::Matrix<double, 6, 1> PerturbationBetween(const Pose& estimate, const Pose& truth);
double SquaredMahalanobis(const PoseWithCovariance& estimate, const Pose& truth);

// Angle of R_a^T R_b in degrees, and |t_a - t_b| in the poses' unit.
double RotationDifferenceDeg(const Pose& a, const Pose& b);
double TranslationDifference(const Pose& a, const Pose& b);

}  // namespace lifmcr::registration
