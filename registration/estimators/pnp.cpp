#include "registration/estimators/pnp.h"

#include "registration/estimators/p3p.h"
#include "registration/estimators/plenoptic_point_noise.h"
#include "registration/estimators/pose_refinement.h"
#include "registration/estimators/tf_projection.h"

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

// The two rows of d tf / d(dt, dr) (pose_covariance.h's perturbation) as
// columns: dp/d(dt) = I, dp/d(dr) = -[R X]x, and a row w^T of d tf / dp
// gives -w^T [R X]x = (R X x w)^T for the rotation.
Eigen::Matrix<double, 6, 2> PoseJacobianRows(const Eigen::Vector3d& rx,
                                             const Eigen::Matrix<double, 2, 3>& j_p) {
  Eigen::Matrix<double, 6, 2> jt;
  jt.col(0) << j_p.row(0).transpose(), rx.cross(j_p.row(0).transpose());
  jt.col(1) << j_p.row(1).transpose(), rx.cross(j_p.row(1).transpose());
  return jt;
}

// Datum i's share of CommonErrorRows (pnp.h): J_i^T e_x, J_i^T e_y,
// J_i^T (tf_i - c) and J_i^T perp(tf_i - c), c the TF principal point.
void AddCommonErrorRows(const Eigen::Matrix<double, 6, 2>& jt, const Eigen::Vector2d& tf,
                        const TfProjection& projection,
                        PlenopticPnpEstimator::CommonErrorRows* common) {
  common->col(0) += jt.col(0);
  common->col(1) += jt.col(1);
  const double ux = tf.x() - projection.tf_cx, uy = tf.y() - projection.tf_cy;
  common->col(2) += jt.col(0) * ux + jt.col(1) * uy;
  common->col(3) += jt.col(1) * ux - jt.col(0) * uy;
}

}  // namespace

Status PnpOptions::Check() const {
  if (Status s = ransac.Check(); !s.ok()) return Error{"pnp options: " + s.error().message};
  if (lo_iterations < 1) return FieldError("lo_iterations", "expected >= 1");
  if (lo_max_data < 6) return FieldError("lo_max_data", "expected >= 6");
  if (!(loss_scale_px > 0) || !std::isfinite(loss_scale_px))
    return FieldError("loss_scale_px", "expected a finite number > 0");
  if (max_refine_iterations < 1) return FieldError("max_refine_iterations", "expected >= 1");
  if (min_inliers < 3) return FieldError("min_inliers", "expected >= 3");
  if (!(sigma_v_relative > 0) || !std::isfinite(sigma_v_relative))
    return FieldError("sigma_v_relative", "expected a finite number > 0");
  if (!(sample_check_sigmas > 0) || !std::isfinite(sample_check_sigmas))
    return FieldError("sample_check_sigmas", "expected a finite number > 0");
  if (!(common_shift_sigma_px >= 0) || !std::isfinite(common_shift_sigma_px))
    return FieldError("common_shift_sigma_px", "expected a finite number >= 0");
  if (!(common_scale_sigma >= 0) || !std::isfinite(common_scale_sigma))
    return FieldError("common_scale_sigma", "expected a finite number >= 0");
  if (!(common_rotation_sigma_rad >= 0) || !std::isfinite(common_rotation_sigma_rad))
    return FieldError("common_rotation_sigma_rad", "expected a finite number >= 0");
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
                                             const PnpInput& input, const PnpOptions& options,
                                             Buffers* buffers)
    : camera_(camera),
      projection_(TfProjection::Of(camera)),
      input_(input),
      lo_iterations_(options.lo_iterations),
      lo_max_data_(options.final_refinement ? static_cast<std::size_t>(options.lo_max_data) : 0),
      sample_check_(options.sample_check),
      sample_check_k2_(options.sample_check_sigmas * options.sample_check_sigmas),
      sigma_v_relative_(options.sigma_v_relative),
      b_(buffers != nullptr ? *buffers : own_) {
  const std::size_t n = input_.points_in_world.size();
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  b_.bearings.assign(n, Eigen::Vector3d::Constant(kNaN));
  b_.bearing_known.assign(n, 0);
  b_.points_in_cam.assign(n, Eigen::Vector3d::Constant(kNaN));
  b_.spread2.assign(n, kNaN);
  b_.lo_subset.clear();
  b_.lo_subset.reserve(n);
}

