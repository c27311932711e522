// The only file of lifmcr that solves hand-eye problems (the closed form
// with Eigen, Ceres for the refinement).
#include "evaluation/hand_eye.h"

#include "evaluation/trajectory_metrics.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <Eigen/Eigenvalues>

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

// Step 2 on the observations in `use`: Shah's Kronecker solution with one
// X per camera and a shared Z (hand_eye.h). False when the system is
// degenerate (too few observations, no finite rotation).
bool ClosedForm(std::span<const HandEyeObservations> cams,
                const std::vector<std::vector<bool>>& use, std::vector<Pose>* x, Pose* z) {
  const int k_cams = static_cast<int>(cams.size());
  const int n = 9 * (k_cams + 1);
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(n, n);
  std::size_t used = 0;
  for (int k = 0; k < k_cams; ++k)
    for (std::size_t i = 0; i < cams[k].a.size(); ++i) {
      if (!use[k][i]) continue;
      ++used;
      const Eigen::Matrix3d ra = cams[k].a[i].linear(), rb = cams[k].b[i].linear();
      // Rows of (R_B ⊗ R_A) vec(R_X) - vec(R_Z): block (r, c) of the
      // Kronecker product is rb(r, c) * ra.
      Eigen::Matrix<double, 9, Eigen::Dynamic> m = Eigen::MatrixXd::Zero(9, n);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m.block<3, 3>(3 * r, 9 * k + 3 * c) = rb(r, c) * ra;
      m.block<9, 9>(0, 9 * k_cams) = -Eigen::Matrix<double, 9, 9>::Identity();
      normal += m.transpose() * m;
    }
  if (used < 3) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(normal);
  if (eigen.info() != Eigen::Success) return false;
  const Eigen::VectorXd v = eigen.eigenvectors().col(0);  // smallest eigenvalue first
  auto block = [&](int j) { return Eigen::Map<const Eigen::Matrix3d>(v.data() + 9 * j); };
  const double det_z = block(k_cams).determinant();
  if (!std::isfinite(det_z) || std::abs(det_z) < 1e-12) return false;
  const double scale = std::cbrt(det_z);  // sign included: det(R_Z) = +1
  std::vector<Eigen::Matrix3d> rx(k_cams);
  for (int k = 0; k < k_cams; ++k) rx[k] = NearestRotation(block(k) / scale);
  const Eigen::Matrix3d rz = NearestRotation(block(k_cams) / scale);

  // R_A t_Xk - t_Z = R_Z t_B - t_A, least squares over [t_X1..t_XK, t_Z].
  const int m_cols = 3 * (k_cams + 1);
  Eigen::MatrixXd jtj = Eigen::MatrixXd::Zero(m_cols, m_cols);
  Eigen::VectorXd jtr = Eigen::VectorXd::Zero(m_cols);
  for (int k = 0; k < k_cams; ++k)
    for (std::size_t i = 0; i < cams[k].a.size(); ++i) {
      if (!use[k][i]) continue;
      Eigen::Matrix<double, 3, Eigen::Dynamic> j = Eigen::MatrixXd::Zero(3, m_cols);
      j.block<3, 3>(0, 3 * k) = cams[k].a[i].linear();
      j.block<3, 3>(0, 3 * k_cams) = -Eigen::Matrix3d::Identity();
      const Eigen::Vector3d r = rz * cams[k].b[i].translation() - cams[k].a[i].translation();
      jtj += j.transpose() * j;
      jtr += j.transpose() * r;
    }
  const Eigen::VectorXd t = jtj.ldlt().solve(jtr);
  if (!t.allFinite() || !rz.allFinite()) return false;
  x->assign(k_cams, Pose::Identity());
  for (int k = 0; k < k_cams; ++k) {
    if (!rx[k].allFinite()) return false;
    (*x)[k].linear() = rx[k];
    (*x)[k].translation() = t.segment<3>(3 * k);
  }
  *z = Pose::Identity();
  z->linear() = rz;
  z->translation() = t.segment<3>(3 * k_cams);
  return true;
}

