#include "registration/estimators/rigid_3d.h"

#include "registration/estimators/ceres_pose_problem.h"
#include "registration/estimators/pose_refinement.h"
#include "registration/estimators/rigid_fit.h"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>

namespace lifmcr::registration {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

Error FieldError(const std::string& field, const std::string& what) {
  return Error{"rigid 3d options: " + field + ": " + what};
}

// Whitened residual z = W (p - R^T (q - t)) of dst_from_src (q, t) for Ceres.
struct WhitenedPointResidual {
  WhitenedPointResidual(const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                        const Eigen::Matrix3d& w)
      : p(p), q(q), w(w) {}

  template <typename T>
  bool operator()(const T* rotation, const T* translation, T* residual) const {
    const Eigen::Quaternion<T> r(rotation[3], rotation[0], rotation[1], rotation[2]);
    const Eigen::Matrix<T, 3, 1> t = Eigen::Map<const Eigen::Matrix<T, 3, 1>>(translation);
    const Eigen::Matrix<T, 3, 1> e = p.cast<T>() - r.conjugate() * (q.cast<T>() - t);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> out(residual);
    out = w.cast<T>() * e;
    return true;
  }

  Eigen::Vector3d p, q;
  Eigen::Matrix3d w;
};

// Whether the distances of the pair (i, j) agree within k sigma.
bool PairAgrees(const Rigid3dInput& input, std::span<const double> spread2, double k, int i,
                int j) {
  const double dp = (input.points_in_src[i] - input.points_in_src[j]).norm();
  const double dq = (input.points_in_dst[i] - input.points_in_dst[j]).norm();
  const double d = dp - dq;
  return d * d <= k * k * (spread2[i] + spread2[j]);
}

}  // namespace

Status Rigid3dOptions::Check() const {
  if (Status s = ransac.Check(); !s.ok()) return Error{"rigid 3d options: " + s.error().message};
  if (!(map_sigma_mm >= 0) || !std::isfinite(map_sigma_mm))
    return FieldError("map_sigma_mm", "expected a finite number >= 0");
  if (prefilter_partners < 1) return FieldError("prefilter_partners", "expected >= 1");
  if (!(prefilter_keep_ratio > 0 && prefilter_keep_ratio <= 1))
    return FieldError("prefilter_keep_ratio", "expected 0 < ratio <= 1");
  if (lo_iterations < 1) return FieldError("lo_iterations", "expected >= 1");
  if (!(loss_scale > 0) || !std::isfinite(loss_scale))
    return FieldError("loss_scale", "expected a finite number > 0");
  if (max_refine_iterations < 1) return FieldError("max_refine_iterations", "expected >= 1");
  if (min_inliers < 3) return FieldError("min_inliers", "expected >= 3");
  return Status::Ok();
}

std::string Rigid3dResult::BriefReport() const {
  char line[256];
  std::snprintf(line, sizeof line,
                "3D RANSAC %s: %zu/%zu inliers (%zu after prefilter), rmse %.2f sigma / %.2f mm, "
                "%d trials, %d refinements, %d Ceres iterations, %.2f ms",
                status.c_str(), num_inliers, inlier_mask.size(), num_prefiltered, rmse_sigma,
                rmse_mm, ransac.trials, ransac.refinements, refine_iterations, time_ms);
  return line;
}

RigidPointEstimator::RigidPointEstimator(const Rigid3dInput& input,
                                         std::span<const Eigen::Matrix3d> whitening,
                                         std::span<const double> spread2,
                                         std::span<const int> active, double max_error,
                                         int lo_iterations)
    : input_(input),
      whitening_(whitening),
      spread2_(spread2),
      active_(active),
      max_error_(max_error),
      lo_iterations_(lo_iterations) {
  inliers_.reserve(active.size());
  weights_.resize(spread2.size());
  for (std::size_t i = 0; i < spread2.size(); ++i) weights_[i] = 3.0 / spread2[i];
}

void RigidPointEstimator::Generate(std::span<const int> sample, std::vector<Model>* models) {
  const int ids[3] = {active_[sample[0]], active_[sample[1]], active_[sample[2]]};
  for (int a = 0; a < 3; ++a)
    for (int b = a + 1; b < 3; ++b)
      if (!PairAgrees(input_, spread2_, max_error_, ids[a], ids[b])) return;
  Pose pose;
  if (FitRigidSubset(input_.points_in_src, input_.points_in_dst, {}, ids, &pose))
    models->push_back(pose);
}

double RigidPointEstimator::SquaredResidual(const Model& dst_from_src, std::size_t k) const {
  const int i = active_[k];
  const Eigen::Vector3d e = input_.points_in_src[i] -
                            dst_from_src.linear().transpose() *
                                (input_.points_in_dst[i] - dst_from_src.translation());
  return (whitening_[i] * e).squaredNorm();
}

