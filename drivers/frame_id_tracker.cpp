#include "drivers/frame_id_tracker.h"

namespace lifmcr {

std::uint64_t FrameIdTracker::Observe(std::uint64_t id) {
  if (width_ == FrameIdWidth::k16Bit) {
    id &= 0xFFFF;
    if (id == 0) zero_seen_ = true;
  }
  if (!last_) {
    last_ = id;
    return 0;
  }
  std::uint64_t step = 0;
  bool backwards = false;
  if (width_ == FrameIdWidth::k64Bit) {
    backwards = id <= *last_;
    step = id - *last_;
  } else {
    // Position on the ring: 1..65535 -> 0..65534 when 0 is skipped.
    const std::uint64_t ring = zero_seen_ ? 65536 : 65535;
    const std::uint64_t offset = zero_seen_ ? 0 : 1;
    const std::uint64_t from = *last_ - (*last_ >= offset ? offset : 0);
    const std::uint64_t to = id - (id >= offset ? offset : 0);
    step = (to + ring - from) % ring;
    backwards = step == 0 || step > ring / 2;
  }
  last_ = id;
  if (backwards) {
    ++restarts_;
    return 0;
  }
  missing_ += step - 1;
  return step - 1;
}

}  // namespace lifmcr
