// The only file of lifmcr that solves hand-eye problems (OpenCV calib3d for
// the closed form, Ceres for the refinement).
#include "registration/hand_eye.h"

#include "registration/trajectory_metrics.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace lifmcr {
namespace {

constexpr double kDeg = M_PI / 180.0;


// E_i = (Z B_i)^-1 A_i X.
Pose Residual(const Pose& a, const Pose& b, const Pose& x, const Pose& z) {
  return (z * b).inverse() * (a * x);
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

struct RobustScales {
  double translation_mm, rotation_rad;
};

// 1.4826 MAD (around 0) of the residual components of the observations in `use`.
RobustScales ScalesOf(std::span<const Pose> a, std::span<const Pose> b, const Pose& x,
                      const Pose& z, const std::vector<bool>& use) {
  std::vector<double> t, r;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!use[i]) continue;
    const Pose e = Residual(a[i], b[i], x, z);
    const Eigen::Vector3d w = RotationLog(e.linear());
    for (int k = 0; k < 3; ++k) {
      t.push_back(std::abs(e.translation()[k]));
      r.push_back(std::abs(w[k]));
    }
  }
  return {std::max(1.4826 * Median(t), 1e-6), std::max(1.4826 * Median(r), 1e-9)};
}

bool ClosedForm(std::span<const Pose> a, std::span<const Pose> b, const std::vector<bool>& use,
                Pose* x, Pose* z) {
  // OpenCV's names: cTw wTb = cTg gTb, i.e. A = world2cam, X = base2world,
  // Z = gripper2cam, B = base2gripper.
  std::vector<cv::Mat> ra, ta, rb, tb;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!use[i]) continue;
    cv::Mat m;
    cv::eigen2cv(Eigen::Matrix3d(a[i].linear()), m);
    ra.push_back(m.clone());
    cv::eigen2cv(Eigen::Vector3d(a[i].translation()), m);
    ta.push_back(m.clone());
    cv::eigen2cv(Eigen::Matrix3d(b[i].linear()), m);
    rb.push_back(m.clone());
    cv::eigen2cv(Eigen::Vector3d(b[i].translation()), m);
    tb.push_back(m.clone());
  }
  if (ra.size() < 3) return false;
  cv::Mat rx, tx, rz, tz;
  try {
    cv::calibrateRobotWorldHandEye(ra, ta, rb, tb, rx, tx, rz, tz, cv::CALIB_ROBOT_WORLD_HAND_EYE_SHAH);
  } catch (const cv::Exception&) {
    return false;
  }
  Eigen::Matrix3d r;
  Eigen::Vector3d t;
  cv::cv2eigen(rx, r);
  cv::cv2eigen(tx, t);
  if (!r.allFinite() || !t.allFinite()) return false;
  *x = Pose::Identity();
  x->linear() = NearestRotation(r);
  x->translation() = t;
  cv::cv2eigen(rz, r);
  cv::cv2eigen(tz, t);
  if (!r.allFinite() || !t.allFinite()) return false;
  *z = Pose::Identity();
  z->linear() = NearestRotation(r);
  z->translation() = t;
  return true;
}

struct AxZbCost {
  AxZbCost(const Pose& a, const Pose& b, double sigma_t, double sigma_r)
      : qa(a.linear()), ta(a.translation()), qb(b.linear()), tb(b.translation()),
        inv_sigma_t(1.0 / sigma_t), inv_sigma_r(1.0 / sigma_r) {}

  template <typename T>
  bool operator()(const T* qx_p, const T* tx_p, const T* qz_p, const T* tz_p, T* r) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> qx(qx_p), qz(qz_p);
    const Eigen::Map<const Vec3> tx(tx_p), tz(tz_p);
    const Eigen::Quaternion<T> qa_t = qa.cast<T>(), qb_t = qb.cast<T>();
    const Eigen::Quaternion<T> q_ax = qa_t * qx;
    const Vec3 t_ax = qa_t * tx + ta.cast<T>();
    const Eigen::Quaternion<T> q_zb = qz * qb_t;
    const Vec3 t_zb = qz * tb.cast<T>() + tz;
    const Eigen::Quaternion<T> q_zb_inv = q_zb.conjugate();
    const Eigen::Quaternion<T> q_e = q_zb_inv * q_ax;
    const Vec3 t_e = q_zb_inv * (t_ax - t_zb);
    const T wxyz[4] = {q_e.w(), q_e.x(), q_e.y(), q_e.z()};
    T w[3];
    ceres::QuaternionToAngleAxis(wxyz, w);
    for (int k = 0; k < 3; ++k) {
      r[k] = t_e[k] * T(inv_sigma_t);
      r[3 + k] = w[k] * T(inv_sigma_r);
    }
    return true;
  }

  Eigen::Quaterniond qa;
  Eigen::Vector3d ta;
  Eigen::Quaterniond qb;
  Eigen::Vector3d tb;
  double inv_sigma_t, inv_sigma_r;
};

