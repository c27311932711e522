#pragma once
// LiFCal's plenoptic projection (processing/camera_model.h states the model)
// written once over a scalar type T, so that the bundle adjustment
// differentiates it (Ceres Jet) and plain code evaluates it (double), with
// the principal point as a parameter.
//
// Intrinsics vector (kIntrinsicsSize doubles):
//   [0] f_L   main-lens focal length (mm)
//   [1] b_L0  main lens -> MLA (mm)
//   [2] B     MLA -> sensor (mm)
//   [3] c_x, [4] c_y   principal point (raw pixels)
//   [5] k1, [6] k2     radial distortion in the MLA plane (mm based)
//   [7] p1, [8] p2     tangential distortion (Brown)
// The pixel size s (mm) is a constant of the sensor.
//
// Camera point (X, Y, Z) -> virtual point (x_v, y_v, v):
//   b_L = f_L Z / (Z - f_L),  x_mla = (X, Y) b_L0 / Z,  x_mla_d = distort(x_mla)
//   (x_v, y_v) = c + x_mla_d b_L / (b_L0 s),  v = (b_L - b_L0) / B
// Micro image k with micro-image centre c_k (white image): its lens centre
// l_k = c + (c_k - c) b_L0 / (b_L0 + B) and the point images at
//   p_k = l_k + (x_v - l_k) / v.

#include "processing/camera_model.h"

#include <Eigen/Core>

#include <array>

namespace lifmcr::registration {

inline constexpr int kIntrinsicsSize = 9;
using IntrinsicsVector = std::array<double, kIntrinsicsSize>;

// From / to the processing model (FromVector sets the principal point;
// ToVector takes the image centre where the intrinsics give none).
IntrinsicsVector ToVector(const processing::CameraIntrinsics& k);
processing::CameraIntrinsics FromVector(const IntrinsicsVector& v,
                                        const processing::CameraIntrinsics& sensor);

// Virtual point of a camera point; false when the point is not in front of
// the main lens beyond its focal length.
template <typename T>
bool ProjectToVirtual(const T* k, double pixel_size_mm, const T* p_in_cam_mm, T* virtual_px) {
  const T& f = k[0];
  const T& b0 = k[1];
  const T& z = p_in_cam_mm[2];
  if (!(z > f)) return false;
  const T b_l = f * z / (z - f);
  const T xm = p_in_cam_mm[0] * b0 / z;
  const T ym = p_in_cam_mm[1] * b0 / z;
  const T r2 = xm * xm + ym * ym;
  const T radial = k[5] * r2 + k[6] * r2 * r2;
  const T xd = xm + xm * radial + k[7] * (r2 + T(2) * xm * xm) + T(2) * k[8] * xm * ym;
  const T yd = ym + ym * radial + k[8] * (r2 + T(2) * ym * ym) + T(2) * k[7] * xm * ym;
  const T scale = b_l / (b0 * pixel_size_mm);
  virtual_px[0] = k[3] + xd * scale;
  virtual_px[1] = k[4] + yd * scale;
  virtual_px[2] = (b_l - b0) / k[2];
  return true;
}

// Image of a virtual point in the micro image centred at c_k.
template <typename T>
void ProjectToMicroImage(const T* k, const T* virtual_px, const Eigen::Vector2d& c_k,
                         T* micro_px) {
  const T lambda = k[1] / (k[1] + k[2]);
  for (int a = 0; a < 2; ++a) {
    const T l = k[3 + a] + (T(c_k[a]) - k[3 + a]) * lambda;
    micro_px[a] = l + (virtual_px[a] - l) / virtual_px[2];
  }
}

}  // namespace lifmcr::registration
