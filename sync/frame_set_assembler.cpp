#include "sync/frame_set_assembler.h"

#include <cmath>
#include <cstdlib>
#include <utility>

namespace lifmcr {

FrameSetAssemblerOptions FrameSetAssemblerOptions::FromRig(const RigConfig& rig) {
  FrameSetAssemblerOptions options;
  for (const CameraConfig& camera : rig.cameras) {
    options.serials.push_back(camera.serial);
    options.device_clocks.push_back(camera.device_clock);
  }
  options.vicon_expected = rig.vicon.source != ViconSourceKind::kNone;
  options.vicon_divider = rig.vicon.trigger_divider;
  options.vicon_rate_hz = rig.vicon.rate_hz;
  options.trigger.trigger_period_ns =
      std::llround(1e9 * rig.vicon.trigger_divider / rig.vicon.rate_hz);
  options.vicon_phase_tolerance_ns = std::llround(0.5e9 / rig.vicon.rate_hz);
  return options;
}

Status FrameSetAssemblerOptions::Check() const {
  auto bad = [](const std::string& what) { return Status(Error{"frame set assembler: " + what}); };
  if (serials.empty()) return bad("serials: expected at least one camera");
  if (!device_clocks.empty() && device_clocks.size() != serials.size())
    return bad("device_clocks: expected none or one per camera (" + std::to_string(serials.size()) +
               "), got " + std::to_string(device_clocks.size()));
  if (Status s = trigger.Check(); !s) return bad(s.error().message);
  if (Status s = clock.Check(); !s) return bad(s.error().message);
  if (vicon_divider < 1) return bad("vicon_divider: expected >= 1");
  if (!(vicon_rate_hz > 0.0) || !std::isfinite(vicon_rate_hz))
    return bad("vicon_rate_hz: expected > 0 Hz");
  if (vicon_phase_tolerance_ns <= 0) return bad("vicon_phase_tolerance_ns: expected > 0");
  if (lateness_ns <= 0) return bad("lateness_ns: expected > 0");
  if (max_vicon_frames < 16) return bad("max_vicon_frames: expected >= 16");
  // vicon_expected, vicon_f0 (any frame number), vicon_arrival_offset_ns (either sign): any.
  return Status::Ok();
}

namespace {
std::vector<std::string> ClocksOf(const FrameSetAssemblerOptions& options) {
  std::vector<std::string> clocks = options.device_clocks;
  clocks.resize(options.serials.size());
  return clocks;
}
}  // namespace

FrameSetAssembler::FrameSetAssembler(FrameSetAssemblerOptions options)
    : options_(std::move(options)),
      placer_(options_.trigger.trigger_period_ns, options_.trigger.tolerance, ClocksOf(options_)) {
  cameras_.reserve(options_.serials.size());
  for (const std::string& serial : options_.serials) {
    Camera camera{TriggerTracker(options_.trigger), ClockModel(options_.clock), -1, {}, {}};
    camera.stats.serial = serial;
    cameras_.push_back(std::move(camera));
  }
  f0_ = options_.vicon_f0;
}

std::int64_t FrameSetAssembler::TriggerHostNs(std::int64_t trigger_index) const {
  return grid_host_ns_ + (trigger_index - grid_trigger_) * options_.trigger.trigger_period_ns;
}

std::int64_t FrameSetAssembler::TriggerByHostTime(const Camera& camera,
                                                  std::int64_t device_ns) const {
  const double steps = static_cast<double>(camera.clock.HostFromDevice(device_ns) - grid_host_ns_) /
                       static_cast<double>(options_.trigger.trigger_period_ns);
  return grid_trigger_ + std::llround(steps);
}

std::optional<std::int64_t> FrameSetAssembler::AddFrame(Frame frame,
                                                        std::optional<std::int64_t> first_trigger) {
  const int index = frame.camera_index;
  if (index < 0 || index >= static_cast<int>(cameras_.size())) {
    drops_.Add(DropKind::kFrameWithoutTrigger);  // a camera the rig does not have
    return std::nullopt;
  }
  Camera& camera = cameras_[index];
  ++camera.stats.frames;
  // A failed frame's timestamps are not trusted to steer the clock model
  // (its device time still places it, and it goes out as failed).
  const ClockUpdate clock = frame.status == FrameStatus::kOk || !camera.clock.valid()
                                ? camera.clock.Add(frame.device_ns, frame.host_ns)
                                : ClockUpdate{};
  if (clock.jump) drops_.Add(DropKind::kClockJump);
  if (!started_) {
    started_ = true;
    grid_trigger_ = first_trigger.value_or(0);
    grid_host_ns_ = camera.clock.HostFromDevice(frame.device_ns);
  }
  Association association;
  if (camera.tracker.anchored()) association = camera.tracker.Add(frame.frame_id, frame.device_ns);
  // A jump in the host offset alone (frames delivered late under load) is not
  // a reason to move the camera off its trigger grid: while the device time
  // and counter still step from trigger to trigger, they decide. Only a frame
  // they cannot place after a jump (the device clock or counter restarted) is
  // re-anchored by host time.
  if (!camera.tracker.anchored() ||
      (clock.jump && association.verdict != FrameVerdict::kAssociated)) {
    association = Association{};
    std::optional<FirstPlacement> placement;
    if (!camera.tracker.anchored() && first_trigger) {
      placement = FirstPlacement{};
      placement->trigger_index = *first_trigger;
      placement->by = FirstPlacement::By::kTriggerCount;
    } else if (!camera.tracker.anchored()) {
      placement = placer_.ByDeviceTime(index, frame.device_ns);
    }
    if (!placement) {
      placement = FirstPlacement{};
      placement->trigger_index = TriggerByHostTime(camera, frame.device_ns);
    }
    association.trigger_index = placement->trigger_index;
    camera.tracker.Anchor(association.trigger_index, frame.frame_id, frame.device_ns);
    if (!camera.first_placement) {
      if (placement->by == FirstPlacement::By::kHostTime)
        placement->note = placer_.WhyNotByDeviceTime(index, frame.device_ns);
      camera.first_placement = placement;
    }
  }
  const std::int64_t k = association.trigger_index;
  if (association.verdict == FrameVerdict::kOffGrid ||
      association.verdict == FrameVerdict::kRepeatedTrigger || k < 0) {
    drops_.Add(DropKind::kFrameWithoutTrigger);
    ++camera.stats.without_trigger;
    return std::nullopt;
  }
  if (origin_ && k < *origin_) {
    ++camera.stats.before_all_armed;  // its trigger is already dropped as before the origin
    return k;
  }
  if (k < next_emit_) {
    drops_.Add(DropKind::kLateFrame);
    ++camera.stats.late;
    return std::nullopt;
  }
  if (association.counter_mismatch) {
    drops_.Add(DropKind::kCounterMismatch);
    ++camera.stats.counter_mismatches;
  }
  camera.stats.lost_after_exposure += static_cast<std::uint64_t>(association.lost_after_exposure);
  camera.stats.not_exposed += static_cast<std::uint64_t>(association.not_exposed);
  Pending& pending = pending_[k];
  if (pending.frames.empty()) pending.frames.resize(cameras_.size());
  if (pending.frames[index].has_value()) {  // only after a re-anchor: keep the first
    drops_.Add(DropKind::kFrameWithoutTrigger);
    ++camera.stats.without_trigger;
    return std::nullopt;
  }
  if (association.verdict == FrameVerdict::kAssociated) {
    camera.last_trigger = std::max(camera.last_trigger, k);
    grid_trigger_ = k;
    grid_host_ns_ = camera.clock.HostFromDevice(frame.device_ns);
    placer_.Placed(index, k, frame.device_ns);
  }
  last_trigger_seen_ = std::max(last_trigger_seen_, k);
  pending.frames[index] = std::move(frame);
  return k;
}

void FrameSetAssembler::AddVicon(ViconFrame frame) {
  if (last_vicon_ >= 0) {
    if (frame.vicon_frame <= last_vicon_) {
      drops_.Add(DropKind::kViconOutOfOrder);
      return;
    }
    if (frame.vicon_frame > last_vicon_ + 1)
      drops_.Add(DropKind::kViconGap,
                 static_cast<std::uint64_t>(frame.vicon_frame - last_vicon_ - 1));
  }
  last_vicon_ = frame.vicon_frame;
  if (!options_.vicon_expected) return;
  // Frames before the next trigger's Vicon frame fired no pending trigger.
  if (f0_ && frame.vicon_frame < *f0_ + options_.vicon_divider * next_emit_) return;
  vicon_.emplace(frame.vicon_frame, std::move(frame));
  while (vicon_.size() > options_.max_vicon_frames) vicon_.erase(vicon_.begin());
}

std::optional<std::int64_t> FrameSetAssembler::SetHostNs(const Pending* pending) const {
  if (pending == nullptr) return std::nullopt;
  double sum = 0.0;
  int count = 0;
  std::int64_t base = 0;
  for (std::size_t i = 0; i < pending->frames.size(); ++i) {
    if (!pending->frames[i]) continue;
    const std::int64_t host = cameras_[i].clock.HostFromDevice(pending->frames[i]->device_ns);
    if (count == 0) base = host;
    sum += static_cast<double>(host - base);
    ++count;
  }
  if (count == 0) return std::nullopt;
  return base + std::llround(sum / count);
}

void FrameSetAssembler::TryEstablishF0(std::int64_t trigger_index, bool forced) {
  if (f0_ || vicon_.empty()) return;
  auto it = pending_.find(trigger_index);
  const std::int64_t target = SetHostNs(it == pending_.end() ? nullptr : &it->second)
                                  .value_or(TriggerHostNs(trigger_index)) +
                              options_.vicon_arrival_offset_ns;
  const ViconFrame* best = nullptr;
  bool seen_past = false;
  for (const auto& [number, vicon] : vicon_) {
    if (vicon.host_ns > target + options_.vicon_phase_tolerance_ns) seen_past = true;
    if (best == nullptr || std::llabs(vicon.host_ns - target) < std::llabs(best->host_ns - target))
      best = &vicon;
  }
  if (!seen_past && !forced) return;  // a nearer frame may still come
  // The Vicon frame number at the target time, extrapolated from the nearest
  // frame received (the trigger's own frame may be the one lost).
  const double frames_from_best =
      static_cast<double>(target - best->host_ns) * options_.vicon_rate_hz * 1e-9;
  const std::int64_t step = std::llround(frames_from_best);
  if (std::llabs(step) > options_.vicon_divider) return;  // too far to count on the rate
  const double off_ns =
      std::abs(frames_from_best - static_cast<double>(step)) * 1e9 / options_.vicon_rate_hz;
  if (off_ns > static_cast<double>(options_.vicon_phase_tolerance_ns)) return;
  f0_ = best->vicon_frame + step - options_.vicon_divider * trigger_index;
}

bool FrameSetAssembler::Ready(std::int64_t k, std::int64_t now_host_ns) {
  const bool late = now_host_ns - TriggerHostNs(k) > options_.lateness_ns;
  auto it = pending_.find(k);
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    const bool has = it != pending_.end() && it->second.frames[i].has_value();
    if (!has && cameras_[i].last_trigger <= k && !late) return false;
  }
  if (!options_.vicon_expected || late) return true;
  TryEstablishF0(k, false);
  if (!f0_) return false;
  const std::int64_t vicon_frame = *f0_ + options_.vicon_divider * k;
  return vicon_.count(vicon_frame) > 0 || last_vicon_ > vicon_frame;
}

