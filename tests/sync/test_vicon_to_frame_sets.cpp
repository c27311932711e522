// End to end over real loopback UDP: ViconUdpSender -> ViconUdpSource ->
// FrameSetAssembler, with camera frames made by the test. The Vicon sender
// stops half way: frames keep coming out in FrameSets, marked without poses.
#include "drivers/vicon_udp_sender.h"
#include "drivers/vicon_udp_source.h"
#include "sync/frame_set_assembler.h"

#include <gtest/gtest.h>

#include <chrono>
#include <ctime>
#include <thread>

namespace lifmcr {
namespace {

std::int64_t RealtimeNs() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1000000000 + now.tv_nsec;
}

TEST(ViconToFrameSets, SenderStoppingMidRunLeavesSetsWithoutPoses) {
  ViconUdpSourceOptions source_options;
  source_options.address = "127.0.0.1";
  source_options.port = 0;
  source_options.objects = {"plate", "cam0"};
  ViconUdpSource source(source_options);
  ASSERT_TRUE(source.Start().ok());
  auto sender = ViconUdpSender::Open("127.0.0.1", source.BoundPort());
  ASSERT_TRUE(sender.ok());

  constexpr int kTriggers = 30, kStopAfter = 15, kDivider = 8;
  constexpr std::int64_t kF0 = 7000;
  FrameSetAssemblerOptions options;
  options.serials = {"cam0", "cam1"};
  options.trigger.trigger_period_ns = 10'000'000;  // 800 Hz Vicon / 8, to keep the test short
  options.vicon_rate_hz = 800.0;
  options.vicon_f0 = kF0;
  options.lateness_ns = 50'000'000;
  FrameSetAssembler assembler(options);

  std::vector<FrameSet> sets;
  auto drain = [&] {
    while (true) {
      auto next = source.Next(std::chrono::milliseconds(0));
      ASSERT_TRUE(next.ok());
      if (!next->has_value()) break;
      assembler.AddVicon(std::move(**next));
    }
    for (FrameSet& set : assembler.Poll(RealtimeNs())) sets.push_back(std::move(set));
  };
  const std::int64_t device0 = 5'000'000'000;
  for (int k = 0; k < kTriggers; ++k) {
    if (k <= kStopAfter) {
      for (int i = 0; i < kDivider; ++i) {
        ViconFrame frame;
        frame.vicon_frame = kF0 + kDivider * k + i;
        Pose pose = Pose::Identity();
        pose.translation() = Eigen::Vector3d(k, i, 0);
        frame.objects = {{"plate", pose}, {"cam0", std::nullopt}};
        ASSERT_TRUE(sender->Send(frame).ok());
      }
    }
    for (int camera = 0; camera < 2; ++camera) {
      Frame frame;
      frame.camera_index = camera;
      frame.frame_id = 65400 + k;
      frame.device_ns = device0 + k * options.trigger.trigger_period_ns;
      frame.host_ns = RealtimeNs();
      assembler.AddFrame(std::move(frame));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    drain();
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(80));
  drain();
  for (FrameSet& set : assembler.Flush()) sets.push_back(std::move(set));

  ASSERT_EQ(sets.size(), static_cast<std::size_t>(kTriggers));
  for (int k = 0; k < kTriggers; ++k) {
    const FrameSet& set = sets[k];
    EXPECT_EQ(set.trigger_index, k);
    EXPECT_EQ(set.vicon_frame, kF0 + kDivider * k);
    EXPECT_TRUE(set.missing.empty()) << k;
    ASSERT_EQ(set.vicon.has_value(), k <= kStopAfter) << k;
    if (set.vicon) {
      ASSERT_EQ(set.vicon->objects.size(), 2u);
      ASSERT_TRUE(set.vicon->objects[0].vicon_from_marker.has_value());
      EXPECT_EQ(set.vicon->objects[0].vicon_from_marker->translation().x(), k);
      EXPECT_FALSE(set.vicon->objects[1].vicon_from_marker.has_value());  // cam0 untracked
    }
  }
  EXPECT_EQ(assembler.drops()[DropKind::kViconMissingForTrigger],
            static_cast<std::uint64_t>(kTriggers - 1 - kStopAfter));
  EXPECT_EQ(assembler.drops()[DropKind::kCameraMissedTrigger], 0u);
  EXPECT_EQ(source.Stats().frames, static_cast<std::uint64_t>((kStopAfter + 1) * kDivider));
}

}  // namespace
}  // namespace lifmcr