// r = [t_e / sigma_t ; angle-axis(q_e) / sigma_r] for a pose error (q_e, t_e).
template <typename T>
void WriteResidual(const Eigen::Quaternion<T>& q_e, const Eigen::Matrix<T, 3, 1>& t_e,
                   double inv_sigma_t, double inv_sigma_r, T* r) {
  const T wxyz[4] = {q_e.w(), q_e.x(), q_e.y(), q_e.z()};
  T w[3];
  ceres::QuaternionToAngleAxis(wxyz, w);
  for (int k = 0; k < 3; ++k) {
    r[k] = t_e[k] * T(inv_sigma_t);
    r[3 + k] = w[k] * T(inv_sigma_r);
  }
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
    WriteResidual(q_e, t_e, inv_sigma_t, inv_sigma_r, r);
    return true;
  }

  Eigen::Quaterniond qa;
  Eigen::Vector3d ta;
  Eigen::Quaterniond qb;
  Eigen::Vector3d tb;
  double inv_sigma_t, inv_sigma_r;
};

Pose PoseOf(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) {
  Pose p = Pose::Identity();
  p.linear() = q.normalized().toRotationMatrix();
  p.translation() = t;
  return p;
}

// The Ceres parameter blocks: one (q, t) per camera's X and one for Z.
// The prior on Z: [t(Z0^-1 Z) / sd_t ; Log(R(Z0^-1 Z)) / sd_r].
struct ZPriorCost {
  explicit ZPriorCost(const HandEyePrior& prior)
      : q0_inv(Eigen::Quaterniond(prior.z.linear()).conjugate()),
        t0(prior.z.translation()),
        inv_sd_t(1.0 / prior.translation_sd_mm),
        inv_sd_r(1.0 / (prior.rotation_sd_deg * kDeg)) {}

  template <typename T>
  bool operator()(const T* qz_p, const T* tz_p, T* r) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> qz(qz_p);
    const Eigen::Map<const Vec3> tz(tz_p);
    const Eigen::Quaternion<T> q0_inv_t = q0_inv.cast<T>();
    const Eigen::Quaternion<T> q_e = q0_inv_t * qz;
    const Vec3 t_e = q0_inv_t * (tz - t0.cast<T>());
    WriteResidual(q_e, t_e, inv_sd_t, inv_sd_r, r);
    return true;
  }

  Eigen::Quaterniond q0_inv;
  Eigen::Vector3d t0;
  double inv_sd_t, inv_sd_r;
};

struct Parameters {
  std::vector<Eigen::Quaterniond> qx;
  std::vector<Eigen::Vector3d> tx;
  Eigen::Quaterniond qz;
  Eigen::Vector3d tz;
  Parameters(const std::vector<Pose>& x, const Pose& z)
      : qz(Eigen::Quaterniond(z.linear()).normalized()), tz(z.translation()) {
    for (const Pose& p : x) {
      qx.push_back(Eigen::Quaterniond(p.linear()).normalized());
      tx.push_back(p.translation());
    }
  }
  Pose X(std::size_t k) const { return PoseOf(qx[k], tx[k]); }
  Pose Z() const { return PoseOf(qz, tz); }
};

