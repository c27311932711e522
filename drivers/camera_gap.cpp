#include "drivers/camera_gap.h"

#include <cstdio>

namespace lifmcr {

std::int64_t CameraGap::FramelessNs() const {
  if (!had_frame_before || !had_frame_after) return 0;
  return first_frame_host_ns - last_frame_host_ns;
}

std::string CameraGap::Describe() const {
  char line[512];
  std::string text;
  if (FramelessNs() > 0) {
    std::snprintf(line, sizeof(line), "no frames for %.2f s: ", FramelessNs() * 1e-9);
    text += line;
  }
  text += "lost (" + reason + ")";
  if (had_frame_before) {
    std::snprintf(line, sizeof(line), " %.2f s after the last frame",
                  (lost_host_ns - last_frame_host_ns) * 1e-9);
    text += line;
  }
  if (back_host_ns != 0) {
    std::snprintf(line, sizeof(line), ", back %.2f s later", (back_host_ns - lost_host_ns) * 1e-9);
    text += line;
  } else {
    text += ", not back yet";
  }
  text += "; frame id ";
  text += had_frame_before ? std::to_string(last_frame_id_before) : std::string("none");
  text += " -> ";
  text += had_frame_after ? std::to_string(first_frame_id_after) : std::string("none yet");
  return text;
}

}  // namespace lifmcr
