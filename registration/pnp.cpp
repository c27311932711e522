#include "registration/pnp.h"

#include "registration/ceres_pose_problem.h"
#include "registration/p3p.h"
#include "registration/plenoptic_point_noise.h"
#include "registration/pose_refinement.h"
#include "registration/tf_projection.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

namespace lifmcr::registration {
namespace {

Error FieldError(const std::string& field, const std::string& what) {
  return Error{"pnp options: " + field + ": " + what};
}

constexpr double kInf = std::numeric_limits<double>::infinity();

// Every selected match's residual in one residual block, the Cauchy loss
// applied inside: Ceres' per-block costs (building the problem, evaluating
// and scattering a block) were 1.3 ms per 1000 inliers, more than
// LO-RANSAC itself (bench_pnp). The objective is the same, 1/2 sum rho(s_i),
// rho(s) = c log(1 + s / c), c = loss_scale^2, s_i = |r_i|^2: each residual
// is replaced by r~ = g r with g = sqrt(rho(s) / s), so |r~|^2 = rho(s), and
// its Jacobian is the exact one of that map,
//   J~ = g J + h r r^T J,   h = (rho'(s) s - rho(s)) / (s^2 g),
// (g -> 1, h -> -1 / (2c) as s -> 0): Gauss-Newton on r~, where Ceres'
// per-block loss would use its corrector (Triggs et al.) on the same
// objective.
class TfReprojectionBatchCost final : public ceres::CostFunction {
 public:
  TfReprojectionBatchCost(const TfProjection& projection, const PnpInput& input,
                          std::span<const char> mask, double loss_scale_px)
      : projection_(projection), input_(input), c_(loss_scale_px * loss_scale_px) {
    for (std::size_t i = 0; i < mask.size(); ++i)
      if (mask[i]) selected_.push_back(i);
    set_num_residuals(static_cast<int>(2 * selected_.size()));
    mutable_parameter_block_sizes()->push_back(4);
    mutable_parameter_block_sizes()->push_back(3);
  }
  std::size_t size() const { return selected_.size(); }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
    const Eigen::Map<const Eigen::Vector3d> t(parameters[1]);
    const Eigen::Matrix3d rotation = q.toRotationMatrix();
    // Parameters q (x, y, z, w; ceres::EigenQuaternionManifold) and t of
    // cam_from_world. The manifold moves q to [cos|d|, sin|d| d/|d|] * q, a
    // rotation by 2 d on the left, so dr/dd = -2 J_p [R X]x; its Jacobian P
    // (4x3, d(q)/dd at d = 0) has orthonormal columns, so the ambient
    // Jacobian dr/dd P^T gives back dr/dd through the chain rule Ceres applies.
    // P: rows x, y, z = w I - [v]x, row w = -v^T (v the vector part of q).
    Eigen::Matrix<double, 4, 3> p;
    p.topRows<3>() = q.w() * Eigen::Matrix3d::Identity() - Skew(q.vec());
    p.row(3) = -q.vec().transpose();
    for (std::size_t k = 0; k < selected_.size(); ++k) {
      const std::size_t i = selected_[k];
      const Eigen::Vector3d rx = rotation * input_.points_in_world[i];
      Eigen::Vector2d tf;
      Eigen::Matrix<double, 2, 3> j_p;
      if (!projection_.WithJacobian(rx + t, &tf, &j_p)) return false;
      const Eigen::Vector2d r = tf - input_.tf_px[i];
      const double s = r.squaredNorm();
      double g = 1, h = -0.5 / c_;
      if (s > 1e-12 * c_) {
        const double rho = c_ * std::log1p(s / c_), rho1 = 1.0 / (1.0 + s / c_);
        g = std::sqrt(rho / s);
        h = (rho1 * s - rho) / (s * s * g);
      }
      residuals[2 * k] = g * r.x();
      residuals[2 * k + 1] = g * r.y();
      if (jacobians == nullptr) continue;
      // d(r~)/d(r): g I + h r r^T, then the chain through the pose.
      const Eigen::Matrix2d w = g * Eigen::Matrix2d::Identity() + h * r * r.transpose();
      const Eigen::Matrix<double, 2, 3> wj_p = w * j_p;
      if (jacobians[0] != nullptr) {
        Eigen::Map<Eigen::Matrix<double, 2, 4, Eigen::RowMajor>> j_q(jacobians[0] + 8 * k);
        j_q = (-2.0 * wj_p * Skew(rx)) * p.transpose();
      }
      if (jacobians[1] != nullptr) {
        Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> j_t(jacobians[1] + 6 * k);
        j_t = wj_p;
      }
    }
    return true;
  }

