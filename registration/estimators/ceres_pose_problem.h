#pragma once
// Internal to registration/*.cpp that already use Ceres: a pose problem with
// one residual block per selected datum, rotation on
// ceres::EigenQuaternionManifold, a Cauchy loss, solved by Levenberg-Marquardt
// on the dense normal equations (six unknowns: a 6x6 Cholesky). Parameter blocks: q[4] in Eigen's x, y, z,
// w order, then t[3].

#include "config/frames.h"

#include <ceres/ceres.h>

#include <Eigen/Geometry>

#include <cstddef>
#include <span>

namespace lifmcr::registration {

// Solves `problem` over (q, t) (q on the quaternion manifold) and stores the
// pose in a_from_b; the iterations run, or -1 (a_from_b unchanged).
inline int SolvePoseAndStore(ceres::Problem* problem, Eigen::Quaterniond& q, Eigen::Vector3d& t,
                             int max_iterations, Pose* a_from_b) {
  problem->SetManifold(q.coeffs().data(), new ceres::EigenQuaternionManifold);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
  if (!summary.IsSolutionUsable()) return -1;
  a_from_b->linear() = q.normalized().toRotationMatrix();
  a_from_b->translation() = t;
  return static_cast<int>(summary.iterations.size());
}

// make_cost(i) returns a new ceres::CostFunction of (q, t) for datum i
// (mask[i] != 0); the problem owns it. Returns the iterations run, or -1 when
// Ceres gave no usable solution (the pose is then unchanged).
template <typename MakeCost>
int SolveCeresPoseProblem(std::span<const char> mask, double loss_scale, int max_iterations,
                          MakeCost make_cost, Pose* a_from_b) {
  Eigen::Quaterniond q(a_from_b->linear());
  Eigen::Vector3d t = a_from_b->translation();
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::TAKE_OWNERSHIP;
  // The blocks all come from here, two parameter blocks of fixed sizes: the
  // per-block checks only cost (bench_pnp, 50 % outliers, ~1000 blocks:
  // 1.99 -> 1.51 ms a PnP on a quiet machine).
  problem_options.disable_all_safety_checks = true;
  ceres::Problem problem(problem_options);
  ceres::CauchyLoss loss(loss_scale);
  int blocks = 0;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    problem.AddResidualBlock(make_cost(i), &loss, q.coeffs().data(), t.data());
    ++blocks;
  }
  if (blocks < 3) return -1;
  return SolvePoseAndStore(&problem, q, t, max_iterations, a_from_b);
}

}  // namespace lifmcr::registration
