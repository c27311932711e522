#pragma once
// Metric depth on the TF grid and the coloured metric point cloud of a frame
// (camera frame, mm; camera_model.h). TF pixel (u, w) with virtual depth v is
// the virtual point (2u + 0.5, 2w + 0.5, v), back-projected by the camera
// model (thin lens, distortion). Uncertainty: sigma_v = v^2 sigma_z
// (z = 1/v) and sigma_Z = |dZ/dv| sigma_v with
//   Z(v) = f_L b / (b - f_L),  b = b_L0 + v B,  dZ/dv = -f_L^2 B / (b - f_L)^2.
// Plain buffers here; processing/ply.h writes them as a PLY file.

#include "processing/camera_model.h"
#include "processing/total_focus.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <vector>

namespace lifmcr::processing {

// Camera z (mm) per TF pixel, NaN where the TF depth map is empty.
void MetricDepthTf(const CameraModel& camera, const TfDepthMap& depth,
                   std::vector<float>* depth_mm);

struct PointCloud {
  std::vector<Eigen::Vector3f> points_mm;        // camera frame
  std::vector<std::array<std::uint8_t, 3>> rgb;  // colour of the TF pixel
  std::vector<float> sigma_z_mm;                 // NaN for filled (not measured) pixels
};

// One point per TF pixel with depth (measured only, or filled too), skipping
// points behind the front focal plane.
void BuildPointCloud(const CameraModel& camera, const TfDepthMap& depth, const TfImage& tf,
                     bool measured_only, PointCloud* cloud);

}  // namespace lifmcr::processing
