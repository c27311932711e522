#include "sync/trigger_tracker.h"

#include "drivers/frame_counter.h"

#include <cmath>

namespace lifmcr {

Status TriggerTrackerOptions::Check() const {
  if (trigger_period_ns <= 0) return Error{"trigger: trigger_period_ns: expected > 0"};
  if (!(tolerance > 0.0 && tolerance < 0.5))
    return Error{"trigger: tolerance: expected in (0, 0.5) periods"};
  if (counter_bits < 2 || counter_bits > 64) return Error{"trigger: counter_bits: expected 2..64"};
  // counter_skips_zero: either.
  return Status::Ok();
}

std::string_view ToString(FrameVerdict verdict) {
  switch (verdict) {
    case FrameVerdict::kAssociated:
      return "associated";
    case FrameVerdict::kOffGrid:
      return "off the trigger grid";
    case FrameVerdict::kRepeatedTrigger:
      return "second frame for one trigger";
    case FrameVerdict::kOlderTrigger:
      return "older than the previous frame's trigger";
  }
  return "?";
}

void TriggerTracker::Anchor(std::int64_t trigger_index, std::uint64_t frame_id,
                            std::int64_t device_ns) {
  previous_ = Previous{trigger_index, frame_id, device_ns};
  candidate_.reset();
}

std::uint64_t TriggerTracker::CounterDelta(std::uint64_t from, std::uint64_t to) const {
  return CounterRing{options_.counter_bits, options_.counter_skips_zero}.Forward(from, to);
}

bool TriggerTracker::CounterUsable(std::int64_t step) const {
  return options_.counter_bits >= 64 ||
         step < static_cast<std::int64_t>((std::uint64_t{1} << options_.counter_bits) - 2);
}

void TriggerTracker::Count(const Previous& from, std::uint64_t frame_id, std::int64_t step,
                           Association& result) const {
  result.triggers_skipped = step - 1;
  if (!CounterUsable(step)) return;
  const auto counted = static_cast<std::int64_t>(CounterDelta(from.frame_id, frame_id));
  if (counted > step || counted == 0) {
    result.counter_mismatch = true;
    result.lost_after_exposure = step - 1;  // unknown split: the time decides
  } else {
    result.lost_after_exposure = counted - 1;
    result.not_exposed = step - counted;
  }
}

Association TriggerTracker::Add(std::uint64_t frame_id, std::int64_t device_ns) {
  Association result;
  const Previous previous = *previous_;
  const auto period = static_cast<double>(options_.trigger_period_ns);
  const double steps = static_cast<double>(device_ns - previous.device_ns) / period;
  const double nearest = std::round(steps);
  const auto step = static_cast<std::int64_t>(nearest);
  result.grid_error = steps - nearest;
  result.trigger_index = previous.trigger_index + step;
  if (std::abs(result.grid_error) > options_.tolerance) {
    // Two off-grid frames on one grid, the counter agreeing: the reference was off.
    if (candidate_) {
      const double from_candidate = static_cast<double>(device_ns - candidate_->device_ns) / period;
      const auto s = static_cast<std::int64_t>(std::round(from_candidate));
      if (s >= 1 && std::abs(from_candidate - static_cast<double>(s)) <= options_.tolerance &&
          CounterUsable(s) &&
          static_cast<std::int64_t>(CounterDelta(candidate_->frame_id, frame_id)) == s) {
        result = Association{};
        result.trigger_index = candidate_->trigger_index + s;
        result.grid_error = from_candidate - static_cast<double>(s);
        result.reanchored = true;
        Count(*candidate_, frame_id, s, result);
        previous_ = Previous{result.trigger_index, frame_id, device_ns};
        candidate_.reset();
        return result;
      }
    }
    candidate_.reset();
    if (steps > 0 && CounterUsable(step + 1)) {
      const auto counted = static_cast<std::int64_t>(CounterDelta(previous.frame_id, frame_id));
      if (counted >= 1 && std::abs(steps - static_cast<double>(counted)) < 1.0)
        candidate_ = Previous{previous.trigger_index + counted, frame_id, device_ns};
    }
    result.verdict = FrameVerdict::kOffGrid;
    return result;
  }
  candidate_.reset();
  if (step == 0) {
    result.verdict = FrameVerdict::kRepeatedTrigger;
    return result;
  }
  if (step < 0) {
    result.verdict = FrameVerdict::kOlderTrigger;
    return result;
  }
  Count(previous, frame_id, step, result);
  previous_ = Previous{result.trigger_index, frame_id, device_ns};
  return result;
}

}  // namespace lifmcr
