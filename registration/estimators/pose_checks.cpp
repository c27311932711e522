#include "registration/estimators/pose_checks.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace lifmcr::registration {
namespace {

constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string Refused(const char* format, double a, double b) {
  char line[160];
  std::snprintf(line, sizeof line, format, a, b);
  return std::string("refused: ") + line;
}

double LargestStdDev(const Eigen::Matrix3d& block) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(block, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, eigen.eigenvalues()(2)));
}

// The q-quantile of `values` (copied; linear between order statistics).
double Quantile(std::vector<double> values, double q) {
  std::sort(values.begin(), values.end());
  const double at = q * static_cast<double>(values.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(at);
  const std::size_t hi = std::min(lo + 1, values.size() - 1);
  return values[lo] + (at - static_cast<double>(lo)) * (values[hi] - values[lo]);
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
  if (!(depth_sigmas > 0)) return Error{"pose checks: depth_sigmas: expected > 0"};
  if (!(min_depth_agreement >= 0 && min_depth_agreement <= 1))
    return Error{"pose checks: min_depth_agreement: expected in [0, 1]"};
  if (!(min_depth_spread >= 0)) return Error{"pose checks: min_depth_spread: expected >= 0"};
  return Status::Ok();
}

PoseCheckOptions PoseCheckOptions::ForErrorBound(double max_error_mm, double max_error_deg) {
  // sqrt(2) for the composition of two poses, 4.03 = sqrt of the 99.9 %
  // quantile of chi-square(3) (pose_checks.h).
  constexpr double kSigmas = 1.4142135623730951 * 4.03;
  PoseCheckOptions o;
  o.max_sigma_mm = max_error_mm / kSigmas;
  o.max_sigma_deg = max_error_deg / kSigmas;
  o.min_depth_agreement = 0.5;
  return o;
}

PoseCheckFigures MeasurePose(const PoseEvidence& e, const PoseCheckOptions& o) {
  PoseCheckFigures f;
  const std::size_t n = e.inlier_tf_px.size();
  f.spread = 1;  // unknown positions are not refused
  if (n >= 2 && e.tf_width > 0 && e.tf_height > 0) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (const Eigen::Vector2d& p : e.inlier_tf_px) mean += p;
    mean /= static_cast<double>(n);
    Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
    for (const Eigen::Vector2d& p : e.inlier_tf_px) cov += (p - mean) * (p - mean).transpose();
    cov /= static_cast<double>(n);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(cov, Eigen::EigenvaluesOnly);
    f.spread =
        std::sqrt(std::max(0.0, eigen.eigenvalues()(0))) / std::min(e.tf_width, e.tf_height);
  }
  if (e.covariance.allFinite()) {
    f.sigma_mm = LargestStdDev(e.covariance.topLeftCorner<3, 3>());
    f.sigma_deg = kDegPerRad * LargestStdDev(e.covariance.bottomRightCorner<3, 3>());
  }
  std::vector<double> z;
  for (const double zi : e.inlier_depth_z)
    if (std::isfinite(zi)) z.push_back(zi);
  if (!z.empty()) {
    const auto agree = std::count_if(z.begin(), z.end(),
                                     [&](double zi) { return std::abs(zi) <= o.depth_sigmas; });
    f.depth_agreement = static_cast<double>(agree) / static_cast<double>(z.size());
    f.median_depth_z = Quantile(z, 0.5);
  }
  std::vector<double> depth;
  for (const double d : e.inlier_depth_mm)
    if (std::isfinite(d)) depth.push_back(d);
  if (depth.size() >= 4) {
    const double median = Quantile(depth, 0.5);
    if (median > 0) f.depth_spread = (Quantile(depth, 0.75) - Quantile(depth, 0.25)) / median;
  }
  return f;
}

void InlierDepths(const processing::CameraModel& camera, const Pose& cam_from_w0,
                  std::span<const Eigen::Vector3d> points_in_w0,
                  std::span<const double> virtual_depth, double sigma_v_relative,
                  std::vector<double>* depth_z, std::vector<double>* depth_mm) {
  depth_z->clear();
  depth_mm->clear();
  for (std::size_t i = 0; i < points_in_w0.size(); ++i) {
    const double z_mm = (cam_from_w0 * points_in_w0[i]).z();
    depth_mm->push_back(z_mm);
    const double v = i < virtual_depth.size() ? virtual_depth[i] : kNaN;
    const double v_of_pose = z_mm > 0 ? camera.VirtualDepthOfDepth(z_mm) : kNaN;
    // A point behind the camera, or one the thin lens images at no finite
    // virtual depth, contradicts any measured depth.
    if (!std::isfinite(v) || !(v > 0)) {
      depth_z->push_back(kNaN);
    } else if (!std::isfinite(v_of_pose)) {
      depth_z->push_back(std::numeric_limits<double>::infinity());
    } else {
      depth_z->push_back((v_of_pose - v) / (sigma_v_relative * v));
    }
  }
}

std::string CheckPose(const PoseEvidence& e, const PoseCheckOptions& o) {
  if (e.inliers < o.min_inliers)
    return Refused("%.0f inliers (< %.0f)", e.inliers, o.min_inliers);
  const PoseCheckFigures f = MeasurePose(e, o);
  if (f.spread < o.min_spread)
    return Refused("inliers span %.1f %% of the image (< %.0f %%)", 100 * f.spread,
                   100 * o.min_spread);
  if (!(e.rmse_px <= o.max_rmse_px))
    return Refused("rmse %.2f px (> %.2f px)", e.rmse_px, o.max_rmse_px);
  if (!e.covariance.allFinite()) return "refused: covariance not finite";
  if (f.sigma_mm > o.max_sigma_mm)
    return Refused("translation sigma %.2f mm (> %.2f mm)", f.sigma_mm, o.max_sigma_mm);
  if (f.sigma_deg > o.max_sigma_deg)
    return Refused("rotation sigma %.3f deg (> %.3f deg)", f.sigma_deg, o.max_sigma_deg);
  if (f.depth_agreement >= 0 && f.depth_agreement < o.min_depth_agreement)
    return Refused("%.0f %% of the inliers at their measured virtual depth (< %.0f %%)",
                   100 * f.depth_agreement, 100 * o.min_depth_agreement);
  if (f.depth_spread >= 0 && f.depth_spread < o.min_depth_spread)
    return Refused("inliers' depths span %.1f %% of their median (< %.1f %%)",
                   100 * f.depth_spread, 100 * o.min_depth_spread);
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
