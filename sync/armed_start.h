#pragma once
// The run's trigger 0 when the rig's cameras take triggers it does not fire
// (a hardware line from a trigger box that pulses all the time): the first
// trigger at which every camera was armed (acquiring).
//
// `record` arms the cameras one after the other, so a pulse between two
// arms is seen by the cameras armed already and not by the rest. Such a
// trigger is not a loss of the recording: nothing could have recorded it
// on every camera. Its frames are "before all cameras armed", reported as
// such and not written, and the run's trigger count starts after it, so the
// file numbers, the report's first frame and the FrameSets' trigger indices
// (LCM trigger_index) all count from the first trigger every camera could see.
//
// Per camera c, from its first frame (placed on trigger f_c of the rig's
// count, stamped d_c on its device clock, arriving at host time h_c) and its
// arm (the device clock latched right after AcquisitionStart, L_c, when the
// device can latch; else the host time its Start returned, E_c): the
// triggers it was armed for before its first frame are those j periods
// (P) earlier with d_c - j P >= L_c + m P, so
//   n_c = max(0, floor((d_c - L_c) / P - m)),   by device time, or
//   n_c = max(0, floor((h_c - E_c) / P - m)),   by host time,
// and camera c was armed from trigger a_c = f_c - n_c on. The margin m (a
// quarter period) allows for a stamp taken after its trigger (exposure,
// transfer) and, by host time, for the frame's delivery latency: a trigger
// within m P after the arm that the camera did not deliver counts as before
// its arm. The device latch compares one clock with itself, so a loaded host
// cannot mislead it; by host time a frame delivered more than m P late
// could make a start-up trigger look like a loss (counted, never hidden).
//
// Origin O = max(min_c f_c, max_c a_c): the first trigger at which every
// camera was armed, never before the rig's first frame (a pulse no camera
// delivered is not known to have fired). Triggers in [a_c, O) are missing
// from camera c as losses; triggers before O are before all cameras armed.
// Decided once every camera has a first frame, or when forced (a camera that
// has delivered nothing by then does not move it: it loses from O on).
//
// Not thread-safe: the caller serialises.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

class ArmedStart {
 public:
  static constexpr double kMargin = 0.25;  // periods

  ArmedStart(int cameras, std::int64_t trigger_period_ns);

  // Camera armed: its Start returned at `host_ns` (CLOCK_REALTIME), its device
  // clock latched then at `device_ns` (nullopt: the device cannot latch).
  void Armed(int camera, std::int64_t host_ns, std::optional<std::int64_t> device_ns);
  // The camera's first good frame, placed on `trigger_index` of the rig's count.
  void FirstFrame(int camera, std::int64_t trigger_index, std::int64_t device_ns,
                  std::int64_t host_ns);
  bool HasFirstFrame(int camera) const { return cameras_[camera].first.has_value(); }
  // Decides the origin when every camera has a first frame, or now when
  // `force` (none at all: 0); returns it once decided.
  std::optional<std::int64_t> Decide(bool force);
  std::optional<std::int64_t> origin() const { return origin_; }

  // The trigger from which camera `camera` was armed (a_c; nullopt before its
  // first frame).
  std::optional<std::int64_t> ArmedFrom(int camera) const;
  // "armed 0.93 periods before its first frame (device clock latched)", for
  // the log and the report; empty before its first frame.
  std::string HowArmed(int camera) const;

 private:
  struct First {
    std::int64_t trigger_index = 0;
    std::int64_t device_ns = 0;
    std::int64_t host_ns = 0;
  };
  struct CameraArm {
    std::optional<std::int64_t> armed_host_ns;
    std::optional<std::int64_t> armed_device_ns;
    std::optional<First> first;
  };
  // (first stamp - arm) / P, by device time when latched.
  std::optional<double> PeriodsArmedBeforeFirst(const CameraArm& camera) const;

  std::int64_t period_ns_;
  std::vector<CameraArm> cameras_;
  std::optional<std::int64_t> origin_;
};

}  // namespace lifmcr
