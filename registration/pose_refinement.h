#pragma once
// The non-linear pose refinement both estimators share, in the perturbation
// of registration/pose_covariance.h (delta = (dt, dr), a_from_b moved to
// (exp([dr]x) R, t + delta_t)).
//
// Levenberg-Marquardt on a robust cost C(pose): each step solves
//   (J^T J + mu diag(J^T J)) delta = -J^T r
// over the data the estimator counts (its inliers), moves the pose by delta,
// and keeps it only when C decreases (mu shrinks tenfold), otherwise mu grows
// tenfold. C is the estimator's MSAC cost, so a step that trades inliers for
// outliers is refused.

#include "config/frames.h"
#include "registration/pose_covariance.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <algorithm>
#include <cstddef>

namespace lifmcr::registration {

// normal_equations(pose, &jtj, &jtr) returns how many data it used;
// cost(pose) the robust cost. True when the pose improved.
template <typename NormalEquations, typename Cost>
bool LevenbergMarquardt(Pose* pose, int iterations, NormalEquations normal_equations, Cost cost) {
  double current = cost(*pose);
  double damping = 1e-6;
  bool improved = false;
  Eigen::Matrix<double, 6, 6> jtj;
  Eigen::Matrix<double, 6, 1> jtr;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    if (normal_equations(*pose, &jtj, &jtr) < 3) break;
    Eigen::Matrix<double, 6, 6> a = jtj;
    a.diagonal() += damping * jtj.diagonal().cwiseMax(1e-12);
    const Eigen::Matrix<double, 6, 1> delta = a.ldlt().solve(-jtr);
    if (!delta.allFinite()) break;
    const Pose candidate = Perturb(*pose, delta);
    const double candidate_cost = cost(candidate);
    if (candidate_cost < current) {
      const double gain = current - candidate_cost;
      *pose = candidate;
      current = candidate_cost;
      improved = true;
      damping = std::max(1e-9, damping * 0.1);
      if (gain < 1e-10 * current) break;
    } else {
      damping *= 10;
      if (damping > 1e4) break;
    }
  }
  return improved;
}

}  // namespace lifmcr::registration
