// apps/pipeline/pose_pairing.h: a trigger's poses of the reference camera and
// each other camera paired in any arrival order, once; a trigger lacking a
// camera's pose reported after the bounded wait, never dropped silently;
// duplicates, late poses and another map's poses refused. And the POSE
// message (publisher.h) round trip over a memq:// bus: what `lifmcr relate`
// decodes is what the pipeline published.
#include "apps/pipeline/pose_pairing.h"
#include "apps/pipeline/publisher.h"
#include "registration/live/extrinsics_monitor.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <lcm/lcm-cpp.hpp>

#include <optional>

namespace lifmcr::apps {
namespace {

constexpr std::int64_t kMs = 1'000'000;

PoseRecord Pose(const std::string& serial, std::int64_t trigger, double x_mm = 0) {
  PoseRecord pose;
  pose.serial = serial;
  pose.reference_serial = "A";
  pose.trigger_index = trigger;
  pose.w0_from_cam.transform = Eigen::Isometry3d::Identity();
  pose.w0_from_cam.transform.translation() = Eigen::Vector3d(x_mm, 0, 0);
  pose.w0_from_cam.localisation = "tracked";
  return pose;
}

PosePairing Pairing(int wait_ms = 100) {
  PosePairingOptions options;
  options.wait = std::chrono::milliseconds(wait_ms);
  EXPECT_TRUE(options.Check());
  return PosePairing(options);
}

TEST(PosePairing, PairsTheReferenceWithEachCameraInAnyOrderOnce) {
  PosePairing pairing = Pairing();
  // Camera B first: it waits for the reference.
  EXPECT_TRUE(pairing.Add(Pose("B", 0, 20), 0).pairs.empty());
  EXPECT_TRUE(pairing.Add(Pose("C", 0, 30), 1).pairs.empty());
  const PosePairing::Added with_reference = pairing.Add(Pose("A", 0, 10), 2);
  ASSERT_EQ(with_reference.pairs.size(), 2u);
  EXPECT_EQ(with_reference.pairs[0].camera.serial, "B");
  EXPECT_EQ(with_reference.pairs[1].camera.serial, "C");
  EXPECT_EQ(with_reference.pairs[0].reference.serial, "A");
  // The reference first: each camera pairs as it comes.
  EXPECT_TRUE(pairing.Add(Pose("A", 1), 3).pairs.empty());
  ASSERT_EQ(pairing.Add(Pose("C", 1), 4).pairs.size(), 1u);
  ASSERT_EQ(pairing.Add(Pose("B", 1), 5).pairs.size(), 1u);
  EXPECT_EQ(pairing.paired().at("B"), 2u);
  EXPECT_EQ(pairing.paired().at("C"), 2u);
  // Complete triggers expire without a report line.
  EXPECT_TRUE(pairing.Expire(200 * kMs).empty());
  EXPECT_EQ(pairing.waiting(), 0u);
  EXPECT_TRUE(pairing.lacked().empty());
}

TEST(PosePairing, ATriggerWhosePairNeverComesIsReportedAfterTheWait) {
  PosePairing pairing = Pairing(100);
  pairing.Add(Pose("A", 0), 0);
  pairing.Add(Pose("B", 0), 0);
  pairing.Add(Pose("A", 1), 10 * kMs);  // B's pose of trigger 1 never comes
  pairing.Add(Pose("B", 2), 20 * kMs);  // nor A's of trigger 2
  EXPECT_TRUE(pairing.Expire(50 * kMs).empty()) << "still within the wait";
  const std::vector<std::string> lines = pairing.Expire(115 * kMs);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], "trigger 1 (pass 0): no pose of camera B within 100 ms");
  const std::vector<std::string> at_end = pairing.Flush();
  ASSERT_EQ(at_end.size(), 1u);
  EXPECT_EQ(at_end[0], "trigger 2 (pass 0): no pose of camera A within 100 ms");
  EXPECT_EQ(pairing.lacked().at("A"), 1u);
  EXPECT_EQ(pairing.lacked().at("B"), 1u);
  EXPECT_NE(pairing.Report().find("lacking a camera's pose: A 1, B 1"), std::string::npos)
      << pairing.Report();
}

// With the rig's cameras given (`lifmcr relate --rig`), a camera whose host
// never published is reported lacking from the first trigger on.
TEST(PosePairing, ARigCameraThatNeverPublishedIsReported) {
  PosePairingOptions options;
  options.wait = std::chrono::milliseconds(100);
  options.cameras = {"A", "B", "C"};
  ASSERT_TRUE(options.Check());
  PosePairing pairing(options);
  EXPECT_EQ(pairing.Add(Pose("A", 0), 0).pairs.size(), 0u);
  EXPECT_EQ(pairing.Add(Pose("B", 0), 0).pairs.size(), 1u);
  const std::vector<std::string> lines = pairing.Expire(100 * kMs);
  ASSERT_EQ(lines.size(), 1u);
  EXPECT_EQ(lines[0], "trigger 0 (pass 0): no pose of camera C within 100 ms");
  EXPECT_EQ(pairing.lacked().at("C"), 1u);
  options.cameras = {"A", "A"};
  EXPECT_FALSE(options.Check());
}

