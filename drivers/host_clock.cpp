#include "drivers/host_clock.h"

#include <ctime>

namespace lifmcr {

std::int64_t HostRealtimeNs() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

}  // namespace lifmcr
