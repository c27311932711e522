#pragma once
// The host clock of Frame::host_ns and arrival_ns and of ViconFrame::host_ns.

#include <cstdint>

namespace lifmcr {

// CLOCK_REALTIME now, in nanoseconds.
std::int64_t HostRealtimeNs();

}  // namespace lifmcr
