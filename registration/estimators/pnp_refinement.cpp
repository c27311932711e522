// The plenoptic PnP's final refinement (RefinePnpCeres, registration/estimators/pnp.h):
// Levenberg-Marquardt on the plenoptic projection with a Huber loss, by
// ceres::TinySolver, Ceres' dense solver for problems of a few parameters.
//
// Why not ceres::Solve: with six unknowns and ~2000 residuals the general
// solver's fixed work per iteration (filling residuals and Jacobians with
// NaN and checking them, the manifold's product into the tangent Jacobian,
// copying into its dense matrix, Jacobi scaling, the trust-region
// bookkeeping) cost as much as evaluating the residuals and Jacobians
// themselves: 380 us for three iterations over 1000 inliers, 130 us when
// started at the optimum (bench_pnp, eleventh session), more than
// LO-RANSAC's whole search. TinySolver runs the same Levenberg-Marquardt
// (trust region, Jacobi scaling) on the 2n x 6 Jacobian the function fills.
//
// The rotation stays on ceres::EigenQuaternionManifold: the six unknowns are
// the tangent coordinates x = (d, dt) of a chart at the start pose,
//   q(d) = Plus(q0, d) = [cos|d|, sin|d| d/|d|] * q0,   t = t0 + dt,
// so R(d) = Exp(2 d) R0, and a camera point p = R(d) X + t moves with
//   dp/dd = -2 [R(d) X]x J_l(2 d),   dp/dt = I,
// J_l the left Jacobian of SO(3) (exact at every d, not only at d = 0:
// TinySolver keeps x in the chart for the whole solve).
//
// Robust loss inside the residual, as Ceres' loss would be on each datum
// (registration/estimators/robust_loss.h). Huber by default: the data are RANSAC's
// inliers, within t = 2 px, and on the bench's Gaussian noise Huber and
// Cauchy give the same pose error (bench_pnp, 80 problems at 50 % outliers:
// translation 0.024 mm with either, 0.94 and 0.97 of OpenCV's) while
// Cauchy's weights move with the pose and its refinement takes a Jacobian
// more (0.15 against 0.21 ms). On real keypoints Cauchy was the more
// accurate, and the live localizer, where a PnP is ~1 ms of a 20 ms frame,
// runs it (map_localizer.cpp).

#include "registration/estimators/pnp.h"

#include "registration/estimators/pose_covariance.h"
#include "registration/estimators/robust_loss.h"
#include "registration/estimators/tf_projection.h"

#include <ceres/manifold.h>
#include <ceres/tiny_solver.h>

#include <Eigen/Geometry>

#include <cmath>
#include <vector>

namespace lifmcr::registration {
namespace {

// J_l(phi) = I + (1 - cos a) / a^2 [phi]x + (a - sin a) / a^3 [phi]x^2,
// a = |phi| (its series below 1e-4 rad, where the closed form loses digits).
Eigen::Matrix3d LeftJacobianSo3(const Eigen::Vector3d& phi) {
  const double a2 = phi.squaredNorm();
  const Eigen::Matrix3d k = Skew(phi);
  if (a2 < 1e-8) return Eigen::Matrix3d::Identity() + 0.5 * k + (1.0 / 6.0) * k * k;
  const double a = std::sqrt(a2);
  return Eigen::Matrix3d::Identity() + ((1 - std::cos(a)) / a2) * k +
         ((a - std::sin(a)) / (a2 * a)) * k * k;
}

// The function TinySolver minimises: residuals r~_i of the selected data in
// the chart at (q0, t0), Jacobian column-major (2n x 6).
class TfReprojectionChart {
 public:
  using Scalar = double;
  enum { NUM_RESIDUALS = Eigen::Dynamic, NUM_PARAMETERS = 6 };

  // The selected data are copied into `points` and `observed` (the
  // caller's, reused across calls): the solver then reads them in order.
  TfReprojectionChart(const TfProjection& projection, const PnpInput& input,
                      std::span<const char> mask, PnpLoss loss, double loss_scale_px,
                      const Pose& start,
                      std::vector<Eigen::Vector3d>* points, std::vector<Eigen::Vector2d>* observed)
      : projection_(projection), loss_(loss), c_(loss_scale_px * loss_scale_px), points_(*points),
        observed_(*observed) {
    SetStart(start);
    points_.clear();
    observed_.clear();
    for (std::size_t i = 0; i < mask.size(); ++i) {
      if (!mask[i]) continue;
      points_.push_back(input.points_in_world[i]);
      observed_.push_back(input.tf_px[i]);
    }
  }
  std::size_t size() const { return points_.size(); }
  // The chart's origin (x = 0).
  void SetStart(const Pose& start) {
    q0_ = Eigen::Quaterniond(start.linear()).normalized();
    t0_ = start.translation();
  }
  int NumResiduals() const { return static_cast<int>(2 * points_.size()); }

  Pose PoseAt(const double* x) const {
    Eigen::Quaterniond q;
    manifold_.Plus(q0_.coeffs().data(), x, q.coeffs().data());
    Pose pose = Pose::Identity();
    pose.linear() = q.normalized().toRotationMatrix();
    pose.translation() = t0_ + Eigen::Vector3d(x[3], x[4], x[5]);
    return pose;
  }