FrameSet FrameSetAssembler::Emit(std::int64_t k) {
  FrameSet set;
  set.trigger_index = k - origin_.value_or(0);
  set.vicon_frame = -1;
  auto it = pending_.find(k);
  const std::optional<std::int64_t> set_host =
      SetHostNs(it == pending_.end() ? nullptr : &it->second);
  set.frames.resize(cameras_.size());
  if (it != pending_.end()) set.frames = std::move(it->second.frames);
  for (std::size_t i = 0; i < cameras_.size(); ++i) {
    Camera& camera = cameras_[i];
    const std::optional<Frame>& frame = set.frames[i];
    if (!frame) {
      set.missing.push_back(
          {static_cast<int>(i), camera.stats.serial, "no frame for this trigger"});
      drops_.Add(DropKind::kCameraMissedTrigger);
      ++camera.stats.missed_triggers;
      continue;
    }
    ++camera.stats.in_sets;
    if (frame->status != FrameStatus::kOk) {
      set.missing.push_back({static_cast<int>(i), camera.stats.serial,
                             "frame " + std::string(ToString(frame->status))});
      drops_.Add(DropKind::kCameraFrameFailed);
      ++camera.stats.failed;
    }
  }
  if (it != pending_.end()) pending_.erase(it);
  if (options_.vicon_expected) {
    if (f0_) {
      set.vicon_frame = *f0_ + options_.vicon_divider * k;
      auto vicon = vicon_.find(set.vicon_frame);
      if (vicon != vicon_.end()) {
        const std::int64_t expected =
            set_host.value_or(TriggerHostNs(k)) + options_.vicon_arrival_offset_ns;
        if (std::llabs(vicon->second.host_ns - expected) > options_.vicon_phase_tolerance_ns)
          drops_.Add(DropKind::kViconPhaseMismatch);
        set.vicon = std::move(vicon->second);
      }
      // Older Vicon frames fired no pending trigger.
      vicon_.erase(vicon_.begin(), vicon_.lower_bound(set.vicon_frame + options_.vicon_divider));
    }
    if (!set.vicon) drops_.Add(DropKind::kViconMissingForTrigger);
  }
  next_emit_ = k + 1;
  return set;
}

