#include "registration/estimators/extrinsics.h"

namespace lifmcr::registration {

PoseWithCovariance C0FromCxByPnp(const PoseWithCovariance& w0_from_c0,
                                 const PoseWithCovariance& w0_from_cx) {
  return Compose(Inverse(w0_from_c0), w0_from_cx);
}

PoseWithCovariance C0FromCxBy3d(const PoseWithCovariance& w0_from_c0,
                                const PoseWithCovariance& w0_from_wx,
                                const PoseWithCovariance& wx_from_cx) {
  return Compose(Compose(Inverse(w0_from_c0), w0_from_wx), wx_from_cx);
}

}  // namespace lifmcr::registration
