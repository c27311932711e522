#include "replay/vicon_interpolation.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace lifmcr {

Pose InterpolatePose(const Pose& a, const Pose& b, double s) {
  const Eigen::Quaterniond qa(a.linear());
  const Eigen::Quaterniond qb(b.linear());
  Pose result = Pose::Identity();
  result.linear() = qa.slerp(s, qb).normalized().toRotationMatrix();
  result.translation() = (1.0 - s) * a.translation() + s * b.translation();
  return result;
}

std::optional<Pose> PoseAtViconFrame(std::span<const ViconPoseSample> samples, double vicon_frame,
                                     int max_gap_frames) {
  if (samples.empty() || !std::isfinite(vicon_frame)) return std::nullopt;
  // First sample with frame >= vicon_frame.
  auto after = std::lower_bound(samples.begin(), samples.end(), vicon_frame,
                                [](const ViconPoseSample& sample, double f) {
                                  return static_cast<double>(sample.vicon_frame) < f;
                                });
  if (after == samples.end()) return std::nullopt;
  if (static_cast<double>(after->vicon_frame) == vicon_frame) return after->vicon_from_marker;
  if (after == samples.begin()) return std::nullopt;
  const auto before = after - 1;
  if (!before->vicon_from_marker || !after->vicon_from_marker) return std::nullopt;
  const std::int64_t span = after->vicon_frame - before->vicon_frame;
  if (span <= 0 || span > max_gap_frames) return std::nullopt;
  const double s =
      (vicon_frame - static_cast<double>(before->vicon_frame)) / static_cast<double>(span);
  return InterpolatePose(*before->vicon_from_marker, *after->vicon_from_marker, s);
}

}  // namespace lifmcr
