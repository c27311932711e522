#include "registration/features/detector_offset.h"

#include <cstddef>
#include <cstdint>

namespace lifmcr::registration {

std::vector<int> PairByPosition(const Features& a, const std::vector<Eigen::Vector2f>& b_xy,
                                const Features& b, float radius_px) {
  std::vector<int> out(a.keypoints.size(), -1);
  for (std::size_t i = 0; i < a.keypoints.size(); ++i) {
    float best = radius_px * radius_px;
    for (std::size_t j = 0; j < b_xy.size(); ++j) {
      const float d2 = (a.keypoints[i].xy_px - b_xy[j]).squaredNorm();
      if (d2 >= best) continue;
      const float size_ratio = a.keypoints[i].size / b.keypoints[j].size;
      if (size_ratio < 0.8f || size_ratio > 1.25f) continue;
      best = d2;
      out[i] = static_cast<int>(j);
    }
  }
  return out;
}

Expected<std::vector<DetectorOffset>> DetectorOffsetsByTurning(ConstImageView image,
                                                               const Features& on_image,
                                                               const FeatureOptions& options) {
  if (image.format != PixelFormat::kMono8 && image.format != PixelFormat::kBgr8)
    return Error{"DetectorOffsetsByTurning: a Mono8 or BGR8 image was expected"};
  const int bytes = image.format == PixelFormat::kBgr8 ? 3 : 1;
  const std::size_t row_bytes = static_cast<std::size_t>(image.width) * bytes;
  std::vector<std::uint8_t> turned(row_bytes * image.height);
  for (int y = 0; y < image.height; ++y) {
    const std::uint8_t* src = image.data + static_cast<std::size_t>(y) * image.stride_bytes;
    std::uint8_t* dst = turned.data() + static_cast<std::size_t>(image.height - 1 - y) * row_bytes;
    for (int x = 0; x < image.width; ++x)
      for (int c = 0; c < bytes; ++c)
        dst[static_cast<std::size_t>(image.width - 1 - x) * bytes + c] =
            src[static_cast<std::size_t>(x) * bytes + c];
  }
  Features on_turned;
  if (Status s = DetectSift(
          ConstImageView(turned.data(), image.width, image.height, row_bytes, image.format),
          options, &on_turned);
      !s)
    return s.error();
  std::vector<Eigen::Vector2f> back;
  back.reserve(on_turned.keypoints.size());
  for (const Keypoint& k : on_turned.keypoints)
    back.emplace_back(image.width - 1 - k.xy_px.x(), image.height - 1 - k.xy_px.y());
  const std::vector<int> pairs = PairByPosition(on_image, back, on_turned, 1.0f);
  std::vector<DetectorOffset> out;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (pairs[i] < 0) continue;
    const Eigen::Vector2f r = on_image.keypoints[i].xy_px;
    const Eigen::Vector2f r_turned = on_turned.keypoints[pairs[i]].xy_px;
    out.push_back({static_cast<int>(i),
                   0.5f * Eigen::Vector2f(r.x() + r_turned.x() - (image.width - 1),
                                          r.y() + r_turned.y() - (image.height - 1))});
  }
  return out;
}

}  // namespace lifmcr::registration
