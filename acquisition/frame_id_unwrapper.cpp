#include "acquisition/frame_id_unwrapper.h"

#include "drivers/frame_counter.h"

namespace lifmcr {

FrameIdUnwrapper::Step FrameIdUnwrapper::Next(std::uint64_t frame_id) {
  Step step;
  if (!last_id_) {
    wide_ = frame_id > 65535;
    last_id_ = frame_id;
    last_index_ = 0;
    return step;
  }
  if (frame_id > 65535) wide_ = true;
  // 16-bit ids 1..65535 (0 skipped) until an id says the counter is wider.
  const std::int64_t delta = CounterRing{wide_ ? 64 : 16, true}.Delta(*last_id_, frame_id);
  if (delta <= 0) {
    step.stale = true;
    step.index = last_index_;
    return step;
  }
  last_id_ = frame_id;
  last_index_ += delta;
  step.index = last_index_;
  step.missing_before = delta - 1;
  return step;
}

void FrameIdUnwrapper::Rebase(std::uint64_t frame_id, std::int64_t index) {
  last_id_ = frame_id;
  wide_ = wide_ || frame_id > 65535;
  last_index_ = index;
}

}  // namespace lifmcr
