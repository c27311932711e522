#pragma once
// Closed-form least-squares rigid motion between two point sets (Umeyama
// 1991 without scale, i.e. weighted Kabsch): the dst_from_src = (R, t) that
// minimises
//   sum_i w_i |R p_i + t - q_i|^2,   p_i in src, q_i in dst, w_i >= 0.
// With weighted centroids p_bar, q_bar and the cross-covariance
//   S = sum_i w_i (q_i - q_bar)(p_i - p_bar)^T = U Sigma V^T,
//   R = U diag(1, 1, det(U V^T)) V^T,   t = q_bar - R p_bar,
// the diag term choosing a rotation over a reflection.

#include "config/frames.h"

#include <Eigen/Core>

#include <cstddef>
#include <span>

namespace lifmcr::registration {

// dst_from_src over the pairs (src[i], dst[i]) with weights (all 1 when
// `weights` is empty). False when fewer than three non-collinear pairs carry
// weight (the rotation is then not determined).
bool FitRigid(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst,
              std::span<const double> weights, Pose* dst_from_src);

// The same over the subset `indices` of the pairs (no copies of the points).
bool FitRigidSubset(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst,
                    std::span<const double> weights, std::span<const int> indices,
                    Pose* dst_from_src);

}  // namespace lifmcr::registration
