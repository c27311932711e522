#include "acquisition/thread_priority.h"

#include <pthread.h>
#include <sched.h>

#include <cstring>

namespace lifmcr {

std::string RaiseThreadToRealtime(int priority) {
  sched_param param{};
  param.sched_priority = priority;
  const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
  if (error == 0) return "SCHED_FIFO priority " + std::to_string(priority);
  return "ordinary scheduling (SCHED_FIFO " + std::to_string(priority) + " refused: " +
         std::strerror(error) +
         "; run as root, grant CAP_SYS_NICE or raise `ulimit -r` for sub-ms Vicon latency under "
         "load)";
}

}  // namespace lifmcr
