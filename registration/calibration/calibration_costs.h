#pragma once
// Internal to calibration: the bundle adjustment's residuals of a keypoint
// and of a plate corner in the raw micro images (calibration.h, step 3), and
// how a keypoint's observed micro-image positions are made. Shared by the
// solve (calibration.cpp) and its evaluation at the ground truth
// (calibration_truth.h).

#include "registration/features/calibration_frames.h"
#include "registration/calibration/plenoptic_projection.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Core>

#include <cmath>
#include <vector>

namespace lifmcr::registration::internal {

// A keypoint observation reprojected into the micro images that see it
// (calibration.h, step 3). Parameters: intrinsics, cam_from_world rotation
// (w, x, y, z) and translation, the point in the world.
//
// Position only (`depth_from_estimate`, a keypoint whose measured virtual
// depth is not to be trusted: keypoint_depth.h): the observed micro-image
// positions are made with the estimated point's own depth instead of the
// measured one. With the processed frame's geometry (lambda0, c0) and the
// estimate's lambda = b_L0 / (b_L0 + B) and depth v, the processed depth of
// that point is v' = 1 / (1 - lambda / lambda0 (1 - 1/v)) (equal micro-image
// positions, calibration.h), and the observed positions
//   p_k = l0_k + (x'(v') - l0_k) / v',   l0_k = c0 + (c_k - c0) lambda0,
// with x'(v') the keypoint's virtual position as processed, moved along the
// main-lens ray from the depth its TF image was rendered at (the measured
// v'_r) to v':
//   x'(v') = c0 + (x' - c0) (lambda0 + v' (1 - lambda0)) / (lambda0 + v'_r (1 - lambda0)).
// TF pixel x at depth v'_r is sampled from the lenses around the point that
// looks at x (processing/tf_kernel.h), so a depth error moves the TF image's
// content along that ray, radially about c (bench_tf_shift --depth-scale):
// x' stands for the point (x'(v'), v') only on the ray. Without the move, a
// keypoint whose measured depth is 10 % off at 1000 px from c at v 3 would
// be held 4 raw px across its ray. The residuals then vanish for every depth
// along the keypoint's ray: they hold its position (the ray) and nothing of
// its depth, with the weight a position has in the micro images.
//
// Depth weight w (`depth_weight` < 1, a keypoint whose measured depth is
// less certain than its position: CalibrationOptions::keypoint_depth_sigma_rel):
// the observed positions are made with 1/v' = w / v'_measured + (1 - w) / v'
// (v' the estimate's, as above). p_k is linear in 1/v', so the residuals
// are those of the measured depth with the part that the depth error makes
// (along x' - l0_k) scaled by w, and the lateral part unchanged: the depth
// enters with sigma / w. w = 0 is position only.
//
// The measured depth's disagreement with the estimate, e = v'_measured /
// v'_estimated - 1 (DepthDisagreement), is what the calibration reweighs a
// keypoint's depth by after its first full solve
// (CalibrationOptions::keypoint_depth_robust).
struct MicroImageCost {
  std::vector<Eigen::Vector2d> observed_px, centres_px;
  double pixel_size_mm = 0;
  bool depth_from_estimate = false;
  double depth_weight = 1;  // in [0, 1]; depth_from_estimate: 0
  double inverse_v_measured = 1;  // 1 / v'_measured
  Eigen::Vector2d observed_virtual_px = Eigen::Vector2d::Zero();  // x' (position only)
  Eigen::Vector2d c0_px = Eigen::Vector2d::Zero();                // c0 (position only)
  double lambda0 = 1;                                             // (position only)

  template <typename T>
  bool operator()(const T* k, const T* q, const T* t, const T* p_in_w, T* residuals) const {
    T p_in_c[3];
    ceres::UnitQuaternionRotatePoint(q, p_in_w, p_in_c);
    for (int a = 0; a < 3; ++a) p_in_c[a] += t[a];
    return Residuals(k, p_in_c, residuals);
  }

  // v'_measured / v'_estimated - 1: the measured virtual depth's
  // relative disagreement with the estimated point (NaN where it does not
  // project), in the processed frame's geometry (above).
  double DepthDisagreement(const double* k, const double* q, const double* t,
                           const double* p_in_w) const {
    double p_in_c[3], virtual_px[3];
    ceres::UnitQuaternionRotatePoint(q, p_in_w, p_in_c);
    for (int a = 0; a < 3; ++a) p_in_c[a] += t[a];
    if (!ProjectToVirtual(k, pixel_size_mm, p_in_c, virtual_px)) return std::nan("");
    const double lambda = k[1] / (k[1] + k[2]);
    const double inverse_v = 1 - lambda / lambda0 * (1 - 1 / virtual_px[2]);
    return inverse_v / inverse_v_measured - 1;
  }

  template <typename T>
  bool Residuals(const T* k, const T* p_in_c, T* residuals) const {
    T virtual_px[3];
    if (!ProjectToVirtual(k, pixel_size_mm, p_in_c, virtual_px)) return false;
    const double w = depth_from_estimate ? 0.0 : depth_weight;
    return VirtualResiduals(k, virtual_px, w, residuals);
  }

