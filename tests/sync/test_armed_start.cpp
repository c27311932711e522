// The run's trigger 0 when cameras are armed one after the other on a line
// that pulses all the time (sync/armed_start.h), and the assembler's
// FrameSets counted from it (FrameSetAssemblerOptions::wait_for_origin).
// Explicit timestamps: 100 ms triggers, device clocks in ns.
#include "sync/armed_start.h"
#include "sync/frame_set_assembler.h"

#include <gtest/gtest.h>

namespace lifmcr {
namespace {

constexpr std::int64_t kPeriod = 100'000'000;
constexpr std::int64_t kDevice0 = 5'000'000'000;            // device time of trigger 0
constexpr std::int64_t kHost0 = 1'700'000'000'000'000'000;  // host time of trigger 0

TEST(ArmedStart, APulseBeforeTheSecondCameraWasArmedIsBeforeAllArmedNotMissed) {
  ArmedStart start(2, kPeriod);
  // Camera 0 armed 0.4 periods before trigger 0, camera 1 0.1 periods before
  // trigger 1 (trigger 0 fell between the two arms).
  start.Armed(0, kHost0 - 40'000'000, kDevice0 - 40'000'000);
  start.Armed(1, kHost0 + 90'000'000, kDevice0 + 90'000'000);
  start.FirstFrame(0, 0, kDevice0, kHost0 + 300'000'000);  // delivered late: the host was busy
  EXPECT_FALSE(start.Decide(false).has_value());           // camera 1 may still come earlier
  start.FirstFrame(1, 1, kDevice0 + kPeriod, kHost0 + 310'000'000);
  EXPECT_EQ(start.ArmedFrom(0), 0);
  EXPECT_EQ(start.ArmedFrom(1), 1);
  ASSERT_EQ(start.Decide(false), 1);
  EXPECT_NE(start.HowArmed(1).find("armed 0.10 periods before its first frame (device clock"),
            std::string::npos)
      << start.HowArmed(1);
}

TEST(ArmedStart, ATriggerMissedAfterTheArmIsALossNotAStartUpTrigger) {
  ArmedStart start(2, kPeriod);
  start.Armed(0, kHost0 - 40'000'000, kDevice0 - 40'000'000);
  // Camera 1 armed 0.2 periods after trigger 0 and its first frame on
  // trigger 3: triggers 1 and 2 came while it was armed (lost), trigger 0 before.
  start.Armed(1, kHost0 + 20'000'000, kDevice0 + 20'000'000);
  start.FirstFrame(0, 0, kDevice0, kHost0 + 2'000'000);
  start.FirstFrame(1, 3, kDevice0 + 3 * kPeriod, kHost0 + 3 * kPeriod + 2'000'000);
  EXPECT_EQ(start.ArmedFrom(1), 1);
  // Trigger 0 is before all cameras armed; camera 1 lost triggers 1 and 2.
  EXPECT_EQ(start.Decide(false), 1);
}

TEST(ArmedStart, WithinAQuarterPeriodAfterTheArmATriggerCountsAsBefore) {
  ArmedStart start(2, kPeriod);
  start.Armed(0, kHost0 - 40'000'000, kDevice0 - 40'000'000);
  // Trigger 0 came 0.2 periods after camera 1's latch: within the margin for
  // a stamp taken after its trigger, so camera 1 counts as armed from trigger 1.
  start.Armed(1, kHost0 - 20'000'000, kDevice0 - 20'000'000);
  start.FirstFrame(0, 0, kDevice0, kHost0 + 2'000'000);
  start.FirstFrame(1, 1, kDevice0 + kPeriod, kHost0 + kPeriod + 2'000'000);
  EXPECT_EQ(start.Decide(false), 1);
}

TEST(ArmedStart, ByHostTimeWhenTheDeviceCannotLatchItsClock) {
  ArmedStart start(2, kPeriod);
  start.Armed(0, kHost0 - 40'000'000, std::nullopt);
  start.Armed(1, kHost0 + 50'000'000, std::nullopt);
  start.FirstFrame(0, 0, kDevice0, kHost0 + 60'000'000);
  start.FirstFrame(1, 1, 777, kHost0 + kPeriod + 5'000'000);  // device time of its own
  EXPECT_EQ(start.ArmedFrom(1), 1);
  EXPECT_EQ(start.Decide(false), 1);
  EXPECT_NE(start.HowArmed(1).find("host time"), std::string::npos) << start.HowArmed(1);
}

TEST(ArmedStart, NeverBeforeTheRigsFirstFrameAndForcedWithoutASilentCamera) {
  // Every camera armed long before the first pulse: trigger 0 is the first
  // frame's (a pulse no camera delivered is not known to have fired).
  ArmedStart armed_early(2, kPeriod);
  armed_early.Armed(0, kHost0 - 2'000'000'000, kDevice0 - 2'000'000'000);
  armed_early.Armed(1, kHost0 - 1'900'000'000, kDevice0 - 1'900'000'000);
  armed_early.FirstFrame(0, 0, kDevice0, kHost0 + 2'000'000);
  armed_early.FirstFrame(1, 0, kDevice0, kHost0 + 3'000'000);
  EXPECT_EQ(armed_early.Decide(false), 0);

  // Camera 2 never delivers: forced, the origin comes from the others.
  ArmedStart silent(3, kPeriod);
  for (int c = 0; c < 3; ++c) silent.Armed(c, kHost0 - 40'000'000 + c * 50'000'000, std::nullopt);
  silent.FirstFrame(0, 0, kDevice0, kHost0 + 1'000'000);
  silent.FirstFrame(1, 1, kDevice0 + kPeriod, kHost0 + kPeriod + 1'000'000);
  EXPECT_FALSE(silent.Decide(false).has_value());
  EXPECT_EQ(silent.Decide(true), 1);
  EXPECT_EQ(silent.origin(), 1);

  ArmedStart nothing(2, kPeriod);
  EXPECT_EQ(nothing.Decide(true), 0);
}

Frame MakeFrame(int camera, std::uint64_t id, std::int64_t trigger) {
  Frame frame;
  frame.camera_index = camera;
  frame.serial = "cam" + std::to_string(camera);
  frame.frame_id = id;
  frame.device_ns = kDevice0 + trigger * kPeriod;
  frame.host_ns = kHost0 + trigger * kPeriod + 2'000'000 + camera * 500'000;
  return frame;
}

TEST(FrameSetAssemblerOrigin, SetsCountFromTheOriginAndEarlierTriggersAreNotLosses) {
  FrameSetAssemblerOptions options;
  options.serials = {"cam0", "cam1"};
  options.device_clocks = {"line", "line"};
  options.vicon_expected = false;
  options.wait_for_origin = true;
  ASSERT_TRUE(options.Check().ok());
  FrameSetAssembler assembler(options);
  // Trigger 0 reached camera 0 only (camera 1 not armed yet).
  EXPECT_EQ(assembler.AddFrame(MakeFrame(0, 1, 0)), 0);
  EXPECT_EQ(assembler.AddFrame(MakeFrame(0, 2, 1)), 1);
  EXPECT_EQ(assembler.AddFrame(MakeFrame(1, 1, 1)), 1);  // by device time against camera 0
  for (std::int64_t k = 2; k < 5; ++k) {
    assembler.AddFrame(MakeFrame(0, static_cast<std::uint64_t>(k + 1), k));
    assembler.AddFrame(MakeFrame(1, static_cast<std::uint64_t>(k), k));
  }
  EXPECT_TRUE(assembler.Poll(kHost0 + 10 * kPeriod).empty());  // waits for the origin
  assembler.SetOrigin(1);
  std::vector<FrameSet> sets = assembler.Poll(kHost0 + 10 * kPeriod);
  for (FrameSet& set : assembler.Flush()) sets.push_back(std::move(set));
  ASSERT_EQ(sets.size(), 4u);
  for (std::size_t i = 0; i < sets.size(); ++i) {
    EXPECT_EQ(sets[i].trigger_index, static_cast<std::int64_t>(i));
    EXPECT_TRUE(sets[i].missing.empty()) << "set " << i;
  }
  EXPECT_EQ(assembler.triggers_before_all_armed(), 1u);
  EXPECT_EQ(assembler.drops().lost(), 0u) << assembler.drops().OneLine();
  const std::vector<CameraSyncStats> stats = assembler.camera_stats();
  EXPECT_EQ(stats[0].before_all_armed, 1u);
  EXPECT_EQ(stats[1].before_all_armed, 0u);
  EXPECT_EQ(stats[0].missed_triggers + stats[1].missed_triggers, 0u);
  EXPECT_EQ(stats[1].first_placement.rfind("trigger 0 by device time against camera 0", 0), 0u)
      << stats[1].first_placement;
  EXPECT_EQ(stats[0].first_placement.rfind("trigger -1 by host time", 0), 0u)
      << stats[0].first_placement;
  EXPECT_EQ(assembler.next_trigger(), 4);
}

}  // namespace
}  // namespace lifmcr
