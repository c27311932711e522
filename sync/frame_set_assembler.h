#pragma once
// Builds one FrameSet per camera trigger from the frames of every camera and
// the Vicon frames, and emits them in trigger order, each exactly once,
// complete or explicitly incomplete.
//
// Trigger index: the rig's first frame (any camera) is trigger 0. A camera's
// first frame is placed by device time against the latest placed frame of a
// camera on the same device clock (sync/first_frame_placement.h), else by
// host time (its clock model maps device to host time; the grid is anchored
// at the latest associated frame of any camera); every later frame by its
// device time and frame counter (TriggerTracker). A device clock jump
// re-anchors the camera by host time (its device time no longer compares).
//
// Vicon: trigger k fired on Vicon frame f0 + divider * k. f0 is given, or
// established once from the first trigger emitted: the Vicon frame number
// at the host time of the trigger's frames (plus vicon_arrival_offset_ns),
// counted at the Vicon rate from the nearest frame received (so a lost
// trigger frame does not matter), provided the host time falls within
// vicon_phase_tolerance_ns of that frame's slot; until then FrameSets have
// vicon_frame = -1. Every later set's Vicon frame is
// checked against its frames' host time the same way (vicon_phase_mismatch,
// the frame number still decides).
//
// Emission: the oldest pending trigger is emitted when every camera has its
// frame there or has already delivered a later one (frames of a camera come
// in order), and its Vicon frame is there or the Vicon stream is past it
// (or Vicon is not expected); or, whatever is missing, once now_host_ns is
// more than lateness_ns past the trigger. A frame for an emitted trigger is
// a late_frame. Flush emits everything pending at the end of a run.
//
// Origin (wait_for_origin): the caller decides which of these triggers is
// the run's trigger 0, the first at which every camera was armed
// (sync/armed_start.h), and says so with SetOrigin; until then nothing is
// emitted. Triggers before the origin are not emitted and not losses: their
// frames are counted per camera as before_all_armed. Emitted FrameSets, the
// first placements and vicon_f0 count from the origin (trigger_index =
// trigger - origin); the Vicon frame numbers stay the stream's own.
// Every loss is counted in drops() (DropKind) and per camera.
//
// Frames stay in their pooled buffers: the assembler moves them, never
// copies pixels, and holds them only until their trigger is emitted.
// Not thread-safe: one thread calls Add*, Poll and Flush.

#include "config/error.h"
#include "config/rig_config.h"
#include "drivers/frame.h"
#include "drivers/vicon_source.h"
#include "sync/clock_model.h"
#include "sync/drop_counter.h"
#include "sync/first_frame_placement.h"
#include "sync/frame_set.h"
#include "sync/trigger_tracker.h"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

struct FrameSetAssemblerOptions {
  std::vector<std::string> serials;  // one per camera, by camera index; at least one
  // Per camera, the clock its device timestamps are on (CameraInfo::device_clock,
  // the rig's cameras[].device_clock): equal non-empty names share a clock.
  // Empty vector or "": every camera a clock of its own.
  std::vector<std::string> device_clocks;
  TriggerTrackerOptions trigger;     // trigger period, grid tolerance, frame counter
  ClockModelOptions clock;
  bool vicon_expected = true;  // false: no Vicon source; sets never wait for Vicon
  int vicon_divider = 8;       // Vicon frames per trigger, >= 1
  double vicon_rate_hz = 80.0;
  std::optional<std::int64_t> vicon_f0;  // Vicon frame of trigger 0 when known (replay)
  // Host arrival of a trigger's Vicon frame minus that of its camera frames
  // (their clock-model times), as expected on this rig.
  std::int64_t vicon_arrival_offset_ns = 0;
  std::int64_t vicon_phase_tolerance_ns = 6'250'000;  // half an 80 Hz period
  std::int64_t lateness_ns = 500'000'000;             // wait at most this for a trigger's parts
  std::size_t max_vicon_frames = 4096;                // Vicon frames buffered, >= 16
  // Emit nothing before SetOrigin (cameras armed one after another on a
  // trigger the rig does not fire); false: the rig's first frame is trigger 0.
  bool wait_for_origin = false;

  // From the rig file: serials, Vicon source, divider and rate; the trigger
  // period is divider / rate.
  static FrameSetAssemblerOptions FromRig(const RigConfig& rig);
  Status Check() const;
};

