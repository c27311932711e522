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

namespace lifmcr::registration {

struct TfProjection {
  double f = 25.0;     // f_L (mm)
  double b_l0 = 24.8;  // b_L0 (mm)
  double inv_b_l0_s = 1.0;  // 1 / (b_L0 s)
  double cx = 0, cy = 0;    // principal point (raw px)
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0;
  bool distorted = false;

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
};

}  // namespace lifmcr::registration
