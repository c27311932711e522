#pragma once
// The non-linear pose refinement both estimators share, in the perturbation
// of registration/estimators/pose_covariance.h (delta = (dt, dr), a_from_b moved to
// (exp([dr]x) R, t + delta_t)).
//
// Levenberg-Marquardt on a robust cost C(pose): each step solves
//   (J^T J + mu diag(J^T J)) delta = -J^T r
// over the data the estimator counts (its inliers), moves the pose by delta,
// and keeps it only when C decreases (mu shrinks tenfold), otherwise mu grows
// tenfold. C is the estimator's MSAC cost, so a step that trades inliers for
// outliers is refused.

#include "config/frames.h"
#include "registration/estimators/pose_covariance.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <algorithm>
#include <cstddef>

namespace lifmcr::registration {

// normal_equations(pose, &jtj, &jtr) returns how many data it used;
// cost(pose) the robust cost (a sum of squares over the data it counts, not
// halved). True when the pose improved.
//
// Stops when the step's predicted decrease of the cost under the linear
// model, -(2 delta^T J^T r + delta^T J^T J delta), falls below 1e-8 of the
// cost: with n data at the noise level the cost is ~ n sigma^2, and a pose
// off by k of its standard deviations costs ~ k^2 sigma^2 more, so the
// remaining error is below 0.01 standard deviations for n up to 10^4. The
// normal equations are formed only where the pose moved (a refused step
// only changes the damping).
template <typename NormalEquations, typename Cost>
bool LevenbergMarquardt(Pose* pose, int iterations, NormalEquations normal_equations, Cost cost) {
  double current = cost(*pose);
  double damping = 1e-6;
  bool improved = false;
  Eigen::Matrix<double, 6, 6> jtj;
  Eigen::Matrix<double, 6, 1> jtr;
  bool stale = true;
  for (int iteration = 0; iteration < iterations; ++iteration) {
    if (stale && normal_equations(*pose, &jtj, &jtr) < 3) break;
    stale = false;
    Eigen::Matrix<double, 6, 6> a = jtj;
    a.diagonal() += damping * jtj.diagonal().cwiseMax(1e-12);
    const Eigen::Matrix<double, 6, 1> delta = a.ldlt().solve(-jtr);
    if (!delta.allFinite()) break;
    const double predicted = -(2.0 * delta.dot(jtr) + delta.dot(jtj * delta));
    if (!(predicted > 1e-8 * current)) break;
    const Pose candidate = Perturb(*pose, delta);
    const double candidate_cost = cost(candidate);
    if (candidate_cost < current) {
      *pose = candidate;
      current = candidate_cost;
      improved = true;
      stale = true;
      damping = std::max(1e-9, damping * 0.1);
    } else {
      damping *= 10;
      if (damping > 1e4) break;
    }
  }
  return improved;
}

}  // namespace lifmcr::registration
