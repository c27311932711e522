#pragma once
// Real-time scheduling for the one thread whose latency a user measures: the
// live Vicon receiver. With processing on every core (2 × 32 MP at 10 Hz), a
// thread under the ordinary scheduler waits behind whatever ran its slice
// (tens of ms at p99 on 2 cores, bench/README.md), however nice the other
// threads are; a SCHED_FIFO thread runs as soon as its packet arrives. It
// sleeps in recvfrom between packets, so it takes little CPU from anyone.
#include <string>

namespace lifmcr {

// Puts the calling thread under SCHED_FIFO at `priority` (1..99). Needs root,
// CAP_SYS_NICE or an `rtprio` limit (ulimit -r); without them the thread
// keeps its policy. Returns one line for the log saying which happened.
std::string RaiseThreadToRealtime(int priority);

}  // namespace lifmcr
