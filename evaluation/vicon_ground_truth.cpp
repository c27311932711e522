#include "evaluation/vicon_ground_truth.h"

#include "replay/vicon_interpolation.h"

#include <cmath>

namespace lifmcr {

Status FrameAssociationOptions::Check() const {
  if (trigger_divider < 1) return Error{"frame association: trigger_divider must be >= 1"};
  if (max_gap_frames < 1) return Error{"frame association: max_gap_frames must be >= 1"};
  if (!std::isfinite(vicon_frame_offset))
    return Error{"frame association: vicon_frame_offset must be finite"};
  return Status::Ok();
}

double FrameAssociationOptions::ViconFrameOf(std::int64_t frame) const {
  return static_cast<double>(vicon_frame_of_first_trigger +
                             static_cast<std::int64_t>(trigger_divider) * (frame - first_frame)) +
         vicon_frame_offset;
}

AssociatedPoses AssociateFrames(std::span<const ViconPoseSample> samples,
                                std::span<const std::int64_t> frames,
                                const FrameAssociationOptions& options) {
  AssociatedPoses result;
  for (std::int64_t frame : frames) {
    const std::optional<Pose> pose =
        PoseAtViconFrame(samples, options.ViconFrameOf(frame), options.max_gap_frames);
    if (pose)
      result.vicon_from_marker.emplace(frame, *pose);
    else
      result.untracked.push_back(frame);
  }
  return result;
}

std::vector<std::int64_t> FramesCoveredBy(std::span<const ViconPoseSample> samples,
                                          const FrameAssociationOptions& options) {
  std::vector<std::int64_t> frames;
  if (samples.empty()) return frames;
  const double first = static_cast<double>(samples.front().vicon_frame);
  const double last = static_cast<double>(samples.back().vicon_frame);
  const double div = options.trigger_divider;
  // Smallest n with v(n) >= first, then every n with v(n) <= last.
  std::int64_t n = options.first_frame +
                   static_cast<std::int64_t>(std::ceil((first - options.ViconFrameOf(options.first_frame)) / div));
  for (; options.ViconFrameOf(n) <= last; ++n)
    if (options.ViconFrameOf(n) >= first) frames.push_back(n);
  return frames;
}

}  // namespace lifmcr
