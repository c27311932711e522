#pragma once
// A time a live camera was lost and found again, as the Aravis and GenTL
// drivers record it (drivers/aravis_camera.h, drivers/gentl_camera.h).

#include <cstdint>
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

}  // namespace lifmcr
