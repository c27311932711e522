#include "registration/estimators/rigid_fit.h"

#include <Eigen/SVD>

namespace lifmcr::registration {
namespace {

template <typename IndexOf>
bool Fit(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst,
         std::span<const double> weights, std::size_t count, IndexOf index_of,
         Pose* dst_from_src) {
  double total = 0;
  Eigen::Vector3d src_mean = Eigen::Vector3d::Zero(), dst_mean = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = index_of(k);
    const double w = weights.empty() ? 1.0 : weights[i];
    total += w;
    src_mean += w * src[i];
    dst_mean += w * dst[i];
  }
  if (!(total > 0)) return false;
  src_mean /= total;
  dst_mean /= total;
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  double spread = 0;
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = index_of(k);
    const double w = weights.empty() ? 1.0 : weights[i];
    const Eigen::Vector3d p = src[i] - src_mean;
    cross += w * (dst[i] - dst_mean) * p.transpose();
    spread += w * p.squaredNorm();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cross, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d& sv = svd.singularValues();
  // Rank < 2: the points are (nearly) collinear in the weighted sense.
  if (!(sv[1] > 1e-12 * spread)) return false;
  Eigen::Vector3d d(1, 1, 1);
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) d[2] = -1;
  Pose pose = Pose::Identity();
  pose.linear() = svd.matrixU() * d.asDiagonal() * svd.matrixV().transpose();
  pose.translation() = dst_mean - pose.linear() * src_mean;
  *dst_from_src = pose;
  return true;
}

}  // namespace

bool FitRigid(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst,
              std::span<const double> weights, Pose* dst_from_src) {
  if (src.size() != dst.size() || (!weights.empty() && weights.size() != src.size()) ||
      src.size() < 3)
    return false;
  return Fit(src, dst, weights, src.size(), [](std::size_t k) { return k; }, dst_from_src);
}

bool FitRigidSubset(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst,
                    std::span<const double> weights, std::span<const int> indices,
                    Pose* dst_from_src) {
  if (src.size() != dst.size() || (!weights.empty() && weights.size() != src.size()) ||
      indices.size() < 3)
    return false;
  return Fit(src, dst, weights, indices.size(),
             [&](std::size_t k) { return static_cast<std::size_t>(indices[k]); }, dst_from_src);
}

}  // namespace lifmcr::registration