struct CameraSyncStats {
  std::string serial;
  std::uint64_t frames = 0;               // frames given to AddFrame
  std::uint64_t in_sets = 0;              // frames that went out in a FrameSet
  std::uint64_t missed_triggers = 0;      // emitted sets without a frame of this camera
  std::uint64_t failed = 0;               // frames in sets with a failed status
  std::uint64_t without_trigger = 0;      // frames on no trigger (off grid, repeated, before start)
  std::uint64_t late = 0;                 // frames whose set was already emitted
  std::uint64_t lost_after_exposure = 0;  // by the frame counter
  std::uint64_t not_exposed = 0;          // triggers the counter says the camera never saw
  std::uint64_t counter_mismatches = 0;
  std::uint64_t before_all_armed = 0;     // frames on triggers before the origin: not in sets
  std::string clock;  // ClockModel::OneLine
  // How its first frame was put on the trigger count (FirstPlacement::OneLine,
  // and why not by device time when host time decided); empty before it.
  std::string first_placement;
};

class FrameSetAssembler {
 public:
  // options must pass Check() (the constructor does not re-check).
  explicit FrameSetAssembler(FrameSetAssemblerOptions options);

  // The trigger the frame was placed on (the FrameSet it goes out in), or
  // nullopt when it is on none (off grid, repeated, late, another camera's).
  // `first_trigger`: the trigger of the camera's first frame when the caller
  // knows it (it fired the software trigger the frame answers); the grid of
  // the rig's first frame is anchored there too.
  std::optional<std::int64_t> AddFrame(Frame frame,
                                       std::optional<std::int64_t> first_trigger = std::nullopt);
  void AddVicon(ViconFrame frame);
  // The FrameSets ready at host time `now_host_ns`, in trigger order.
  std::vector<FrameSet> Poll(std::int64_t now_host_ns);
  // End of the run: every trigger up to the last one seen, ready or not.
  std::vector<FrameSet> Flush();
  // The run's trigger 0 on the count the frames were placed on (once; see
  // wait_for_origin). Flush without one takes 0.
  void SetOrigin(std::int64_t origin);
  bool has_origin() const { return origin_.has_value(); }
  // Triggers before the origin dropped as "before all cameras armed".
  std::uint64_t triggers_before_all_armed() const { return triggers_before_origin_; }

  const DropCounter& drops() const { return drops_; }
  std::vector<CameraSyncStats> camera_stats() const;
  const ClockModel& clock(int camera_index) const { return cameras_[camera_index].clock; }
  // How the camera's first frame was placed (nullopt before it arrived).
  const std::optional<FirstPlacement>& first_placement(int camera_index) const {
    return cameras_[camera_index].first_placement;
  }
  // The Vicon frame of the run's trigger 0.
  std::optional<std::int64_t> vicon_f0() const {
    if (!f0_) return std::nullopt;
    return *f0_ + options_.vicon_divider * origin_.value_or(0);
  }
  // = FrameSets emitted so far
  std::int64_t next_trigger() const { return next_emit_ - origin_.value_or(0); }
  std::size_t pending_triggers() const { return pending_.size(); }
  std::size_t buffered_vicon_frames() const { return vicon_.size(); }
  // Host time the grid puts trigger k at (valid once a frame arrived).
  std::int64_t TriggerHostNs(std::int64_t trigger_index) const;

 private:
  struct Camera {
    TriggerTracker tracker;
    ClockModel clock;
    std::int64_t last_trigger = -1;  // latest trigger this camera delivered a frame for
    std::optional<FirstPlacement> first_placement;
    CameraSyncStats stats;
  };
  struct Pending {
    std::vector<std::optional<Frame>> frames;
  };

  std::int64_t TriggerByHostTime(const Camera& camera, std::int64_t device_ns) const;
  bool Ready(std::int64_t trigger_index, std::int64_t now_host_ns);
  void TryEstablishF0(std::int64_t trigger_index, bool forced);
  std::optional<std::int64_t> SetHostNs(const Pending* pending) const;
  FrameSet Emit(std::int64_t trigger_index);
  // Triggers before the origin: their frames counted, nothing emitted.
  void DropBeforeOrigin();

  FrameSetAssemblerOptions options_;
  std::vector<Camera> cameras_;
  FirstFramePlacer placer_;
  bool started_ = false;
  std::int64_t grid_trigger_ = 0;  // grid anchor: a trigger index and its host time
  std::int64_t grid_host_ns_ = 0;
  std::int64_t last_trigger_seen_ = -1;
  std::int64_t next_emit_ = 0;
  std::map<std::int64_t, Pending> pending_;
  std::optional<std::int64_t> f0_;  // on the placement count (trigger 0: the rig's first frame)
  std::optional<std::int64_t> origin_;
  std::uint64_t triggers_before_origin_ = 0;
  std::map<std::int64_t, ViconFrame> vicon_;
  std::int64_t last_vicon_ = -1;
  DropCounter drops_;
};

}  // namespace lifmcr