void BuildProblem(ceres::Problem* problem, Parameters* p,
                  std::span<const HandEyeObservations> cams,
                  const std::vector<RobustScales>& scales, double huber,
                  const std::optional<HandEyePrior>& z_prior) {
  if (z_prior)
    problem->AddResidualBlock(
        new ceres::AutoDiffCostFunction<ZPriorCost, 6, 4, 3>(new ZPriorCost(*z_prior)), nullptr,
        p->qz.coeffs().data(), p->tz.data());
  for (std::size_t k = 0; k < cams.size(); ++k) {
    for (std::size_t i = 0; i < cams[k].a.size(); ++i) {
      auto* cost = new ceres::AutoDiffCostFunction<AxZbCost, 6, 4, 3, 4, 3>(new AxZbCost(
          cams[k].a[i], cams[k].b[i], scales[k].translation_mm, scales[k].rotation_rad));
      problem->AddResidualBlock(cost, new ceres::HuberLoss(huber), p->qx[k].coeffs().data(),
                                p->tx[k].data(), p->qz.coeffs().data(), p->tz.data());
    }
    problem->SetManifold(p->qx[k].coeffs().data(), new ceres::EigenQuaternionManifold);
  }
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

Status HandEyePrior::Check() const {
  if (!(translation_sd_mm > 0)) return Error{"hand-eye prior on Z: translation_sd_mm must be > 0"};
  if (!(rotation_sd_deg > 0)) return Error{"hand-eye prior on Z: rotation_sd_deg must be > 0"};
  if (!z.matrix().allFinite()) return Error{"hand-eye prior on Z: z must be finite"};
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
  if (a.size() != b.size()) {
    HandEyeResult result;
    result.observations = a.size();
    result.message = "the two pose lists differ in length";
    return result;
  }
  const HandEyeObservations one{"", std::vector<Pose>(a.begin(), a.end()),
                                std::vector<Pose>(b.begin(), b.end())};
  JointHandEyeResult joint = SolveJointRobotWorldHandEye(std::span(&one, 1), options);
  if (joint.cameras.empty()) {
    HandEyeResult result;
    result.observations = a.size();
    result.message = joint.message;
    return result;
  }
  HandEyeResult result = std::move(joint.cameras.front());
  if (!joint.success) result.message = joint.message;
  return result;
}

std::string JointHandEyeResult::BriefReport() const {
  if (!success) return "joint hand-eye: failed: " + message;
  const Eigen::Vector3d t = z.translation();
  const Eigen::Vector3d w = RotationLog(z.linear()) / kDeg;
  char line[256];
  std::snprintf(line, sizeof(line), "joint hand-eye of %zu cameras: Z t=(%.2f, %.2f, %.2f) mm, "
                "r=(%.3f, %.3f, %.3f) deg",
                cameras.size(), t.x(), t.y(), t.z(), w.x(), w.y(), w.z());
  return line;
}

JointHandEyeResult SolveJointRobotWorldHandEye(std::span<const HandEyeObservations> cams,
                                               const HandEyeOptions& options,
                                               const std::optional<HandEyePrior>& z_prior) {
  JointHandEyeResult joint;
  joint.cameras.resize(cams.size());
  auto fail = [&](const std::string& message) {
    joint.message = message;
    for (HandEyeResult& c : joint.cameras) c.message = message;
    return joint;
  };
  if (Status s = options.Check(); !s) return fail(s.error().message);
  if (z_prior)
    if (Status s = z_prior->Check(); !s) return fail(s.error().message);
  if (cams.empty()) return fail("no camera to solve for");
  const bool several = cams.size() > 1;
  for (std::size_t k = 0; k < cams.size(); ++k) {
    const HandEyeObservations& c = cams[k];
    HandEyeResult& result = joint.cameras[k];
    result.observations = c.a.size();
    const std::string who = several ? "camera " + c.name + ": " : "";
    if (c.a.size() != c.b.size()) return fail(who + "the two pose lists differ in length");
    if (c.a.size() < static_cast<std::size_t>(options.min_observations))
      return fail(who + std::to_string(c.a.size()) + " observations, at least " +
                  std::to_string(options.min_observations) + " are needed");
    result.rotation_spread_deg = RotationSpreadDeg(c.b);
    if (result.rotation_spread_deg[1] < options.min_rotation_spread_deg) {
      char why[400];
      std::snprintf(why, sizeof(why),
                    "the motions cannot determine the offset: the camera rotations spread %.2f "
                    "deg about their main axis but only %.2f and %.2f deg about the other two (at "
                    "least %.2f deg about a second axis is needed; rotations about one axis leave "
                    "the offset along it free)",
                    result.rotation_spread_deg[0], result.rotation_spread_deg[1],
                    result.rotation_spread_deg[2], options.min_rotation_spread_deg);
      return fail(who + why);
    }
  }

  // Closed form on all, then again without each camera's gross outliers.
  std::vector<std::vector<bool>> use;
  for (const HandEyeObservations& c : cams) use.emplace_back(c.a.size(), true);
  std::vector<Pose> x;
  Pose z;
  if (!ClosedForm(cams, use, &x, &z)) return fail("the closed-form solution (Shah) failed");
  {
    bool enough = true;
    for (std::size_t k = 0; k < cams.size(); ++k) {
      const RobustScales s = ScalesOf(cams[k].a, cams[k].b, x[k], z, use[k]);
      std::size_t kept = 0;
      for (std::size_t i = 0; i < cams[k].a.size(); ++i) {
        const Pose e = Residual(cams[k].a[i], cams[k].b[i], x[k], z);
        use[k][i] = e.translation().norm() <= 5 * std::sqrt(3.0) * s.translation_mm &&
                    RotationLog(e.linear()).norm() <= 5 * std::sqrt(3.0) * s.rotation_rad;
        kept += use[k][i];
      }
      enough = enough && kept >= static_cast<std::size_t>(options.min_observations);
    }
    std::vector<Pose> x2;
    Pose z2;
    if (enough && ClosedForm(cams, use, &x2, &z2)) {
      x = x2;
      z = z2;
    }
  }
  if (z_prior) {
    // Start from the measured Z: X_k = mean of A_ki^-1 Z0 B_ki over the
    // closed form's inliers (chordal mean of the rotations).
    z = z_prior->z;
    for (std::size_t k = 0; k < cams.size(); ++k) {
      Eigen::Matrix3d sum_r = Eigen::Matrix3d::Zero();
      Eigen::Vector3d sum_t = Eigen::Vector3d::Zero();
      std::size_t n = 0;
      for (std::size_t i = 0; i < cams[k].a.size(); ++i) {
        if (!use[k][i]) continue;
        const Pose xi = cams[k].a[i].inverse() * z * cams[k].b[i];
        sum_r += xi.linear();
        sum_t += xi.translation();
        ++n;
      }
      x[k].linear() = NearestRotation(sum_r);
      x[k].translation() = sum_t / static_cast<double>(n);
    }
  }
  for (std::size_t k = 0; k < cams.size(); ++k) {
    joint.cameras[k].x_closed_form = x[k];
    joint.cameras[k].z_closed_form = z;
  }

  Parameters params(x, z);
  std::vector<RobustScales> scales(
      cams.size(), RobustScales{options.translation_sigma_mm, options.rotation_sigma_deg * kDeg});
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_iterations;
  solver_options.num_threads = 1;
  ceres::Solver::Summary summary;
  std::unique_ptr<ceres::Problem> problem;
  std::vector<RobustScales> used = scales;
  int iterations = 0;
  for (int pass = 0; pass < 2; ++pass) {
    used = scales;
    problem = std::make_unique<ceres::Problem>();
    BuildProblem(problem.get(), &params, cams, scales, options.huber_threshold, z_prior);
    ceres::Solve(solver_options, problem.get(), &summary);
    iterations += static_cast<int>(summary.iterations.size());
    if (!summary.IsSolutionUsable()) return fail("the refinement failed: " + summary.message);
    // Weights from the data for the next pass (and for the covariance).
    for (std::size_t k = 0; k < cams.size(); ++k)
      scales[k] = ScalesOf(cams[k].a, cams[k].b, params.X(k), params.Z(),
                           std::vector<bool>(cams[k].a.size(), true));
  }
  joint.z = params.Z();

  // Residuals of the final solve (normalised by the scales it used) decide
  // the inliers and the variance factor of the covariance.
  double sum_normalised = 0;
  std::size_t all_inliers = 0;
  for (std::size_t k = 0; k < cams.size(); ++k) {
    HandEyeResult& result = joint.cameras[k];
    result.x = params.X(k);
    result.z = joint.z;
    result.iterations = iterations;
    result.translation_sigma_mm = used[k].translation_mm;
    result.rotation_sigma_deg = used[k].rotation_rad / kDeg;
    double sum_t = 0, sum_r = 0;
    for (std::size_t i = 0; i < cams[k].a.size(); ++i) {
      const Pose e = Residual(cams[k].a[i], cams[k].b[i], result.x, result.z);
      const Eigen::Vector3d rt = e.translation() / used[k].translation_mm;
      const Eigen::Vector3d rr = RotationLog(e.linear()) / used[k].rotation_rad;
      if (std::max(rt.cwiseAbs().maxCoeff(), rr.cwiseAbs().maxCoeff()) > options.huber_threshold)
        continue;
      ++result.inliers;
      sum_t += e.translation().squaredNorm();
      sum_r += RotationLog(e.linear()).squaredNorm();
      sum_normalised += rt.squaredNorm() + rr.squaredNorm();
    }
    all_inliers += result.inliers;
    if (result.inliers > 0) {
      result.translation_rms_mm = std::sqrt(sum_t / result.inliers);
      result.rotation_rms_deg = std::sqrt(sum_r / result.inliers) / kDeg;
    }
  }

  if (z_prior) {
    // The prior's own normalised residual joins the variance factor.
    const Pose e = z_prior->z.inverse() * joint.z;
    sum_normalised += (e.translation() / z_prior->translation_sd_mm).squaredNorm() +
                      (RotationLog(e.linear()) / (z_prior->rotation_sd_deg * kDeg)).squaredNorm();
  }

  // Covariance at the optimum of the last problem.
  ceres::Covariance::Options cov_options;
  cov_options.algorithm_type = ceres::DENSE_SVD;
  cov_options.null_space_rank = -1;
  ceres::Covariance covariance(cov_options);
  std::vector<std::pair<const double*, const double*>> blocks{
      {params.qz.coeffs().data(), params.qz.coeffs().data()}, {params.tz.data(), params.tz.data()}};
  for (std::size_t k = 0; k < cams.size(); ++k) {
    blocks.emplace_back(params.qx[k].coeffs().data(), params.qx[k].coeffs().data());
    blocks.emplace_back(params.tx[k].data(), params.tx[k].data());
  }
  if (covariance.Compute(blocks, problem.get())) {
    const double parameters = 6.0 * static_cast<double>(cams.size() + 1);
    const double m = 6.0 * static_cast<double>(all_inliers + (z_prior ? 1 : 0));
    const double factor = m > parameters ? sum_normalised / (m - parameters) : 1.0;
    Eigen::Matrix3d c;
    auto sd = [&](const double* block, bool tangent, double unit) {
      if (tangent)
        covariance.GetCovarianceBlockInTangentSpace(block, block, c.data());
      else
        covariance.GetCovarianceBlock(block, block, c.data());
      return Eigen::Vector3d((c.diagonal() * factor).cwiseMax(0).cwiseSqrt() * unit);
    };
    // The quaternion manifold's tangent step delta rotates by 2 |delta|.
    const Eigen::Vector3d z_rotation_sd = sd(params.qz.coeffs().data(), true, 2.0 / kDeg);
    const Eigen::Vector3d z_translation_sd = sd(params.tz.data(), false, 1.0);
    for (std::size_t k = 0; k < cams.size(); ++k) {
      HandEyeResult& result = joint.cameras[k];
      result.x_rotation_sd_deg = sd(params.qx[k].coeffs().data(), true, 2.0 / kDeg);
      result.x_translation_sd_mm = sd(params.tx[k].data(), false, 1.0);
      result.z_rotation_sd_deg = z_rotation_sd;
      result.z_translation_sd_mm = z_translation_sd;
    }
  }
  for (HandEyeResult& result : joint.cameras) result.success = true;
  joint.success = true;
  return joint;
}

}  // namespace lifmcr
