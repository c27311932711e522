#include "acquisition/rig_controller.h"

#include "acquisition/thread_priority.h"
#include "drivers/host_clock.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace lifmcr {
namespace {

std::string Fixed(double value, int digits) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", digits, value);
  return text;
}

}  // namespace

Status RigControllerOptions::Check() const {
  if (frame_timeout.count() <= 0 || frame_timeout.count() > 60'000)
    return Error{"rig controller: frame_timeout: expected 1..60000 ms"};
  if (!(trigger_hz >= 0 && trigger_hz <= 10'000))
    return Error{"rig controller: trigger_hz: expected 0..10000 (0: no software triggers)"};
  if (stale_frames_for_restart < 1)
    return Error{"rig controller: stale_frames_for_restart: expected >= 1"};
  if (drain.count() < 0) return Error{"rig controller: drain: expected >= 0 ms"};
  if (all_armed_wait.count() < 0 || all_armed_wait.count() > 60'000)
    return Error{"rig controller: all_armed_wait: expected 0..60000 ms"};
  if (sync_poll.count() <= 0) return Error{"rig controller: sync_poll: expected > 0 ms"};
  if (vicon_lead_triggers < 0) return Error{"rig controller: vicon_lead_triggers: expected >= 0"};
  if (vicon_lead_triggers > 0 && !sync)
    return Error{"rig controller: vicon_lead_triggers: needs sync (Vicon frames per trigger)"};
  if (vicon_realtime_priority < 0 || vicon_realtime_priority > 99)
    return Error{"rig controller: vicon_realtime_priority: expected 0..99 (0: ordinary)"};
  if (trigger_realtime_priority < 0 || trigger_realtime_priority > 99)
    return Error{"rig controller: trigger_realtime_priority: expected 0..99 (0: ordinary)"};
  if (sync) {
    if (Status s = sync->Check(); !s) return Error{"rig controller: sync: " + s.error().message};
  } else if (number_files_by_sync) {
    return Error{"rig controller: number_files_by_sync: needs sync"};
  }
  return Status::Ok();
}

std::uint64_t CameraHealth::Lost() const {
  return incomplete + missing_by_id + missing_in_gaps + no_frame_at_end + not_in_any_set +
         triggers_not_fired + recorder.lost();
}

std::string CameraHealth::LossLine() const {
  std::ostringstream out;
  out << "lost " << Lost() << " [incomplete " << incomplete << ", missing ids " << missing_by_id
      << ", missed while lost " << missing_in_gaps << ", no frame at end " << no_frame_at_end
      << ", trigger not fired in time " << triggers_not_fired << ", not in any FrameSet "
      << not_in_any_set << ", queue full " << recorder.dropped_queue_full << ", write error "
      << recorder.lost_write_error << ", after stop " << recorder.lost_stopped << "]";
  return out.str();
}

std::vector<std::string> RigHealth::LossLines() const {
  std::vector<std::string> lines;
  for (const CameraHealth& c : cameras)
    if (c.Lost() > 0) lines.push_back("camera " + c.serial + ": " + c.LossLine());
  if (has_vicon && (recorder.vicon_lost + vicon.gaps + vicon.malformed > 0))
    lines.push_back("Vicon: lost lines " + std::to_string(recorder.vicon_lost) +
                    ", frame-number gaps " + std::to_string(vicon.gaps) + ", malformed " +
                    std::to_string(vicon.malformed));
  if (has_sync && sync_drops.lost() > 0) lines.push_back("sync: " + sync_drops.OneLine());
  return lines;
}

std::uint64_t RigHealth::FramesLost() const {
  std::uint64_t lost = 0;
  for (const CameraHealth& camera : cameras) lost += camera.Lost();
  return lost;
}

bool RigHealth::AnythingLost() const {
  return FramesLost() > 0 || vicon.gaps > 0 || vicon.malformed > 0 || recorder.vicon_lost > 0 ||
         recorder.stop_reason.has_value() || (files_numbered_by_sync && sync_drops.lost() > 0);
}

std::string RigHealth::StatusLine() const {
  std::ostringstream out;
  out << Fixed(elapsed_s, 1) << "s";
  for (const CameraHealth& c : cameras) {
    out << " | " << c.serial << " " << Fixed(c.fps, 1) << "fps " << Fixed(c.mb_per_s, 1) << "MB/s q"
        << c.recorder.queue_depth << " rec" << c.recorder.written << " lost" << c.Lost();
  }
  if (has_vicon)
    out << " | Vicon " << Fixed(vicon_hz, 1) << "Hz gaps" << vicon.gaps << " bad"
        << vicon.malformed;
  out << " | disk backlog " << Fixed(static_cast<double>(recorder.backlog_bytes) / 1e6, 1) << "MB";
  if (recorder.stop_reason) out << " | STOPPED: " << *recorder.stop_reason;
  return out.str();
}

std::string RigHealth::FinalReport() const {
  std::ostringstream out;
  out << "recording: " << Fixed(elapsed_s, 1) << " s";
  if (triggers_fired > 0) out << ", " << triggers_fired << " software triggers";
  out << "\n";
  for (const CameraHealth& c : cameras) {
    out << "  camera " << c.serial << ": recorded " << c.recorder.written;
    if (c.counter_restarts > 0)
      out << " (" << c.counter_restarts << " reconnects/counter restarts, " << c.missing_in_gaps
          << " triggers missed in them)";
    if (c.recorder.written > 0)
      out << " (frames " << c.recorder.first_frame << ".." << c.recorder.last_frame << ")";
    out << ", " << c.LossLine() << "; driver: completed " << c.driver.completed << ", failed "
        << c.driver.failed << ", underruns " << c.driver.underruns << ", reconnects "
        << c.driver.reconnects;
    if (c.stale > 0) out << ", stale frames dropped " << c.stale;
    if (c.before_all_armed > 0)
      out << ", before all cameras armed " << c.before_all_armed << " (not written)";
    if (c.triggers_skipped > c.triggers_not_fired)
      out << ", software triggers skipped while failing " << c.triggers_skipped - c.triggers_not_fired;
    if (c.errors > 0) out << ", device errors " << c.errors << " (last: " << c.last_error << ")";
    if (!c.first_placement.empty()) out << "; first frame: " << c.first_placement;
    out << "\n";
  }
  if (triggers_before_all_armed > 0)
    out << "  start: " << triggers_before_all_armed << " trigger"
        << (triggers_before_all_armed == 1 ? "" : "s")
        << " before all cameras armed (not the run's: trigger 0 is the first every camera was "
           "armed for; their frames are not written, not lost)\n";
  if (has_vicon) {
    out << "  Vicon: received " << vicon.frames << ", written " << recorder.vicon_written
        << ", lost lines " << recorder.vicon_lost << ", frame-number gaps " << vicon.gaps
        << ", malformed " << vicon.malformed << ", out of order " << vicon.out_of_order;
    if (recorder.vicon_unknown_objects > 0)
      out << ", object poses not in the CSV header " << recorder.vicon_unknown_objects;
    out << "\n";
  }
  if (has_sync) {
    out << "  sync: " << frame_sets << " triggers (FrameSets), " << complete_frame_sets
        << (has_vicon ? " complete" : " with every camera's frame (no Vicon source)")
        << "; Vicon frame of trigger 0: "
        << (vicon_f0 ? std::to_string(*vicon_f0) : std::string("not established"))
        << "; drops: " << sync_drops.OneLine() << "\n";
    for (const CameraSyncStats& c : sync_cameras)
      out << "    " << c.serial << ": in sets " << c.in_sets << ", missed triggers "
          << c.missed_triggers << ", failed " << c.failed << ", without trigger "
          << c.without_trigger << ", late " << c.late << "; clock " << c.clock << "\n";
  }
  out << "  disk: " << recorder.OneLine() << "\n";
  out << (AnythingLost() ? "result: something was lost (see above)\n" : "result: nothing lost\n");
  return out.str();
}

RigController::RigController(std::vector<std::unique_ptr<Camera>> cameras,
                             std::vector<bool> software_trigger, std::unique_ptr<ViconSource> vicon,
                             Recorder* recorder, RigControllerOptions options, RigObserver observer)
    : vicon_(std::move(vicon)),
      recorder_(recorder),
      options_(options),
      observer_(std::move(observer)) {
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    auto slot = std::make_unique<CameraSlot>();
    slot->camera = std::move(cameras[i]);
    slot->software_trigger = i < software_trigger.size() && software_trigger[i];
    slots_.push_back(std::move(slot));
  }
}

RigController::~RigController() { Stop(); }

Status RigController::Start() {
  if (started_) return Error{"rig: already started"};
  if (Status s = options_.Check(); !s) return s;
  for (auto& slot : slots_) {
    if (Status s = slot->camera->Open(); !s) return s;
    slot->health.serial = slot->camera->Info().serial;
  }
  // The clock of each camera's device timestamps: the rig's word, else the driver's.
  std::vector<std::string> clocks(slots_.size());
  for (std::size_t i = 0; i < slots_.size(); ++i)
    clocks[i] = i < options_.device_clocks.size() && !options_.device_clocks[i].empty()
                    ? options_.device_clocks[i]
                    : slots_[i]->camera->Info().device_clock;
  if (options_.sync) {
    options_.sync->device_clocks = clocks;
    options_.sync->wait_for_origin = options_.start_at_all_armed;
    if (Status s = options_.sync->Check(); !s) return s;
  }
  {
    std::lock_guard<std::mutex> lock(anchor_mutex_);
    const std::int64_t period_ns =
        options_.trigger_hz > 0 ? std::llround(1e9 / options_.trigger_hz) : 100'000'000;
    placer_ = std::make_unique<FirstFramePlacer>(
        period_ns,
        options_.sync ? options_.sync->trigger.tolerance : TriggerTrackerOptions{}.tolerance,
        clocks);
    if (options_.start_at_all_armed) {
      armed_start_ = std::make_unique<ArmedStart>(static_cast<int>(slots_.size()), period_ns);
    } else {
      origin_ = 0;
      origin_known_ = true;
    }
  }
  if (vicon_) {
    if (Status s = vicon_->Start(); !s) return s;
  }
  if (options_.sync) {
    assembler_ = std::make_unique<FrameSetAssembler>(*options_.sync);
    syncing_ = true;
    sync_thread_ = std::thread([this] { SyncLoop(); });
  }
  spdlog::info("rig: {} camera(s), Vicon {}, software triggers at {} Hz, sync {}",
               slots_.size(), vicon_ ? "on" : "off", options_.trigger_hz,
               options_.sync ? "on" : "off");
  start_time_ = last_health_ = std::chrono::steady_clock::now();
  // The software trigger threads start here, raise their priority and wait
  // for the schedule, set as Start returns once they all wait (at most a
  // second). Created after it, a thread fired trigger 0 late on a loaded
  // host (a new thread waits a scheduler slice before it first runs and can
  // raise its priority; seen: trigger 0 28 to 174 ms late at 10 Hz beside
  // CPU hogs, the later ticks on time), so that frame was off the grid of
  // every later one (sync/trigger_tracker.h). Woken from the wait under
  // their priority, they fire trigger 0 on time.
  const bool fires_triggers = std::any_of(slots_.begin(), slots_.end(),
                                          [](const auto& slot) { return slot->software_trigger; });
  if (options_.trigger_hz > 0 && fires_triggers) {
    {
      std::lock_guard<std::mutex> lock(trigger_mutex_);
      schedule_set_.store(false);
      trigger_threads_ready_ = 0;
      ticks_begun_ = 0;
    }
    triggering_ = true;
    for (std::size_t i = 0; i < slots_.size(); ++i) {
      if (!slots_[i]->software_trigger) continue;
      trigger_threads_.emplace_back([this, i] { TriggerLoop(static_cast<int>(i)); });
    }
  }
  grabbing_ = true;
  // Each camera's grab thread starts as soon as the camera is armed, so its
  // frames are taken (and stamped on arrival) while the next camera arms
  // rather than waiting in the driver's queue. Its arm: the host time its
  // Start returned, and its device clock latched then where the device can
  // (sync/armed_start.h).
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    if (Status s = slots_[i]->camera->Start(); !s) {
      {
        std::lock_guard<std::mutex> lock(trigger_mutex_);
        triggering_ = false;
      }
      schedule_set_.store(true);  // the threads wake, see no triggering and end
      schedule_set_.notify_all();
      for (std::thread& thread : trigger_threads_) thread.join();
      trigger_threads_.clear();
      grabbing_ = false;
      for (std::size_t j = 0; j < i; ++j) {
        slots_[j]->thread.join();
        (void)slots_[j]->camera->Stop();
      }
      syncing_ = false;
      if (sync_thread_.joinable()) sync_thread_.join();
      if (vicon_) (void)vicon_->Stop();
      return s;
    }
    if (armed_start_ != nullptr) {
      const std::int64_t armed_host_ns = HostRealtimeNs();
      const std::optional<std::int64_t> armed_device_ns = slots_[i]->camera->ArmedDeviceNs();
      std::lock_guard<std::mutex> lock(anchor_mutex_);
      armed_start_->Armed(static_cast<int>(i), armed_host_ns, armed_device_ns);
    }
    slots_[i]->thread = std::thread([this, i] { GrabLoop(static_cast<int>(i)); });
  }
  if (armed_start_ != nullptr) {
    std::lock_guard<std::mutex> lock(anchor_mutex_);
    all_armed_host_ns_ = HostRealtimeNs();
  }
  started_ = true;
  if (vicon_) {
    vicon_running_ = true;
    vicon_thread_ = std::thread([this] { ViconLoop(); });
  }
  // The trigger schedule exists only when this controller fires triggers:
  // a hardware-triggered rig's first frames are not placed on it. It starts
  // as Start returns (callers time their own events from it); a trigger
  // thread woken late on a loaded host skips the ticks already past (counted).
  if (!trigger_threads_.empty()) {
    {
      std::unique_lock<std::mutex> lock(trigger_mutex_);
      trigger_ready_.wait_for(lock, std::chrono::seconds(1),
                              [&] { return trigger_threads_ready_ == trigger_threads_.size(); });
    }
    {
      std::lock_guard<std::mutex> anchor(anchor_mutex_);
      trigger_schedule_host_ns_ = HostRealtimeNs();
    }
    // The trigger threads wait on the atomic (a futex), not on a condition
    // variable under trigger_mutex_. There, this ordinary thread lost its
    // CPU to the first real-time thread it woke (or let have the mutex) and
    // the others waited for its next turn: beside 8 CPU hogs, tick 0 fired
    // 10-44 ms after the schedule's start in 5 of 25 runs (notified after
    // the unlock: one camera, exactly as late as the notify) and 8-35 ms in
    // 6 of 25 (notified under the lock: both); at 40 Hz a tick 0 more than
    // a period late skips ticks, "trigger not fired in time", lost
    // (Recorder.TwoCamerasAndViconEveryTriggerAccountedFor). Woken here,
    // they need nothing more from this thread.
    schedule_start_ = std::chrono::steady_clock::now();
    schedule_set_.store(true, std::memory_order_release);
    schedule_set_.notify_all();
  }
  return Status::Ok();
}

void RigController::Stop() {
  if (!started_) return;
  started_ = false;
  {
    std::lock_guard<std::mutex> lock(trigger_mutex_);
    triggering_ = false;
  }
  for (std::thread& thread : trigger_threads_) thread.join();
  trigger_threads_.clear();
  // Frames already triggered are still on their way: keep grabbing a moment.
  std::this_thread::sleep_for(options_.drain);
  grabbing_ = false;
  for (auto& slot : slots_)
    if (slot->thread.joinable()) slot->thread.join();
  for (auto& slot : slots_) (void)slot->camera->Stop();
  vicon_running_ = false;
  if (vicon_thread_.joinable()) vicon_thread_.join();
  if (vicon_) (void)vicon_->Stop();
  syncing_ = false;
  if (sync_thread_.joinable()) sync_thread_.join();
  if (assembler_) {
    std::vector<FrameSet> rest;
    {
      std::lock_guard<std::mutex> lock(sync_mutex_);
      rest = assembler_->Flush();
    }
    RecordSets(std::move(rest));
  }
}

void RigController::SyncLoop() {
  while (syncing_.load()) {
    std::vector<FrameSet> sets;
    {
      std::lock_guard<std::mutex> lock(sync_mutex_);
      sets = assembler_->Poll(HostRealtimeNs());
    }
    RecordSets(std::move(sets));
    std::this_thread::sleep_for(options_.sync_poll);
  }
}

void RigController::RecordSets(std::vector<FrameSet> sets) {
  std::uint64_t complete = 0;
  for (FrameSet& set : sets) {
    // Without a Vicon source no set can hold a Vicon frame: complete there
    // means every camera's frame is in it (FrameSet::complete's note).
    complete += (vicon_ ? set.complete() : set.missing.empty()) ? 1 : 0;
    if (observer_.on_frame_set) observer_.on_frame_set(set);
    if (!options_.number_files_by_sync) continue;  // the grab threads submitted them
    for (std::size_t c = 0; c < set.frames.size(); ++c) {
      std::optional<Frame>& frame = set.frames[c];
      if (!frame || frame->status != FrameStatus::kOk) continue;
      if (observer_.on_frame) observer_.on_frame(static_cast<int>(c), set.trigger_index, *frame);
      if (recorder_ != nullptr)
        recorder_->SubmitFrame(static_cast<int>(c), set.trigger_index, std::move(*frame));
    }
  }
  std::lock_guard<std::mutex> lock(sync_mutex_);
  frame_sets_ += sets.size();
  complete_frame_sets_ += complete;
}

void RigController::GrabLoop(int index) {
  CameraSlot& slot = *slots_[index];
  while (grabbing_.load()) {
    // Held frames go out as soon as the run's trigger 0 is known (decided on
    // another camera's thread, or by the wait's end).
    if (!slot.held.empty() || (slot.first_index && !slot.start_counted)) {
      if (const std::optional<std::int64_t> origin = Origin(false)) SettleStart(index, *origin);
    }
    Expected<std::optional<Frame>> next = slot.camera->NextFrame(options_.frame_timeout);
    if (!next) {
      std::lock_guard<std::mutex> lock(slot.mutex);
      ++slot.health.errors;
      slot.health.last_error = next.error().message;
      if (!slot.lost) spdlog::warn("camera {}: lost: {}", slot.health.serial, next.error().message);
      slot.lost = true;
      continue;  // the driver reconnects on the next call
    }
    if (!next->has_value()) continue;
    Frame frame = std::move(**next);
    frame.camera_index = index;
    frame.arrival_ns = HostRealtimeNs();  // the start of the latency to publication
    const std::size_t bytes =
        frame.image.stride_bytes * static_cast<std::size_t>(frame.image.height);
    std::int64_t frame_index = 0;
    // A camera's first good frame goes to the assembler first, so that the
    // trigger it places the frame on numbers the file too: the recording's
    // file numbers and the FrameSets' trigger indices (LCM trigger_index)
    // then count from one placement. (Only this grab thread touches the
    // unwrapper.)
    std::optional<std::int64_t> placed;
    std::optional<FirstPlacement> placed_by;
    bool in_assembler = false;
    const bool first_good = frame.status == FrameStatus::kOk && slot.unwrapper.last_index() < 0;
    // A camera this controller triggers answers the triggers in the order it
    // fired them, all after every camera was armed: its first good frame is
    // on the first trigger not answered by a failed frame. Its arrival time
    // would mislead: a busy host delivers it more than a period late at 50 Hz.
    std::optional<std::int64_t> by_trigger_count;
    if (first_good && slot.software_trigger && options_.trigger_hz > 0)
      by_trigger_count = static_cast<std::int64_t>(slot.health.failed_since_ok);
    if (assembler_ != nullptr && !options_.number_files_by_sync && first_good) {
      std::lock_guard<std::mutex> lock(sync_mutex_);
      placed = assembler_->AddFrame(frame, by_trigger_count);
      in_assembler = true;
      if (placed) placed_by = assembler_->first_placement(index);
    }
    if (first_good && !placed_by) {
      if (by_trigger_count) {
        placed_by = FirstPlacement{};
        placed_by->trigger_index = *by_trigger_count;
        placed_by->by = FirstPlacement::By::kTriggerCount;
      } else {
        placed_by = PlaceFirstFrame(index, frame);
      }
      placed = placed_by->trigger_index;
    }
    {
      std::lock_guard<std::mutex> lock(slot.mutex);
      if (frame.status != FrameStatus::kOk) {
        // A failed frame's id and timestamps may be garbage (its leader
        // packet can be the lost one): count it, keep it out of the counter
        // and clock bookkeeping; the next good frame's id gap covers it.
        ++slot.health.incomplete;
        ++slot.health.failed_since_ok;
        ++slot.interval_frames;
      } else {
        FrameIdUnwrapper::Step step;
        if (slot.unwrapper.last_index() < 0) {
          // The camera's first good frame: placed on the rig's trigger count
          // by host time from the rig's first frame (cameras armed at
          // different moments of a running trigger see different first
          // triggers), after any failed frames before it (each was a trigger).
          const auto failed = static_cast<std::int64_t>(slot.health.failed_since_ok);
          const std::int64_t first = std::max(*placed, failed);
          slot.first_placed = placed_by;
          if (first != *placed) slot.first_suffix = ", after its failed frames";
          spdlog::info("camera {}: first frame on {}{}", slot.health.serial, placed_by->OneLine(),
                       slot.first_suffix);
          (void)slot.unwrapper.Next(frame.frame_id);
          slot.unwrapper.Rebase(frame.frame_id, first);
          step.index = first;
          step.missing_before = first - failed;
          if (options_.start_at_all_armed) {
            // The triggers before it are missed only from the run's trigger
            // 0 on (SettleStart counts them once that is known).
            slot.first_index = first;
            slot.failed_before_first = failed;
            step.missing_before = 0;
            std::lock_guard<std::mutex> anchor(anchor_mutex_);
            armed_start_->FirstFrame(index, first, frame.device_ns, frame.host_ns);
          }
          slot.health.failed_since_ok = 0;
          slot.lost = false;
        } else if (!slot.lost) {
          step = slot.unwrapper.Next(frame.frame_id);
          slot.stale_in_a_row = step.stale ? slot.stale_in_a_row + 1 : 0;
        }
        const bool restarted =
            slot.unwrapper.last_index() >= 0 &&
            (slot.lost || slot.stale_in_a_row >= options_.stale_frames_for_restart);
        if (restarted) {
          // Ticks skipped after its last frame are in the silence below,
          // not triggers it missed while working.
          if (slot.health.counter_restarts == 0) {
            const std::int64_t last_answered = slot.unwrapper.last_index();
            for (auto it = slot.skips.begin(); it != slot.skips.end();) {
              if (static_cast<std::int64_t>(it->first) <= last_answered) {
                ++it;
                continue;
              }
              slot.health.triggers_not_fired -= it->second;
              it = slot.skips.erase(it);
            }
          }
          // The device restarted its counter (a reconnect): the triggers it
          // missed are its silence in host time over the trigger period.
          const double silence_s =
              slot.last_host_ns > 0 && frame.host_ns > slot.last_host_ns
                  ? static_cast<double>(frame.host_ns - slot.last_host_ns) * 1e-9
                  : 0.0;
          const auto triggers = std::max<std::int64_t>(
              1, static_cast<std::int64_t>(std::llround(silence_s * options_.trigger_hz)));
          // From its last frame's tick (mapped past the skipped ticks).
          const std::int64_t last_tick =
              slot.software_trigger && slot.health.counter_restarts == 0
                  ? TickOfTrigger(slot, slot.unwrapper.last_index())
                  : slot.unwrapper.last_index();
          slot.unwrapper.Rebase(frame.frame_id, last_tick + triggers);
          step = FrameIdUnwrapper::Step{slot.unwrapper.last_index(), 0, false};
          slot.health.missing_in_gaps += static_cast<std::uint64_t>(triggers - 1);
          ++slot.health.counter_restarts;
          spdlog::warn("camera {}: back after {:.1f} s; {} trigger(s) missed while it was lost",
                       slot.health.serial, silence_s, triggers - 1);
          slot.lost = false;
          slot.stale_in_a_row = 0;
        } else if (slot.lost) {
          // Lost before its first frame: nothing to rebase against.
          step = slot.unwrapper.Next(frame.frame_id);
          slot.lost = false;
        }
        if (step.stale) {
          ++slot.health.stale;
          continue;
        }
        // Ids skipped by failed frames already counted as incomplete.
        const auto missing = static_cast<std::uint64_t>(step.missing_before);
        slot.health.missing_by_id +=
            missing > slot.health.failed_since_ok ? missing - slot.health.failed_since_ok : 0;
        slot.health.failed_since_ok = 0;
        // Software triggers: the frame counter counts the triggers fired;
        // ticks skipped (a trigger call overran) are triggers of the rig too.
        // (After a counter restart the index is on the ticks already.)
        frame_index = slot.software_trigger && slot.health.counter_restarts == 0
                          ? TickOfTrigger(slot, step.index)
                          : step.index;
        slot.health.last_index = frame_index;
        slot.last_answered = step.index;
        slot.last_host_ns = frame.host_ns;
        {
          std::lock_guard<std::mutex> anchor(anchor_mutex_);
          placer_->Placed(index, frame_index, frame.device_ns);
        }
        ++slot.interval_frames;
        slot.interval_bytes += bytes;
        ++slot.health.received;
      }
    }
    if (assembler_ != nullptr && !in_assembler &&
        (frame.status == FrameStatus::kOk || options_.number_files_by_sync)) {
      // Observing, the assembler gets a copy sharing the buffer, and only
      // good frames: a failed frame's timestamps can be garbage (lost leader
      // packet) and would move the trigger grid of every camera; it is
      // counted here already. Numbering by sync, failed frames go in too, so
      // a set says why a camera's frame is missing.
      std::lock_guard<std::mutex> lock(sync_mutex_);
      if (options_.number_files_by_sync) {
        assembler_->AddFrame(std::move(frame));
        continue;
      }
      assembler_->AddFrame(frame);
    }
    if (frame.status != FrameStatus::kOk) continue;
    const std::optional<std::int64_t> origin =
        Origin(slot.held.size() + 1 >= RigControllerOptions::kMaxHeldFrames);
    if (!origin) {
      slot.held.emplace_back(frame_index, std::move(frame));
      continue;
    }
    SettleStart(index, *origin);  // frames held before this one first
    Submit(index, frame_index, *origin, std::move(frame));
  }
  if (options_.start_at_all_armed) SettleStart(index, *Origin(true));
}

std::optional<std::int64_t> RigController::Origin(bool force) {
  if (origin_known_.load()) return origin_.load();
  std::optional<std::int64_t> origin;
  {
    std::lock_guard<std::mutex> lock(anchor_mutex_);
    const bool was_decided = armed_start_->origin().has_value();
    const std::int64_t wait_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(options_.all_armed_wait).count();
    // The wait for first frames runs from the last camera's arm.
    const bool waited =
        all_armed_host_ns_.has_value() && HostRealtimeNs() >= *all_armed_host_ns_ + wait_ns;
    origin = armed_start_->Decide(force || waited);
    if (!origin) return std::nullopt;
    if (!was_decided) {
      for (std::size_t i = 0; i < slots_.size(); ++i)
        spdlog::info("camera {}: {}", slots_[i]->camera->Info().serial,
                     armed_start_->HasFirstFrame(static_cast<int>(i))
                         ? armed_start_->HowArmed(static_cast<int>(i)) +
                               ", from trigger " +
                               std::to_string(*armed_start_->ArmedFrom(static_cast<int>(i)))
                         : std::string("no frame yet"));
      spdlog::info("rig: trigger 0 of the run is trigger {} of the first frames' count (the "
                   "first every camera was armed for)",
                   *origin);
    }
  }
  if (assembler_ != nullptr) {
    std::lock_guard<std::mutex> lock(sync_mutex_);
    assembler_->SetOrigin(*origin);
  }
  origin_ = *origin;
  origin_known_ = true;
  return origin;
}

void RigController::SettleStart(int index, std::int64_t origin) {
  CameraSlot& slot = *slots_[index];
  if (slot.first_index && !slot.start_counted) {
    std::lock_guard<std::mutex> lock(slot.mutex);
    const std::int64_t missing =
        std::max<std::int64_t>(0, *slot.first_index - origin) - slot.failed_before_first;
    if (missing > 0) slot.health.missing_by_id += static_cast<std::uint64_t>(missing);
    slot.start_counted = true;
  }
  std::vector<std::pair<std::int64_t, Frame>> held = std::move(slot.held);
  slot.held.clear();
  for (auto& [frame_index, frame] : held) Submit(index, frame_index, origin, std::move(frame));
}

void RigController::Submit(int index, std::int64_t frame_index, std::int64_t origin, Frame frame) {
  if (frame_index < origin) {
    std::lock_guard<std::mutex> lock(slots_[index]->mutex);
    ++slots_[index]->health.before_all_armed;
    return;
  }
  if (observer_.on_frame) observer_.on_frame(index, frame_index - origin, frame);
  if (recorder_ != nullptr) recorder_->SubmitFrame(index, frame_index - origin, std::move(frame));
}

FirstPlacement RigController::PlaceFirstFrame(int index, const Frame& frame) {
  FirstPlacement placement;
  {
    std::lock_guard<std::mutex> lock(anchor_mutex_);
    if (std::optional<FirstPlacement> by_device = placer_->ByDeviceTime(index, frame.device_ns))
      return *by_device;
    placement.note = placer_->WhyNotByDeviceTime(index, frame.device_ns);
  }
  placement.trigger_index = FirstIndexByHostTime(frame.host_ns);
  return placement;
}

std::int64_t RigController::FirstIndexByHostTime(std::int64_t host_ns) {
  std::lock_guard<std::mutex> lock(anchor_mutex_);
  // A frame arrives after its trigger and (latency < one period) before the
  // next one. With the trigger schedule known (software triggers fired here)
  // the trigger is the last one fired before the frame arrived: floor, not
  // round, since a camera's latency can be anywhere in the period (the
  // Aravis simulator's is 20-50 ms of a 100 ms period).
  if (trigger_schedule_host_ns_) {
    const double periods =
        static_cast<double>(host_ns - *trigger_schedule_host_ns_) * 1e-9 * options_.trigger_hz;
    return std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor(periods)));
  }
  // Hardware triggers: anchored on the rig's first frame. The cameras' frames
  // of one trigger arrive within a quarter period of each other; a frame
  // later than that belongs to a later trigger.
  if (!rig_first_host_ns_) {
    rig_first_host_ns_ = host_ns;
    return 0;
  }
  const double periods =
      static_cast<double>(host_ns - *rig_first_host_ns_) * 1e-9 * options_.trigger_hz;
  return std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor(periods + 0.25)));
}

