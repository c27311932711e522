#pragma once
// Everything the rig captured for one camera trigger: the frame of every
// camera (or why it is missing) and the Vicon frame that fired the trigger.
// A FrameSet is complete or explicitly incomplete; it is never silently
// short of a camera.

#include "drivers/frame.h"
#include "drivers/vicon_source.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

struct MissingFrame {
  int camera_index = 0;
  std::string serial;
  std::string reason;  // "no frame for this trigger", "frame incomplete (lost packets)", ...
};

struct FrameSet {
  std::int64_t trigger_index = 0;  // 0 for the first trigger of the run
  // The Vicon frame the trigger fired on (f0 + divider * trigger_index); -1
  // while f0 is not established and when the rig has no Vicon source.
  std::int64_t vicon_frame = 0;
  std::vector<std::optional<Frame>> frames;  // one entry per camera of the rig, by camera index
  std::vector<MissingFrame> missing;         // one entry per empty (or failed) camera slot
  std::optional<ViconFrame> vicon;           // empty when that Vicon frame was not received

  // Every camera's frame, valid, and the Vicon frame. (A rig without Vicon
  // has no complete sets; check missing.empty() there.)
  bool complete() const { return missing.empty() && vicon.has_value(); }
};

}  // namespace lifmcr
