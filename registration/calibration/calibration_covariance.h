#pragma once
// Internal to calibration: the covariance of a bundle adjustment's camera
// parameters (intrinsics, poses) by the Schur complement of its points, and,
// where it is singular, the directions it cannot determine.
//
// With J the Jacobian (tangent space, the loss applied) of the solved
// problem and H = J^T J split into the kept blocks c and the point blocks p
// (3 x 3 each, eliminated): S = H_cc - sum_i H_cp_i H_pp_i^-1 H_pc_i, and the
// covariance of c is S^-1 (unit residual variance). S is scaled to unit
// diagonal, D S D, before its eigen-decomposition; an eigenvalue below
// `rank_tolerance` times the largest is a direction the observations do not
// determine, and the largest components of its eigenvector name the
// parameters along it.

#include "config/error.h"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace ceres {
class Problem;
}

namespace lifmcr::registration::internal {

struct KeptBlock {
  double* block = nullptr;
  std::vector<std::string> names;  // one per tangent coordinate (e.g. "f_L", "pose 3 rx")
};

struct ReducedCovariance {
  std::vector<double> std_dev;  // unit-variance standard deviation per kept coordinate
  int rank_deficiency = 0;      // eigenvalues of D S D below the tolerance
  int singular_points = 0;      // point blocks whose 3 x 3 H_pp is singular
  std::string null_directions;  // "(eigenvalue: name component, ...)" per deficient direction
  std::string weakest_direction;  // the same for the smallest eigenvalue
  double smallest_relative_eigenvalue = 0;
  // The whole unit-variance covariance of the kept coordinates (tangent
  // space, pseudo-inverse where deficient) and where each kept block starts
  // in it (-1: skipped), for blocks whose correlations matter (a rig's
  // c0_from_cx: rotation and translation together).
  Eigen::MatrixXd covariance;
  std::vector<int> first_coordinate;
};

// `points`: the eliminated blocks (3 coordinates each). Kept blocks that are
// constant or not in the problem are skipped (their std_dev is NaN).
Expected<ReducedCovariance> ComputeReducedCovariance(ceres::Problem* problem,
                                                     const std::vector<KeptBlock>& kept,
                                                     const std::vector<double*>& points,
                                                     double rank_tolerance = 1e-12);

}  // namespace lifmcr::registration::internal
