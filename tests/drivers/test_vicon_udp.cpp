// ViconUdpSender -> real UDP on loopback -> ViconUdpSource: the same poses
// come back; malformed, duplicated, reordered and skipped datagrams are
// counted. Each test binds port 0 (a free port chosen by the kernel).
#include "drivers/vicon_tracker_packet.h"
#include "drivers/vicon_udp_sender.h"
#include "drivers/vicon_udp_source.h"
#include "tests/drivers/vicon_test_poses.h"

#include <gtest/gtest.h>

#include <chrono>
#include <random>
#include <vector>

namespace lifmcr {
namespace {

using std::chrono::milliseconds;

struct Loopback {
  explicit Loopback(ViconUdpSourceOptions options) : source(std::move(options)) {}
  ViconUdpSource source;
  std::optional<ViconUdpSender> sender;
};

// A started source on 127.0.0.1:<free port> and a sender aimed at it.
std::unique_ptr<Loopback> MakeLoopback(ViconPoseOptions pose, std::vector<std::string> objects) {
  ViconUdpSourceOptions options;
  options.address = "127.0.0.1";
  options.port = 0;
  options.pose = pose;
  options.objects = std::move(objects);
  auto loop = std::make_unique<Loopback>(options);
  const Status started = loop->source.Start();
  EXPECT_TRUE(started.ok()) << (started.ok() ? "" : started.error().message);
  auto sender = ViconUdpSender::Open("127.0.0.1", loop->source.BoundPort(), pose);
  EXPECT_TRUE(sender.ok());
  if (sender.ok()) loop->sender.emplace(std::move(*sender));
  return loop;
}

ViconFrame NextOrFail(ViconUdpSource& source) {
  auto next = source.Next(milliseconds(2000));
  EXPECT_TRUE(next.ok());
  if (!next.ok() || !next->has_value()) {
    ADD_FAILURE() << "no frame within 2 s";
    return {};
  }
  return **next;
}

TEST(ViconUdp, SenderAndSourceAgreeOnPosesForEveryConvention) {
  std::mt19937 rng(7);
  for (RotationRepresentation rotation :
       {RotationRepresentation::kHelicalRad, RotationRepresentation::kEulerXyzDeg}) {
    for (Handedness handedness : {Handedness::kRight, Handedness::kLeftFlipY}) {
      const ViconPoseOptions pose{rotation, handedness};
      auto loop = MakeLoopback(pose, {"plate", "cam0", "cam1"});
      ASSERT_TRUE(loop->sender.has_value());
      for (int i = 0; i < 40; ++i) {
        ViconFrame sent;
        sent.vicon_frame = 1000 + i;
        sent.objects = {{"cam1", test::RandomPose(rng)},
                        {"plate", test::RandomPose(rng)},
                        {"cam0", i % 5 == 0 ? std::nullopt : std::optional(test::RandomPose(rng))},
                        {"not_in_rig", test::RandomPose(rng)}};
        ASSERT_TRUE(loop->sender->Send(sent).ok());
        const ViconFrame got = NextOrFail(loop->source);
        EXPECT_EQ(got.vicon_frame, sent.vicon_frame);
        EXPECT_GT(got.host_ns, 0);
        ASSERT_EQ(got.objects.size(), 3u);  // the rig's objects, in the rig's order
        EXPECT_EQ(got.objects[0].name, "plate");
        EXPECT_EQ(got.objects[1].name, "cam0");
        EXPECT_EQ(got.objects[2].name, "cam1");
        ASSERT_TRUE(got.objects[0].vicon_from_marker.has_value());
        EXPECT_TRUE(test::PosesNear(*got.objects[0].vicon_from_marker,
                                    *sent.objects[1].vicon_from_marker, 1e-9));
        EXPECT_TRUE(test::PosesNear(*got.objects[2].vicon_from_marker,
                                    *sent.objects[0].vicon_from_marker, 1e-9));
        EXPECT_EQ(got.objects[1].vicon_from_marker.has_value(), i % 5 != 0);
        if (got.objects[1].vicon_from_marker) {
          EXPECT_TRUE(test::PosesNear(*got.objects[1].vicon_from_marker,
                                      *sent.objects[2].vicon_from_marker, 1e-9));
        }
      }
      EXPECT_EQ(loop->source.Stats().frames, 40u);
      EXPECT_EQ(loop->source.Stats().malformed, 0u);
    }
  }
}

TEST(ViconUdp, WithoutAnObjectListTheDatagramsObjectsComeAsTheyAre) {
  auto loop = MakeLoopback({}, {});
  ViconFrame sent;
  sent.vicon_frame = 5;
  sent.objects = {{"b", Pose::Identity()}, {"a", Pose::Identity()}};
  ASSERT_TRUE(loop->sender->Send(sent).ok());
  const ViconFrame got = NextOrFail(loop->source);
  ASSERT_EQ(got.objects.size(), 2u);
  EXPECT_EQ(got.objects[0].name, "b");
  EXPECT_EQ(got.objects[1].name, "a");
}

TEST(ViconUdp, MalformedDatagramsAreCountedAndSkipped) {
  auto loop = MakeLoopback({}, {"cam0"});
  ViconFrame frame;
  frame.objects = {{"cam0", Pose::Identity()}};
  TrackerPacket packet;
  packet.frame_number = 1;
  packet.objects = {{"cam0", {1, 2, 3}, {0, 0, 0}}};
  const std::vector<std::uint8_t> good = *EncodeTrackerPacket(packet);
  std::vector<std::vector<std::uint8_t>> bad;
  bad.push_back({1, 2, 3});  // shorter than the header
  bad.push_back(std::vector<std::uint8_t>(good.begin(), good.end() - 1));  // truncated
  bad.push_back(good);
  bad.back()[4] = 9;  // wrong count
  bad.push_back(good);
  for (int i = 0; i < 24; ++i) bad.back()[8 + i] = 'x';  // name without NUL
  bad.push_back(good);
  bad.back()[6] = 0xff;  // ItemDataSize 0xff48
  bad.back()[7] = 0xff;
  bad.push_back(std::vector<std::uint8_t>(kMaxUdpPayloadBytes, 0xab));  // oversized garbage
  int frame_number = 10;
  for (const auto& datagram : bad) {
    ASSERT_TRUE(loop->sender->SendBytes(datagram).ok());
    frame.vicon_frame = frame_number++;
    ASSERT_TRUE(loop->sender->Send(frame).ok());
  }
  for (int i = 0; i < static_cast<int>(bad.size()); ++i)
    EXPECT_EQ(NextOrFail(loop->source).vicon_frame, 10 + i);
  const ViconSourceStats stats = loop->source.Stats();
  EXPECT_EQ(stats.malformed, bad.size());
  EXPECT_EQ(stats.frames, bad.size());
  EXPECT_EQ(stats.gaps, 0u);
  EXPECT_NE(loop->source.LastError().find("Vicon Tracker packet"), std::string::npos);
}

TEST(ViconUdp, GapsAndOutOfOrderFramesAreCounted) {
  auto loop = MakeLoopback({}, {"cam0"});
  ViconFrame frame;
  frame.objects = {{"cam0", Pose::Identity()}};
  for (int number : {10, 11, 14, 12, 14, 15, 19}) {
    frame.vicon_frame = number;
    ASSERT_TRUE(loop->sender->Send(frame).ok());
  }
  std::vector<std::int64_t> delivered;
  for (int i = 0; i < 5; ++i) delivered.push_back(NextOrFail(loop->source).vicon_frame);
  EXPECT_EQ(delivered, (std::vector<std::int64_t>{10, 11, 14, 15, 19}));
  const ViconSourceStats stats = loop->source.Stats();
  EXPECT_EQ(stats.gaps, 2u + 3u);  // 12, 13 and 16, 17, 18
  EXPECT_EQ(stats.out_of_order, 2u);
}

TEST(ViconUdp, NextTimesOutWithoutDataAndRefusesBeforeStart) {
  ViconUdpSourceOptions options;
  options.address = "127.0.0.1";
  options.port = 0;
  ViconUdpSource source(options);
  EXPECT_FALSE(source.Next(milliseconds(1)).ok());
  ASSERT_TRUE(source.Start().ok());
  const auto start = std::chrono::steady_clock::now();
  auto next = source.Next(milliseconds(50));
  const auto waited = std::chrono::steady_clock::now() - start;
  ASSERT_TRUE(next.ok());
  EXPECT_FALSE(next->has_value());
  EXPECT_GE(waited, milliseconds(45));
  EXPECT_LT(waited, milliseconds(1000));
}

TEST(ViconUdp, BindErrorsNameTheEndpoint) {
  ViconUdpSourceOptions options;
  options.address = "127.0.0.1";
  options.port = 0;
  ViconUdpSource first(options);
  ASSERT_TRUE(first.Start().ok());
  options.port = first.BoundPort();
  ViconUdpSource second(options);
  const Status taken = second.Start();
  ASSERT_FALSE(taken.ok());
  EXPECT_NE(taken.error().message.find("127.0.0.1:" + std::to_string(options.port)),
            std::string::npos)
      << taken.error().message;
  // Bad options name their field (ViconUdpSourceOptions::Check, at Start).
  options.address = "not-an-address";
  ViconUdpSource third(options);
  const Status bad_address = third.Start();
  ASSERT_FALSE(bad_address.ok());
  EXPECT_NE(bad_address.error().message.find("address"), std::string::npos)
      << bad_address.error().message;
  options.address = "127.0.0.1";
  options.port = 70000;
  EXPECT_NE(options.Check().error().message.find("port"), std::string::npos);
  options.port = 0;
  options.receive_buffer_bytes = 0;
  EXPECT_NE(options.Check().error().message.find("receive_buffer_bytes"), std::string::npos);
  EXPECT_FALSE(ViconUdpSender::Open("127.0.0.1", 0).ok());
}

TEST(ViconUdp, OptionsFromTheRigFile) {
  RigConfig rig;
  rig.vicon.udp.address = "127.0.0.1";
  rig.vicon.udp.port = 40000;
  rig.vicon.rotation = RotationRepresentation::kEulerXyzRad;
  rig.vicon.handedness = Handedness::kLeftFlipX;
  rig.cameras.resize(3);
  rig.cameras[0].vicon_object = "cam0";
  rig.cameras[2].vicon_object = "cam2";
  const ViconUdpSourceOptions options = ViconUdpSourceOptions::FromRig(rig);
  EXPECT_EQ(options.address, "127.0.0.1");
  EXPECT_EQ(options.port, 40000);
  EXPECT_EQ(options.pose.rotation, RotationRepresentation::kEulerXyzRad);
  EXPECT_EQ(options.pose.handedness, Handedness::kLeftFlipX);
  EXPECT_EQ(options.objects, (std::vector<std::string>{"plate", "cam0", "cam2"}));
}

}  // namespace
}  // namespace lifmcr
