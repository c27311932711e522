#pragma once
// Plenoptic PnP (the paper's section "Plenoptic PnP Method"): the pose
// cam_from_world of a plenoptic camera from matches between 3D points of the
// reference map (world = w0, mm) and keypoints of its totally focused image.
//
// Observation i: the keypoint tf_i (TF pixels) and, when known, the virtual
// depth v_i of the TF image there.
//   Hypotheses: Lambda Twist P3P (registration/estimators/p3p.h) on the paper's central
//   perspective projection (eqs. projX/projY): the virtual point
//   (RawOfTf(tf_i), v_i) is undistorted and projected through the main-lens
//   centre, CameraModel::FeatureImagePoint, a pinhole of focal length
//   FeatureFocalPx(); its bearing is ((x - c) / f, (y - c) / f, 1).
//   Observations without a virtual depth are scored and refined, never sampled.
//   Sample check (what a plenoptic camera adds to P3P): the virtual depth
//   also places each observation in 3D, p_i = BackProject(RawOfTf(tf_i), v_i),
//   and a rigid motion keeps distances, so a sample of inliers has
//     | |p_i - p_j| - |X_i - X_j| | <= k sqrt(s_i^2 + s_j^2)
//   for each of its three pairs, s_i^2 = sigma_ray,i^2 + 1 mm^2 (the
//   point's variance along its viewing ray, registration/estimators/plenoptic_point_noise.h,
//   with sigma_v = sigma_v_relative v_i; 1 mm^2 for the map point and the
//   keypoint's lateral noise), k = sample_check_sigmas. A sample that fails
//   is not solved: at 80 % outliers nearly every sample holds an outlier, and the test
//   (six square roots) costs a fraction of a P3P and the scoring of its up
//   to four models. The trial count still counts these samples (they are
//   draws whose chance of being all-inlier the confidence is about).
//   Residual: r_i = pi(R X_i + t) - tf_i in TF pixels, pi the plenoptic
//   projection (registration/estimators/tf_projection.h). It does not use v_i, so
//   the depth map's noise does not enter the refined pose.
//   Robust core: LO-RANSAC (registration/estimators/ransac.h) with MSAC on |r_i|; local
//   optimisation by Gauss-Newton on the truncated quadratic loss over the
//   data within 3 t of the model being refined (only those within t count,
//   and a refinement moves few data across 3 t: at 80 % outliers it reads a
//   fifth of the data).
//   When the final refinement follows, the local optimisation fits at most
//   lo_max_data (256) of those data, evenly spaced, and scores on all
//   (Lebeda, Matas, Chum, "Fixing the locally optimized RANSAC", BMVC 2012,
//   cap the least-squares fits of LO the same way): its job is the inlier
//   set, for the trial count and the refinement's start, and 256 data place
//   the pose within sqrt(n / 256) of its final standard deviation (2 for
//   1000 inliers), far inside the 2 px threshold; the final refinement
//   reads all inliers. Without the final refinement LO reads all data.
//   Polish: iteratively reweighted Gauss-Newton steps of the refinement's
//   loss over RANSAC's inliers (one for Huber, two for Cauchy), so that the
//   refinement starts within a fraction of a standard deviation.
//   Final refinement: Ceres (ceres::TinySolver, registration/estimators/pnp_refinement.cpp),
//   Levenberg-Marquardt over the RANSAC inliers with the options' loss
//   (Huber by default; the live localizer runs Cauchy), rotation on
//   ceres::EigenQuaternionManifold, repeated (at most 3 times) while a refit
//   changes the inlier set by more than 0.5 % (pnp.cpp).
//   Covariance: Sigma = s^2 (J^T J)^-1 + G diag(s_b^2, s_b^2, s_k^2, s_w^2) G^T,
//   s^2 = sum r_i^2 / (2 n - 6) over the final inliers at the final pose,
//   J^T J from the polish's last pass (within ~2 standard deviations of the
//   final pose, where it is the same to ~1e-5; pnp.cpp) or, after a refit,
//   formed anew there; in the convention of
//   registration/estimators/pose_covariance.h (of cam_from_world).
//   The first term holds for keypoint errors independent between
//   keypoints; the residuals measure it. The second is what they cannot
//   measure: errors common to all keypoints of a frame, a small similarity
//   of the TF image about its principal point c, tf_i -> tf_i + b + k (tf_i
//   - c) + w perp(tf_i - c) (shift b in TF px, scale k, rotation w), which
//   the pose absorbs (a shift as a tilt, a scale as a translation along the
//   axis, a rotation as a roll) and which no number of inliers averages
//   out. To first order the pose moves by G (b, k, w), G = (J^T J)^-1
//   sum_i J_i^T [e_x, e_y, tf_i - c, perp(tf_i - c)]. They are the map's and
//   the TF image's systematic errors against the camera model, measured on
//   rendered sequences at the true pose (docs/registration.md,
//   "Covariance"): s_b = common_shift_sigma_px, s_k = common_scale_sigma,
//   s_w = common_rotation_sigma_rad.