  // The residuals of the virtual point `virtual_px` (the estimate's) with
  // the measured depth entering with weight w (above).
  template <typename T>
  bool VirtualResiduals(const T* k, const T* virtual_px, double w, T* residuals) const {
    if (w < 1) {
      const T lambda = k[1] / (k[1] + k[2]);
      const T inverse_v_processed =
          T(1) - lambda / T(lambda0) * (T(1) - T(1) / virtual_px[2]);
      if (!(inverse_v_processed > T(0)) || !(inverse_v_processed < T(1))) return false;
      // x'(v') / x' about c0: along the main-lens ray from v'_r to v' (above).
      const double v_rendered = 1 / inverse_v_measured;
      const T along = (T(lambda0) + (T(1) / inverse_v_processed) * T(1 - lambda0)) /
                      T(lambda0 + v_rendered * (1 - lambda0));
      for (std::size_t n = 0; n < centres_px.size(); ++n) {
        T micro[2];
        ProjectToMicroImage(k, virtual_px, centres_px[n], micro);
        for (int a = 0; a < 2; ++a) {
          const double l0 = c0_px[a] + (centres_px[n][a] - c0_px[a]) * lambda0;
          const T x_moved = T(c0_px[a]) + T(observed_virtual_px[a] - c0_px[a]) * along;
          // observed_px[n] = l0 + (x' - l0) / v'_measured (MakeMicroImageCost).
          const T estimated = T(l0) + (x_moved - T(l0)) * inverse_v_processed;
          const T observed = T(w * observed_px[n][a]) + T(1 - w) * estimated;
          residuals[2 * n + a] = micro[a] - observed;
        }
      }
      return true;
    }
    for (std::size_t n = 0; n < centres_px.size(); ++n) {
      T micro[2];
      ProjectToMicroImage(k, virtual_px, centres_px[n], micro);
      residuals[2 * n] = micro[0] - observed_px[n].x();
      residuals[2 * n + 1] = micro[1] - observed_px[n].y();
    }
    return true;
  }
};

// A plate corner: a fixed point of the plate frame. The detected corner is
// modelled as the projected corner moved by `inset` TF pixels (2 inset raw
// pixels in the virtual image) towards the projected marker centre; the
// inset is one parameter of the solve, separated from the scale by the
// distances between the markers' centres. With corners from the markers'
// edges (marker_edges.h) it stays near zero on the synthetic TF images
// (cornerSubPix's corners lay 0.3 TF px inside the square); it is kept for
// images whose blur is not symmetric. Residuals in the micro images that see
// the corner (with the virtual depth measured there: `micro`), else in the
// virtual image. Parameters: intrinsics, cam_from_world rotation (w, x, y,
// z) and translation, inset (TF px).
struct PlateCornerCost {
  Eigen::Vector3d p_in_w_mm, centre_in_w_mm;  // the corner and its marker's centre
  Eigen::Vector2d observed_px;                // virtual image (without micro images)
  MicroImageCost micro;                       // micro images (with)
  bool use_micro = false;
  double pixel_size_mm = 0;

  int residuals() const {
    return use_micro ? 2 * static_cast<int>(micro.centres_px.size()) : 2;
  }

  template <typename T>
  bool operator()(const T* k, const T* q, const T* t, const T* inset, T* residuals) const {
    T corner[3], centre[3];
    for (int a = 0; a < 3; ++a) {
      corner[a] = T(p_in_w_mm[a]);
      centre[a] = T(centre_in_w_mm[a]);
    }
    T corner_in_c[3], centre_in_c[3];
    ceres::UnitQuaternionRotatePoint(q, corner, corner_in_c);
    ceres::UnitQuaternionRotatePoint(q, centre, centre_in_c);
    for (int a = 0; a < 3; ++a) {
      corner_in_c[a] += t[a];
      centre_in_c[a] += t[a];
    }
    T x_v[3], centre_v[3];
    if (!ProjectToVirtual(k, pixel_size_mm, corner_in_c, x_v) ||
        !ProjectToVirtual(k, pixel_size_mm, centre_in_c, centre_v))
      return false;
    const T dx = centre_v[0] - x_v[0], dy = centre_v[1] - x_v[1];
    const T norm = ceres::sqrt(dx * dx + dy * dy);
    if (!(norm > T(1e-9))) return false;
    x_v[0] += T(2) * inset[0] * dx / norm;
    x_v[1] += T(2) * inset[0] * dy / norm;
    if (!use_micro) {
      residuals[0] = x_v[0] - observed_px.x();
      residuals[1] = x_v[1] - observed_px.y();
      return true;
    }
    return micro.VirtualResiduals(k, x_v, 1.0, residuals);
  }
};

// The principal point's prior: (c - c_initial) / sigma. Parameters:
// intrinsics (k[3], k[4] the principal point).
struct PrincipalPointPriorCost {
  Eigen::Vector2d initial_px;
  double sigma_px = 1;
  template <typename T>
  bool operator()(const T* k, T* residuals) const {
    residuals[0] = (k[3] - T(initial_px.x())) / T(sigma_px);
    residuals[1] = (k[4] - T(initial_px.y())) / T(sigma_px);
    return true;
  }
};

// The micro-image observations of virtual point x_v (calibration.h step 3):
// the max_lenses most central micro images that see it (at its measured
// depth); `position_only`: MicroImageCost::depth_from_estimate;
// `depth_weight`: MicroImageCost::depth_weight.
bool MakeMicroImageCost(const Eigen::Vector3d& x_v, const MicroImages& micro,
                        const Eigen::Vector2d& c0, double lambda0, int max_lenses, double s,
                        std::vector<int>* lenses, MicroImageCost* cost,
                        bool position_only = false, double depth_weight = 1);

// The cost of plate corner n of `frame`: its marker's centre the mean of the
// marker's four corners (all four are detected with the marker), observed at
// its TF position and, where its virtual depth is known, in the micro images
// MakeMicroImageCost picks. Used by the single-camera and the rig calibration.
PlateCornerCost MakePlateCornerCost(const CalibrationFrame& frame, std::size_t n,
                                    const MicroImages& micro, const Eigen::Vector2d& c0,
                                    double lambda0, int max_lenses, double pixel_size_mm,
                                    std::vector<int>* lenses);

}  // namespace lifmcr::registration::internal
