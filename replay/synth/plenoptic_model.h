#pragma once
// The forward model of a focused plenoptic camera that `lifmcr synth` renders
// with. It is the ground truth that processing/ (LiFCal's inverse model) is
// tested against, so it is written out here on its own.
//
// Geometry (processing/camera_model.h, docs/processing.md). Camera frame: origin at
// the main-lens centre, x right, y down, z along the optical axis. Image side:
// z is the distance behind the main lens; lateral coordinates are mirrored so
// that the image is upright (the sensor is read out rotated by 180 degrees), as
// in LiFCal: an object point (X, Y, Z) images at
//   b_L = f_L Z / (Z - f_L),   x_m = X b_L / Z,   y_m = Y b_L / Z     (thin lens)
// The MLA is the plane z = b_L0, the sensor the plane z = b_L0 + B. A raw pixel
// p (0-based, pixel centres at integers) sits at x_s = (p - c) s with c the
// principal point, the image centre ((W-1)/2, (H-1)/2).
//
// Virtual depth: v = (b_L - b_L0) / B. Galilean mode: v > 1 puts the virtual
// image behind the sensor.
//
// MLA. Micro-image centres c_k form the hex lattice of the Raytrix XML
// (config/mla.h): in y-up coordinates relative to the reference lens,
//   c(i, j) = R(theta) D (i (1, 0) + j (1/2, sqrt(3)/2)),
// lens type (i - j) mod 3 (XML id; type 1 at +lens_base_x, type 2 at
// +lens_base_y: the same colouring as LiFCal's `gridX mod 3`). A micro-image
// centre is the micro-lens centre seen from the main-lens centre, so the lens
// centre is L_k = c_k b_L0 / (b_L0 + B) (metric), on the possibly tilted MLA
// plane.
//
// Rendering a raw pixel: its chief ray runs from the sensor point P through
// L_k to the main lens, which it meets at M; the thin lens maps that line to
// the object-side ray from (M, 0) with direction (Q_x / f_L, Q_y / f_L, 1),
// Q the line's point at z = f_L. The pixel is lit if |M| <= A / 2 (A = f_L / N
// the aperture): so each micro image is the main-lens aperture seen through
// its micro lens, a disc of diameter A B / (b_L0 s) px around c_k.
//
// Micro-image position of a virtual point X_v (lateral x_v px, depth v):
//   p_k = l_k + (x_v - l_k) / v,   l_k = L_k / s   (untilted MLA)
// and with c_k in place of l_k the disparity is biased by (1 - lambda) v,
// lambda = b_L0 / (b_L0 + B) (processing/camera_model.h).
//
// Defocus: a micro lens of focal length f_t images the point at v sharply when
// B / f_t = 1 - 1 / v; otherwise a point spreads to a disc of diameter
//   rho = d (1 - 1/v - B/f_t),   d = micro-lens pitch = D s b_L0 / (b_L0 + B),
// so type t is sharp (rho <= sharp_blur_px) for
//   1 - 1/v in [B/f_t - tau, B/f_t + tau],   tau = sharp_blur_px s / d.
//
// Distortion (LiFCal): radial k1, k2 and tangential p1, p2 act on the central
// projection onto the MLA plane, x_mla = x_m b_L0 / b_L (mm):
//   x_d = x_u + x_u (k1 r^2 + k2 r^4) + (p1 (r^2 + 2 x^2) + 2 p2 x y, p2 (r^2 + 2 y^2) + 2 p1 x y).
//
// Totally focused (TF) grid: W/2 x H/2; TF pixel (u, w) is the orthographic
// sample of the virtual image at raw position (2u + 0.5, 2w + 0.5). Its object
// ray passes through the front focal point (0, 0, f_L) with direction
// (x_m / f_L, y_m / f_L, 1): the TF image is a pinhole image with its centre at
// the front focal point, which is why an all-in-focus pinhole render is its
// ground truth. (The paper's projX/projY re-projects onto a pinhole at the
// main-lens centre instead; processing/ converts.)

#include "config/mla.h"
#include "replay/synth/synth_params.h"

#include <Eigen/Core>

#include <array>
#include <optional>

namespace lifmcr::synth {

struct Ray {
  Eigen::Vector3d origin;     // camera frame, mm
  Eigen::Vector3d direction;  // not normalised; z component 1
};

struct MicroLens {
  int i = 0, j = 0;           // lattice index (axial hex coordinates)
  int type = 0;               // XML lens-type id 0..2
  Eigen::Vector2d center_px;  // c_k, micro-image centre (raw pixels)
  Eigen::Vector3d lens_mm;    // L_k, image side (x, y mirrored-upright, z from main lens)
};

// What one raw pixel sees.
struct PixelSample {
  MicroLens lens;
  Ray ray;                // object-side chief ray (camera frame)
  double coverage = 0.0;  // share of the micro-lens bundle inside the main-lens aperture
  double falloff = 0.0;   // cos^4 falloff
  double weight = 0.0;    // coverage * falloff
  double radius_px = 0;   // |p - c_k|
};

class PlenopticModel {
 public:
  explicit PlenopticModel(const SynthCameraParams& params);

