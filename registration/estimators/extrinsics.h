#pragma once
// c0_from_cx, the paper's H^{C0}_{CX}, from what each method estimates. The
// names decide the order of the factors (the paper prints its equations
// H_C0_CX_3DRANSAC and H_C0_CX_PnP with them the other way round):
//   PnP:        c0_from_cx = c0_from_w0 * w0_from_cx
//                          = (w0_from_c0)^-1 * w0_from_cx
//   3D RANSAC:  c0_from_cx = c0_from_w0 * w0_from_wx * wx_from_cx
// w0 is the reference map's frame (camera 0's calibration), wx camera X's own
// point-cloud frame; per frame, wx may be the camera itself (wx_from_cx = I).
// The estimates are independent, so their covariances add through the
// Jacobians of registration/estimators/pose_covariance.h.

#include "registration/estimators/pose_covariance.h"

namespace lifmcr::registration {

PoseWithCovariance C0FromCxByPnp(const PoseWithCovariance& w0_from_c0,
                                 const PoseWithCovariance& w0_from_cx);

PoseWithCovariance C0FromCxBy3d(const PoseWithCovariance& w0_from_c0,
                                const PoseWithCovariance& w0_from_wx,
                                const PoseWithCovariance& wx_from_cx);

}  // namespace lifmcr::registration
