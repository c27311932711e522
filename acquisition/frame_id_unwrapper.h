#pragma once
// Turns a camera's frame counter into a run-relative frame index and counts
// the frames its gaps say were lost (the counter arithmetic is
// drivers/frame_counter.h's).
//
// GigE Vision 1 block ids are 16-bit and skip 0 (..., 65534, 65535, 1, 2, ...;
// Aravis' fake camera starts at 65400 to expose wrap bugs), so a counter that
// starts below 65536 is read modulo 65535 with 0 skipped. A counter that goes
// above 65535 (GigE Vision 2 extended ids, GenTL, replay) is read as a plain
// 64-bit number. The first frame is index 0; a later one is the previous
// index plus the counter's step. A step of 0 or one that goes backwards by
// less than half the counter's range is a stale frame (repeated or late), not
// a new one.

#include <cstdint>
#include <optional>

namespace lifmcr {

class FrameIdUnwrapper {
 public:
  struct Step {
    std::int64_t index = 0;           // run-relative frame index
    std::int64_t missing_before = 0;  // counter values skipped since the previous frame
    bool stale = false;               // a repeated or late frame: index is meaningless
  };

  Step Next(std::uint64_t frame_id);
  // Continues at `index` with `frame_id` as the new reference (after the
  // device restarted its counter, e.g. a reconnect). `index` must be greater
  // than last_index().
  void Rebase(std::uint64_t frame_id, std::int64_t index);
  // Index of the last accepted frame, -1 before the first.
  std::int64_t last_index() const { return last_index_; }

 private:
  std::optional<std::uint64_t> last_id_;
  bool wide_ = false;
  std::int64_t last_index_ = -1;
};

}  // namespace lifmcr
