#include "registration/estimators/plenoptic_point_noise.h"

#include <Eigen/Geometry>

#include <algorithm>

namespace lifmcr::registration {

namespace {

// The unit ray from the front focal point through p and sigma_ray of the noise
// model (plenoptic_point_noise.h).
double RaySigma(const processing::CameraModel& camera, const Eigen::Vector3d& p, double sigma_v,
                Eigen::Vector3d* ray) {
  const processing::CameraIntrinsics& k = camera.intrinsics();
  const double f = k.main_focal_length_mm;
  const double depth_from_focus = std::max(p.z() - f, 1e-6);
  *ray = (p - Eigen::Vector3d(0, 0, f)).normalized();
  const double sigma_z = k.mla_to_sensor_mm * depth_from_focus * depth_from_focus / (f * f) * sigma_v;
  return sigma_z / std::max(ray->z(), 1e-6);
}

}  // namespace

Eigen::Matrix3d PlenopticPointCovariance(const processing::CameraModel& camera,
                                         const Eigen::Vector3d& p, double sigma_v,
                                         double sigma_tf_px) {
  const processing::CameraIntrinsics& k = camera.intrinsics();
  const double f = k.main_focal_length_mm;
  const double depth_from_focus = std::max(p.z() - f, 1e-6);
  Eigen::Vector3d ray;
  const double sigma_ray = RaySigma(camera, p, sigma_v, &ray);
  const double sigma_lat = 2.0 * sigma_tf_px * k.pixel_size_mm * depth_from_focus / f;
  const Eigen::Matrix3d along = ray * ray.transpose();
  return sigma_lat * sigma_lat * (Eigen::Matrix3d::Identity() - along) +
         sigma_ray * sigma_ray * along;
}

double PlenopticRayVariance(const processing::CameraModel& camera, const Eigen::Vector3d& p,
                            double sigma_v) {
  Eigen::Vector3d ray;
  const double sigma_ray = RaySigma(camera, p, sigma_v, &ray);
  return sigma_ray * sigma_ray;
}

}  // namespace lifmcr::registration
