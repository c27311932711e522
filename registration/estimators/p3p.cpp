#include "registration/estimators/p3p.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace lifmcr::registration {
namespace {

// Adjugate of a symmetric 3x3 matrix (symmetric too): cofactors.
Eigen::Matrix3d Adjugate(const Eigen::Matrix3d& m) {
  Eigen::Matrix3d adj;
  adj(0, 0) = m(1, 1) * m(2, 2) - m(1, 2) * m(2, 1);
  adj(0, 1) = m(0, 2) * m(2, 1) - m(0, 1) * m(2, 2);
  adj(0, 2) = m(0, 1) * m(1, 2) - m(0, 2) * m(1, 1);
  adj(1, 0) = m(1, 2) * m(2, 0) - m(1, 0) * m(2, 2);
  adj(1, 1) = m(0, 0) * m(2, 2) - m(0, 2) * m(2, 0);
  adj(1, 2) = m(0, 2) * m(1, 0) - m(0, 0) * m(1, 2);
  adj(2, 0) = m(1, 0) * m(2, 1) - m(1, 1) * m(2, 0);
  adj(2, 1) = m(0, 1) * m(2, 0) - m(0, 0) * m(2, 1);
  adj(2, 2) = m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0);
  return adj;
}

// The three rigidity residuals f_ij = l_i^2 + l_j^2 - 2 c_ij l_i l_j - a_ij
// (pairs 12, 13, 23) and a few Gauss-Newton steps on them.
void PolishDepths(const double c[3], const double a[3], Eigen::Vector3d* lambda) {
  constexpr int kPairs[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  Eigen::Vector3d& l = *lambda;
  for (int iteration = 0; iteration < 3; ++iteration) {
    Eigen::Vector3d f;
    Eigen::Matrix3d jac = Eigen::Matrix3d::Zero();
    for (int p = 0; p < 3; ++p) {
      const int i = kPairs[p][0], j = kPairs[p][1];
      f[p] = l[i] * l[i] + l[j] * l[j] - 2 * c[p] * l[i] * l[j] - a[p];
      jac(p, i) = 2 * l[i] - 2 * c[p] * l[j];
      jac(p, j) = 2 * l[j] - 2 * c[p] * l[i];
    }
    const double det = jac.determinant();
    if (!(std::abs(det) > 1e-300)) return;
    const Eigen::Vector3d step = jac.inverse() * f;
    if (!step.allFinite()) return;
    l -= step;
    if (step.squaredNorm() < 1e-28 * l.squaredNorm()) return;
  }
}

}  // namespace

int SolveMonicCubic(double b, double c, double d, double roots[3]) {
  // x = y - b/3 gives the depressed cubic y^3 + p y + q = 0.
  const double shift = b / 3.0;
  const double p = c - b * shift;
  const double q = 2.0 * shift * shift * shift - c * shift + d;
  const double disc = 0.25 * q * q + p * p * p / 27.0;
  int count;
  if (disc > 0) {
    const double s = std::sqrt(disc);
    roots[0] = std::cbrt(-0.5 * q + s) + std::cbrt(-0.5 * q - s) - shift;
    count = 1;
  } else if (p == 0) {
    roots[0] = -shift;
    count = 1;
  } else {
    // Three real roots: y = 2 sqrt(-p/3) cos(phi/3 - 2 pi k / 3).
    const double r = std::sqrt(-p / 3.0);
    const double arg = std::clamp(-0.5 * q / (r * r * r), -1.0, 1.0);
    const double phi = std::acos(arg);
    for (int k = 0; k < 3; ++k)
      roots[k] = 2.0 * r * std::cos((phi - 2.0 * std::numbers::pi * k) / 3.0) - shift;
    count = 3;
  }
  for (int k = 0; k < count; ++k) {
    double& x = roots[k];
    for (int iteration = 0; iteration < 2; ++iteration) {
      const double f = ((x + b) * x + c) * x + d;
      const double df = (3.0 * x + 2.0 * b) * x + c;
      if (df == 0) break;
      x -= f / df;
    }
  }
  std::sort(roots, roots + count);
  return count;
}

