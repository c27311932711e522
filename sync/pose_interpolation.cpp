#include "sync/pose_interpolation.h"

#include <algorithm>
#include <cmath>

namespace lifmcr {

std::optional<Pose> ObjectPose(const ViconFrame& frame, std::string_view object) {
  for (const ViconObjectPose& pose : frame.objects) {
    if (pose.name == object) return pose.vicon_from_marker;
  }
  return std::nullopt;
}

double ViconFrameAt(std::int64_t reference_frame, std::int64_t reference_host_ns,
                    std::int64_t host_ns, double rate_hz) {
  return static_cast<double>(reference_frame) +
         static_cast<double>(host_ns - reference_host_ns) * rate_hz * 1e-9;
}

}  // namespace lifmcr
