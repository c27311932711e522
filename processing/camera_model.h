#pragma once
// LiFCal's plenoptic camera model (Fleith et al. 2024; docs/processing.md)
// and the paper's central perspective projection (eqs. projX, projY,
// section "Plenoptic PnP Method").
//
// Conventions (the same as replay/synth/plenoptic_model.h, the ground truth):
// camera frame at the main-lens centre, x right, y down, z forward (mm).
// Image side: z is the distance behind the main lens; lateral coordinates are
// mirrored so that the image is upright. Raw pixels are 0-based with centres
// at integers; the principal point c (where the main lens' optical axis
// meets the sensor) is the image centre ((W-1)/2, (H-1)/2) unless the
// intrinsics give it (a calibration estimates it).
//
// Symbols: f_L main-lens focal length, b_L0 main lens -> MLA, B MLA ->
// sensor, s pixel size (mm/px), v virtual depth (unit-less), b_L = b_L0 + v B
// the main-lens image distance of a point at virtual depth v.
//
// Virtual point (x_v, y_v, v), x_v in raw pixels, of a camera point (X, Y, Z):
//   b_L = f_L Z / (Z - f_L)                        (thin lens)
//   x_mla = X b_L0 / Z                             (central projection onto the MLA, mm)
//   x_mla_d = x_mla + x_mla (k1 r^2 + k2 r^4)
//             + (p1 (r^2 + 2 x^2) + 2 p2 x y, p2 (r^2 + 2 y^2) + 2 p1 x y)   (LiFCal)
//   x_v = c + x_mla_d b_L / (b_L0 s),   v = (b_L - b_L0) / B
// Back-projection inverts it: x_mla_d = (x_v - c) s b_L0 / b_L, undistort by
// LiFCal's fixed point x <- x_d - delta(x), Z = f_L b_L / (b_L - f_L),
// X = x_mla Z / b_L0.
//
// Micro-lens centre adjustment (LiFCal `mlCenterAdjustment`): a micro-image
// centre c_k (what a white image shows) is the micro-lens centre seen from
// the main-lens centre, so the lens centre in sensor pixels is
//   l_k = c + (c_k - c) lambda,   lambda = b_L0 / (b_L0 + B),
// and a virtual point images in micro image k at
//   p_k = l_k + (x_v - l_k) / v.
//
// Central perspective projection (paper eqs. projX/projY): the virtual point
// is projected through the main-lens centre onto the plane 2B behind the MLA:
//   x_proj = (x_v - c) (2B + b_L0) / (v B + b_L0) + c
// (v = 2 is left unchanged). With distortion corrected first, this is a
// pinhole image at the main-lens centre with focal length (b_L0 + 2B) / s px:
//   x_proj = c + X (b_L0 + 2B) / (Z s).
//
// Totally focused (TF) grid: W/2 x H/2; TF pixel (u, w) is the virtual image
// at raw position (2u + 0.5, 2w + 0.5).

#include "config/error.h"

#include <Eigen/Core>

#include <optional>
#include <string>

namespace lifmcr::processing {

struct CameraIntrinsics {
  double main_focal_length_mm = 25.0;     // f_L
  double mla_to_main_lens_mm = 24.8;      // b_L0
  double mla_to_sensor_mm = 0.2;          // B
  double pixel_size_mm = 0.0055;          // s
  int width_px = 1024;                    // raw width
  int height_px = 768;                    // raw height
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0;  // LiFCal distortion in the MLA plane (mm based)
  // c (raw pixels); unset: the image centre ((W-1)/2, (H-1)/2).
  std::optional<Eigen::Vector2d> principal_point_px;

  // c as given, else the image centre.
  Eigen::Vector2d PrincipalPointPx() const {
    return principal_point_px.value_or(Eigen::Vector2d((width_px - 1) / 2.0, (height_px - 1) / 2.0));
  }
  // Every field in range (c, when given, inside the image); the message
  // names the field.
  Status Check() const;
};

class CameraModel {
 public:
  explicit CameraModel(const CameraIntrinsics& intrinsics);

  const CameraIntrinsics& intrinsics() const { return k_; }
  Eigen::Vector2d principal_point_px() const { return c_; }
  double lambda() const { return lambda_; }  // b_L0 / (b_L0 + B)

  // Thin lens: metric depth Z (mm) <-> virtual depth v.
  double VirtualDepthOfDepth(double z_mm) const;
  double DepthOfVirtualDepth(double v) const;

  // Distortion in the MLA plane (mm) and LiFCal's fixed-point inverse.
  Eigen::Vector2d Distort(const Eigen::Vector2d& x_mla_mm) const;
  Eigen::Vector2d Undistort(const Eigen::Vector2d& x_mla_distorted_mm, int iterations = 20) const;

  // Camera point (mm) -> virtual point (x_v px, y_v px, v) and back.
  Eigen::Vector3d Project(const Eigen::Vector3d& p_in_cam_mm) const;
  Eigen::Vector3d BackProject(const Eigen::Vector3d& virtual_px) const;

  // Micro-lens centre of the micro image centred at c_k (raw pixels).
  Eigen::Vector2d LensCenterPx(const Eigen::Vector2d& micro_image_center_px) const;
  // Where virtual point (x_v, y_v, v) appears in the micro image centred at c_k.
  Eigen::Vector2d ProjectToMicroImage(const Eigen::Vector3d& virtual_px,
                                      const Eigen::Vector2d& micro_image_center_px) const;

  // Paper eqs. projX/projY on a virtual point as given (no distortion correction).
  Eigen::Vector2d CentralProjection(const Eigen::Vector3d& virtual_px) const;
  // Distortion corrected first, then projX/projY: the pinhole image of the
  // main-lens centre with focal length FeatureFocalPx().
  Eigen::Vector2d FeatureImagePoint(const Eigen::Vector3d& virtual_px) const;
  double FeatureFocalPx() const;  // (b_L0 + 2B) / s

  // TF grid <-> raw (virtual-image) pixels.
  static Eigen::Vector2d RawOfTf(const Eigen::Vector2d& tf_px) {
    return 2.0 * tf_px + Eigen::Vector2d(0.5, 0.5);
  }
  static Eigen::Vector2d TfOfRaw(const Eigen::Vector2d& raw_px) {
    return (raw_px - Eigen::Vector2d(0.5, 0.5)) / 2.0;
  }

 private:
  CameraIntrinsics k_;
  Eigen::Vector2d c_;
  double lambda_ = 1.0;
  bool distorted_ = false;
};

}  // namespace lifmcr::processing
