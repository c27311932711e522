#pragma once
// A time a live camera was lost and found again, as the Aravis and GenTL
// drivers record it (drivers/aravis_camera.h, drivers/gentl_camera.h).

#include <cstdint>
#include <string>

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

}  // namespace lifmcr
