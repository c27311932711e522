#pragma once
// The uncertainty of a point a plenoptic camera measures, for the 3D RANSAC
// (registration/estimators/rigid_3d.h) and PnP's sample check (registration/estimators/pnp.h).
//
// A plenoptic point is back-projected from its TF pixel and its virtual
// depth v. With the TF pixel fixed, the point moves along the TF pinhole's
// ray through the front focal point F = (0, 0, f_L)
// (registration/estimators/tf_projection.h) as v varies, by
//   dZ/dv = -B (Z - f_L)^2 / f_L^2           (thin lens, Z = f_L b / (b - f_L))
// in depth, i.e. sigma_ray = |dZ/dv| sigma_v / r_z along the unit ray r, and
// laterally by the keypoint noise, sigma_lat = 2 sigma_tf s (Z - f_L) / f_L
// (a TF pixel is two raw pixels). So
//   Sigma = sigma_lat^2 (I - r r^T) + sigma_ray^2 r r^T,
// which grows quadratically with distance and lies along the viewing ray.

#include "processing/camera_model.h"

#include <Eigen/Core>

namespace lifmcr::registration {

// Sigma for a point measured at p_in_cam (mm) with virtual-depth noise
// sigma_v and keypoint noise sigma_tf_px (TF pixels).
Eigen::Matrix3d PlenopticPointCovariance(const processing::CameraModel& camera,
                                         const Eigen::Vector3d& p_in_cam, double sigma_v,
                                         double sigma_tf_px);

// sigma_ray^2 alone (the trace of Sigma without keypoint noise).
double PlenopticRayVariance(const processing::CameraModel& camera, const Eigen::Vector3d& p_in_cam,
                            double sigma_v);

}  // namespace lifmcr::registration
