#include "sync/drop_counter.h"

namespace lifmcr {

std::string_view ToString(DropKind kind) {
  switch (kind) {
    case DropKind::kCameraMissedTrigger:
      return "camera_missed_trigger";
    case DropKind::kCameraFrameFailed:
      return "camera_frame_failed";
    case DropKind::kFrameWithoutTrigger:
      return "frame_without_trigger";
    case DropKind::kLateFrame:
      return "late_frame";
    case DropKind::kViconGap:
      return "vicon_gap";
    case DropKind::kViconMissingForTrigger:
      return "vicon_missing_for_trigger";
    case DropKind::kCounterMismatch:
      return "counter_mismatch";
    case DropKind::kViconOutOfOrder:
      return "vicon_out_of_order";
    case DropKind::kViconPhaseMismatch:
      return "vicon_phase_mismatch";
    case DropKind::kClockJump:
      return "clock_jump";
    case DropKind::kCount:
      break;
  }
  return "?";
}

bool IsLoss(DropKind kind) { return kind < DropKind::kCounterMismatch; }

std::uint64_t DropCounter::lost() const {
  std::uint64_t sum = 0;
  for (int i = 0; i < kDropKindCount; ++i)
    if (IsLoss(static_cast<DropKind>(i))) sum += counts_[i];
  return sum;
}

std::uint64_t DropCounter::anomalies() const {
  std::uint64_t sum = 0;
  for (int i = 0; i < kDropKindCount; ++i)
    if (!IsLoss(static_cast<DropKind>(i))) sum += counts_[i];
  return sum;
}

std::string DropCounter::OneLine() const {
  std::string line;
  for (int i = 0; i < kDropKindCount; ++i) {
    if (counts_[i] == 0) continue;
    if (!line.empty()) line += ' ';
    line += std::string(ToString(static_cast<DropKind>(i))) + "=" + std::to_string(counts_[i]);
  }
  return line.empty() ? "no drops" : line;
}

}  // namespace lifmcr
