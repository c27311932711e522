#pragma once
// Which trigger a camera's first frame belongs to (docs/architecture.md,
// "Trigger numbering"). Every later frame of a camera is placed from its own
// previous one (TriggerTracker, FrameIdUnwrapper); the first has no previous
// one, so it is placed against another camera's frames.
//
// By device time, when a camera that shares its device clock (the same
// non-empty `device_clock` name: replay cameras of one sequence, cameras
// synchronised by PTP, or stamped by one frame grabber) already has frames
// on the trigger count. The clock's offset to the trigger schedule is the
// median of (device_ns - trigger_index * trigger_period_ns) over the last
// kOffsetFrames frames placed on it (any camera; one frame stamped late
// does not move it), and
//   steps         = (device_ns - offset_ns) / trigger_period_ns
//   trigger_index = round(steps),
// accepted when |steps - round(steps)| <= tolerance (else the clocks do not
// agree with the grid and host time decides). The device clock stamps the
// exposure, so the placement does not depend on when the host got to the
// frame: a loaded machine delays arrival, not the stamp.
//
// By host time otherwise (the first camera of a clock, cameras with a clock
// of their own): the caller's rule (the assembler's clock models, or the
// controller's trigger schedule), which a loaded machine can mislead by the
// scheduling delay; the placement says which rule decided.
//
// Device frame counters are not compared across cameras: each starts where
// its camera's acquisition started (GigE Vision at 1, the Aravis simulator
// at 65400), so only within a camera do they count triggers.
//
// Not thread-safe: the caller serialises (one assembler thread, or a mutex).

#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

struct FirstPlacement {
  // kTriggerCount: a software-triggered camera's first frame answers the
  // first trigger the rig fired to it (the caller counts them).
  enum class By { kDeviceTime, kHostTime, kTriggerCount };
  std::int64_t trigger_index = 0;
  By by = By::kHostTime;
  int reference_camera = -1;  // kDeviceTime: the camera of the latest frame on its clock
  double grid_error = 0.0;    // kDeviceTime: steps - round(steps), periods
  std::string note;           // kHostTime: why not by device time (WhyNotByDeviceTime)
  // "trigger 3 by device time against camera 0 (grid error +0.02 periods)",
  // or "trigger 3 by host time (no camera on its device clock placed yet)".
  std::string OneLine() const;
};

class FirstFramePlacer {
 public:
  // `device_clocks[c]` names camera c's device clock ("" = a clock of its own).
  FirstFramePlacer(std::int64_t trigger_period_ns, double tolerance,
                   std::vector<std::string> device_clocks);

  // A frame of `camera` is on `trigger_index` (any frame, first or later):
  // the reference for cameras sharing its clock.
  void Placed(int camera, std::int64_t trigger_index, std::int64_t device_ns);
  // The first frame of `camera` by device time against the frames placed on
  // its clock; nullopt when none is (host time then decides).
  std::optional<FirstPlacement> ByDeviceTime(int camera, std::int64_t device_ns) const;
  // Why ByDeviceTime gave nothing, for the host-time placement's log line.
  std::string WhyNotByDeviceTime(int camera, std::int64_t device_ns) const;

  const std::string& device_clock(int camera) const { return clocks_[camera]; }

  static constexpr std::size_t kOffsetFrames = 16;

 private:
  struct Clock {
    std::deque<std::int64_t> offsets_ns;  // device_ns - k * period of its latest frames
    int latest_camera = -1;
  };
  const Clock* ClockOf(int camera) const;
  // steps of `device_ns` from the clock's offset (its median).
  double Steps(const Clock& clock, std::int64_t device_ns) const;

  std::int64_t period_ns_;
  double tolerance_;
  std::vector<std::string> clocks_;
  std::map<std::string, Clock> by_name_;
};

}  // namespace lifmcr
