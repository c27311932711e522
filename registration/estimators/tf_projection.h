#pragma once
// The plenoptic projection of processing/camera_model.h written once as a
// template, so that Ceres (automatic differentiation) and the hand-written
// Gauss-Newton of the PnP estimator evaluate the same function as
// CameraModel::Project. A camera point p = (X, Y, Z) (mm) images in the
// totally focused (TF) image at
//   b_L = f_L Z / (Z - f_L),   x_mla = (X, Y) b_L0 / Z,   x_d = distort(x_mla),
//   x_v = c + x_d b_L / (b_L0 s)          (raw / virtual-image pixels)
//   tf = (x_v - 1/2) / 2                  (TF pixels, CameraModel::TfOfRaw)
// Without distortion this is x_v - c = (X, Y) f_L / ((Z - f_L) s): a pinhole
// centred at the front focal point (0, 0, f_L), which is why points at or in
// front of that plane (Z <= f_L) have no image.

#include "processing/camera_model.h"

#include <Eigen/Core>

#include <limits>

namespace lifmcr::registration {

struct TfProjection {
  double f = 25.0;     // f_L (mm)
  double b_l0 = 24.8;  // b_L0 (mm)
  double inv_b_l0_s = 1.0;  // 1 / (b_L0 s)
  double cx = 0, cy = 0;    // principal point (raw px)
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0;
  bool distorted = false;
  double half_f_over_s = 1.0;  // f_L / (2 s): the TF pinhole's focal length (TF px)
  double tf_cx = 0, tf_cy = 0;  // (c - 1/2) / 2: its principal point (TF px)

  static TfProjection Of(const processing::CameraModel& camera) {
    const processing::CameraIntrinsics& k = camera.intrinsics();
    TfProjection t;
    t.f = k.main_focal_length_mm;
    t.b_l0 = k.mla_to_main_lens_mm;
    t.inv_b_l0_s = 1.0 / (k.mla_to_main_lens_mm * k.pixel_size_mm);
    t.cx = camera.principal_point_px().x();
    t.cy = camera.principal_point_px().y();
    t.k1 = k.k1;
    t.k2 = k.k2;
    t.p1 = k.p1;
    t.p2 = k.p2;
    t.distorted = k.k1 != 0 || k.k2 != 0 || k.p1 != 0 || k.p2 != 0;
    t.half_f_over_s = 0.5 * t.f / k.pixel_size_mm;
    t.tf_cx = (t.cx - 0.5) * 0.5;
    t.tf_cy = (t.cy - 0.5) * 0.5;
    return t;
  }

  // TF pixel of camera point p; false (tf untouched) when Z <= f_L.
  template <typename T>
  bool operator()(const T* p, T* tf) const {
    if (!(p[2] > T(f))) return false;
    const T inv_z = T(1) / p[2];
    const T b_l = T(f) * p[2] / (p[2] - T(f));
    T x = p[0] * T(b_l0) * inv_z;
    T y = p[1] * T(b_l0) * inv_z;
    if (distorted) {
      const T r2 = x * x + y * y;
      const T radial = T(k1) * r2 + T(k2) * r2 * r2;
      const T xd = x + x * radial + T(p1) * (r2 + T(2) * x * x) + T(2) * T(p2) * x * y;
      const T yd = y + y * radial + T(p2) * (r2 + T(2) * y * y) + T(2) * T(p1) * x * y;
      x = xd;
      y = yd;
    }
    const T scale = b_l * T(inv_b_l0_s);
    tf[0] = (T(cx) + x * scale - T(0.5)) * T(0.5);
    tf[1] = (T(cy) + y * scale - T(0.5)) * T(0.5);
    return true;
  }

  // |tf(p) - observed|^2, +inf when Z <= f_L; one division without distortion.
  double SquaredError(const Eigen::Vector3d& p, const Eigen::Vector2d& observed) const {
    if (!(p.z() > f)) return std::numeric_limits<double>::infinity();
    double dx, dy;
    if (!distorted) {
      const double a = half_f_over_s / (p.z() - f);
      dx = tf_cx + a * p.x() - observed.x();
      dy = tf_cy + a * p.y() - observed.y();
    } else {
      double tf[2];
      (*this)(p.data(), tf);
      dx = tf[0] - observed.x();
      dy = tf[1] - observed.y();
    }
    return dx * dx + dy * dy;
  }

  // The TF pixel and its 2x3 Jacobian d tf / d p. Without distortion in
  // closed form: with a = f_L / (2 s (Z - f_L)),
  //   tf = (c - 1/2) / 2 + a (X, Y),   d tf / dX = a,   d tf / dZ = -a (X, Y) / (Z - f_L);
  // with distortion by automatic differentiation (tf_projection.cpp).
  bool WithJacobian(const Eigen::Vector3d& p, Eigen::Vector2d* tf,
                    Eigen::Matrix<double, 2, 3>* jacobian) const {
    if (!(p.z() > f)) return false;
    if (!distorted) {
      const double inv_depth = 1.0 / (p.z() - f);
      const double a = half_f_over_s * inv_depth;
      *tf = Eigen::Vector2d(tf_cx + a * p.x(), tf_cy + a * p.y());
      *jacobian << a, 0, -a * p.x() * inv_depth, 0, a, -a * p.y() * inv_depth;
      return true;
    }
    return DistortedWithJacobian(p, tf, jacobian);
  }

 private:
  bool DistortedWithJacobian(const Eigen::Vector3d& p, Eigen::Vector2d* tf,
                             Eigen::Matrix<double, 2, 3>* jacobian) const;
};

}  // namespace lifmcr::registration
