// The live Vicon thread's real-time scheduling (acquisition/thread_priority.h)
// and the grab loop's option for it.
#include "acquisition/rig_controller.h"
#include "acquisition/thread_priority.h"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <unistd.h>

#include <string>
#include <thread>

namespace lifmcr {
namespace {

TEST(ThreadPriority, RaisesTheCallingThreadOnlyAndSaysWhatItGot) {
  std::string said;
  int policy_inside = -1, priority_inside = -1;
  std::thread worker([&] {
    said = RaiseThreadToRealtime(7);
    sched_param param{};
    (void)pthread_getschedparam(pthread_self(), &policy_inside, &param);
    priority_inside = param.sched_priority;
  });
  worker.join();
  int policy_here = -1;
  sched_param param_here{};
  ASSERT_EQ(pthread_getschedparam(pthread_self(), &policy_here, &param_here), 0);
  EXPECT_EQ(policy_here, SCHED_OTHER) << "the caller's thread is left as it was";
  if (said.rfind("SCHED_FIFO", 0) == 0) {
    EXPECT_EQ(said, "SCHED_FIFO priority 7");
    EXPECT_EQ(policy_inside, SCHED_FIFO);
    EXPECT_EQ(priority_inside, 7);
  } else {
    // Without root, CAP_SYS_NICE or an rtprio limit the thread keeps its
    // policy and the line tells the operator how to grant it.
    EXPECT_EQ(policy_inside, SCHED_OTHER);
    EXPECT_NE(said.find("refused"), std::string::npos) << said;
    EXPECT_NE(said.find("ulimit -r"), std::string::npos) << said;
    if (geteuid() == 0) ADD_FAILURE() << "refused as root: " << said;
  }
}

TEST(ThreadPriority, OptionOutOfRangeNamesTheField) {
  RigControllerOptions options;
  EXPECT_EQ(options.vicon_realtime_priority, 0) << "off unless a live stream asks for it";
  options.vicon_realtime_priority = 100;
  const Status checked = options.Check();
  ASSERT_FALSE(checked.ok());
  EXPECT_NE(checked.error().message.find("vicon_realtime_priority"), std::string::npos);
  options.vicon_realtime_priority = RigControllerOptions::kLiveViconPriority;
  EXPECT_TRUE(options.Check().ok());
}

}  // namespace
}  // namespace lifmcr
