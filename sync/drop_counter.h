#pragma once
// What the synchronisation lost or found wrong, counted by kind. Every lost
// frame or pose ends up in exactly one loss kind; the anomaly kinds flag
// things that were wrong but lost nothing by themselves.

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace lifmcr {

enum class DropKind {
  // Losses.
  kCameraMissedTrigger,     // a FrameSet emitted with no frame of a camera
  kCameraFrameFailed,       // a camera's frame for the trigger came with a failed status
  kFrameWithoutTrigger,     // a frame off the trigger grid, a second one for a trigger, or one
                            // before the rig's first trigger: not in any FrameSet
  kLateFrame,               // a frame whose FrameSet was already emitted (lateness bound)
  kViconGap,                // Vicon frame numbers never received (each number counts once)
  kViconMissingForTrigger,  // a FrameSet emitted without its Vicon frame
  // Anomalies.
  kCounterMismatch,     // a camera's frame counter advanced more than its triggers
  kViconOutOfOrder,     // a Vicon frame not newer than the last one, dropped
  kViconPhaseMismatch,  // a trigger's Vicon frame received far from the trigger's time
  kClockJump,           // a camera's device clock jumped against the host clock
  kCount,
};
inline constexpr int kDropKindCount = static_cast<int>(DropKind::kCount);

// snake_case names as in logs and reports: "camera_missed_trigger", ...
std::string_view ToString(DropKind kind);
bool IsLoss(DropKind kind);

class DropCounter {
 public:
  void Add(DropKind kind, std::uint64_t count = 1) { counts_[static_cast<int>(kind)] += count; }
  std::uint64_t operator[](DropKind kind) const { return counts_[static_cast<int>(kind)]; }
  // Sum of the loss kinds (what makes `lifmcr record` exit non-zero).
  std::uint64_t lost() const;
  std::uint64_t anomalies() const;
  // The non-zero kinds, "camera_missed_trigger=2 vicon_gap=5", or "no drops".
  std::string OneLine() const;
  bool operator==(const DropCounter&) const = default;

 private:
  std::array<std::uint64_t, kDropKindCount> counts_{};
};

}  // namespace lifmcr
