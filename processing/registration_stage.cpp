// The composition of the per-trigger extrinsics (registration_stage.h).

#include "processing/registration_stage.h"

namespace lifmcr::processing {
namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Adjoint of T = (R, t) for xi = (rho, phi): Ad = [R, [t]x R; 0, R], so
// T exp(xi) T^-1 = exp(Ad xi).
Eigen::Matrix<double, 6, 6> Adjoint(const Eigen::Isometry3d& t) {
  Eigen::Matrix<double, 6, 6> ad = Eigen::Matrix<double, 6, 6>::Zero();
  const Eigen::Matrix3d r = t.rotation();
  ad.topLeftCorner<3, 3>() = r;
  ad.topRightCorner<3, 3>() = Skew(t.translation()) * r;
  ad.bottomRightCorner<3, 3>() = r;
  return ad;
}

}  // namespace

CameraPose ComposeExtrinsics(const CameraPose& w0_from_c0, const CameraPose& w0_from_cx) {
  CameraPose out = w0_from_cx;
  const Eigen::Isometry3d c0_from_w0 = w0_from_c0.transform.inverse();
  out.transform = c0_from_w0 * w0_from_cx.transform;
  // With A = exp(a) A_hat, B = exp(b) B_hat: A^-1 B ~ exp(Ad(A_hat^-1) (b - a)) A_hat^-1 B_hat,
  // a and b independent.
  const bool known_c0 = !w0_from_c0.covariance.isZero(0);
  const bool known_cx = !w0_from_cx.covariance.isZero(0);
  if (known_c0 && known_cx) {
    const Eigen::Matrix<double, 6, 6> ad = Adjoint(c0_from_w0);
    out.covariance = ad * (w0_from_cx.covariance + w0_from_c0.covariance) * ad.transpose();
  } else {
    out.covariance.setZero();
  }
  if (w0_from_c0.status != "ok") out.status = "reference camera: " + w0_from_c0.status;
  return out;
}

const char* ToString(ExtrinsicsChange::State state) {
  switch (state) {
    case ExtrinsicsChange::State::kSettling: return "settling";
    case ExtrinsicsChange::State::kSteady: return "steady";
    case ExtrinsicsChange::State::kDeparting: return "departing";
    case ExtrinsicsChange::State::kChanged: return "CHANGED";
  }
  return "?";
}

CameraPose RegistrationStage::Relate(const std::string& /*serial*/, std::int64_t /*trigger_index*/,
                                     const CameraPose& w0_from_c0, const CameraPose& w0_from_cx) {
  return ComposeExtrinsics(w0_from_c0, w0_from_cx);
}

}  // namespace lifmcr::processing