bool RigController::ViconAhead(std::int64_t last_vicon_frame) const {
  if (!first_vicon_frame_) return false;
  std::int64_t slowest = INT64_MAX;
  for (const auto& slot : slots_) {
    if (slot->camera->Finished()) continue;
    std::lock_guard<std::mutex> lock(slot->mutex);
    slowest = std::min(slowest, slot->health.last_index);
  }
  if (slowest == INT64_MAX) return false;  // every camera done: Vicon drains
  // The last frame of trigger slowest + lead is f0 + divider (slowest + lead + 1) - 1.
  return last_vicon_frame >=
         *first_vicon_frame_ +
             static_cast<std::int64_t>(options_.sync->vicon_divider) *
                 (slowest + options_.vicon_lead_triggers + 1) -
             1;
}

void RigController::ViconLoop() {
  if (options_.vicon_realtime_priority > 0)
    spdlog::info("rig: Vicon thread under {}",
                 RaiseThreadToRealtime(options_.vicon_realtime_priority));
  std::optional<std::int64_t> last_vicon_frame;
  int in_burst = 0;
  while (vicon_running_.load()) {
    if (options_.vicon_lead_triggers > 0) {
      if ((last_vicon_frame && ViconAhead(*last_vicon_frame)) ||
          in_burst >= options_.sync->vicon_divider) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        in_burst = 0;
        continue;
      }
    }
    Expected<std::optional<ViconFrame>> next = vicon_->Next(std::chrono::milliseconds(100));
    if (!next) {
      std::lock_guard<std::mutex> lock(vicon_mutex_);
      ++vicon_errors_;
      continue;
    }
    if (!next->has_value()) {
      if (vicon_->Finished()) return;
      continue;
    }
    if (!first_vicon_frame_) first_vicon_frame_ = (*next)->vicon_frame;
    last_vicon_frame = (*next)->vicon_frame;
    ++in_burst;
    if (observer_.on_vicon) observer_.on_vicon(**next);
    if (recorder_ != nullptr) recorder_->SubmitVicon(**next);
    if (assembler_ != nullptr) {
      std::lock_guard<std::mutex> lock(sync_mutex_);
      assembler_->AddVicon(std::move(**next));
    }
    std::lock_guard<std::mutex> lock(vicon_mutex_);
    ++vicon_interval_frames_;
  }
}

