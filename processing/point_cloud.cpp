#include "processing/point_cloud.h"

#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>

namespace lifmcr::processing {

void MetricDepthTf(const CameraModel& camera, const TfDepthMap& depth,
                   std::vector<float>* depth_mm) {
  depth_mm->resize(depth.virtual_depth.size());
  tbb::parallel_for(std::size_t{0}, depth.virtual_depth.size(), [&](std::size_t t) {
    const float v = depth.virtual_depth[t];
    (*depth_mm)[t] = std::isnan(v) ? std::numeric_limits<float>::quiet_NaN()
                                   : static_cast<float>(camera.DepthOfVirtualDepth(v));
  });
}

void BuildPointCloud(const CameraModel& camera, const TfDepthMap& depth, const TfImage& tf,
                     bool measured_only, PointCloud* cloud) {
  cloud->points_mm.clear();
  cloud->rgb.clear();
  cloud->sigma_z_mm.clear();
  const CameraIntrinsics& k = camera.intrinsics();
  const int channels = BytesPerPixel(tf.format);
  for (int w = 0; w < depth.height; ++w)
    for (int u = 0; u < depth.width; ++u) {
      const std::size_t t = static_cast<std::size_t>(w) * depth.width + u;
      const float v = depth.virtual_depth[t];
      if (std::isnan(v) || v <= 0) continue;
      const bool measured = !std::isnan(depth.sigma_z[t]);
      if (measured_only && !measured) continue;
      const Eigen::Vector2d raw = CameraModel::RawOfTf(Eigen::Vector2d(u, w));
      const Eigen::Vector3d p = camera.BackProject({raw.x(), raw.y(), v});
      if (!(p.z() > k.main_focal_length_mm) || !std::isfinite(p.z())) continue;
      cloud->points_mm.push_back(p.cast<float>());
      const std::uint8_t* c = tf.pixels.data() + t * channels;
      cloud->rgb.push_back(channels == 3 ? std::array<std::uint8_t, 3>{c[2], c[1], c[0]}
                                         : std::array<std::uint8_t, 3>{c[0], c[0], c[0]});
      float sigma = std::numeric_limits<float>::quiet_NaN();
      if (measured) {
        const double b = k.mla_to_main_lens_mm + v * k.mla_to_sensor_mm;
        const double f = k.main_focal_length_mm;
        const double dz_dv = f * f * k.mla_to_sensor_mm / ((b - f) * (b - f));
        sigma = static_cast<float>(dz_dv * v * v * depth.sigma_z[t]);
      }
      cloud->sigma_z_mm.push_back(sigma);
    }
}

}  // namespace lifmcr::processing
