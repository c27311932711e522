#include "acquisition/frame_id_unwrapper.h"

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
  std::int64_t delta = 0;
  if (wide_) {
    delta = static_cast<std::int64_t>(frame_id - *last_id_);
  } else {
    // 16-bit ids 1..65535 -> 0..65534, difference modulo 65535.
    const std::int64_t now = static_cast<std::int64_t>(frame_id == 0 ? kPeriod16 : frame_id) - 1;
    const std::int64_t before =
        static_cast<std::int64_t>(*last_id_ == 0 ? kPeriod16 : *last_id_) - 1;
    delta = ((now - before) % kPeriod16 + kPeriod16) % kPeriod16;
    if (delta > kPeriod16 / 2) delta -= kPeriod16;  // behind: late or repeated
  }
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
