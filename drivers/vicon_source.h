#pragma once
// Live and replayed Vicon poses: the Tracker UDP object stream, or a CSV
// export played back. Poses are right-handed (converted once, with the rig
// file's rotation representation and handedness; see config/frames.h).

#include "config/error.h"
#include "config/frames.h"

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

struct ViconObjectPose {
  std::string name;                       // object name as Vicon sends it ("cam0")
  std::optional<Pose> vicon_from_marker;  // empty when not tracked in this frame
};

struct ViconFrame {
  std::int64_t vicon_frame = 0;  // Vicon's frame number: the time axis of the rig
  std::int64_t host_ns = 0;      // host CLOCK_REALTIME at receipt (or the replay's equivalent)
  std::vector<ViconObjectPose> objects;
};

struct ViconSourceStats {
  std::uint64_t frames = 0;        // frames delivered
  std::uint64_t malformed = 0;     // packets or rows rejected (counted, never read past)
  std::uint64_t gaps = 0;          // Vicon frame numbers skipped between delivered frames
  std::uint64_t out_of_order = 0;  // frames older than the last one, dropped and counted
};

class ViconSource {
 public:
  virtual ~ViconSource() = default;
  virtual Status Start() = 0;
  virtual Status Stop() = 0;
  // The next frame, or nullopt when none arrived within `timeout` (or the
  // replay ended: see Finished).
  virtual Expected<std::optional<ViconFrame>> Next(std::chrono::milliseconds timeout) = 0;
  virtual bool Finished() const = 0;
  virtual ViconSourceStats Stats() const = 0;
};

}  // namespace lifmcr
