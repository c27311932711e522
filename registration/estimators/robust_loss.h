#pragma once
// The PnP refinement's robust losses. The objective 1/2 sum rho(s_i),
// s_i = |r_i|^2, is minimised as the plain least squares of r~_i = g r_i
// with g = sqrt(rho(s) / s), so |r~|^2 = rho(s) (registration/
// pnp_refinement.cpp); its Jacobian is the exact one of that map,
//   J~ = g J + h r r^T J,   h = (rho'(s) s - rho(s)) / (s^2 g).
// d(r~)/d(r) = g I + h r r^T has the eigenvalues g (across r) and
// rho'(s) / g (along r): positive for both losses. The polish before it
// (pnp.cpp) takes iteratively reweighted steps instead, weights rho'(s).
//   Huber:  rho(s) = s (s <= c),   2 sqrt(c s) - c (s > c)
//   Cauchy: rho(s) = c log(1 + s / c)
// c = scale^2.

#include <cmath>

namespace lifmcr::registration {

enum class PnpLoss { kHuber, kCauchy };

// log(1 + x) for x >= 0 without std::log1p, which took a fifth of the PnP
// refinement (perf, bench_pnp): std::log(1 + x) loses to the rounding of
// 1 + x at most 1.1e-16 / x relative, 1e-12 for x >= 1e-4; below that the
// series x - x^2/2 + x^3/3 - x^4/4 is exact to x^5/5 (2e-21).
inline double Log1pNonNegative(double x) {
  if (x >= 1e-4) return std::log(1.0 + x);
  return x * (1.0 - x * (0.5 - x * (1.0 / 3.0 - 0.25 * x)));
}

// rho'(s), the iteratively reweighted least squares weight of squared
// residual s.
inline double RobustWeight(PnpLoss loss, double c, double s) {
  if (loss == PnpLoss::kCauchy) return 1.0 / (1.0 + s / c);
  return s > c ? std::sqrt(c / s) : 1.0;
}

// g and h of the comment above for squared residual s.
inline void RobustCorrection(PnpLoss loss, double c, double s, double* g, double* h) {
  if (loss == PnpLoss::kHuber) {
    *g = 1;
    *h = 0;
    if (s > c) {
      const double root_s = std::sqrt(s), root_c = std::sqrt(c);
      const double rho = 2 * root_c * root_s - c, rho1 = root_c / root_s;
      *g = std::sqrt(rho / s);
      *h = (rho1 * s - rho) / (s * s * *g);
    }
    return;
  }
  if (!(s > 1e-12 * c)) {  // Cauchy's limit at s -> 0
    *g = 1;
    *h = -0.5 / c;
    return;
  }
  const double rho = c * Log1pNonNegative(s / c), rho1 = 1.0 / (1.0 + s / c);
  *g = std::sqrt(rho / s);
  *h = (rho1 * s - rho) / (s * s * *g);
}

}  // namespace lifmcr::registration