void RigController::TriggerLoop(int index) {
  CameraSlot& slot = *slots_[index];
  if (options_.trigger_realtime_priority > 0)
    spdlog::info("rig: software trigger thread of camera {} under {}", slot.health.serial,
                 RaiseThreadToRealtime(options_.trigger_realtime_priority));
  {
    std::lock_guard<std::mutex> lock(trigger_mutex_);
    ++trigger_threads_ready_;
  }
  trigger_ready_.notify_all();
  schedule_set_.wait(false, std::memory_order_acquire);
  const std::chrono::steady_clock::time_point start = schedule_start_;
  const auto period =
      std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / options_.trigger_hz));
  std::uint64_t tick = 0;
  for (;;) {
    {
      // At Stop every camera is still fired up to the last tick any camera
      // was fired for (each has its own thread), so the run ends on a
      // trigger every camera saw rather than one some cameras missed.
      std::lock_guard<std::mutex> lock(trigger_mutex_);
      if (!triggering_.load() && tick >= ticks_begun_) break;
      ticks_begun_ = std::max(ticks_begun_, tick + 1);
    }
    const Status fired = slot.camera->SoftwareTrigger();
    if (!fired) {
      std::lock_guard<std::mutex> lock(slot.mutex);
      ++slot.health.errors;
      slot.health.last_error = fired.error().message;
    }
    // A trigger call that overran the period: the ticks it covered are not
    // fired late in a burst (the camera would merge them), they are skipped
    // and counted.
    const auto elapsed = std::chrono::steady_clock::now() - start;
    const auto now_tick = static_cast<std::uint64_t>(elapsed / period);
    const std::uint64_t next = std::max(tick + 1, now_tick);
    ++slot.fired;
    if (next > tick + 1) {
      std::lock_guard<std::mutex> lock(slot.mutex);
      slot.health.triggers_skipped += next - tick - 1;
      // A working camera's overran call: the ticks are triggers it never
      // got, which its frame counter does not count (the grab thread maps
      // them, TickOfTrigger) and which are lost. A failing or lost camera's
      // silence is counted by host time at its return (missing_in_gaps).
      if (fired && !slot.lost && slot.health.counter_restarts == 0) {
        slot.skips.emplace_back(slot.fired, next - tick - 1);
        slot.health.triggers_not_fired += next - tick - 1;
      }
    }
    tick = next;
    slot.trigger_ticks.store(tick);
    std::this_thread::sleep_until(start + tick * period);
  }
}