double RigidPointEstimator::Score(const Model& dst_from_src, double threshold2, double bound,
                                  std::size_t* num_inliers) const {
  const Eigen::Matrix3d rt = dst_from_src.linear().transpose();
  const Eigen::Vector3d b = -rt * dst_from_src.translation();
  double cost = 0;
  std::size_t inliers = 0;
  for (const int i : active_) {
    const Eigen::Vector3d e = input_.points_in_src[i] - (rt * input_.points_in_dst[i] + b);
    const double r2 = (whitening_[i] * e).squaredNorm();
    if (r2 < threshold2) {
      ++inliers;
      cost += r2;
    } else {
      cost += threshold2;
    }
    if (cost >= bound) break;
  }
  *num_inliers = inliers;
  return cost;
}

bool RigidPointEstimator::Refine(Model* dst_from_src, double threshold) {
  const double t2 = threshold * threshold;
  std::size_t count = 0;
  double cost = Score(*dst_from_src, t2, kInf, &count);
  bool improved = false;
  // Umeyama refits (isotropic weights): fast, and they gather the inliers.
  for (int iteration = 0; iteration < lo_iterations_; ++iteration) {
    inliers_.clear();
    for (std::size_t k = 0; k < active_.size(); ++k)
      if (SquaredResidual(*dst_from_src, k) < t2) inliers_.push_back(active_[k]);
    Pose candidate;
    if (!FitRigidSubset(input_.points_in_src, input_.points_in_dst, weights_, inliers_,
                        &candidate))
      break;
    const double candidate_cost = Score(candidate, t2, kInf, &count);
    if (!(candidate_cost < cost)) break;
    cost = candidate_cost;
    *dst_from_src = candidate;
    improved = true;
  }
  // Then Gauss-Newton on the whitened residuals: isotropic weights cannot
  // express uncertainty along the rays, which is most of it.
  improved |= LevenbergMarquardt(
      dst_from_src, 2 * lo_iterations_,
      [&](const Pose& pose, Eigen::Matrix<double, 6, 6>* jtj, Eigen::Matrix<double, 6, 1>* jtr) {
        return NormalEquations(pose, t2, jtj, jtr);
      },
      [&](const Pose& pose) { return Score(pose, t2, kInf, &count); });
  return improved;
}

std::size_t RigidPointEstimator::NormalEquations(const Model& dst_from_src, double threshold2,
                                                 Eigen::Matrix<double, 6, 6>* jtj,
                                                 Eigen::Matrix<double, 6, 1>* jtr) const {
  // dz/d(dt) = W R^T, dz/d(dr) = -W R^T [q - t]x (pose_covariance.h perturbation).
  const Eigen::Matrix3d rt = dst_from_src.linear().transpose();
  const Eigen::Vector3d& t = dst_from_src.translation();
  jtj->setZero();
  jtr->setZero();
  std::size_t used = 0;
  for (const int i : active_) {
    const Eigen::Vector3d q_minus_t = input_.points_in_dst[i] - t;
    const Eigen::Vector3d z = whitening_[i] * (input_.points_in_src[i] - rt * q_minus_t);
    if (!(z.squaredNorm() < threshold2)) continue;
    Eigen::Matrix<double, 3, 6> j;
    j.leftCols<3>() = whitening_[i] * rt;
    j.rightCols<3>() = -j.leftCols<3>() * Skew(q_minus_t);
    jtj->noalias() += j.transpose() * j;
    jtr->noalias() += j.transpose() * z;
    ++used;
  }
  return used;
}

namespace {

// Ceres over the matches with mask[i] != 0; iterations run, or -1 when Ceres
// gave no usable solution (the pose is then unchanged).
int RefineRigidCeres(const Rigid3dInput& input, std::span<const Eigen::Matrix3d> whitening,
                     std::span<const char> mask, const Rigid3dOptions& options,
                     Pose* dst_from_src) {
  return SolveCeresPoseProblem(
      mask, options.loss_scale, options.max_refine_iterations,
      [&](std::size_t i) {
        return new ceres::AutoDiffCostFunction<WhitenedPointResidual, 3, 4, 3>(
            new WhitenedPointResidual(input.points_in_src[i], input.points_in_dst[i],
                                      whitening[i]));
      },
      dst_from_src);
}

}  // namespace

