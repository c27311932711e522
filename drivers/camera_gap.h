#pragma once
// A time a live camera was lost and found again, as the Aravis and GenTL
// drivers record it (drivers/aravis_camera.h, drivers/gentl_camera.h).

#include "config/error.h"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

// One time the camera was lost, and found again (back_host_ns != 0).
struct CameraGap {
  std::int64_t lost_host_ns = 0;  // CLOCK_REALTIME when the loss was detected
  std::int64_t back_host_ns = 0;  // CLOCK_REALTIME when it was open again; 0 while lost
  bool had_frame_before = false;
  std::uint64_t last_frame_id_before = 0;
  std::int64_t last_frame_host_ns = 0;  // host_ns of that frame
  bool had_frame_after = false;
  std::uint64_t first_frame_id_after = 0;
  std::int64_t first_frame_host_ns = 0;  // host_ns of that frame
  std::string reason;

  // Host time without frames: first frame after - last frame before (0 when
  // either is unknown).
  std::int64_t FramelessNs() const;
  // One line, e.g. "no frames for 3.02 s: lost (control channel lost) 2.71 s
  // after the last frame, back 0.21 s later; frame id 65410 -> 65401".
  std::string Describe() const;
};

// The gaps of one live camera, kept one way for both live drivers: a gap
// opens when the device is found lost (after its last frame), gets its back
// time when it is open again, and its first frame after that. Thread-safe:
// the grab thread writes, Stats/Gaps callers read.
class CameraGapLog {
 public:
  // The device was found lost; `last_frame_id`: its last frame's id, if any.
  void Lost(const std::string& reason, std::optional<std::uint64_t> last_frame_id);
  // The device is open again (CLOCK_REALTIME now); the next frame closes the gap.
  void Back();
  // Every frame the driver delivers.
  void OnFrame(std::uint64_t frame_id, std::int64_t host_ns);
  std::vector<CameraGap> gaps() const;

 private:
  mutable std::mutex mutex_;
  std::vector<CameraGap> gaps_;
  std::int64_t last_frame_host_ns_ = 0;
  bool frame_since_back_ = true;
};

// Lost and found again, one way for both live drivers (their grab thread):
// MarkLost opens a gap in the log and drops the device; while lost,
// Reconnect has NextFrame report the loss once, then tries to open the
// device again every interval, and closes the gap when it is back.
// lost() may be read from any thread; the rest is the grab thread's.
class CameraReconnect {
 public:
  using Clock = std::chrono::steady_clock;
  enum class Step {
    kReportLoss,  // NextFrame returns the loss (reason()) as its error, once
    kStillLost,   // not back yet: NextFrame returns no frame
    kBack,        // open again: count the reconnect, go on
  };

  bool lost() const { return lost_.load(); }
  const std::string& reason() const { return reason_; }
  // The device was found lost (its last frame `last_frame_id`, if any):
  // marked lost first, then `drop` closes every handle (so it does not stop
  // acquisition on a device that is gone). Nothing when already lost.
  void MarkLost(const std::string& reason, std::optional<std::uint64_t> last_frame_id,
                const std::function<void()>& drop);
  // The caller has returned the loss as an error already.
  void LossReported() { reported_ = true; }
  // While lost: the next step. `reopen` (open the device, restart its
  // acquisition) is tried at most every `interval`, at once when `try_now`
  // says so (a USB3 Vision device arrived; may be empty), waiting until
  // `deadline` at most.
  Step Reconnect(Clock::time_point deadline, std::chrono::milliseconds interval,
                 const std::function<bool()>& try_now, const std::function<Status()>& reopen);
  CameraGapLog& log() { return log_; }
  const CameraGapLog& log() const { return log_; }

 private:
  std::atomic<bool> lost_{false};
  std::string reason_;
  bool reported_ = false;
  Clock::time_point last_try_{};
  CameraGapLog log_;
};

}  // namespace lifmcr
