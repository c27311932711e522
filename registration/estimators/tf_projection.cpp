#include "registration/estimators/tf_projection.h"

#include <ceres/jet.h>

namespace lifmcr::registration {

bool TfProjection::DistortedWithJacobian(const Eigen::Vector3d& p, Eigen::Vector2d* tf,
                                         Eigen::Matrix<double, 2, 3>* jacobian) const {
  using Jet = ceres::Jet<double, 3>;
  const Jet jp[3] = {Jet(p.x(), 0), Jet(p.y(), 1), Jet(p.z(), 2)};
  Jet out[2];
  if (!(*this)(jp, out)) return false;
  *tf = Eigen::Vector2d(out[0].a, out[1].a);
  jacobian->row(0) = out[0].v.transpose();
  jacobian->row(1) = out[1].v.transpose();
  return true;
}

}  // namespace lifmcr::registration