const Eigen::Vector3d& PlenopticPnpEstimator::Bearing(int i) {
  if (b_.bearing_known[i]) return b_.bearings[i];
  b_.bearing_known[i] = 1;
  if (static_cast<std::size_t>(i) >= input_.virtual_depth.size()) return b_.bearings[i];
  const double v = input_.virtual_depth[i];
  if (!std::isfinite(v) || v <= 0) return b_.bearings[i];
  const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(input_.tf_px[i]);
  const Eigen::Vector2d x = camera_.FeatureImagePoint({raw.x(), raw.y(), v});
  const double focal = camera_.FeatureFocalPx();
  const Eigen::Vector2d c = camera_.principal_point_px();
  b_.bearings[i] =
      Eigen::Vector3d((x.x() - c.x()) / focal, (x.y() - c.y()) / focal, 1.0).normalized();
  return b_.bearings[i];
}

void PlenopticPnpEstimator::PrepareSampleCheck(int i) {
  if (!std::isnan(b_.spread2[i])) return;
  const double v = input_.virtual_depth[i];
  const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(input_.tf_px[i]);
  b_.points_in_cam[i] = camera_.BackProject({raw.x(), raw.y(), v});
  // 1 mm^2 for the map point's error and the keypoint's lateral noise (pnp.h).
  b_.spread2[i] = PlenopticRayVariance(camera_, b_.points_in_cam[i], sigma_v_relative_ * v) + 1.0;
}

bool PlenopticPnpEstimator::SampleAgrees(std::span<const int> sample) {
  for (int k = 0; k < 3; ++k) PrepareSampleCheck(sample[k]);
  constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (const auto& pair : kPairs) {
    const int i = sample[pair[0]], j = sample[pair[1]];
    const double d_cam = (b_.points_in_cam[i] - b_.points_in_cam[j]).norm();
    const double d_world = (input_.points_in_world[i] - input_.points_in_world[j]).norm();
    const double d = d_cam - d_world;
    if (!(d * d <= sample_check_k2_ * (b_.spread2[i] + b_.spread2[j]))) return false;
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
    Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr, double* sum_squares,
    char* mask, CommonErrorRows* common) const {
  const Eigen::Matrix3d r = cam_from_world.linear();
  const Eigen::Vector3d t = cam_from_world.translation();
  // The upper triangle of J^T J, mirrored at the end (42 + 12
  // multiply-adds a datum).
  double h[6][6] = {}, g[6] = {};
  *sum_squares = 0;
  std::size_t used = 0;
  Eigen::Vector2d tf;
  Eigen::Matrix<double, 2, 3> j_p;
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = indices(k);
    const Eigen::Vector3d rx = r * input_.points_in_world[i];
    // The residual first (an outlier needs no Jacobian).
    const double r2 = projection_.SquaredError(rx + t, input_.tf_px[i]);
    if (!(r2 < threshold2)) continue;
    projection_.WithJacobian(rx + t, &tf, &j_p);
    const Eigen::Vector2d res = tf - input_.tf_px[i];
    const Eigen::Matrix<double, 6, 2> jt = PoseJacobianRows(rx, j_p);
    const double* ju = jt.col(0).data();
    const double* jv = jt.col(1).data();
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b) h[a][b] += ju[a] * ju[b] + jv[a] * jv[b];
      g[a] += ju[a] * res.x() + jv[a] * res.y();
    }
    *sum_squares += r2;
    ++used;
    if (mask != nullptr) mask[i] = 1;
    if (common != nullptr) AddCommonErrorRows(jt, input_.tf_px[i], projection_, common);
  }
  for (int a = 0; a < 6; ++a) {
    (*jtr)(a) = g[a];
    for (int b = a; b < 6; ++b) (*jtj)(a, b) = (*jtj)(b, a) = h[a][b];
  }
  return used;
}