void FrameSetAssembler::SetOrigin(std::int64_t origin) {
  if (!origin_) origin_ = origin;
}

void FrameSetAssembler::DropBeforeOrigin() {
  while (origin_ && next_emit_ < *origin_) {
    auto it = pending_.find(next_emit_);
    if (it != pending_.end()) {
      for (std::size_t i = 0; i < cameras_.size(); ++i)
        if (it->second.frames[i]) ++cameras_[i].stats.before_all_armed;
      pending_.erase(it);
    }
    if (next_emit_ <= last_trigger_seen_) ++triggers_before_origin_;
    ++next_emit_;
  }
}

std::vector<FrameSet> FrameSetAssembler::Poll(std::int64_t now_host_ns) {
  std::vector<FrameSet> sets;
  if (options_.wait_for_origin && !origin_) return sets;
  DropBeforeOrigin();
  while (next_emit_ <= last_trigger_seen_ && Ready(next_emit_, now_host_ns)) {
    if (options_.vicon_expected && !f0_) TryEstablishF0(next_emit_, true);
    sets.push_back(Emit(next_emit_));
  }
  return sets;
}

std::vector<FrameSet> FrameSetAssembler::Flush() {
  std::vector<FrameSet> sets;
  SetOrigin(0);  // no-op once set
  DropBeforeOrigin();
  while (next_emit_ <= last_trigger_seen_) {
    if (options_.vicon_expected && !f0_) TryEstablishF0(next_emit_, true);
    sets.push_back(Emit(next_emit_));
  }
  return sets;
}

std::vector<CameraSyncStats> FrameSetAssembler::camera_stats() const {
  std::vector<CameraSyncStats> stats;
  for (const Camera& camera : cameras_) {
    stats.push_back(camera.stats);
    stats.back().clock = camera.clock.OneLine();
    if (camera.first_placement) {
      FirstPlacement placement = *camera.first_placement;
      placement.trigger_index -= origin_.value_or(0);
      stats.back().first_placement = placement.OneLine();
    }
  }
  return stats;
}

}  // namespace lifmcr
