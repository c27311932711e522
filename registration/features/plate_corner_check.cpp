#include "registration/features/plate_corner_check.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <optional>

namespace lifmcr::registration {

namespace {

// Similarity that moves the points' centroid to the origin and their mean
// distance from it to sqrt(2) (Hartley's normalisation: the DLT's matrix is
// then well conditioned).
Eigen::Matrix3d Normalising(const std::vector<Eigen::Vector2d>& p) {
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& x : p) mean += x;
  mean /= static_cast<double>(p.size());
  double spread = 0;
  for (const Eigen::Vector2d& x : p) spread += (x - mean).norm();
  spread /= static_cast<double>(p.size());
  const double s = spread > 0 ? std::sqrt(2.0) / spread : 1.0;
  Eigen::Matrix3d t = Eigen::Matrix3d::Identity();
  t(0, 0) = t(1, 1) = s;
  t.block<2, 1>(0, 2) = -s * mean;
  return t;
}

// u ~ H x by the normalised DLT (each correspondence gives two rows of
// A h = 0; h is A's right singular vector of the smallest singular value).
// None when the fit is degenerate (the smallest two singular values alike:
// points on a line).
std::optional<Eigen::Matrix3d> FitHomography(const std::vector<Eigen::Vector2d>& x,
                                             const std::vector<Eigen::Vector2d>& u) {
  const Eigen::Matrix3d tx = Normalising(x), tu = Normalising(u);
  const int n = static_cast<int>(x.size());
  Eigen::MatrixXd a(2 * n, 9);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d p = tx * x[i].homogeneous();
    const Eigen::Vector3d q = tu * u[i].homogeneous();
    a.row(2 * i) << 0, 0, 0, -q.z() * p.transpose(), q.y() * p.transpose();
    a.row(2 * i + 1) << q.z() * p.transpose(), 0, 0, 0, -q.x() * p.transpose();
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
  const Eigen::VectorXd& sv = svd.singularValues();
  if (!(sv(7) > 1e-9 * sv(0))) return std::nullopt;
  const Eigen::VectorXd h = svd.matrixV().col(8);
  Eigen::Matrix3d hn;
  hn << h(0), h(1), h(2), h(3), h(4), h(5), h(6), h(7), h(8);
  return tu.inverse() * hn * tx;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(m), v.end());
  return v[m];
}

}  // namespace

Status PlateCornerCheckOptions::Check() const {
  auto fail = [](const std::string& what) { return Error{"plate corner check: " + what}; };
  // Leave-one-out needs four corners for the homography of the others and
  // one more to be redundant.
  if (min_corners < 6) return fail("min_corners: expected >= 6");
  if (!(max_residual_tf_px > 0)) return fail("max_residual_tf_px: expected > 0");
  if (!(max_residual_over_reference >= 1))
    return fail("max_residual_over_reference: expected >= 1");
  return Status::Ok();
}

namespace {

// Leave-one-out residuals of corners[kept[k]]; none when a fit is degenerate.
std::optional<std::vector<double>> Residuals(const std::vector<PlateCorner>& corners,
                                             const std::vector<int>& kept) {
  std::vector<double> residual(kept.size(), 0);
  std::vector<Eigen::Vector2d> x, u;
  for (std::size_t k = 0; k < kept.size(); ++k) {
    x.clear();
    u.clear();
    for (std::size_t j = 0; j < kept.size(); ++j) {
      if (j == k) continue;
      x.push_back(corners[kept[j]].p_in_w_mm.head<2>());
      u.push_back(corners[kept[j]].tf_px);
    }
    const std::optional<Eigen::Matrix3d> h = FitHomography(x, u);
    if (!h) return std::nullopt;
    const Eigen::Vector3d p = *h * corners[kept[k]].p_in_w_mm.head<2>().homogeneous();
    residual[k] = (p.hnormalized() - corners[kept[k]].tf_px).norm();
  }
  return residual;
}

std::vector<int> AllOf(const std::vector<PlateCorner>& corners) {
  std::vector<int> all(corners.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  return all;
}

}  // namespace

std::vector<double> PlateCornerResiduals(const std::vector<PlateCorner>& corners,
                                         const PlateCornerCheckOptions& options) {
  if (static_cast<int>(corners.size()) < options.min_corners)
    return std::vector<double>(corners.size(), std::nan(""));
  std::optional<std::vector<double>> r = Residuals(corners, AllOf(corners));
  return r ? *r : std::vector<double>(corners.size(), std::nan(""));
}

double MedianPlateCornerResidual(const std::vector<std::vector<PlateCorner>>& frames,
                                 const PlateCornerCheckOptions& options) {
  std::vector<double> all;
  for (const std::vector<PlateCorner>& corners : frames)
    for (const double r : PlateCornerResiduals(corners, options))
      if (!std::isnan(r)) all.push_back(r);
  return Median(std::move(all));
}

PlateCornerCheck CheckPlateCorners(const std::vector<PlateCorner>& corners,
                                   double reference_tf_px,
                                   const PlateCornerCheckOptions& options) {
  PlateCornerCheck out;
  const int n = static_cast<int>(corners.size());
  out.residual_tf_px.assign(n, std::nan(""));
  if (n < options.min_corners) return out;
  out.threshold_tf_px = std::max(options.max_residual_tf_px,
                                 options.max_residual_over_reference * reference_tf_px);
  std::vector<int> kept = AllOf(corners);
  while (true) {
    const std::optional<std::vector<double>> residual = Residuals(corners, kept);
    if (!residual) {
      PlateCornerCheck none;
      none.residual_tf_px.assign(n, std::nan(""));
      return none;
    }
    out.checked = true;
    for (std::size_t k = 0; k < kept.size(); ++k) out.residual_tf_px[kept[k]] = (*residual)[k];
    const std::size_t worst = static_cast<std::size_t>(
        std::max_element(residual->begin(), residual->end()) - residual->begin());
    if (!((*residual)[worst] > out.threshold_tf_px) ||
        static_cast<int>(kept.size()) - 1 < options.min_corners)
      break;
    out.rejected.push_back(kept[worst]);
    out.rejected_residual_tf_px.push_back((*residual)[worst]);
    kept.erase(kept.begin() + static_cast<std::ptrdiff_t>(worst));
  }
  return out;
}

}  // namespace lifmcr::registration