#include "config/error.h"
#include "config/frames.h"
#include "processing/camera_model.h"
#include "registration/estimators/tf_projection.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/estimators/ransac.h"
#include "registration/estimators/robust_loss.h"

#include <Eigen/Core>

#include <span>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct PnpOptions {
  // max_error: inlier threshold on |r_i| in TF pixels.
  RansacOptions ransac{.max_error = 2.0};
  int lo_iterations = 8;           // Gauss-Newton steps per local optimisation (>= 1)
  // With the final refinement on, a local optimisation fits at most this
  // many of the data within 3 t (evenly spaced in their order; >= 6): see
  // the comment at the top.
  int lo_max_data = 256;
  bool final_refinement = true;    // Ceres refinement after RANSAC
  PnpLoss loss = PnpLoss::kHuber;  // the final refinement's loss (robust_loss.h)
  double loss_scale_px = 1.0;      // its scale (TF px, > 0)
  int max_refine_iterations = 30;  // Ceres iterations (>= 1)
  int min_inliers = 12;            // fewer inliers: the pose is rejected (>= 3)
  bool sample_check = true;        // the sample check of the comment above
  double sigma_v_relative = 0.007;   // its virtual-depth noise / v (processing: median 0.69 %), > 0
  double sample_check_sigmas = 5.0;  // its k (> 0)
  // The covariance's errors common to a frame's keypoints (comment at the
  // top): a shift (TF px), a scale and a rotation (rad) about the
  // principal point, >= 0.
  double common_shift_sigma_px = 0.15;
  double common_scale_sigma = 3e-4;
  double common_rotation_sigma_rad = 3e-4;

  Status Check() const;
};

// The matches, index-aligned. `virtual_depth` may be empty (no hypotheses can
// then be made) or hold NaN where the depth map had none.
struct PnpInput {
  std::span<const Eigen::Vector3d> points_in_world;  // X_i, mm
  std::span<const Eigen::Vector2d> tf_px;            // tf_i
  std::span<const double> virtual_depth;             // v_i
};

struct PnpResult {
  bool success = false;
  Pose cam_from_world = Pose::Identity();
  Covariance6 covariance = Covariance6::Zero();  // of cam_from_world
  std::size_t num_inliers = 0;
  double rmse_px = 0;  // over the final inliers, TF pixels
  std::vector<char> inlier_mask;
  RansacReport ransac;
  int refine_iterations = 0;  // Ceres iterations of the final refinement
  int samples_rejected = 0;   // minimal samples the sample check left unsolved
  double time_ms = 0;         // everything, RANSAC included
  std::string status = "not run";  // "ok" or why it failed

  // "PnP ok: 812/2000 inliers, rmse 0.41 px, 152 trials, 6 refinements, 3.1 ms".
  std::string BriefReport() const;
};

// The estimator the RANSAC core runs; public for tests and the localizer
// (which runs it with a predicted pose). Model = cam_from_world.
class PlenopticPnpEstimator {
 public:
  using Model = Pose;
  static constexpr int kSampleSize = 3;

  // sum_i J_i^T applied to a frame's common keypoint errors: columns
  // sum_i J_i^T e_x, sum_i J_i^T e_y (a shift), sum_i J_i^T (tf_i - c) (a
  // scale about the TF principal point c) and sum_i J_i^T perp(tf_i - c)
  // (a rotation about it, perp(x, y) = (-y, x)), over the same data as
  // J^T J.
  using CommonErrorRows = Eigen::Matrix<double, 6, 4>;

  // Per-datum scratch, sized to the input on construction. A caller that
  // estimates again and again passes its own (EstimatePlenopticPnp keeps
  // one per thread): sized once, it is not allocated anew each call, where
  // glibc's default policy returns the freed pages to the system and every
  // call page-faults them in again (bench_pnp: a quarter of a PnP's time).
  struct Buffers {
    std::vector<Eigen::Vector3d> bearings;      // datum i's unit bearing (NaN: no depth)
    std::vector<char> bearing_known;            // bearings[i] computed
    std::vector<Eigen::Vector3d> points_in_cam;  // p_i of the sample check
    std::vector<double> spread2;                // its s_i^2 (mm^2); NaN until computed
    std::vector<int> lo_subset;                 // Refine's data within 3 t
  };

  // `buffers` null: the estimator keeps its own.
  PlenopticPnpEstimator(const processing::CameraModel& camera, const PnpInput& input,
                        const PnpOptions& options, Buffers* buffers = nullptr);
  PlenopticPnpEstimator(const PlenopticPnpEstimator&) = delete;  // b_ may refer to own_
  PlenopticPnpEstimator& operator=(const PlenopticPnpEstimator&) = delete;

