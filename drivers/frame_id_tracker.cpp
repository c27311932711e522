#include "drivers/frame_id_tracker.h"

#include "drivers/frame_counter.h"

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
  // A zero seen once: the device counts on the full ring of 65536.
  const CounterRing ring{width_ == FrameIdWidth::k64Bit ? 64 : 16, !zero_seen_};
  const std::int64_t delta = ring.Delta(*last_, id);
  const bool backwards = delta <= 0;
  const auto step = static_cast<std::uint64_t>(delta);
  last_ = id;
  if (backwards) {
    ++restarts_;
    return 0;
  }
  missing_ += step - 1;
  return step - 1;
}

}  // namespace lifmcr
