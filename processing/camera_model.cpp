#include "processing/camera_model.h"

#include <cmath>
#include <string>

namespace lifmcr::processing {
namespace {

Error FieldError(const std::string& field, const std::string& what) {
  return Error{"camera intrinsics: " + field + ": " + what};
}

}  // namespace

Status CameraIntrinsics::Check() const {
  if (!(main_focal_length_mm > 0)) return FieldError("main_focal_length_mm", "expected > 0");
  if (!(mla_to_main_lens_mm > 0)) return FieldError("mla_to_main_lens_mm", "expected > 0");
  if (!(mla_to_sensor_mm > 0 && mla_to_sensor_mm < mla_to_main_lens_mm))
    return FieldError("mla_to_sensor_mm", "expected 0 < B < b_L0");
  if (!(pixel_size_mm > 0)) return FieldError("pixel_size_mm", "expected > 0");
  if (width_px <= 0 || height_px <= 0) return FieldError("width_px/height_px", "expected > 0");
  if (!std::isfinite(k1) || !std::isfinite(k2) || !std::isfinite(p1) || !std::isfinite(p2))
    return FieldError("k1/k2/p1/p2", "expected finite numbers");
  if (principal_point_px) {
    const Eigen::Vector2d& c = *principal_point_px;
    if (!(c.x() >= 0 && c.x() <= width_px - 1 && c.y() >= 0 && c.y() <= height_px - 1))
      return FieldError("principal_point_px", "expected inside the image (0 .. " +
                                                  std::to_string(width_px - 1) + ", 0 .. " +
                                                  std::to_string(height_px - 1) + ")");
  }
  return Status::Ok();
}

CameraModel::CameraModel(const CameraIntrinsics& intrinsics) : k_(intrinsics) {
  c_ = k_.PrincipalPointPx();
  lambda_ = k_.mla_to_main_lens_mm / (k_.mla_to_main_lens_mm + k_.mla_to_sensor_mm);
  distorted_ = k_.k1 != 0 || k_.k2 != 0 || k_.p1 != 0 || k_.p2 != 0;
}

double CameraModel::VirtualDepthOfDepth(double z_mm) const {
  const double f = k_.main_focal_length_mm;
  const double b_l = f * z_mm / (z_mm - f);
  return (b_l - k_.mla_to_main_lens_mm) / k_.mla_to_sensor_mm;
}

double CameraModel::DepthOfVirtualDepth(double v) const {
  const double f = k_.main_focal_length_mm;
  const double b_l = k_.mla_to_main_lens_mm + v * k_.mla_to_sensor_mm;
  return f * b_l / (b_l - f);
}

Eigen::Vector2d CameraModel::Distort(const Eigen::Vector2d& x) const {
  const double r2 = x.squaredNorm();
  const double radial = k_.k1 * r2 + k_.k2 * r2 * r2;
  return {x.x() + x.x() * radial + k_.p1 * (r2 + 2 * x.x() * x.x()) + 2 * k_.p2 * x.x() * x.y(),
          x.y() + x.y() * radial + k_.p2 * (r2 + 2 * x.y() * x.y()) + 2 * k_.p1 * x.x() * x.y()};
}

Eigen::Vector2d CameraModel::Undistort(const Eigen::Vector2d& x_d, int iterations) const {
  if (!distorted_) return x_d;
  Eigen::Vector2d x = x_d;
  for (int k = 0; k < iterations; ++k) x = x_d - (Distort(x) - x);
  return x;
}

Eigen::Vector3d CameraModel::Project(const Eigen::Vector3d& p) const {
  const double f = k_.main_focal_length_mm, b_l0 = k_.mla_to_main_lens_mm;
  const double b_l = f * p.z() / (p.z() - f);
  const Eigen::Vector2d x_mla_d = Distort(p.head<2>() * b_l0 / p.z());
  const Eigen::Vector2d x_px = c_ + x_mla_d * b_l / (b_l0 * k_.pixel_size_mm);
  return {x_px.x(), x_px.y(), (b_l - b_l0) / k_.mla_to_sensor_mm};
}

Eigen::Vector3d CameraModel::BackProject(const Eigen::Vector3d& virtual_px) const {
  const double f = k_.main_focal_length_mm, b_l0 = k_.mla_to_main_lens_mm;
  const double b_l = b_l0 + virtual_px.z() * k_.mla_to_sensor_mm;
  const Eigen::Vector2d x_mla_d = (virtual_px.head<2>() - c_) * k_.pixel_size_mm * b_l0 / b_l;
  const Eigen::Vector2d x_mla = Undistort(x_mla_d);
  const double z = f * b_l / (b_l - f);
  const Eigen::Vector2d xy = x_mla * z / b_l0;
  return {xy.x(), xy.y(), z};
}

Eigen::Vector2d CameraModel::LensCenterPx(const Eigen::Vector2d& c_k) const {
  return c_ + (c_k - c_) * lambda_;
}

Eigen::Vector2d CameraModel::ProjectToMicroImage(const Eigen::Vector3d& virtual_px,
                                                 const Eigen::Vector2d& c_k) const {
  const Eigen::Vector2d l = LensCenterPx(c_k);
  return l + (virtual_px.head<2>() - l) / virtual_px.z();
}

Eigen::Vector2d CameraModel::CentralProjection(const Eigen::Vector3d& virtual_px) const {
  const double b = k_.mla_to_sensor_mm, b_l0 = k_.mla_to_main_lens_mm;
  return (virtual_px.head<2>() - c_) * (2 * b + b_l0) / (virtual_px.z() * b + b_l0) + c_;
}

double CameraModel::FeatureFocalPx() const {
  return (k_.mla_to_main_lens_mm + 2 * k_.mla_to_sensor_mm) / k_.pixel_size_mm;
}

Eigen::Vector2d CameraModel::FeatureImagePoint(const Eigen::Vector3d& virtual_px) const {
  const double b_l0 = k_.mla_to_main_lens_mm;
  const double b_l = b_l0 + virtual_px.z() * k_.mla_to_sensor_mm;
  const Eigen::Vector2d x_mla_d = (virtual_px.head<2>() - c_) * k_.pixel_size_mm * b_l0 / b_l;
  const Eigen::Vector2d x_mla = Undistort(x_mla_d);
  // Undistorted virtual point on the MLA-plane ray, then projX/projY.
  return c_ + x_mla * FeatureFocalPx() / b_l0;
}

}  // namespace lifmcr::processing
