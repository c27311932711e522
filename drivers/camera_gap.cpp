#include "drivers/camera_gap.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <thread>

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

void CameraGapLog::Lost(const std::string& reason, std::optional<std::uint64_t> last_frame_id) {
  CameraGap gap;
  gap.lost_host_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                         std::chrono::system_clock::now().time_since_epoch())
                         .count();
  gap.had_frame_before = last_frame_id.has_value();
  gap.last_frame_id_before = last_frame_id.value_or(0);
  gap.reason = reason;
  std::lock_guard<std::mutex> lock(mutex_);
  gap.last_frame_host_ns = last_frame_host_ns_;
  gaps_.push_back(gap);
}

void CameraGapLog::Back() {
  std::lock_guard<std::mutex> lock(mutex_);
  frame_since_back_ = false;
  if (!gaps_.empty())
    gaps_.back().back_host_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                    std::chrono::system_clock::now().time_since_epoch())
                                    .count();
}

void CameraGapLog::OnFrame(std::uint64_t frame_id, std::int64_t host_ns) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_frame_host_ns_ = host_ns;
  if (frame_since_back_) return;
  frame_since_back_ = true;
  if (!gaps_.empty() && gaps_.back().back_host_ns != 0 && !gaps_.back().had_frame_after) {
    gaps_.back().had_frame_after = true;
    gaps_.back().first_frame_id_after = frame_id;
    gaps_.back().first_frame_host_ns = host_ns;
  }
}

std::vector<CameraGap> CameraGapLog::gaps() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return gaps_;
}

void CameraReconnect::MarkLost(const std::string& reason,
                               std::optional<std::uint64_t> last_frame_id,
                               const std::function<void()>& drop) {
  if (lost_.load()) return;
  log_.Lost(reason, last_frame_id);
  reason_ = reason;
  reported_ = false;
  lost_.store(true);
  drop();
  last_try_ = Clock::now();
}

CameraReconnect::Step CameraReconnect::Reconnect(Clock::time_point deadline,
                                                 std::chrono::milliseconds interval,
                                                 const std::function<bool()>& try_now,
                                                 const std::function<Status()>& reopen) {
  if (!reported_) {
    reported_ = true;
    return Step::kReportLoss;
  }
  if (!(try_now && try_now()) && Clock::now() - last_try_ < interval) {
    std::this_thread::sleep_until(std::min(deadline, last_try_ + interval));
    if (Clock::now() - last_try_ < interval) return Step::kStillLost;
  }
  last_try_ = Clock::now();
  if (!reopen()) return Step::kStillLost;
  lost_.store(false);
  log_.Back();
  return Step::kBack;
}

}  // namespace lifmcr
