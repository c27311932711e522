#include "evaluation/trajectory_metrics.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace lifmcr {

ErrorStats ErrorStats::Of(std::span<const double> values) {
  ErrorStats stats;
  stats.count = values.size();
  if (values.empty()) return stats;
  double sum = 0, sum_sq = 0;
  for (double v : values) {
    sum += v;
    sum_sq += v * v;
  }
  const double n = static_cast<double>(values.size());
  stats.mean = sum / n;
  stats.rmse = std::sqrt(sum_sq / n);
  double var = 0;
  for (double v : values) var += (v - stats.mean) * (v - stats.mean);
  stats.sd = std::sqrt(var / n);
  std::vector<double> sorted(values.begin(), values.end());
  std::sort(sorted.begin(), sorted.end());
  const std::size_t mid = sorted.size() / 2;
  stats.median = sorted.size() % 2 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  stats.min = sorted.front();
  stats.max = sorted.back();
  return stats;
}

std::string ErrorStats::BriefReport(const std::string& unit) const {
  char line[200];
  std::snprintf(line, sizeof(line), "rmse %.3f mean %.3f median %.3f sd %.3f (n=%zu) %s", rmse,
                mean, median, sd, count, unit.c_str());
  return line;
}

Eigen::Vector3d RotationLog(const Eigen::Matrix3d& rotation) {
  const Eigen::AngleAxisd aa(rotation);
  return aa.angle() * aa.axis();
}

Eigen::Matrix3d NearestRotation(const Eigen::Matrix3d& m) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(m, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  d(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1 : 1;
  return svd.matrixU() * d * svd.matrixV().transpose();
}

double RotationAngleDeg(const Eigen::Matrix3d& rotation) {
  // atan2 of |sin| and cos is accurate near 0 and 180 degrees, acos is not.
  const Eigen::Matrix3d skew = rotation - rotation.transpose();
  const double sin_angle = 0.5 * Eigen::Vector3d(skew(2, 1), skew(0, 2), skew(1, 0)).norm();
  const double cos_angle = std::clamp(0.5 * (rotation.trace() - 1.0), -1.0, 1.0);
  return std::atan2(sin_angle, cos_angle) * 180.0 / M_PI;
}

Pose PoseError(const Pose& estimate, const Pose& reference) {
  return estimate.inverse() * reference;
}

namespace {

void Append(PoseErrors* errors, std::int64_t frame, const Pose& e) {
  errors->frames.push_back(frame);
  errors->translation_mm.push_back(e.translation().norm());
  errors->rotation_deg.push_back(RotationAngleDeg(e.linear()));
  errors->translation_axes_mm.push_back(e.translation());
  errors->rotation_axes_deg.push_back(RotationLog(e.linear()) * 180.0 / M_PI);
}

}  // namespace

PoseErrors AbsolutePoseErrors(const FramePoses& estimate, const FramePoses& reference) {
  PoseErrors errors;
  for (const auto& [frame, p] : estimate) {
    const auto q = reference.find(frame);
    if (q != reference.end()) Append(&errors, frame, PoseError(p, q->second));
  }
  return errors;
}

PoseErrors RelativePoseErrors(const FramePoses& estimate, const FramePoses& reference) {
  PoseErrors errors;
  for (auto p = estimate.begin(); p != estimate.end(); ++p) {
    const auto p_next = std::next(p);
    if (p_next == estimate.end() || p_next->first != p->first + 1) continue;
    const auto q = reference.find(p->first);
    const auto q_next = reference.find(p->first + 1);
    if (q == reference.end() || q_next == reference.end()) continue;
    const Pose estimate_motion = p->second.inverse() * p_next->second;
    const Pose reference_motion = q->second.inverse() * q_next->second;
    Append(&errors, p->first, PoseError(reference_motion, estimate_motion));
  }
  return errors;
}

ErrorSummary SummarizeErrors(const PoseErrors& errors) {
  ErrorSummary summary;
  summary.translation_mm = ErrorStats::Of(errors.translation_mm);
  summary.rotation_deg = ErrorStats::Of(errors.rotation_deg);
  std::vector<double> values(errors.size());
  for (int axis = 0; axis < 3; ++axis) {
    for (std::size_t k = 0; k < errors.size(); ++k)
      values[k] = errors.translation_axes_mm[k][axis];
    summary.translation_axis_mm[axis] = ErrorStats::Of(values);
    for (std::size_t k = 0; k < errors.size(); ++k) values[k] = errors.rotation_axes_deg[k][axis];
    summary.rotation_axis_deg[axis] = ErrorStats::Of(values);
  }
  return summary;
}

FramePoses FramesBetween(const FramePoses& poses, std::int64_t first, std::int64_t last) {
  return FramePoses(poses.lower_bound(first), poses.upper_bound(last));
}

}  // namespace lifmcr
