#pragma once
// A generated rig run with known truth, for the synchronisation property
// tests: a trigger every period, each camera with its own device clock
// (offset, drift), exposure and arrival jitter, a 16-bit frame counter from
// 65400 that skips 0, and faults drawn at random: triggers not exposed,
// frames lost after exposure, failed frames, frames arriving late, spurious
// frames off the trigger grid; an 80 Hz Vicon stream with dropped frames.
// Events (frames and Vicon frames) come sorted by host arrival time.

#include "drivers/frame.h"
#include "drivers/vicon_source.h"

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

namespace lifmcr::test {

struct TimelineOptions {
  int cameras = 3;
  int triggers = 300;
  std::int64_t period_ns = 100'000'000;
  int divider = 8;
  std::int64_t f0 = 5000;  // Vicon frame of trigger 0
  std::int64_t start_host_ns = 1'763'800'000'000'000'000;
  double p_not_exposed = 0.02;
  double p_lost = 0.02;
  double p_failed = 0.02;
  double p_late = 0.01;
  double p_spurious = 0.01;
  double p_vicon_drop = 0.02;
  double max_drift_ppm = 100.0;
  std::int64_t late_by_ns = 800'000'000;
  std::int64_t vicon_latency_ns = 1'000'000;
  unsigned seed = 1;
};

enum class Truth { kOk, kFailed, kNotExposed, kLost, kLate };

struct Event {
  std::int64_t host_ns = 0;
  bool is_vicon = false;
  Frame frame;
  ViconFrame vicon;
};

struct Timeline {
  std::vector<Event> events;                         // by arrival
  std::vector<std::vector<Truth>> truth;             // [camera][trigger]
  std::vector<std::vector<std::uint64_t>> frame_id;  // [camera][trigger], for exposed triggers
  std::vector<bool> vicon_dropped;                   // [vicon frame - first_vicon]
  std::int64_t first_vicon = 0;
  int spurious = 0;
  std::int64_t camera_latency_mean_ns = 0;
};

inline Timeline MakeTimeline(const TimelineOptions& o) {
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Timeline t;
  t.truth.assign(o.cameras, std::vector<Truth>(o.triggers, Truth::kOk));
  t.frame_id.assign(o.cameras, std::vector<std::uint64_t>(o.triggers, 0));
  auto trigger_host = [&](double k) {
    return o.start_host_ns + static_cast<std::int64_t>(k * static_cast<double>(o.period_ns));
  };
  std::int64_t latency_sum = 0;
  for (int c = 0; c < o.cameras; ++c) {
    const double drift = (unit(rng) * 2 - 1) * o.max_drift_ppm * 1e-6;
    const std::int64_t device_offset = static_cast<std::int64_t>(unit(rng) * 1e12);
    const std::int64_t latency = 2'000'000 + static_cast<std::int64_t>(unit(rng) * 3e6);
    latency_sum += latency;
    std::uint64_t counter = 65400;
    auto next_counter = [&]() {
      const std::uint64_t id = counter;
      counter = counter == 65535 ? 1 : counter + 1;
      return id;
    };
    auto device_at = [&](std::int64_t host) {
      return device_offset +
             static_cast<std::int64_t>(static_cast<double>(host - o.start_host_ns) * (1.0 + drift));
    };
    auto push_frame = [&](std::int64_t exposure_host, std::uint64_t id, FrameStatus status,
                          std::int64_t extra_delay) {
      Event event;
      event.host_ns =
          exposure_host + latency + static_cast<std::int64_t>(unit(rng) * 1e6) + extra_delay;
      event.frame.camera_index = c;
      event.frame.serial = "cam" + std::to_string(c);
      event.frame.frame_id = id;
      event.frame.device_ns = device_at(exposure_host);
      event.frame.host_ns = event.host_ns;
      event.frame.status = status;
      t.events.push_back(std::move(event));
    };
    for (int k = 0; k < o.triggers; ++k) {
      const bool protected_start = (c == 0 && k < 2);  // the rig's trigger 0 is seen
      const std::int64_t exposure =
          trigger_host(k) + static_cast<std::int64_t>((unit(rng) - 0.5) * 200'000);
      const double draw = unit(rng);
      Truth truth = Truth::kOk;
      if (!protected_start && k < o.triggers - 1) {
        double edge = o.p_not_exposed;
        if (draw < edge) {
          truth = Truth::kNotExposed;
        } else if (draw < (edge += o.p_lost)) {
          truth = Truth::kLost;
        } else if (draw < (edge += o.p_failed)) {
          truth = Truth::kFailed;
        } else if (draw < (edge += o.p_late)) {
          truth = Truth::kLate;
        }
      }
      t.truth[c][k] = truth;
      if (truth == Truth::kNotExposed) continue;
      t.frame_id[c][k] = next_counter();
      if (truth == Truth::kLost) continue;
      push_frame(exposure, t.frame_id[c][k],
                 truth == Truth::kFailed ? FrameStatus::kIncomplete : FrameStatus::kOk,
                 truth == Truth::kLate ? o.late_by_ns : 0);
      if (k > 2 && k < o.triggers - 3 && unit(rng) < o.p_spurious) {
        push_frame(trigger_host(k + 0.5), next_counter(), FrameStatus::kOk, 0);
        ++t.spurious;
      }
    }
  }
  t.camera_latency_mean_ns = latency_sum / o.cameras + 500'000;
  // Vicon: from 40 frames before trigger 0 to 40 after the last trigger.
  t.first_vicon = o.f0 - 40;
  const std::int64_t last_vicon =
      o.f0 + static_cast<std::int64_t>(o.divider) * (o.triggers - 1) + 40;
  for (std::int64_t f = t.first_vicon; f <= last_vicon; ++f) {
    const bool drop = f != t.first_vicon && f != last_vicon && unit(rng) < o.p_vicon_drop;
    t.vicon_dropped.push_back(drop);
    if (drop) continue;
    Event event;
    event.is_vicon = true;
    event.host_ns = trigger_host(static_cast<double>(f - o.f0) / o.divider) + o.vicon_latency_ns +
                    static_cast<std::int64_t>(unit(rng) * 500'000);
    event.vicon.vicon_frame = f;
    event.vicon.host_ns = event.host_ns;
    event.vicon.objects = {{"cam0", std::nullopt}};
    t.events.push_back(std::move(event));
  }
  std::stable_sort(t.events.begin(), t.events.end(),
                   [](const Event& a, const Event& b) { return a.host_ns < b.host_ns; });
  return t;
}

}  // namespace lifmcr::test
