#include "registration/features/keypoint_depth.h"

#include <algorithm>
#include <cmath>

namespace lifmcr::registration {

float VirtualDepthRange(const std::vector<float>& tf_virtual_depth, int width, int height,
                        const Eigen::Vector2f& tf_px, int radius_tf_px) {
  const int cx = static_cast<int>(std::lround(tf_px.x()));
  const int cy = static_cast<int>(std::lround(tf_px.y()));
  const int r = std::max(radius_tf_px, 0);
  std::vector<float> values;
  values.reserve(static_cast<std::size_t>((2 * r + 1) * (2 * r + 1)));
  int in_disc = 0;
  for (int dy = -r; dy <= r; ++dy)
    for (int dx = -r; dx <= r; ++dx) {
      if (dx * dx + dy * dy > r * r) continue;
      ++in_disc;
      const int x = cx + dx, y = cy + dy;
      if (x < 0 || y < 0 || x >= width || y >= height) continue;
      const float v = tf_virtual_depth[static_cast<std::size_t>(y) * width + x];
      if (!std::isnan(v)) values.push_back(v);
    }
  if (values.empty() || 2 * static_cast<int>(values.size()) < in_disc) return std::nanf("");
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  const float range = *hi - *lo;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return range / values[values.size() / 2];
}

}  // namespace lifmcr::registration