 private:
  const TfProjection& projection_;
  const PnpInput& input_;
  double c_;
  std::vector<std::size_t> selected_;
};

}  // namespace

Status PnpOptions::Check() const {
  if (Status s = ransac.Check(); !s.ok()) return Error{"pnp options: " + s.error().message};
  if (lo_iterations < 1) return FieldError("lo_iterations", "expected >= 1");
  if (!(loss_scale_px > 0) || !std::isfinite(loss_scale_px))
    return FieldError("loss_scale_px", "expected a finite number > 0");
  if (max_refine_iterations < 1) return FieldError("max_refine_iterations", "expected >= 1");
  if (min_inliers < 3) return FieldError("min_inliers", "expected >= 3");
  if (!(sigma_v_relative > 0) || !std::isfinite(sigma_v_relative))
    return FieldError("sigma_v_relative", "expected a finite number > 0");
  if (!(sample_check_sigmas > 0) || !std::isfinite(sample_check_sigmas))
    return FieldError("sample_check_sigmas", "expected a finite number > 0");
  return Status::Ok();
}

std::string PnpResult::BriefReport() const {
  char line[320];
  std::snprintf(line, sizeof line,
                "PnP %s: %zu/%zu inliers, rmse %.3f px, %d trials (%d samples left unsolved by the "
                "depth check), %d refinements, %d Ceres iterations, %.2f ms",
                status.c_str(), num_inliers, ransac.num_data, rmse_px, ransac.trials,
                samples_rejected, ransac.refinements, refine_iterations, time_ms);
  return line;
}

PlenopticPnpEstimator::PlenopticPnpEstimator(const processing::CameraModel& camera,
                                             const PnpInput& input, const PnpOptions& options)
    : camera_(camera),
      projection_(TfProjection::Of(camera)),
      input_(input),
      lo_iterations_(options.lo_iterations),
      sample_check_(options.sample_check),
      sample_check_k2_(options.sample_check_sigmas * options.sample_check_sigmas),
      sigma_v_relative_(options.sigma_v_relative) {
  const std::size_t n = input_.points_in_world.size();
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  bearings_.resize(n, Eigen::Vector3d::Constant(kNaN));
  bearing_known_.assign(n, 0);
  points_in_cam_.resize(n, Eigen::Vector3d::Constant(kNaN));
  spread2_.resize(n, kNaN);
  lo_subset_.reserve(n);
}

const Eigen::Vector3d& PlenopticPnpEstimator::Bearing(int i) {
  if (bearing_known_[i]) return bearings_[i];
  bearing_known_[i] = 1;
  if (static_cast<std::size_t>(i) >= input_.virtual_depth.size()) return bearings_[i];
  const double v = input_.virtual_depth[i];
  if (!std::isfinite(v) || v <= 0) return bearings_[i];
  const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(input_.tf_px[i]);
  const Eigen::Vector2d x = camera_.FeatureImagePoint({raw.x(), raw.y(), v});
  const double focal = camera_.FeatureFocalPx();
  const Eigen::Vector2d c = camera_.principal_point_px();
  bearings_[i] =
      Eigen::Vector3d((x.x() - c.x()) / focal, (x.y() - c.y()) / focal, 1.0).normalized();
  return bearings_[i];
}

void PlenopticPnpEstimator::PrepareSampleCheck(int i) {
  if (!std::isnan(spread2_[i])) return;
  const double v = input_.virtual_depth[i];
  const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(input_.tf_px[i]);
  points_in_cam_[i] = camera_.BackProject({raw.x(), raw.y(), v});
  // 1 mm^2 for the map point's error and the keypoint's lateral noise (pnp.h).
  spread2_[i] = PlenopticRayVariance(camera_, points_in_cam_[i], sigma_v_relative_ * v) + 1.0;
}