  const SynthCameraParams& params() const { return p_; }
  int width() const { return p_.width_px; }
  int height() const { return p_.height_px; }
  int tf_width() const { return p_.width_px / 2; }
  int tf_height() const { return p_.height_px / 2; }
  Eigen::Vector2d principal_point_px() const { return principal_px_; }
  double aperture_mm() const { return p_.main_focal_length_mm / p_.f_number; }
  double micro_lens_pitch_mm() const;  // d
  double micro_image_disc_px() const;  // A B / (b_L0 s)

  // Nominal lattice (the one the written XML describes).
  Eigen::Vector2d LatticeCenterPx(int i, int j) const;
  static int LensType(int i, int j);
  // Lens (i, j) with its true micro-image centre (differs from the lattice
  // only for a tilted MLA).
  MicroLens Lens(int i, int j) const;
  // Lattice index of the micro image nearest to p (hex rounding).
  void NearestLens(const Eigen::Vector2d& p_px, int* i, int* j) const;

  // Thin lens: v of an object at depth z (mm) and back.
  double VirtualDepthOfDepth(double z_mm) const;
  double DepthOfVirtualDepth(double v) const;
  // Virtual image of a point in the camera frame: (x_v px, y_v px, v),
  // distortion included.
  Eigen::Vector3d VirtualPoint(const Eigen::Vector3d& p_in_cam) const;
  // Where the virtual point (x_v, y_v, v) appears in the micro image of `lens`.
  Eigen::Vector2d ProjectThroughLens(const MicroLens& lens,
                                     const Eigen::Vector3d& virtual_px) const;

  // The chief ray of raw pixel p; nullopt when p lies outside every micro
  // image (dark). `ray` ignores distortion: with distortion the object-side
  // locus is not a straight line, and renderers start from `ray` and iterate
  // with RawLineAt and ObjectRayOfImagePoint.
  std::optional<PixelSample> TraceRawPixel(const Eigen::Vector2d& p_px) const;
  // The same for a pixel known to belong to `lens`.
  std::optional<PixelSample> TraceThroughLens(const Eigen::Vector2d& p_px,
                                              const MicroLens& lens) const;
  bool has_distortion() const { return has_distortion_; }

  // Object ray of TF pixel (u, w), see header comment (undistorted part).
  Ray TfPixelRay(const Eigen::Vector2d& tf_px) const;

  // Image-side lines: the raw pixel's chief-ray line (through P and L_k) and
  // the TF pixel's line parallel to the axis, evaluated at image distance b.
  Eigen::Vector3d RawLineAt(const PixelSample& sample, const Eigen::Vector2d& p_px,
                            double b_mm) const;
  Eigen::Vector3d TfLineAt(const Eigen::Vector2d& tf_px, double b_mm) const;
  // With distortion: the ray from the main-lens centre that holds the object
  // point whose (distorted) image is x_img = (x, y, b); the object point is
  // on it at depth z = f_L b / (b - f_L). Renderers iterate on z.
  Ray ObjectRayOfImagePoint(const Eigen::Vector3d& x_img) const;
  double ImageDistanceOfDepth(double z_mm) const;  // b = f_L z / (z - f_L)

  // Defocus disc diameter (px) of lens type t at virtual depth v.
  double BlurDiameterPx(int type, double v) const;
  // The virtual-depth range in which type t is sharp (min, max), max capped at 100.
  Eigen::Vector2d SharpRange(int type) const;
  // Total covering plane: v at which neighbouring micro images start to share
  // points, 2 D / (disc - 2 border).
  double TotalCoveringPlane() const;

  // The MLA file: the nominal lattice, or for a tilted MLA the least-squares
  // lattice through the true centres; depth ranges from SharpRange.
  MlaCalibration ToMlaCalibration() const;

  // LiFCal distortion in the MLA plane (mm) and its fixed-point inverse.
  Eigen::Vector2d Distort(const Eigen::Vector2d& x_mla) const;
  Eigen::Vector2d Undistort(const Eigen::Vector2d& x_mla_distorted) const;

 private:
  Eigen::Vector3d SensorPoint(const Eigen::Vector2d& p_px) const;
  Eigen::Vector3d LensCenter3d(const Eigen::Vector2d& lattice_px) const;

  SynthCameraParams p_;
  Eigen::Vector2d principal_px_;
  Eigen::Vector2d reference_px_;  // lattice origin in image pixels
  Eigen::Matrix2d lattice_;       // columns: image-pixel steps of i and j
  Eigen::Matrix2d lattice_inv_;
  Eigen::Matrix3d mla_tilt_;
  bool tilted_ = false;
  bool has_distortion_ = false;
};

}  // namespace lifmcr::synth
