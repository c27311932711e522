#include "registration/calibration/plenoptic_projection.h"

namespace lifmcr::registration {

IntrinsicsVector ToVector(const processing::CameraIntrinsics& k) {
  const Eigen::Vector2d c = k.PrincipalPointPx();
  return {k.main_focal_length_mm, k.mla_to_main_lens_mm, k.mla_to_sensor_mm, c.x(), c.y(),
          k.k1, k.k2, k.p1, k.p2};
}

processing::CameraIntrinsics FromVector(const IntrinsicsVector& v,
                                        const processing::CameraIntrinsics& sensor) {
  processing::CameraIntrinsics k = sensor;
  k.main_focal_length_mm = v[0];
  k.mla_to_main_lens_mm = v[1];
  k.mla_to_sensor_mm = v[2];
  k.principal_point_px = Eigen::Vector2d(v[3], v[4]);
  k.k1 = v[5];
  k.k2 = v[6];
  k.p1 = v[7];
  k.p2 = v[8];
  return k;
}

}  // namespace lifmcr::registration
