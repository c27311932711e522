#include "registration/estimators/pose_checks.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace lifmcr::registration {
namespace {

constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;

std::string Refused(const char* format, double a, double b) {
  char line[160];
  std::snprintf(line, sizeof line, format, a, b);
  return std::string("refused: ") + line;
}

double LargestStdDev(const Eigen::Matrix3d& block) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(block, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eigen.eigenvalues()(2)));
}

}  // namespace

Status PoseCheckOptions::Check() const {
  if (min_inliers < 3) return Error{"pose checks: min_inliers: expected >= 3"};
  if (!(min_spread >= 0 && min_spread < 1))
    return Error{"pose checks: min_spread: expected in [0, 1)"};
  if (!(max_rmse_px > 0)) return Error{"pose checks: max_rmse_px: expected > 0"};
  if (!(max_sigma_mm > 0)) return Error{"pose checks: max_sigma_mm: expected > 0"};
  if (!(max_sigma_deg > 0)) return Error{"pose checks: max_sigma_deg: expected > 0"};
  if (!(max_jump_mm > 0)) return Error{"pose checks: max_jump_mm: expected > 0"};
  if (!(max_jump_deg > 0)) return Error{"pose checks: max_jump_deg: expected > 0"};
  return Status::Ok();
}

std::string CheckPose(const PoseEvidence& e, const PoseCheckOptions& o) {
  if (e.inliers < o.min_inliers)
    return Refused("%.0f inliers (< %.0f)", e.inliers, o.min_inliers);
  const std::size_t n = e.inlier_tf_px.size();
  if (n >= 2 && e.tf_width > 0 && e.tf_height > 0) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& p : e.inlier_tf_px) mean += p;
    mean /= static_cast<double>(n);
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const Eigen::Vector2d& p : e.inlier_tf_px) cov += (p - mean) * (p - mean).transpose();
    cov /= static_cast<double>(n);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(cov, Eigen::EigenvaluesOnly);
    const double spread =
        std::sqrt(std::max(0.0, eigen.eigenvalues()(0))) / std::min(e.tf_width, e.tf_height);
    if (spread < o.min_spread)
      return Refused("inliers span %.1f %% of the image (< %.0f %%)", 100 * spread,
                     100 * o.min_spread);
  }
  if (!(e.rmse_px <= o.max_rmse_px))
    return Refused("rmse %.2f px (> %.2f px)", e.rmse_px, o.max_rmse_px);
  if (!e.covariance.allFinite()) return "refused: covariance not finite";
  const double sigma_mm = LargestStdDev(e.covariance.topLeftCorner<3, 3>());
  if (sigma_mm > o.max_sigma_mm)
    return Refused("translation sigma %.2f mm (> %.2f mm)", sigma_mm, o.max_sigma_mm);
  const double sigma_deg = kDegPerRad * LargestStdDev(e.covariance.bottomRightCorner<3, 3>());
  if (sigma_deg > o.max_sigma_deg)
    return Refused("rotation sigma %.3f deg (> %.3f deg)", sigma_deg, o.max_sigma_deg);
  if (e.predicted_w0_from_cam) {
    const double jump_mm = TranslationDifference(e.w0_from_cam, *e.predicted_w0_from_cam);
    if (jump_mm > o.max_jump_mm)
      return Refused("%.1f mm from the predicted pose (> %.1f mm)", jump_mm, o.max_jump_mm);
    const double jump_deg = RotationDifferenceDeg(e.w0_from_cam, *e.predicted_w0_from_cam);
    if (jump_deg > o.max_jump_deg)
      return Refused("%.2f deg from the predicted pose (> %.2f deg)", jump_deg, o.max_jump_deg);
  }
  return "ok";
}

}  // namespace lifmcr::registration