bool PlenopticPnpEstimator::SampleAgrees(std::span<const int> sample) {
  for (int k = 0; k < 3; ++k) PrepareSampleCheck(sample[k]);
  constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (const auto& pair : kPairs) {
    const int i = sample[pair[0]], j = sample[pair[1]];
    const double d_cam = (points_in_cam_[i] - points_in_cam_[j]).norm();
    const double d_world = (input_.points_in_world[i] - input_.points_in_world[j]).norm();
    const double d = d_cam - d_world;
    if (!(d * d <= sample_check_k2_ * (spread2_[i] + spread2_[j]))) return false;
  }
  return true;
}

void PlenopticPnpEstimator::Generate(std::span<const int> sample, std::vector<Model>* models) {
  std::array<Eigen::Vector3d, 3> bearings, points;
  for (int k = 0; k < 3; ++k) {
    bearings[k] = Bearing(sample[k]);
    if (!bearings[k].allFinite()) return;
    points[k] = input_.points_in_world[sample[k]];
  }
  if (sample_check_ && !SampleAgrees(sample)) {
    ++samples_rejected_;
    return;
  }
  SolveP3P(bearings, points, models);
}

double PlenopticPnpEstimator::Score(const Model& cam_from_world, double threshold2, double bound,
                                    std::size_t* num_inliers) const {
  const Eigen::Matrix3d r = cam_from_world.linear();
  const Eigen::Vector3d t = cam_from_world.translation();
  const std::size_t n = NumData();
  double cost = 0;
  std::size_t inliers = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r2 = projection_.SquaredError(r * input_.points_in_world[i] + t, input_.tf_px[i]);
    if (r2 < threshold2) {
      ++inliers;
      cost += r2;
    } else {
      cost += threshold2;
    }
    if (cost >= bound) break;  // cannot beat the best any more
  }
  *num_inliers = inliers;
  return cost;
}

template <typename Indices>
double PlenopticPnpEstimator::CostOver(const Model& cam_from_world, double threshold2,
                                       std::size_t count, Indices indices) const {
  const Eigen::Matrix3d r = cam_from_world.linear();
  const Eigen::Vector3d t = cam_from_world.translation();
  double cost = 0;
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = indices(k);
    cost += std::min(threshold2,
                     projection_.SquaredError(r * input_.points_in_world[i] + t, input_.tf_px[i]));
  }
  return cost;
}

template <typename Indices>
std::size_t PlenopticPnpEstimator::NormalEquationsOver(
    const Model& cam_from_world, double threshold2, std::size_t count, Indices indices,
    Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr, double* sum_squares) const {
  const Eigen::Matrix3d r = cam_from_world.linear();
  const Eigen::Vector3d t = cam_from_world.translation();
  jtj->setZero();
  jtr->setZero();
  *sum_squares = 0;
  std::size_t used = 0;
  Eigen::Vector2d tf;
  Eigen::Matrix<double, 2, 3> j_p;
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = indices(k);
    const Eigen::Vector3d rx = r * input_.points_in_world[i];
    if (!projection_.WithJacobian(rx + t, &tf, &j_p)) continue;
    const Eigen::Vector2d res = tf - input_.tf_px[i];
    const double r2 = res.squaredNorm();
    if (!(r2 < threshold2)) continue;
    // dp/d(dt) = I, dp/d(dr) = -[R X]x.
    Eigen::Matrix<double, 2, 6> j;
    j.leftCols<3>() = j_p;
    j.rightCols<3>() = -j_p * Skew(rx);
    jtj->noalias() += j.transpose() * j;
    jtr->noalias() += j.transpose() * res;
    *sum_squares += r2;
    ++used;
  }
  return used;
}

std::size_t PlenopticPnpEstimator::NormalEquations(const Model& cam_from_world, double threshold2,
                                                   Eigen::Matrix<double, 6, 6>* jtj,
                                                   Eigen::Matrix<double, 6, 1>* jtr,
                                                   double* sum_squares) const {
  return NormalEquationsOver(
      cam_from_world, threshold2, NumData(), [](std::size_t k) { return k; }, jtj, jtr,
      sum_squares);
}