struct Parameters {
  Eigen::Quaterniond qx, qz;
  Eigen::Vector3d tx, tz;
  explicit Parameters(const Pose& x, const Pose& z)
      : qx(Eigen::Quaterniond(x.linear()).normalized()),
        qz(Eigen::Quaterniond(z.linear()).normalized()),
        tx(x.translation()),
        tz(z.translation()) {}
  Pose X() const {
    Pose p = Pose::Identity();
    p.linear() = qx.normalized().toRotationMatrix();
    p.translation() = tx;
    return p;
  }
  Pose Z() const {
    Pose p = Pose::Identity();
    p.linear() = qz.normalized().toRotationMatrix();
    p.translation() = tz;
    return p;
  }
};

void BuildProblem(ceres::Problem* problem, Parameters* p, std::span<const Pose> a,
                  std::span<const Pose> b, const RobustScales& scales, double huber) {
  for (std::size_t i = 0; i < a.size(); ++i) {
    auto* cost = new ceres::AutoDiffCostFunction<AxZbCost, 6, 4, 3, 4, 3>(
        new AxZbCost(a[i], b[i], scales.translation_mm, scales.rotation_rad));
    problem->AddResidualBlock(cost, new ceres::HuberLoss(huber), p->qx.coeffs().data(),
                              p->tx.data(), p->qz.coeffs().data(), p->tz.data());
  }
  problem->SetManifold(p->qx.coeffs().data(), new ceres::EigenQuaternionManifold);
  problem->SetManifold(p->qz.coeffs().data(), new ceres::EigenQuaternionManifold);
}

}  // namespace

Status HandEyeOptions::Check() const {
  auto bad = [](const std::string& what) { return Error{"hand-eye options: " + what}; };
  if (!(min_rotation_spread_deg >= 0)) return bad("min_rotation_spread_deg must be >= 0");
  if (!(translation_sigma_mm > 0)) return bad("translation_sigma_mm must be > 0");
  if (!(rotation_sigma_deg > 0)) return bad("rotation_sigma_deg must be > 0");
  if (!(huber_threshold > 0)) return bad("huber_threshold must be > 0");
  if (max_iterations < 1) return bad("max_iterations must be >= 1");
  if (min_observations < 3) return bad("min_observations must be >= 3");
  return Status::Ok();
}

std::string HandEyeResult::BriefReport() const {
  if (!success) return "hand-eye: failed: " + message;
  const Eigen::Vector3d t = x.translation();
  const Eigen::Vector3d w = RotationLog(x.linear()) / kDeg;
  char line[512];
  std::snprintf(line, sizeof(line),
                "hand-eye: %zu obs, %zu inliers, residual %.2f mm / %.3f deg, X t=(%.2f, %.2f, "
                "%.2f) +- (%.2f, %.2f, %.2f) mm, r=(%.2f, %.2f, %.2f) +- (%.3f, %.3f, %.3f) deg, "
                "rotation spread %.1f/%.1f/%.1f deg",
                observations, inliers, translation_rms_mm, rotation_rms_deg, t.x(), t.y(), t.z(),
                x_translation_sd_mm.x(), x_translation_sd_mm.y(), x_translation_sd_mm.z(), w.x(),
                w.y(), w.z(), x_rotation_sd_deg.x(), x_rotation_sd_deg.y(), x_rotation_sd_deg.z(),
                rotation_spread_deg.x(), rotation_spread_deg.y(), rotation_spread_deg.z());
  return line;
}

Eigen::Vector3d RotationSpreadDeg(std::span<const Pose> poses) {
  if (poses.empty()) return Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  for (const Pose& p : poses) sum += p.linear();
  const Eigen::Matrix3d mean = NearestRotation(sum);
  Eigen::MatrixXd w(poses.size(), 3);
  for (std::size_t i = 0; i < poses.size(); ++i)
    w.row(static_cast<Eigen::Index>(i)) = RotationLog(mean.transpose() * poses[i].linear());
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(w);
  return svd.singularValues() / std::sqrt(static_cast<double>(poses.size())) / kDeg;
}