  // A datum behind the front focal plane has no image: its residual is
  // kFar, so a step that moves one there is refused (TinySolver does not
  // read the function's return value for a candidate step).
  bool operator()(const double* x, double* residuals, double* jacobian) const {
    constexpr double kFar = 1e6;
    const Pose pose = PoseAt(x);
    const Eigen::Matrix3d rotation = pose.linear();
    const Eigen::Vector3d t = pose.translation();
    Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
    if (jacobian != nullptr) a = 2.0 * LeftJacobianSo3(2.0 * Eigen::Vector3d(x[0], x[1], x[2]));
    const std::size_t m = 2 * points_.size();
    Eigen::Vector2d tf;
    Eigen::Matrix<double, 2, 3> j_p;
    for (std::size_t k = 0; k < points_.size(); ++k) {
      const Eigen::Vector3d rx = rotation * points_[k];
      if (!projection_.WithJacobian(rx + t, &tf, &j_p)) {
        residuals[2 * k] = residuals[2 * k + 1] = kFar;
        if (jacobian != nullptr)
          for (std::size_t col = 0; col < 6; ++col)
            jacobian[col * m + 2 * k] = jacobian[col * m + 2 * k + 1] = 0;
        continue;
      }
      const Eigen::Vector2d r = tf - observed_[k];
      const double s = r.squaredNorm();
      double g, h;
      RobustCorrection(loss_, c_, s, &g, &h);
      residuals[2 * k] = g * r.x();
      residuals[2 * k + 1] = g * r.y();
      if (jacobian == nullptr) continue;
      // d(r~)/d(r) = g I + h r r^T, then the chain through the pose.
      const Eigen::Matrix2d w = g * Eigen::Matrix2d::Identity() + h * r * r.transpose();
      const Eigen::Matrix<double, 2, 3> wj_p = w * j_p;
      const Eigen::Matrix<double, 2, 3> j_d = -(wj_p * Skew(rx)) * a;
      for (std::size_t col = 0; col < 3; ++col) {
        jacobian[col * m + 2 * k] = j_d(0, col);
        jacobian[col * m + 2 * k + 1] = j_d(1, col);
        jacobian[(col + 3) * m + 2 * k] = wj_p(0, col);
        jacobian[(col + 3) * m + 2 * k + 1] = wj_p(1, col);
      }
    }
    return true;
  }

 private:
  const TfProjection& projection_;
  PnpLoss loss_;
  double c_;
  Eigen::Quaterniond q0_;
  Eigen::Vector3d t0_;
  ceres::EigenQuaternionManifold manifold_;
  std::vector<Eigen::Vector3d>& points_;
  std::vector<Eigen::Vector2d>& observed_;
};

}  // namespace

int RefinePnpCeres(const processing::CameraModel& camera, const PnpInput& input,
                   std::span<const char> mask, PnpLoss loss, double loss_scale_px,
                   int max_iterations, Pose* cam_from_world, double start_cost) {
  const TfProjection projection = TfProjection::Of(camera);
  // The solver's residuals and Jacobian (2n x 6) and the selected data are
  // kept per thread and reused (as PlenopticPnpEstimator::Buffers: sized
  // once, not page-faulted in again each call).
  thread_local std::vector<Eigen::Vector3d> points;
  thread_local std::vector<Eigen::Vector2d> observed;
  thread_local ceres::TinySolver<TfReprojectionChart> solver;
  thread_local Eigen::VectorXd start_residuals;
  TfReprojectionChart chart(projection, input, mask, loss, loss_scale_px, *cam_from_world,
                            &points, &observed);
  if (chart.size() < 3) return -1;
  // TinySolver counts the first evaluation as iteration 0 and stops at
  // max_num_iterations. Its function tolerance is absolute (Ceres 2.1) and
  // compared with twice a step's decrease; it is set so that a step stops
  // the solve when it gains less than 1e-4 of the start's cost
  // C ~ n sigma^2 (n data, 2n residuals):
  // a pose k standard deviations of its estimate off the optimum costs
  // k^2 sigma^2 / 2 more, so a step that gains less than 1e-4 C started
  // within k < sqrt(2e-4 n) (0.45 for n = 1000) and, a Gauss-Newton step
  // on a nearly linear problem, ends far closer; TinySolver keeps that last
  // step. ceres::Solver's default 1e-6 took one more iteration (a Jacobian,
  // J^T J, ~40 us per 1000 inliers) for nothing (bench_pnp).
  if (!(start_cost >= 0)) {
    start_residuals.resize(chart.NumResiduals());
    chart(Eigen::Matrix<double, 6, 1>::Zero().eval().data(), start_residuals.data(), nullptr);
    start_cost = 0.5 * start_residuals.squaredNorm();
  }
  if (!std::isfinite(start_cost)) return -1;
  // The tolerance is the start's: from a start far off (more than half the
  // cost to gain) the solve stops on a cost it has long left behind, so it
  // is solved again from where it stopped, the chart there and the
  // tolerance of its cost (PnP's starts, a fraction of a standard deviation
  // off, take one solve).
  int iterations = 0;
  for (int solve = 0; solve < 4 && iterations < max_iterations; ++solve) {
    chart.SetStart(*cam_from_world);
    solver.options.max_num_iterations = max_iterations - iterations + 1;
    solver.options.function_tolerance = 2 * 1e-4 * start_cost;
    Eigen::Matrix<double, 6, 1> x = Eigen::Matrix<double, 6, 1>::Zero();
    const auto& summary = solver.Solve(chart, &x);
    if (!x.allFinite() || !(summary.final_cost <= summary.initial_cost))
      return iterations > 0 ? iterations : -1;
    *cam_from_world = chart.PoseAt(x.data());
    iterations += summary.iterations;
    if (!(summary.final_cost < 0.5 * summary.initial_cost)) break;
    start_cost = summary.final_cost;
  }
  return iterations;
}

}  // namespace lifmcr::registration