std::size_t PlenopticPnpEstimator::NormalEquations(const Model& cam_from_world, double threshold2,
                                                   Eigen::Matrix<double, 6, 6>* jtj,
                                                   Eigen::Matrix<double, 6, 1>* jtr,
                                                   double* sum_squares,
                                                   std::vector<char>* mask,
                                                   CommonErrorRows* common) const {
  if (mask != nullptr) mask->assign(NumData(), 0);
  if (common != nullptr) common->setZero();
  return NormalEquationsOver(
      cam_from_world, threshold2, NumData(), [](std::size_t k) { return k; }, jtj, jtr,
      sum_squares, mask != nullptr ? mask->data() : nullptr, common);
}

bool PlenopticPnpEstimator::Refine(Model* cam_from_world, double threshold) {
  const double t2 = threshold * threshold;
  b_.lo_subset.clear();
  for (std::size_t i = 0; i < NumData(); ++i)
    if (SquaredResidual(*cam_from_world, i) < 9 * t2) b_.lo_subset.push_back(static_cast<int>(i));
  // The cap (pnp.h): every k-th of them.
  if (lo_max_data_ > 0 && b_.lo_subset.size() > lo_max_data_) {
    const std::size_t stride = (b_.lo_subset.size() + lo_max_data_ - 1) / lo_max_data_;
    std::size_t kept = 0;
    for (std::size_t k = 0; k < b_.lo_subset.size(); k += stride)
      b_.lo_subset[kept++] = b_.lo_subset[k];
    b_.lo_subset.resize(kept);
  }
  const auto subset = [this](std::size_t k) { return static_cast<std::size_t>(b_.lo_subset[k]); };
  double sum_squares = 0;
  return LevenbergMarquardt(
      cam_from_world, lo_iterations_,
      [&](const Pose& pose, Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr) {
        return NormalEquationsOver(pose, t2, b_.lo_subset.size(), subset, jtj, jtr, &sum_squares,
                                   nullptr);
      },
      [&](const Pose& pose) { return CostOver(pose, t2, b_.lo_subset.size(), subset); });
}

PlenopticPnpEstimator::PolishResult PlenopticPnpEstimator::Polish(Model* cam_from_world,
                                                                  double threshold,
                                                                  std::span<const char> mask,
                                                                  PnpLoss loss,
                                                                  double loss_scale_px,
                                                                  bool plain_jtj) const {
  const double t2 = threshold * threshold;
  const double c = loss_scale_px * loss_scale_px;
  const Eigen::Matrix3d r = cam_from_world->linear();
  const Eigen::Vector3d t = cam_from_world->translation();
  // The weighted normal equations of the step and the plain J^T J of the
  // covariance, in one pass.
  Eigen::Matrix<double, 6, 6> hw = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g_w = Eigen::Matrix<double, 6, 1>::Zero();
  PolishResult out;
  Eigen::Vector2d tf;
  Eigen::Matrix<double, 2, 3> j_p;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (!mask[i]) continue;
    const Eigen::Vector3d rx = r * input_.points_in_world[i];
    const double s = projection_.SquaredError(rx + t, input_.tf_px[i]);
    if (!(s < t2)) continue;
    projection_.WithJacobian(rx + t, &tf, &j_p);
    const Eigen::Vector2d res = tf - input_.tf_px[i];
    const double w = RobustWeight(loss, c, s);
    const Eigen::Matrix<double, 6, 2> jt = PoseJacobianRows(rx, j_p);
    // Upper triangles (mirrored below), 21 entries each.
    const double* ju = jt.col(0).data();
    const double* jv = jt.col(1).data();
    // h collects only (1 - w) J^T J, where w != 1 (Huber: the few data
    // beyond its scale): J^T J = hw + h.
    const bool weighted = plain_jtj && w != 1.0;
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b) {
        const double jj = ju[a] * ju[b] + jv[a] * jv[b];
        hw(a, b) += w * jj;
        if (weighted) h(a, b) += (1.0 - w) * jj;
      }
      g_w(a) += w * (ju[a] * res.x() + jv[a] * res.y());
    }
    if (plain_jtj) AddCommonErrorRows(jt, input_.tf_px[i], projection_, &out.common);
    out.sum_squares += s;
    ++out.used;
  }
  hw = hw.selfadjointView<Eigen::Upper>();
  if (plain_jtj) out.jtj = hw + Eigen::Matrix<double, 6, 6>(h.selfadjointView<Eigen::Upper>());
  if (out.used < 3) return out;
  const Eigen::Matrix<double, 6, 1> delta = hw.ldlt().solve(-g_w);
  if (delta.allFinite()) *cam_from_world = Perturb(*cam_from_world, delta);
  return out;
}