  std::size_t NumData() const { return input_.points_in_world.size(); }
  void Generate(std::span<const int> sample, std::vector<Model>* models);
  double Score(const Model& cam_from_world, double threshold2, double bound,
               std::size_t* num_inliers) const;
  double SquaredResidual(const Model& cam_from_world, std::size_t i) const {
    return projection_.SquaredError(cam_from_world * input_.points_in_world[i], input_.tf_px[i]);
  }
  bool Refine(Model* cam_from_world, double threshold);
  // One iteratively reweighted Gauss-Newton step of `loss` (weights
  // rho'(s_i) at the start; robust_loss.h) over the data with mask[i] != 0
  // and r_i < t (no cap), taken unchecked (pnp.cpp: TinySolver follows);
  // the plain J^T J and the sum of s_i of those data at the start pose.
  struct PolishResult {
    Eigen::Matrix<double, 6, 6> jtj = Eigen::Matrix<double, 6, 6>::Zero();
    CommonErrorRows common = CommonErrorRows::Zero();  // with jtj (below)
    std::size_t used = 0;     // data within the threshold at the start
    double sum_squares = 0;   // their sum of r_i^2
  };
  // `plain_jtj` false: PolishResult::jtj is left zero (a pass less of work).
  PolishResult Polish(Model* cam_from_world, double threshold, std::span<const char> mask,
                      PnpLoss loss, double loss_scale_px, bool plain_jtj) const;
  // The data with r_i^2 < threshold2 (mask 1) and the sum of their r_i^2;
  // returns their number.
  std::size_t Inliers(const Model& cam_from_world, double threshold2, std::vector<char>* mask,
                      double* sum_squares) const;
  // Minimal samples the sample check rejected so far.
  int samples_rejected() const { return samples_rejected_; }

  // J^T J and J^T r of the data whose squared residual is below threshold2
  // (all when infinite), in the perturbation of pose_covariance.h; returns
  // the number used and their sum of squared residuals; `mask` (when given)
  // receives 1 for the data used, 0 for the others; `common` (when given)
  // the CommonErrorRows of those data.
  std::size_t NormalEquations(const Model& cam_from_world, double threshold2,
                              Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr,
                              double* sum_squares, std::vector<char>* mask = nullptr,
                              CommonErrorRows* common = nullptr) const;

 private:
  // Whether sample (i, j, k) passes the sample check; its data's p_i and
  // s_i^2 are computed when first sampled (at 50 % outliers a call samples
  // a tenth of the data).
  bool SampleAgrees(std::span<const int> sample);
  void PrepareSampleCheck(int i);
  // NormalEquations and the MSAC cost over the data `indices(k)`, k < count.
  template <typename Indices>
  std::size_t NormalEquationsOver(const Model& cam_from_world, double threshold2, std::size_t count,
                                  Indices indices, Eigen::Matrix<double, 6, 6>* jtj,
                                  Eigen::Matrix<double, 6, 1>* jtr, double* sum_squares,
                                  char* mask, CommonErrorRows* common = nullptr) const;
  template <typename Indices>
  double CostOver(const Model& cam_from_world, double threshold2, std::size_t count,
                  Indices indices) const;

  processing::CameraModel camera_;
  TfProjection projection_;
  PnpInput input_;
  int lo_iterations_;
  std::size_t lo_max_data_;  // 0: no cap (no final refinement)
  bool sample_check_;
  double sample_check_k2_;
  double sigma_v_relative_;
  // Datum i's unit bearing from the main-lens centre (NaN when v_i is
  // unknown), computed when first sampled.
  const Eigen::Vector3d& Bearing(int i);
  Buffers own_;
  Buffers& b_;
  int samples_rejected_ = 0;
};

// The whole estimate: LO-RANSAC, Ceres refinement, covariance, final inliers.
PnpResult EstimatePlenopticPnp(const processing::CameraModel& camera, const PnpInput& input,
                               const PnpOptions& options);

// Ceres refinement of cam_from_world over the data with mask[i] != 0 (`loss`
// of scale loss_scale_px; registration/estimators/pnp_refinement.cpp); returns
// the iterations run, or -1 when Ceres reported no usable solution (the pose
// is then unchanged).
// `start_cost`: the objective at the start if the caller knows it (or an
// upper bound: it only sets the function tolerance), else negative.
int RefinePnpCeres(const processing::CameraModel& camera, const PnpInput& input,
                   std::span<const char> mask, PnpLoss loss, double loss_scale_px,
                   int max_iterations, Pose* cam_from_world, double start_cost = -1);

}  // namespace lifmcr::registration
