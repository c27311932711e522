#include "registration/calibration/calibration_covariance.h"

#include <ceres/ceres.h>
#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

namespace lifmcr::registration::internal {

Expected<ReducedCovariance> ComputeReducedCovariance(ceres::Problem* problem,
                                                     const std::vector<KeptBlock>& kept,
                                                     const std::vector<double*>& points,
                                                     double rank_tolerance) {
  ceres::Problem::EvaluateOptions evaluate;
  std::vector<std::string> names;
  std::vector<int> first_of_block;  // column of each kept block, -1 when skipped
  int nc = 0;
  for (const KeptBlock& b : kept) {
    if (!problem->HasParameterBlock(b.block) || problem->IsParameterBlockConstant(b.block)) {
      first_of_block.push_back(-1);
      continue;
    }
    const int size = problem->ParameterBlockTangentSize(b.block);
    first_of_block.push_back(nc);
    evaluate.parameter_blocks.push_back(b.block);
    for (int i = 0; i < size; ++i)
      names.push_back(i < static_cast<int>(b.names.size()) ? b.names[i]
                                                           : "block " + std::to_string(i));
    nc += size;
  }
  int np = 0;
  for (double* p : points) {
    if (!problem->HasParameterBlock(p)) continue;
    if (problem->ParameterBlockTangentSize(p) != 3)
      return Error{"reduced covariance: a point block is not of size 3"};
    evaluate.parameter_blocks.push_back(p);
    np += 3;
  }
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(evaluate, nullptr, nullptr, nullptr, &crs))
    return Error{"reduced covariance: the Jacobian could not be evaluated"};
  using Sparse = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
  const Eigen::Map<const Eigen::SparseMatrix<double, Eigen::RowMajor, int>> j(
      crs.num_rows, crs.num_cols, static_cast<int>(crs.values.size()), crs.rows.data(),
      crs.cols.data(), crs.values.data());
  const Sparse jc = j;  // column-major copy for J^T J
  const Sparse h = Sparse(jc.transpose()) * jc;

  // S = H_cc - sum_i H_cp_i H_pp_i^-1 H_pc_i.
  Eigen::MatrixXd s = Eigen::MatrixXd(h.topLeftCorner(nc, nc));
  ReducedCovariance out;
  for (int i = 0; i < np / 3; ++i) {
    const int col = nc + 3 * i;
    Eigen::Matrix3d hpp = Eigen::Matrix3d::Zero();
    // Gather the coupled kept coordinates of this point's three columns.
    std::vector<std::pair<int, std::array<double, 3>>> coupled;
    for (int a = 0; a < 3; ++a)
      for (Sparse::InnerIterator it(h, col + a); it; ++it) {
        if (it.row() >= col && it.row() < col + 3) {
          hpp(it.row() - col, a) = it.value();
        } else if (it.row() < nc) {
          auto found = std::find_if(coupled.begin(), coupled.end(),
                                    [&](const auto& e) { return e.first == it.row(); });
          if (found == coupled.end()) {
            coupled.push_back({static_cast<int>(it.row()), {0, 0, 0}});
            found = coupled.end() - 1;
          }
          found->second[a] = it.value();
        }
      }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(hpp);
    if (!(eig.eigenvalues()(0) > rank_tolerance * std::max(eig.eigenvalues()(2), 1e-300))) {
      ++out.singular_points;
      continue;
    }
    const Eigen::Matrix3d hpp_inv = eig.eigenvectors() *
                                    eig.eigenvalues().cwiseInverse().asDiagonal() *
                                    eig.eigenvectors().transpose();
    Eigen::MatrixXd b(coupled.size(), 3);
    for (std::size_t r = 0; r < coupled.size(); ++r)
      for (int a = 0; a < 3; ++a) b(r, a) = coupled[r].second[a];
    const Eigen::MatrixXd update = b * hpp_inv * b.transpose();
    for (std::size_t r = 0; r < coupled.size(); ++r)
      for (std::size_t q = 0; q < coupled.size(); ++q)
        s(coupled[r].first, coupled[q].first) -= update(r, q);
  }

  // Unit diagonal: D S D with D = diag(S)^-1/2.
  Eigen::VectorXd d(nc);
  for (int i = 0; i < nc; ++i) d(i) = s(i, i) > 0 ? 1 / std::sqrt(s(i, i)) : 0;
  const Eigen::MatrixXd scaled = d.asDiagonal() * s * d.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(scaled);
  const Eigen::VectorXd& lambda = eig.eigenvalues();
  const double largest = lambda.size() > 0 ? lambda(lambda.size() - 1) : 0;
  out.smallest_relative_eigenvalue = lambda.size() > 0 && largest > 0 ? lambda(0) / largest : 0;
  // Eigenvector i by its largest components (scaled coordinates), with its
  // eigenvalue relative to the largest.
  auto describe = [&](int i) {
    const Eigen::VectorXd v = eig.eigenvectors().col(i);
    std::vector<int> order(nc);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](int a, int b) { return std::abs(v(a)) > std::abs(v(b)); });
    char text[96];
    std::snprintf(text, sizeof(text), "(%.1e:", lambda(i) / std::max(largest, 1e-300));
    std::string line = text;
    for (int n = 0; n < std::min(nc, 4); ++n) {
      if (n > 0 && std::abs(v(order[n])) < 0.05) break;
      std::snprintf(text, sizeof(text), "%s %s %+.2f", n > 0 ? "," : "", names[order[n]].c_str(),
                    v(order[n]));
      line += text;
    }
    return line + ")";
  };
  Eigen::VectorXd inverse_lambda = Eigen::VectorXd::Zero(nc);
  for (int i = 0; i < nc; ++i) {
    if (lambda(i) > rank_tolerance * largest && d(i) >= 0) {
      inverse_lambda(i) = 1 / lambda(i);
      continue;
    }
    ++out.rank_deficiency;
    out.null_directions += (out.null_directions.empty() ? "" : "; ") + describe(i);
  }
  if (nc > 0) out.weakest_direction = describe(0);
  // Covariance (pseudo-inverse where deficient): D V Lambda^-1 V^T D.
  const Eigen::MatrixXd cov = d.asDiagonal() * eig.eigenvectors() * inverse_lambda.asDiagonal() *
                              eig.eigenvectors().transpose() * d.asDiagonal();
  out.first_coordinate = first_of_block;
  for (std::size_t b = 0; b < kept.size(); ++b) {
    const int first = first_of_block[b];
    const int size = first < 0 ? static_cast<int>(kept[b].names.size())
                               : problem->ParameterBlockTangentSize(kept[b].block);
    for (int i = 0; i < size; ++i)
      out.std_dev.push_back(first < 0 ? std::numeric_limits<double>::quiet_NaN()
                                      : std::sqrt(std::max(cov(first + i, first + i), 0.0)));
  }
  out.covariance = cov;
  return out;
}

}  // namespace lifmcr::registration::internal