TEST(PosePairing, RefusesDuplicatesLatePosesAndAnotherMap) {
  PosePairing pairing = Pairing(100);
  pairing.Add(Pose("A", 0), 0);
  EXPECT_NE(pairing.Add(Pose("A", 0), 1).refused.find("a second pose"), std::string::npos);
  pairing.Expire(200 * kMs);
  const PosePairing::Added late = pairing.Add(Pose("B", 0), 201 * kMs);
  EXPECT_TRUE(late.pairs.empty());
  EXPECT_NE(late.refused.find("late"), std::string::npos) << late.refused;
  PoseRecord other = Pose("B", 5);
  other.reference_serial = "Z";
  EXPECT_NE(pairing.Add(other, 300 * kMs).refused.find("camera Z's map"), std::string::npos);
  EXPECT_EQ(pairing.refused(), 3u);
  // Passes are kept apart (replay --loop numbers triggers from 0 again).
  PoseRecord next_pass = Pose("A", 0);
  next_pass.pass = 1;
  EXPECT_TRUE(pairing.Add(next_pass, 400 * kMs).refused.empty());
}

TEST(PosePairing, OptionsAreChecked) {
  PosePairingOptions options;
  options.wait = std::chrono::milliseconds(0);
  EXPECT_FALSE(options.Check());
}

// The POSE message through a real LCM bus (memq://) and back: every field,
// and c0_from_cx related from decoded poses equals the one related from the
// poses as published (the quaternion in transit costs < 1e-12).
TEST(PoseMessage, RoundTripsThroughLcmAndRelatesAsTheOriginal) {
  lcm::LCM bus("memq://");
  ASSERT_TRUE(bus.good());
  PublisherOptions options;
  options.bus = &bus;
  options.channel_prefix = "RIG7";
  auto publisher = Publisher::Create(options);
  ASSERT_TRUE(publisher) << publisher.error().message;
  std::vector<PoseRecord> received;
  struct Sink {
    std::vector<PoseRecord>* out;
    void On(const lcm::ReceiveBuffer* buffer, const std::string&) {
      auto pose = DecodePoseMessage(buffer->data, static_cast<int>(buffer->data_size));
      ASSERT_TRUE(pose) << pose.error().message;
      out->push_back(*pose);
    }
  } sink{&received};
  bus.subscribe("RIG7_.*_POSE", &Sink::On, &sink);

  PoseRecord sent[2] = {Pose("A", 7), Pose("B", 7)};
  sent[0].w0_from_cam.transform = Eigen::Translation3d(12.5, -3.25, 800.0) *
                                  Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized());
  sent[1].w0_from_cam.transform =
      Eigen::Translation3d(-140.0, 4.0, 760.5) *
      Eigen::AngleAxisd(-0.7, Eigen::Vector3d(0.2, 1, -0.4).normalized());
  for (PoseRecord& pose : sent) {
    pose.pass = 2;
    pose.frame_id = 41;
    pose.arrival_ns = 1'700'000'000'123'456'000;
    pose.w0_from_cam.method = "pnp";
    pose.w0_from_cam.inliers = 57;
    pose.w0_from_cam.rmse_px = 0.42;
    for (int k = 0; k < 6; ++k) pose.w0_from_cam.covariance(k, k) = k < 3 ? 0.25 : 1e-6;
    pose.w0_from_cam.covariance(0, 4) = pose.w0_from_cam.covariance(4, 0) = 1e-5;
    publisher->get()->PublishPose(pose);
  }
  for (int i = 0; i < 2; ++i) bus.handleTimeout(100);
  ASSERT_EQ(received.size(), 2u);
  for (int i = 0; i < 2; ++i) {
    const PoseRecord& got = received[static_cast<std::size_t>(i)];
    const PoseRecord& want = sent[i];
    EXPECT_EQ(got.serial, want.serial);
    EXPECT_EQ(got.reference_serial, "A");
    EXPECT_EQ(got.trigger_index, 7);
    EXPECT_EQ(got.pass, 2);
    EXPECT_EQ(got.frame_id, 41u);
    EXPECT_EQ(got.arrival_ns, want.arrival_ns);
    EXPECT_EQ(got.w0_from_cam.method, "pnp");
    EXPECT_EQ(got.w0_from_cam.localisation, "tracked");
    EXPECT_EQ(got.w0_from_cam.status, "ok");
    EXPECT_EQ(got.w0_from_cam.inliers, 57);
    EXPECT_DOUBLE_EQ(got.w0_from_cam.rmse_px, 0.42);
    EXPECT_EQ(got.w0_from_cam.covariance, want.w0_from_cam.covariance);
    EXPECT_TRUE(got.w0_from_cam.transform.isApprox(want.w0_from_cam.transform, 1e-12));
  }
  registration::ExtrinsicsRelater direct, relayed;
  const processing::CameraPose a = direct.Relate("B", sent[0].w0_from_cam, sent[1].w0_from_cam);
  const processing::CameraPose b =
      relayed.Relate("B", received[0].w0_from_cam, received[1].w0_from_cam);
  EXPECT_LT((a.transform.matrix() - b.transform.matrix()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((a.covariance - b.covariance).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_FALSE(DecodePoseMessage("xyz", 3));
}

}  // namespace
}  // namespace lifmcr::apps