int SolveP3P(const std::array<Eigen::Vector3d, 3>& bearings,
             const std::array<Eigen::Vector3d, 3>& points, std::vector<Pose>* cam_from_world) {
  const Eigen::Vector3d y[3] = {bearings[0].normalized(), bearings[1].normalized(),
                                bearings[2].normalized()};
  const Eigen::Vector3d d12 = points[0] - points[1];
  const Eigen::Vector3d d13 = points[0] - points[2];
  const Eigen::Vector3d d23 = points[1] - points[2];
  Eigen::Matrix3d world_basis;
  world_basis << d12, d13, d12.cross(d13);
  const double scale2 = std::max({d12.squaredNorm(), d13.squaredNorm(), d23.squaredNorm()});
  // Collinear (or coincident) points: no unique rotation.
  if (!(world_basis.col(2).squaredNorm() > 1e-20 * scale2 * scale2)) return 0;

  // Pairs in the order 12, 13, 23.
  const double c[3] = {y[0].dot(y[1]), y[0].dot(y[2]), y[1].dot(y[2])};
  const double a[3] = {d12.squaredNorm(), d13.squaredNorm(), d23.squaredNorm()};
  Eigen::Matrix3d m12, m13, m23;
  m12 << 1, -c[0], 0, -c[0], 1, 0, 0, 0, 0;
  m13 << 1, 0, -c[1], 0, 0, 0, -c[1], 0, 1;
  m23 << 0, 0, 0, 0, 1, -c[2], 0, -c[2], 1;
  const Eigen::Matrix3d d1 = a[2] * m12 - a[0] * m23;
  const Eigen::Matrix3d d2 = a[2] * m13 - a[1] * m23;

  const double k3 = d2.determinant();
  if (!(std::abs(k3) > 1e-14 * scale2 * scale2 * scale2)) return 0;
  const double k2 = (d1 * Adjugate(d2)).trace();
  const double k1 = (Adjugate(d1) * d2).trace();
  const double k0 = d1.determinant();
  double gammas[3];
  const int num_gammas = SolveMonicCubic(k2 / k3, k1 / k3, k0 / k3, gammas);

  // The first root whose degenerate conic is a real pair of planes.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen;
  bool found = false;
  for (int g = num_gammas - 1; g >= 0 && !found; --g) {
    eigen.computeDirect(d1 + gammas[g] * d2);
    const Eigen::Vector3d& s = eigen.eigenvalues();  // ascending
    found = s[0] < 0 && s[2] > 0;
  }
  if (!found) return 0;
  const Eigen::Vector3d& s = eigen.eigenvalues();
  const Eigen::Vector3d e_a = eigen.eigenvectors().col(0);
  const Eigen::Vector3d e_c = eigen.eigenvectors().col(2);
  const double ratio = std::sqrt(-s[0] / s[2]);
  // Sum of the three rigidity equations: lambda^T S lambda = a12 + a13 + a23.
  Eigen::Matrix3d sum;
  sum << 2, -c[0], -c[1], -c[0], 2, -c[2], -c[1], -c[2], 2;
  const double a_sum = a[0] + a[1] + a[2];

  const Eigen::Matrix3d world_basis_inv = world_basis.inverse();
  int count = 0;
  for (const double sign : {1.0, -1.0}) {
    const Eigen::Vector3d normal = (e_c - sign * ratio * e_a).normalized();
    // Orthonormal basis (u, w) of the plane normal . lambda = 0.
    const Eigen::Vector3d u = normal.unitOrthogonal();
    const Eigen::Vector3d w = normal.cross(u);
    const double qa = u.dot(d2 * u), qb = u.dot(d2 * w), qc = w.dot(d2 * w);
    const double disc = qb * qb - qa * qc;
    if (disc < 0) continue;
    const double root = std::sqrt(disc);
    for (const double branch : {1.0, -1.0}) {
      Eigen::Vector3d dir;
      if (std::abs(qa) >= std::abs(qc)) {
        if (qa == 0) continue;
        dir = ((-qb + branch * root) / qa) * u + w;
      } else {
        dir = u + ((-qb + branch * root) / qc) * w;
      }
      if (dir[0] < 0) dir = -dir;
      if (dir[1] <= 0 || dir[2] <= 0 || dir[0] <= 0) continue;
      const double norm = dir.dot(sum * dir);
      if (!(norm > 0)) continue;
      Eigen::Vector3d lambda = dir * std::sqrt(a_sum / norm);
      PolishDepths(c, a, &lambda);
      if (!(lambda.minCoeff() > 0) || !lambda.allFinite()) continue;
      const Eigen::Vector3d p[3] = {lambda[0] * y[0], lambda[1] * y[1], lambda[2] * y[2]};
      Eigen::Matrix3d cam_basis;
      cam_basis.col(0) = p[0] - p[1];
      cam_basis.col(1) = p[0] - p[2];
      cam_basis.col(2) = cam_basis.col(0).cross(cam_basis.col(1));
      const Eigen::Matrix3d r = cam_basis * world_basis_inv;
      // Nearest rotation (exact solutions are rotations already; this removes rounding).
      const Eigen::Quaterniond q(r);
      if (!q.coeffs().allFinite() || q.norm() < 1e-12) continue;
      Pose pose = Pose::Identity();
      pose.linear() = q.normalized().toRotationMatrix();
      pose.translation() = p[0] - pose.linear() * points[0];
      cam_from_world->push_back(pose);
      ++count;
    }
  }
  return count;
}

}  // namespace lifmcr::registration
