// A camera's first frame on the trigger count (sync/first_frame_placement.h):
// by device time against a camera on the same device clock, whatever the
// host's delay in delivering it; by host time only when no camera shares
// its clock (or its device time is off that camera's grid), and the
// placement says which rule decided. Explicit timestamps: 100 ms triggers.
#include "sync/first_frame_placement.h"
#include "sync/frame_set_assembler.h"

#include <gtest/gtest.h>

namespace lifmcr {
namespace {

constexpr std::int64_t kPeriod = 100'000'000;
constexpr std::int64_t kDevice0 = 5'000'000'000;            // device clock at trigger 0
constexpr std::int64_t kHost0 = 1'700'000'000'000'000'000;  // host clock at trigger 0
constexpr std::int64_t kLatency = 3'000'000;

TEST(FirstFramePlacer, ByDeviceTimeAgainstTheLatestFrameOnTheSameClock) {
  FirstFramePlacer placer(kPeriod, 0.25, {"ptp", "ptp", "", "other"});
  EXPECT_FALSE(placer.ByDeviceTime(1, kDevice0).has_value());
  EXPECT_NE(placer.WhyNotByDeviceTime(1, kDevice0).find("no camera on its device clock"),
            std::string::npos);
  placer.Placed(0, 0, kDevice0);
  placer.Placed(0, 7, kDevice0 + 7 * kPeriod + 1'000'000);
  // 12 periods and 0.03 after camera 0's trigger-7 frame.
  const auto placed = placer.ByDeviceTime(1, kDevice0 + 19 * kPeriod + 4'000'000);
  ASSERT_TRUE(placed.has_value());
  EXPECT_EQ(placed->trigger_index, 19);
  EXPECT_EQ(placed->by, FirstPlacement::By::kDeviceTime);
  EXPECT_EQ(placed->reference_camera, 0);
  EXPECT_NEAR(placed->grid_error, 0.03, 1e-9);
  EXPECT_EQ(placed->OneLine(),
            "trigger 19 by device time against camera 0 (grid error +0.03 periods)");
  // Before the reference: a negative step.
  EXPECT_EQ(placer.ByDeviceTime(1, kDevice0 + 5 * kPeriod)->trigger_index, 5);
  // Off the grid by 0.39 periods: the clocks disagree with the grid; host time decides.
  EXPECT_FALSE(placer.ByDeviceTime(1, kDevice0 + 9 * kPeriod + 40'000'000).has_value());
  EXPECT_NE(placer.WhyNotByDeviceTime(1, kDevice0 + 9 * kPeriod + 40'000'000).find("+0.39 periods"),
            std::string::npos);
  // A clock of its own, or another clock: never by device time.
  EXPECT_FALSE(placer.ByDeviceTime(2, kDevice0 + 3 * kPeriod).has_value());
  EXPECT_EQ(placer.WhyNotByDeviceTime(2, 0), "its device clock is its own");
  EXPECT_FALSE(placer.ByDeviceTime(3, kDevice0 + 3 * kPeriod).has_value());
}

Frame MakeFrame(int camera, std::uint64_t id, std::int64_t device_ns, std::int64_t host_ns) {
  Frame frame;
  frame.camera_index = camera;
  frame.serial = "cam" + std::to_string(camera);
  frame.frame_id = id;
  frame.device_ns = device_ns;
  frame.host_ns = host_ns;
  return frame;
}

struct LateStart {
  std::vector<FrameSet> sets;
  std::string placement;  // camera 1's CameraSyncStats::first_placement
};

// Camera 0 delivers triggers 0..9; camera 1 is armed late and its first
// frame is trigger 3's, delivered `host_delay_ns` after it should have
// arrived (a loaded host), then on time.
LateStart RunLateStart(std::vector<std::string> clocks, std::int64_t host_delay_ns) {
  FrameSetAssemblerOptions options;
  options.serials = {"cam0", "cam1"};
  options.device_clocks = std::move(clocks);
  options.vicon_expected = false;
  EXPECT_TRUE(options.Check().ok());
  FrameSetAssembler assembler(options);
  for (int k = 0; k < 10; ++k) {
    const std::int64_t exposed = kDevice0 + k * kPeriod;
    const std::int64_t arrives = kHost0 + k * kPeriod + kLatency;
    assembler.AddFrame(MakeFrame(0, 100 + k, exposed, arrives));
    if (k >= 3) {
      const std::int64_t delay = k == 3 ? host_delay_ns : 0;
      assembler.AddFrame(MakeFrame(1, 1 + (k - 3), exposed + 200'000, arrives + 500'000 + delay));
    }
  }
  LateStart result;
  result.sets = assembler.Flush();
  result.placement = assembler.camera_stats()[1].first_placement;
  return result;
}

TEST(FirstFramePlacement, ALoadedHostDoesNotMisplaceACameraOnASharedClock) {
  // 70 ms late: by host time that is trigger 4 (nearer to 4 than to 3).
  const LateStart shared = RunLateStart({"rig clock", "rig clock"}, 70'000'000);
  ASSERT_EQ(shared.sets.size(), 10u);
  for (int k = 0; k < 10; ++k) {
    SCOPED_TRACE(k);
    ASSERT_EQ(shared.sets[k].frames[1].has_value(), k >= 3);
    if (k >= 3) {
      EXPECT_EQ(shared.sets[k].frames[1]->frame_id, static_cast<std::uint64_t>(k - 2));
    }
  }
  EXPECT_EQ(shared.placement,
            "trigger 3 by device time against camera 0 (grid error +0.00 periods)");

  // Clocks of their own: host time is the fallback, and the log says so;
  // this delay misplaces the frame (why device time comes first).
  const LateStart own = RunLateStart({}, 70'000'000);
  EXPECT_EQ(own.placement, "trigger 4 by host time (its device clock is its own)");
  // The same without the delay: host time places it right.
  const LateStart on_time = RunLateStart({}, 0);
  EXPECT_EQ(on_time.placement, "trigger 3 by host time (its device clock is its own)");
  ASSERT_TRUE(on_time.sets[3].frames[1].has_value());
  EXPECT_EQ(on_time.sets[3].frames[1]->frame_id, 1u);
}

TEST(FirstFramePlacement, DeviceClocksMustBeOnePerCamera) {
  FrameSetAssemblerOptions options;
  options.serials = {"cam0", "cam1"};
  options.device_clocks = {"one"};
  const Status status = options.Check();
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.error().message.find("device_clocks"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr
