#include "registration/estimators/pose_covariance.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <cmath>
#include <limits>
#include <numbers>

namespace lifmcr::registration {

PoseWithCovariance Inverse(const PoseWithCovariance& a_from_b) {
  const Eigen::Matrix3d rt = a_from_b.pose.linear().transpose();
  Covariance6 j = Covariance6::Zero();
  j.topLeftCorner<3, 3>() = -rt;
  j.topRightCorner<3, 3>() = -rt * Skew(a_from_b.pose.translation());
  j.bottomRightCorner<3, 3>() = -rt;
  return {a_from_b.pose.inverse(), j * a_from_b.covariance * j.transpose()};
}

PoseWithCovariance Compose(const PoseWithCovariance& a_from_b,
                           const PoseWithCovariance& b_from_c) {
  const Eigen::Matrix3d& r_ab = a_from_b.pose.linear();
  Covariance6 j1 = Covariance6::Identity();
  j1.topRightCorner<3, 3>() = -Skew(r_ab * b_from_c.pose.translation());
  Covariance6 j2 = Covariance6::Zero();
  j2.topLeftCorner<3, 3>() = r_ab;
  j2.bottomRightCorner<3, 3>() = r_ab;
  return {a_from_b.pose * b_from_c.pose, j1 * a_from_b.covariance * j1.transpose() +
                                             j2 * b_from_c.covariance * j2.transpose()};
}

Pose Perturb(const Pose& a_from_b, const Eigen::Matrix<double, 6, 1>& delta) {
  Pose moved = a_from_b;
  const Eigen::Vector3d dr = delta.tail<3>();
  const double angle = dr.norm();
  const Eigen::Matrix3d exp_dr =
      angle > 0 ? Eigen::AngleAxisd(angle, dr / angle).toRotationMatrix()
                : Eigen::Matrix3d::Identity();
  moved.linear() = exp_dr * a_from_b.linear();
  moved.translation() += delta.head<3>();
  return moved;
}

Eigen::Matrix<double, 6, 1> PerturbationBetween(const Pose& estimate, const Pose& truth) {
  Eigen::Matrix<double, 6, 1> delta;
  delta.head<3>() = estimate.translation() - truth.translation();
  const Eigen::AngleAxisd dr(estimate.linear() * truth.linear().transpose());
  delta.tail<3>() = dr.angle() * dr.axis();
  return delta;
}

double SquaredMahalanobis(const PoseWithCovariance& estimate, const Pose& truth) {
  const Eigen::Matrix<double, 6, 1> delta = PerturbationBetween(estimate.pose, truth);
  const Eigen::LDLT<Covariance6> ldlt(estimate.covariance);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() ||
      (ldlt.vectorD().array() <= 0).any())
    return std::numeric_limits<double>::infinity();
  return delta.dot(ldlt.solve(delta));
}

double RotationDifferenceDeg(const Pose& a, const Pose& b) {
  const Eigen::AngleAxisd difference(a.linear().transpose() * b.linear());
  return std::abs(difference.angle()) * 180.0 / std::numbers::pi;
}

double TranslationDifference(const Pose& a, const Pose& b) {
  return (a.translation() - b.translation()).norm();
}

}  // namespace lifmcr::registration
