#pragma once
// The Vicon stream of the latency benchmarks (bench_pipeline, bench_sync):
// Tracker packets of fixed poses sent at a steady rate, each one's send time
// kept for the latency figures.

#include "drivers/vicon_udp_sender.h"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <string>
#include <thread>
#include <vector>

namespace lifmcr::bench {

// Sends sent_ns.size() packets, frame numbers from `first_frame`, at
// `rate_hz` on the steady clock's schedule (a late packet is sent at once,
// the schedule keeps its pace); sent_ns[i] = steady clock just before packet
// i goes out. Returns the first send error, "" when every packet went out.
inline std::string SendPacedVicon(ViconUdpSender& sender, const std::vector<std::string>& objects,
                                  std::int64_t first_frame, double rate_hz,
                                  std::vector<std::atomic<std::int64_t>>& sent_ns) {
  using Clock = std::chrono::steady_clock;
  ViconFrame frame;
  for (const std::string& name : objects) {
    Pose pose = Pose::Identity();
    pose.translation() = Eigen::Vector3d(100, 200, 300);
    frame.objects.push_back({name, pose});
  }
  const auto start = Clock::now();
  for (std::size_t i = 0; i < sent_ns.size(); ++i) {
    std::this_thread::sleep_until(
        start + std::chrono::nanoseconds(std::llround(static_cast<double>(i) * 1e9 / rate_hz)));
    frame.vicon_frame = first_frame + static_cast<std::int64_t>(i);
    sent_ns[i].store(std::chrono::duration_cast<std::chrono::nanoseconds>(
                         Clock::now().time_since_epoch())
                         .count(),
                     std::memory_order_release);
    if (Status sent = sender.Send(frame); !sent) return sent.error().message;
  }
  return "";
}

}  // namespace lifmcr::bench
