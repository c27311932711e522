#pragma once
// Which trigger a camera's frame belongs to (docs/architecture.md, sync): by
// time on the trigger grid, cross-checked with the camera's frame counter
// (drivers/frame_counter.h).
//
// A frame is placed relative to the camera's previous associated frame:
//   steps = (device_ns - previous_device_ns) / trigger_period_ns
//   trigger_index = previous_index + round(steps)
// and must lie within `tolerance` periods of the grid (|steps - round(steps)|
// <= tolerance), else it belongs to no trigger. Using the previous frame (not
// the first) as the reference absorbs a slow drift between the camera's
// clock and the trigger generator. The first frame of a camera is anchored
// by the caller (FrameSetAssembler: from the host time of the rig's first
// trigger).
//
// The reference itself can be off the grid the later triggers follow: a
// software trigger thread that starts late on a loaded host fires trigger 0
// late and the rest on schedule (seen: trigger 0 28 ms late at 10 Hz under
// CPU hogs, every later frame then 0.72 periods from it and none placed).
// So an off-grid frame becomes a candidate reference, its trigger taken from
// the frame counter (previous_index + counted, when counted is one of the two
// triggers either side of it); when the next frame is also off the reference's
// grid but on the candidate's, with the counter agreeing (counted == steps),
// two frames outvote one: the candidate becomes the reference and the frame
// is associated (Association::reanchored). The candidate frame itself stays
// off-grid (already reported).
//
// The device frame counter (16-bit on GigE Vision 1, wrapping and skipping 0;
// the fake camera starts at 65400 on purpose) counts frames the camera
// produced. Between two associated frames `triggers = index - previous` and
// `counted = counter delta` (wrap-aware):
//   counted == triggers: every trigger exposed; triggers - 1 frames were lost
//                        after exposure (transport, buffers);
//   counted <  triggers: triggers - counted triggers were never exposed;
//   counted >  triggers: the camera produced frames on no trigger we know
//                        (a counter mismatch, counted, the time decides).
// Gaps of more than 2^bits - 2 frames make the counter check ambiguous: it
// is then skipped and the time alone decides.

#include "config/error.h"

#include <cstdint>
#include <optional>
#include <string_view>

namespace lifmcr {

struct TriggerTrackerOptions {
  std::int64_t trigger_period_ns = 100'000'000;  // 80 Hz Vicon / divider 8; > 0
  double tolerance = 0.25;         // allowed distance from the grid, periods, (0, 0.5)
  int counter_bits = 16;           // 16 (GigE Vision 1 block id) .. 64 (no wrap)
  bool counter_skips_zero = true;  // GigE Vision block ids go 65535 -> 1
  bool operator==(const TriggerTrackerOptions&) const = default;
  Status Check() const;  // every field; the message names the field
};

enum class FrameVerdict {
  kAssociated,       // trigger_index is the frame's trigger
  kOffGrid,          // not within tolerance of any trigger: belongs to no trigger
  kRepeatedTrigger,  // a second frame for the previous frame's trigger
  kOlderTrigger,     // before the previous frame's trigger (reordered); trigger_index is set
};
std::string_view ToString(FrameVerdict verdict);

struct Association {
  FrameVerdict verdict = FrameVerdict::kAssociated;
  std::int64_t trigger_index = 0;
  double grid_error = 0.0;  // steps - round(steps), periods
  // Between the previous associated frame and this one (kAssociated only):
  std::int64_t triggers_skipped = 0;     // triggers with no frame of this camera
  std::int64_t lost_after_exposure = 0;  // of them, frames the counter shows were produced
  std::int64_t not_exposed = 0;          // of them, triggers the camera never exposed
  bool counter_mismatch = false;         // the counter advanced more than the triggers
  bool reanchored =
      false;  // placed from the off-grid frame before it (see above), not the reference
};

class TriggerTracker {
 public:
  explicit TriggerTracker(TriggerTrackerOptions options = {}) : options_(options) {}

  bool anchored() const { return previous_.has_value(); }
  // The first frame of the camera, placed by the caller at `trigger_index`.
  void Anchor(std::int64_t trigger_index, std::uint64_t frame_id, std::int64_t device_ns);
  // Every later frame (anchored() must be true).
  Association Add(std::uint64_t frame_id, std::int64_t device_ns);

  // Frames produced from id `from` to id `to` by a counter of
  // options.counter_bits (wrap-aware, skipping 0 on wrap when so configured):
  // 65534 -> 2 is 3 with skips (65535, 1, 2). Equal ids give 0 (a full wrap
  // cannot be told apart).
  std::uint64_t CounterDelta(std::uint64_t from, std::uint64_t to) const;

 private:
  struct Previous {
    std::int64_t trigger_index;
    std::uint64_t frame_id;
    std::int64_t device_ns;
  };
  // Counter bookkeeping between two associated frames `step` triggers apart.
  void Count(const Previous& from, std::uint64_t frame_id, std::int64_t step,
             Association& result) const;
  bool CounterUsable(std::int64_t step) const;

  TriggerTrackerOptions options_;
  std::optional<Previous> previous_;
  std::optional<Previous> candidate_;  // the last frame, off the reference's grid
};

}  // namespace lifmcr
