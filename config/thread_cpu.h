#pragma once
// CPU time of the calling thread: what a piece of work costs whatever else
// runs on the machine (exact for work the thread computes alone; of a
// parallel loop, the calling thread's share only).

#include <ctime>

namespace lifmcr {

inline double ThreadCpuSeconds() {
  timespec cpu{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &cpu);
  return static_cast<double>(cpu.tv_sec) + 1e-9 * static_cast<double>(cpu.tv_nsec);
}

}  // namespace lifmcr
