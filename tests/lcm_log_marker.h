#pragma once
// lcm-logger says neither when it has subscribed nor when it has written what
// it received (it flushes its file every 100 ms). A test that logs a burst of
// messages therefore publishes a marker on a channel of its own and reads the
// log until the marker is in it: once before the burst (the logger listens)
// and once after it (the burst's datagrams, sent before the marker, were
// received before it). Fixed waits of 700 ms failed at a load of 15-20: the
// logger was not yet subscribed, or had not yet written the last frame.

#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <thread>

namespace lifmcr::test {

// Publishes a one-byte message on `channel` through `url` every 100 ms until
// the lcm-logger file at `log_path` holds one, or `timeout` has passed; true
// when it did.
inline bool PublishUntilLogged(const std::string& url, const std::string& log_path,
                               const std::string& channel,
                               std::chrono::seconds timeout = std::chrono::seconds(60)) {
  lcm::LCM lcm(url);
  if (!lcm.good()) return false;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  const std::uint8_t byte = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    lcm.publish(channel, &byte, 1);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (!std::filesystem::exists(log_path)) continue;
    lcm::LogFile log(log_path, "r");
    if (!log.good()) continue;
    while (const lcm::LogEvent* event = log.readNextEvent())
      if (event->channel == channel) return true;
  }
  return false;
}

}  // namespace lifmcr::test