std::int64_t RigController::TickOfTrigger(const CameraSlot& slot, std::int64_t answered) {
  std::int64_t tick = answered;
  for (const auto& [fired_before, skipped] : slot.skips)
    if (static_cast<std::int64_t>(fired_before) <= answered)
      tick += static_cast<std::int64_t>(skipped);
  return tick;
}

std::optional<std::chrono::steady_clock::time_point> RigController::ScheduleStart() const {
  if (!started_ || trigger_threads_.empty()) return std::nullopt;
  return schedule_start_;
}

bool RigController::ViconFinished() const { return vicon_ && vicon_->Finished(); }

bool RigController::CamerasFinished() const {
  if (slots_.empty()) return false;
  for (const auto& slot : slots_)
    if (!slot->camera->Finished()) return false;
  return true;
}

RigHealth RigController::Health() {
  RigHealth health;
  const auto now = std::chrono::steady_clock::now();
  const double interval_s = std::chrono::duration<double>(now - last_health_).count();
  last_health_ = now;
  health.elapsed_s = std::chrono::duration<double>(now - start_time_).count();
  for (auto& slot : slots_)
    health.triggers_fired = std::max(health.triggers_fired, slot->trigger_ticks.load());
  if (recorder_ != nullptr) health.recorder = recorder_->Stats();
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    CameraSlot& slot = *slots_[i];
    CameraHealth camera;
    {
      std::lock_guard<std::mutex> lock(slot.mutex);
      if (interval_s > 0) {
        slot.health.fps = static_cast<double>(slot.interval_frames) / interval_s;
        slot.health.mb_per_s = static_cast<double>(slot.interval_bytes) / 1e6 / interval_s;
      }
      slot.interval_frames = slot.interval_bytes = 0;
      camera = slot.health;
    }
    camera.driver = slot.camera->Stats();
    if (i < health.recorder.cameras.size()) {
      camera.recorder = health.recorder.cameras[i];
      camera.serial = camera.recorder.serial;  // the rig's serial, as in the file names
    }
    camera.triggers = slot.trigger_ticks.load();
    {
      std::lock_guard<std::mutex> lock(slot.mutex);
      if (slot.first_placed) {
        // On the run's count (trigger 0: the first every camera was armed for).
        FirstPlacement placement = *slot.first_placed;
        placement.trigger_index -= origin_known_.load() ? origin_.load() : 0;
        camera.first_placement = placement.OneLine() + slot.first_suffix;
      }
    }
    if (armed_start_ != nullptr && !camera.first_placement.empty()) {
      std::lock_guard<std::mutex> lock(anchor_mutex_);
      camera.first_placement += "; " + armed_start_->HowArmed(static_cast<int>(i));
    }
    if (slot.software_trigger && !grabbing_.load()) {
      const auto expected = static_cast<std::int64_t>(slot.trigger_ticks.load());
      // Failed frames after the last good one are already counted as
      // incomplete, ticks skipped after it as not fired.
      std::int64_t skipped_after = 0;
      {
        std::lock_guard<std::mutex> lock(slot.mutex);
        if (slot.health.counter_restarts == 0)
          for (const auto& [fired_before, skipped] : slot.skips)
            if (static_cast<std::int64_t>(fired_before) > slot.last_answered)
              skipped_after += static_cast<std::int64_t>(skipped);
      }
      const std::int64_t at_end = expected - camera.last_index - 1 -
                                  static_cast<std::int64_t>(camera.failed_since_ok) -
                                  skipped_after;
      if (at_end > 0) camera.no_frame_at_end = static_cast<std::uint64_t>(at_end);
    }
    health.cameras.push_back(std::move(camera));
  }
  if (armed_start_ != nullptr && assembler_ == nullptr && origin_known_.load()) {
    // Without the assembler: the triggers from the rig's first frame to the origin.
    std::optional<std::int64_t> rig_first;
    for (auto& slot : slots_) {
      std::lock_guard<std::mutex> lock(slot->mutex);
      if (slot->first_index)
        rig_first = rig_first ? std::min(*rig_first, *slot->first_index) : *slot->first_index;
    }
    if (rig_first && origin_.load() > *rig_first)
      health.triggers_before_all_armed = static_cast<std::uint64_t>(origin_.load() - *rig_first);
  }
  if (assembler_) {
    std::lock_guard<std::mutex> lock(sync_mutex_);
    health.has_sync = true;
    health.frame_sets = frame_sets_;
    health.complete_frame_sets = complete_frame_sets_;
    health.sync_drops = assembler_->drops();
    health.sync_cameras = assembler_->camera_stats();
    health.vicon_f0 = assembler_->vicon_f0();
    health.triggers_before_all_armed = assembler_->triggers_before_all_armed();
    health.files_numbered_by_sync = options_.number_files_by_sync;
    for (std::size_t c = 0; c < health.cameras.size() && c < health.sync_cameras.size() &&
                            options_.number_files_by_sync;
         ++c)
      health.cameras[c].not_in_any_set =
          health.sync_cameras[c].without_trigger + health.sync_cameras[c].late;
  }
  if (vicon_) {
    health.has_vicon = true;
    health.vicon = vicon_->Stats();
    std::lock_guard<std::mutex> lock(vicon_mutex_);
    if (interval_s > 0) vicon_hz_ = static_cast<double>(vicon_interval_frames_) / interval_s;
    vicon_interval_frames_ = 0;
    health.vicon_hz = vicon_hz_;
    health.vicon_errors = vicon_errors_;
  }
  return health;
}

}  // namespace lifmcr
