#pragma once
// Vicon poses of the live pipeline: objects of a ViconFrame, and the Vicon
// frame at a host time. The interpolation itself (InterpolatePose,
// PoseAtViconFrame) lives in replay/vicon_interpolation.h so that offline
// evaluation shares it.

#include "config/frames.h"
#include "drivers/vicon_source.h"
#include "replay/vicon_interpolation.h"
#include "replay/vicon_poses.h"

#include <cstdint>
#include <optional>
#include <span>
#include <string_view>

namespace lifmcr {

// The pose of `object` in a frame, nullopt when absent or untracked.
std::optional<Pose> ObjectPose(const ViconFrame& frame, std::string_view object);

// The Vicon frame (fractional) at host time `host_ns`, given a Vicon frame
// `reference_frame` known to be at `reference_host_ns` and the Vicon rate.
double ViconFrameAt(std::int64_t reference_frame, std::int64_t reference_host_ns,
                    std::int64_t host_ns, double rate_hz);

}  // namespace lifmcr