std::size_t PlenopticPnpEstimator::Inliers(const Model& cam_from_world, double threshold2,
                                           std::vector<char>* mask, double* sum_squares) const {
  const Eigen::Matrix3d r = cam_from_world.linear();
  const Eigen::Vector3d t = cam_from_world.translation();
  mask->assign(NumData(), 0);
  *sum_squares = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < NumData(); ++i) {
    const double r2 = projection_.SquaredError(r * input_.points_in_world[i] + t, input_.tf_px[i]);
    if (!(r2 < threshold2)) continue;
    (*mask)[i] = 1;
    *sum_squares += r2;
    ++count;
  }
  return count;
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
  // Reused by every call on this thread (PlenopticPnpEstimator::Buffers).
  thread_local PlenopticPnpEstimator::Buffers buffers;
  PlenopticPnpEstimator estimator(camera, input, options, &buffers);
  Pose pose;
  result.ransac = Ransac(options.ransac, estimator, &pose);
  result.samples_rejected = estimator.samples_rejected();
  if (!result.ransac.success) return finish("no pose hypothesis");

  const double t2 = options.ransac.max_error * options.ransac.max_error;
  // The covariance's J^T J and the final inliers' squared residuals.
  Eigen::Matrix<double, 6, 6> jtj = Eigen::Matrix<double, 6, 6>::Zero();
  PlenopticPnpEstimator::CommonErrorRows common = PlenopticPnpEstimator::CommonErrorRows::Zero();
  double sum_squares = 0;
  // Whether jtj stands for the final inliers at the final pose (below).
  bool jtj_current = false;
  result.inlier_mask = result.ransac.inlier_mask;
  double start_cost = -1;  // the refinement's start cost, when known
  const Pose ransac_pose = pose;  // back to it if the refinement fails after the polish
  // LO fitted a subset (lo_max_data) on the truncated loss: iteratively
  // reweighted Gauss-Newton steps of the refinement's own loss over all of
  // RANSAC's inliers (our normal equations, 15-25 ns a datum) bring the
  // pose within a fraction of its standard deviation of the refinement's
  // optimum, so TinySolver stops after one Jacobian (~40 us per 1000
  // inliers) where it took two or three (pnp_refinement.cpp: its function
  // tolerance). (A Gauss-Newton step on the loss-corrected residuals of
  // robust_loss.h did worse than two reweighted ones for Cauchy.) The steps
  // are taken unchecked: TinySolver, next, evaluates the cost and refuses
  // steps that raise it.
  // The last pass's plain J^T J serves the covariance: it is taken at most
  // ~sqrt(n / lo_max_data) standard deviations from the final pose (0.05 mm
  // at 1 m for the bench's 1000 inliers), where J, a function of the camera
  // points, differs by ~1e-5 relative, against the 3 % uncertainty of s^2
  // from 1000 inliers; over RANSAC's inliers, which the refits below leave
  // unchanged to 0.5 % (else J^T J is formed anew).
  if (options.final_refinement) {
    // Iteratively reweighted (weights rho'(s)): Huber lands close enough in
    // one step, Cauchy's weights move more with the pose and take two (with
    // one the refinement took two Jacobians: bench_pnp 50 %, 0.25 -> 0.21 ms).
    const int steps = options.loss == PnpLoss::kCauchy ? 2 : 1;
    PlenopticPnpEstimator::PolishResult polish;
    for (int step = 0; step < steps; ++step)
      polish = estimator.Polish(&pose, options.ransac.max_error, result.inlier_mask, options.loss,
                                options.loss_scale_px, step + 1 == steps);
    jtj = polish.jtj;
    common = polish.common;
    jtj_current = polish.used > 3;
    // rho(s) <= s for both losses: an upper bound of the start's cost.
    start_cost = 0.5 * polish.sum_squares;
  }
  bool assessed = false;
  // Refit while the refit changed the inlier set by more than 0.5 % of its
  // size (at most 3 times): a datum that crosses t sits at the threshold,
  // where the Huber loss already weighs it down, and moves the pose by
  // about 1 / n of its spread; refitting for each such datum doubled the
  // time of a PnP at 50 % outliers (bench_pnp).
  for (int round = 0; options.final_refinement && round < 3; ++round) {
    const std::vector<char> previous = result.inlier_mask;
    const int iterations =
        RefinePnpCeres(camera, input, result.inlier_mask, options.loss, options.loss_scale_px,
                       options.max_refine_iterations, &pose, round == 0 ? start_cost : -1);
    if (iterations < 0) {
      // Nothing checked the polish's steps: RANSAC's pose, and J^T J there.
      if (round == 0) {
        pose = ransac_pose;
        jtj_current = false;
      }
      break;
    }
    result.refine_iterations += iterations;
    result.num_inliers = estimator.Inliers(pose, t2, &result.inlier_mask, &sum_squares);
    assessed = true;
    std::size_t changed = 0;
    for (std::size_t i = 0; i < n; ++i) changed += result.inlier_mask[i] != previous[i];
    if (200 * changed <= result.num_inliers) break;
    jtj_current = false;
  }
  if (!assessed || !jtj_current) {
    Eigen::Matrix<double, 6, 1> jtr;
    result.num_inliers = estimator.NormalEquations(pose, t2, &jtj, &jtr, &sum_squares,
                                                   &result.inlier_mask, &common);
  }
  result.cam_from_world = pose;
  const std::size_t used = result.num_inliers;
  if (used > 0) result.rmse_px = std::sqrt(sum_squares / static_cast<double>(used));
  if (used > 3) {
    const double sigma2 = sum_squares / static_cast<double>(2 * used - 6);
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(jtj);
    const Eigen::Matrix<double, 6, 6> jtj_inverse =
        ldlt.solve(Eigen::Matrix<double, 6, 6>::Identity());
    // The pose's response to the frame's common keypoint errors (pnp.h).
    const Eigen::Matrix<double, 6, 4> g = jtj_inverse * common;
    const Eigen::Vector4d common_variance(
        options.common_shift_sigma_px * options.common_shift_sigma_px,
        options.common_shift_sigma_px * options.common_shift_sigma_px,
        options.common_scale_sigma * options.common_scale_sigma,
        options.common_rotation_sigma_rad * options.common_rotation_sigma_rad);
    result.covariance =
        sigma2 * jtj_inverse + g * common_variance.asDiagonal() * g.transpose();
  }
  if (result.num_inliers < static_cast<std::size_t>(options.min_inliers))
    return finish("too few inliers (" + std::to_string(result.num_inliers) + " < " +
                  std::to_string(options.min_inliers) + ")");
  result.success = true;
  return finish("ok");
}

}  // namespace lifmcr::registration
