#pragma once
// The paper's 3D RANSAC (section "3D transformation estimation via RANSAC"):
// the rigid dst_from_src between matched 3D points, src measured by a
// plenoptic camera (each point with its own, strongly anisotropic
// uncertainty) and dst the reference map.
//
// Noise model: each point's covariance Sigma_i of
// registration/estimators/plenoptic_point_noise.h (along the viewing ray, growing
// quadratically with distance).
//
// Residual of match i for dst_from_src = (R, t), in the src (camera) frame,
// where the map's isotropic noise keeps its shape under any rotation:
//   e_i = p_i - R^T (q_i - t),   C_i = Sigma_i + sigma_map^2 I,
//   z_i = L_i^-1 e_i,  L_i L_i^T = C_i       (whitened: |z_i| in sigma units).
// Robust core: LO-RANSAC (registration/estimators/ransac.h) with MSAC on |z_i|.
//   Prefilter: rigid motions keep distances, so for inliers i, j
//   | |p_i - p_j| - |q_i - q_j| | <= k sqrt(tr C_i + tr C_j), k = max_error;
//   each match is tested against up to `prefilter_partners` others and kept
//   when it agrees with at least prefilter_keep_ratio times the best count
//   (TEASER++'s pairwise-invariant idea, PCL's polygon test). The same test
//   rejects a degenerate or inconsistent minimal sample before it is solved.
//   Hypotheses: Kabsch on 3 points (registration/estimators/rigid_fit.h).
//   Local optimisation: Umeyama refit on the inliers, weighted by
//   3 / tr C_i, repeated while it lowers the MSAC cost; then Gauss-Newton on
//   the truncated quadratic loss of |z_i| (the anisotropic weighting, which
//   the isotropic refit cannot express).
//   Final refinement: Ceres over the inliers on |z_i| with a Cauchy loss,
//   rotation on ceres::EigenQuaternionManifold, repeated (at most 3 times)
//   until the inlier set no longer changes.
//   Covariance: s^2 (J^T J)^-1 of z at the final pose, s^2 = sum |z|^2 /
//   (3 n - 6), in the convention of registration/estimators/pose_covariance.h.

#include "config/error.h"
#include "config/frames.h"
#include "processing/camera_model.h"
#include "registration/estimators/plenoptic_point_noise.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/estimators/ransac.h"

#include <Eigen/Core>

#include <span>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct Rigid3dOptions {
  // max_error: inlier threshold on |z_i| (sigma units).
  RansacOptions ransac{.max_error = 3.0};
  double map_sigma_mm = 0.5;         // isotropic noise of the map points (>= 0)
  bool prefilter = true;             // pairwise-distance consistency prefilter
  int prefilter_partners = 200;      // partners each match is tested against (>= 1)
  double prefilter_keep_ratio = 0.5;  // of the best agreement count, in (0, 1]
  int lo_iterations = 3;             // Umeyama refits per local optimisation (>= 1)
  bool final_refinement = true;      // Ceres refinement after RANSAC
  double loss_scale = 1.0;           // Cauchy scale of the final refinement (sigma units, > 0)
  int max_refine_iterations = 30;    // Ceres iterations (>= 1)
  int min_inliers = 12;              // fewer inliers: the pose is rejected (>= 3)

  Status Check() const;
};

// The matches, index-aligned; `src_covariance` may be empty (1 mm^2 isotropic).
struct Rigid3dInput {
  std::span<const Eigen::Vector3d> points_in_src;   // p_i, measured (mm)
  std::span<const Eigen::Matrix3d> src_covariance;  // Sigma_i (mm^2)
  std::span<const Eigen::Vector3d> points_in_dst;   // q_i, the map (mm)
};

struct Rigid3dResult {
  bool success = false;
  Pose dst_from_src = Pose::Identity();
  Covariance6 covariance = Covariance6::Zero();  // of dst_from_src
  std::size_t num_inliers = 0;
  std::size_t num_prefiltered = 0;  // matches that passed the prefilter
  double rmse_sigma = 0;            // RMS of |z_i| over the inliers
  double rmse_mm = 0;               // RMS of |e_i| over the inliers
  std::vector<char> inlier_mask;
  RansacReport ransac;
  int refine_iterations = 0;
  double time_ms = 0;
  std::string status = "not run";

  // "3D RANSAC ok: 640/2000 inliers (1100 after prefilter), rmse 0.93 sigma / 4.1 mm, ...".
  std::string BriefReport() const;
};

// The estimator the RANSAC core runs over the matches `active` (indices into
// the input). Model = dst_from_src.
class RigidPointEstimator {
 public:
  using Model = Pose;
  static constexpr int kSampleSize = 3;

  // `whitening[i]` = L_i^-1, `spread2[i]` = tr C_i.
  RigidPointEstimator(const Rigid3dInput& input, std::span<const Eigen::Matrix3d> whitening,
                      std::span<const double> spread2, std::span<const int> active,
                      double max_error, int lo_iterations);

  std::size_t NumData() const { return active_.size(); }
  void Generate(std::span<const int> sample, std::vector<Model>* models);
  double Score(const Model& dst_from_src, double threshold2, double bound,
               std::size_t* num_inliers) const;
  double SquaredResidual(const Model& dst_from_src, std::size_t k) const;
  bool Refine(Model* dst_from_src, double threshold);
  // J^T J and J^T z of the whitened residuals below threshold2, in the
  // perturbation of pose_covariance.h; returns how many were used.
  std::size_t NormalEquations(const Model& dst_from_src, double threshold2,
                              Eigen::Matrix<double, 6, 6>* jtj,
                              Eigen::Matrix<double, 6, 1>* jtr) const;

 private:
  Rigid3dInput input_;
  std::span<const Eigen::Matrix3d> whitening_;
  std::span<const double> spread2_;
  std::span<const int> active_;
  double max_error_;
  int lo_iterations_;
  std::vector<int> inliers_;   // scratch of Refine (indices into the input)
  std::vector<double> weights_;  // 3 / tr C_i over the input
};

Rigid3dResult EstimateRigid3d(const Rigid3dInput& input, const Rigid3dOptions& options);

}  // namespace lifmcr::registration