Rigid3dResult EstimateRigid3d(const Rigid3dInput& input, const Rigid3dOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  Rigid3dResult result;
  const auto finish = [&](std::string status) {
    result.status = std::move(status);
    result.time_ms = std::chrono::duration<double, std::milli>(
                         std::chrono::steady_clock::now() - start)
                         .count();
    return result;
  };
  const std::size_t n = input.points_in_src.size();
  if (input.points_in_dst.size() != n ||
      (!input.src_covariance.empty() && input.src_covariance.size() != n))
    return finish("inputs of different lengths");
  result.inlier_mask.assign(n, 0);
  if (n < static_cast<std::size_t>(options.min_inliers))
    return finish("too few matches (" + std::to_string(n) + ")");

  // Whitening L_i^-1 of C_i = Sigma_i + sigma_map^2 I, and tr C_i.
  std::vector<Eigen::Matrix3d> whitening(n);
  std::vector<double> spread2(n);
  const double map2 = options.map_sigma_mm * options.map_sigma_mm;
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Matrix3d c = input.src_covariance.empty() ? Eigen::Matrix3d::Identity()
                                                     : input.src_covariance[i];
    c.diagonal().array() += map2;
    const Eigen::LLT<Eigen::Matrix3d> llt(c);
    if (llt.info() != Eigen::Success) return finish("covariance of match " + std::to_string(i) +
                                                    " is not positive definite");
    whitening[i] = llt.matrixL().solve(Eigen::Matrix3d::Identity());
    spread2[i] = c.trace();
  }

  // Pairwise-distance consistency prefilter.
  std::vector<int> active(n);
  std::iota(active.begin(), active.end(), 0);
  if (options.prefilter) {
    std::mt19937_64 rng(options.ransac.seed ^ 0x9e3779b97f4a7c15ULL);
    const int partners = static_cast<int>(std::min<std::size_t>(options.prefilter_partners, n - 1));
    std::vector<int> agree(n, 0);
    for (std::size_t i = 0; i < n; ++i) {
      for (int k = 0; k < partners; ++k) {
        // All others when they are few, a random subset otherwise.
        std::size_t j = partners == static_cast<int>(n - 1) ? (k < static_cast<int>(i) ? k : k + 1)
                                                            : rng() % n;
        if (j == i) continue;
        agree[i] += PairAgrees(input, spread2, options.ransac.max_error, static_cast<int>(i),
                               static_cast<int>(j));
      }
    }
    const int best = *std::max_element(agree.begin(), agree.end());
    std::vector<int> kept;
    kept.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
      if (agree[i] >= options.prefilter_keep_ratio * best) kept.push_back(static_cast<int>(i));
    if (kept.size() >= static_cast<std::size_t>(options.min_inliers)) active = std::move(kept);
  }
  result.num_prefiltered = active.size();

  RigidPointEstimator estimator(input, whitening, spread2, active, options.ransac.max_error,
                                options.lo_iterations);
  Pose pose;
  result.ransac = Ransac(options.ransac, estimator, &pose);
  if (!result.ransac.success) return finish("no pose hypothesis");

  // Inliers over all matches (not only those the prefilter kept).
  const double t2 = options.ransac.max_error * options.ransac.max_error;
  const auto residual = [&](const Pose& dst_from_src, std::size_t i) -> Eigen::Vector3d {
    return input.points_in_src[i] -
           dst_from_src.linear().transpose() * (input.points_in_dst[i] - dst_from_src.translation());
  };
  const auto mark_inliers = [&](const Pose& dst_from_src) {
    result.num_inliers = 0;
    for (std::size_t i = 0; i < n; ++i) {
      result.inlier_mask[i] = (whitening[i] * residual(dst_from_src, i)).squaredNorm() < t2;
      result.num_inliers += result.inlier_mask[i];
    }
  };
  mark_inliers(pose);

  // Refit until the inlier set settles: inliers are decided at the current
  // pose, and a better pose may admit or reject a few.
  for (int round = 0; options.final_refinement && round < 3; ++round) {
    const std::vector<char> previous = result.inlier_mask;
    const int iterations = RefineRigidCeres(input, whitening, result.inlier_mask, options, &pose);
    if (iterations < 0) break;
    result.refine_iterations += iterations;
    mark_inliers(pose);
    if (result.inlier_mask == previous) break;
  }
  result.dst_from_src = pose;

  // Covariance and RMS over the final inliers; J of z wrt the perturbation
  // (dt, dr) of dst_from_src: dz/d(dt) = W R^T, dz/d(dr) = -W R^T [q - t]x.
  Eigen::Matrix<double, 6, 6> jtj = Eigen::Matrix<double, 6, 6>::Zero();
  double sum_z2 = 0, sum_e2 = 0;
  const Eigen::Matrix3d rt = pose.linear().transpose();
  for (std::size_t i = 0; i < n; ++i) {
    if (!result.inlier_mask[i]) continue;
    const Eigen::Vector3d e = residual(pose, i);
    sum_z2 += (whitening[i] * e).squaredNorm();
    sum_e2 += e.squaredNorm();
    Eigen::Matrix<double, 3, 6> j;
    j.leftCols<3>() = whitening[i] * rt;
    j.rightCols<3>() = -whitening[i] * rt * Skew(input.points_in_dst[i] - pose.translation());
    jtj.noalias() += j.transpose() * j;
  }
  if (result.num_inliers > 0) {
    const double count = static_cast<double>(result.num_inliers);
    result.rmse_sigma = std::sqrt(sum_z2 / count);
    result.rmse_mm = std::sqrt(sum_e2 / count);
  }
  if (result.num_inliers > 2) {
    const double s2 = sum_z2 / static_cast<double>(3 * result.num_inliers - 6);
    result.covariance = s2 * jtj.ldlt().solve(Eigen::Matrix<double, 6, 6>::Identity());
  }
  if (result.num_inliers < static_cast<std::size_t>(options.min_inliers))
    return finish("too few inliers (" + std::to_string(result.num_inliers) + " < " +
                  std::to_string(options.min_inliers) + ")");
  result.success = true;
  return finish("ok");
}

}  // namespace lifmcr::registration