HandEyeResult SolveRobotWorldHandEye(std::span<const Pose> a, std::span<const Pose> b,
                                     const HandEyeOptions& options) {
  HandEyeResult result;
  result.observations = a.size();
  if (Status s = options.Check(); !s) {
    result.message = s.error().message;
    return result;
  }
  if (a.size() != b.size()) {
    result.message = "the two pose lists differ in length";
    return result;
  }
  if (a.size() < static_cast<std::size_t>(options.min_observations)) {
    result.message = std::to_string(a.size()) + " observations, at least " +
                     std::to_string(options.min_observations) + " are needed";
    return result;
  }
  result.rotation_spread_deg = RotationSpreadDeg(b);
  if (result.rotation_spread_deg[1] < options.min_rotation_spread_deg) {
    char why[400];
    std::snprintf(why, sizeof(why),
                  "the motions cannot determine the offset: the camera rotations spread %.2f deg "
                  "about their main axis but only %.2f and %.2f deg about the other two (at least "
                  "%.2f deg about a second axis is needed; rotations about one axis leave the "
                  "offset along it free)",
                  result.rotation_spread_deg[0], result.rotation_spread_deg[1],
                  result.rotation_spread_deg[2], options.min_rotation_spread_deg);
    result.message = why;
    return result;
  }

  // Closed form on all, then again without gross outliers.
  std::vector<bool> use(a.size(), true);
  Pose x, z;
  if (!ClosedForm(a, b, use, &x, &z)) {
    result.message = "the closed-form solution (OpenCV, Shah) failed";
    return result;
  }
  {
    const RobustScales s = ScalesOf(a, b, x, z, use);
    std::size_t kept = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const Pose e = Residual(a[i], b[i], x, z);
      use[i] = e.translation().norm() <= 5 * std::sqrt(3.0) * s.translation_mm &&
               RotationLog(e.linear()).norm() <= 5 * std::sqrt(3.0) * s.rotation_rad;
      kept += use[i];
    }
    Pose x2, z2;
    if (kept >= static_cast<std::size_t>(options.min_observations) &&
        ClosedForm(a, b, use, &x2, &z2)) {
      x = x2;
      z = z2;
    }
  }
  result.x_closed_form = x;
  result.z_closed_form = z;

  Parameters params(x, z);
  RobustScales scales{options.translation_sigma_mm, options.rotation_sigma_deg * kDeg};
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = 1;
  ceres::Solver::Summary summary;
  std::unique_ptr<ceres::Problem> problem;
  RobustScales used = scales;
  for (int pass = 0; pass < 2; ++pass) {
    used = scales;
    problem = std::make_unique<ceres::Problem>();
    BuildProblem(problem.get(), &params, a, b, scales, options.huber_threshold);
    ceres::Solve(solver_options, problem.get(), &summary);
    result.iterations += static_cast<int>(summary.iterations.size());
    if (!summary.IsSolutionUsable()) {
      result.message = "the refinement failed: " + summary.message;
      return result;
    }
    // Weights from the data for the next pass (and for the covariance).
    const std::vector<bool> all(a.size(), true);
    scales = ScalesOf(a, b, params.X(), params.Z(), all);
  }
  result.x = params.X();
  result.z = params.Z();
  result.translation_sigma_mm = used.translation_mm;
  result.rotation_sigma_deg = used.rotation_rad / kDeg;

  // Residuals of the final solve (normalised by the scales it used) decide
  // the inliers and the variance factor of the covariance.
  double sum_t = 0, sum_r = 0, sum_normalised = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const Pose e = Residual(a[i], b[i], result.x, result.z);
    const Eigen::Vector3d rt = e.translation() / used.translation_mm;
    const Eigen::Vector3d rr = RotationLog(e.linear()) / used.rotation_rad;
    if (std::max(rt.cwiseAbs().maxCoeff(), rr.cwiseAbs().maxCoeff()) > options.huber_threshold)
      continue;
    ++result.inliers;
    sum_t += e.translation().squaredNorm();
    sum_r += RotationLog(e.linear()).squaredNorm();
    sum_normalised += rt.squaredNorm() + rr.squaredNorm();
  }
  if (result.inliers > 0) {
    result.translation_rms_mm = std::sqrt(sum_t / result.inliers);
    result.rotation_rms_deg = std::sqrt(sum_r / result.inliers) / kDeg;
  }

  // Covariance at the optimum of the last problem.
  ceres::Covariance::Options cov_options;
  cov_options.algorithm_type = ceres::DENSE_SVD;
  cov_options.null_space_rank = -1;
  ceres::Covariance covariance(cov_options);
  std::vector<std::pair<const double*, const double*>> blocks{
      {params.qx.coeffs().data(), params.qx.coeffs().data()},
      {params.tx.data(), params.tx.data()},
      {params.qz.coeffs().data(), params.qz.coeffs().data()},
      {params.tz.data(), params.tz.data()}};
  if (covariance.Compute(blocks, problem.get())) {
    const double m = 6.0 * static_cast<double>(result.inliers);
    const double factor = m > 12 ? sum_normalised / (m - 12.0) : 1.0;
    Eigen::Matrix3d c;
    auto sd = [&](const double* block, bool tangent, double unit) {
      if (tangent)
        covariance.GetCovarianceBlockInTangentSpace(block, block, c.data());
      else
        covariance.GetCovarianceBlock(block, block, c.data());
      return Eigen::Vector3d((c.diagonal() * factor).cwiseMax(0).cwiseSqrt() * unit);
    };
    // The quaternion manifold's tangent step delta rotates by 2 |delta|.
    result.x_rotation_sd_deg = sd(params.qx.coeffs().data(), true, 2.0 / kDeg);
    result.x_translation_sd_mm = sd(params.tx.data(), false, 1.0);
    result.z_rotation_sd_deg = sd(params.qz.coeffs().data(), true, 2.0 / kDeg);
    result.z_translation_sd_mm = sd(params.tz.data(), false, 1.0);
  }
  result.success = true;
  return result;
}

}  // namespace lifmcr
