#pragma once
// One camera frame as every driver delivers it: pixels in a pooled buffer,
// the device and host timestamps, the device's frame counter and a status.

#include "config/image.h"
#include "drivers/frame_pool.h"

#include <cstdint>
#include <string>
#include <string_view>

namespace lifmcr {

enum class FrameStatus {
  kOk,
  kIncomplete,  // data missing (lost packets); the pixels are not trustworthy
  kTimeout,     // the driver gave up waiting for the rest of the frame
  kError,       // any other transport or device error (see the driver's log)
};
std::string_view ToString(FrameStatus status);

struct Frame {
  int camera_index = 0;        // position of the camera in the rig file
  std::string serial;          // camera serial, as in TypeE_<serial>
  std::uint64_t frame_id = 0;  // the device's counter as delivered (16-bit on GigE Vision 1, wraps)
  std::int64_t device_ns = 0;  // device clock at exposure (or the driver's best substitute)
  std::int64_t host_ns = 0;    // host CLOCK_REALTIME when the frame (its first packet) arrived
  // Host CLOCK_REALTIME when the grab loop handed the frame on (0: not yet):
  // the start of the latency to publication. Unlike host_ns, never replaced
  // (a replay at --rate max places frames by a host_ns of its own making).
  std::int64_t arrival_ns = 0;
  FrameStatus status = FrameStatus::kOk;
  ImageView image;   // points into `buffer`
  BufferRef buffer;  // keeps the pixels alive; back to the pool when the last holder drops it
};

}  // namespace lifmcr