bool PlenopticPnpEstimator::Refine(Model* cam_from_world, double threshold) {
  const double t2 = threshold * threshold;
  lo_subset_.clear();
  for (std::size_t i = 0; i < NumData(); ++i)
    if (SquaredResidual(*cam_from_world, i) < 9 * t2) lo_subset_.push_back(static_cast<int>(i));
  const auto subset = [this](std::size_t k) { return static_cast<std::size_t>(lo_subset_[k]); };
  double sum_squares = 0;
  return LevenbergMarquardt(
      cam_from_world, lo_iterations_,
      [&](const Pose& pose, Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr) {
        return NormalEquationsOver(pose, t2, lo_subset_.size(), subset, jtj, jtr, &sum_squares);
      },
      [&](const Pose& pose) { return CostOver(pose, t2, lo_subset_.size(), subset); });
}

int RefinePnpCeres(const processing::CameraModel& camera, const PnpInput& input,
                   std::span<const char> mask, double loss_scale_px, int max_iterations,
                   Pose* cam_from_world) {
  const TfProjection projection = TfProjection::Of(camera);
  auto cost = std::make_unique<TfReprojectionBatchCost>(projection, input, mask, loss_scale_px);
  if (cost->size() < 3) return -1;
  return SolveCeresPoseBlock(cost.release(), max_iterations, cam_from_world);
}

PnpResult EstimatePlenopticPnp(const processing::CameraModel& camera, const PnpInput& input,
                               const PnpOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  PnpResult result;
  const auto finish = [&](std::string status) {
    result.status = std::move(status);
    result.time_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
  };
  const std::size_t n = input.points_in_world.size();
  if (input.tf_px.size() != n || (!input.virtual_depth.empty() && input.virtual_depth.size() != n))
    return finish("inputs of different lengths");
  if (n < static_cast<std::size_t>(options.min_inliers)) {
    result.ransac.num_data = n;
    return finish("too few matches (" + std::to_string(n) + ")");
  }
  PlenopticPnpEstimator estimator(camera, input, options);
  Pose pose;
  result.ransac = Ransac(options.ransac, estimator, &pose);
  result.samples_rejected = estimator.samples_rejected();
  if (!result.ransac.success) return finish("no pose hypothesis");

  const double t2 = options.ransac.max_error * options.ransac.max_error;
  const auto mark_inliers = [&] {
    result.num_inliers = 0;
    for (std::size_t i = 0; i < n; ++i) {
      result.inlier_mask[i] = estimator.SquaredResidual(pose, i) < t2;
      result.num_inliers += result.inlier_mask[i];
    }
  };
  result.inlier_mask = result.ransac.inlier_mask;
  // Refit until the inlier set settles (at most 3 times).
  for (int round = 0; options.final_refinement && round < 3; ++round) {
    const std::vector<char> previous = result.inlier_mask;
    const int iterations = RefinePnpCeres(camera, input, result.inlier_mask, options.loss_scale_px,
                                          options.max_refine_iterations, &pose);
    if (iterations < 0) break;
    result.refine_iterations += iterations;
    mark_inliers();
    if (result.inlier_mask == previous) break;
  }
  mark_inliers();
  result.cam_from_world = pose;
  Eigen::Matrix<double, 6, 6> jtj;
  Eigen::Matrix<double, 6, 1> jtr;
  double sum_squares = 0;
  const std::size_t used = estimator.NormalEquations(pose, t2, &jtj, &jtr, &sum_squares);
  if (used > 0) result.rmse_px = std::sqrt(sum_squares / static_cast<double>(used));
  if (used > 3) {
    const double sigma2 = sum_squares / static_cast<double>(2 * used - 6);
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(jtj);
    result.covariance = sigma2 * ldlt.solve(Eigen::Matrix<double, 6, 6>::Identity());
  }
  if (result.num_inliers < static_cast<std::size_t>(options.min_inliers))
    return finish("too few inliers (" + std::to_string(result.num_inliers) + " < " +
                  std::to_string(options.min_inliers) + ")");
  result.success = true;
  return finish("ok");
}

}  // namespace lifmcr::registration
