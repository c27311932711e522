#pragma once
// A small rig for the recorder tests: two cameras with the example MLA files,
// a Vicon UDP source, and a Vicon sender thread on loopback (port chosen by
// the kernel) streaming poses of every object at a given rate.

#include "config/rig_config.h"
#include "drivers/vicon_udp_sender.h"
#include "drivers/vicon_udp_source.h"

#include <Eigen/Geometry>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <thread>

namespace lifmcr::test {

inline RigConfig TwoCameraRig() {
  const std::filesystem::path mla =
      std::filesystem::path(LIFMCR_SOURCE_DIR) / "config/examples/Calibration/02_MLA_Calibration";
  RigConfig rig;
  rig.name = "test_rig";
  for (int i = 0; i < 2; ++i) {
    CameraConfig camera;
    camera.serial = i == 0 ? "MEMA" : "MEMB";
    camera.name = "cam" + std::to_string(i);
    camera.role = i == 0 ? CameraRole::kReference : CameraRole::kRegistered;
    camera.driver.kind = DriverKind::kReplay;
    camera.mla_file = mla / (i == 0 ? "TypeE_40398678_MLA.xml" : "TypeE_40398673_MLA.xml");
    camera.trigger.mode = TriggerMode::kSoftware;
    camera.vicon_object = camera.name;
    rig.cameras.push_back(camera);
  }
  rig.vicon.source = ViconSourceKind::kUdp;
  rig.vicon.udp.address = "127.0.0.1";
  rig.vicon.udp.port = 0;
  return rig;
}

// Sends one datagram per Vicon frame at `rate_hz` from its own thread until
// destroyed (or `Pause`d); every object of the rig gets a slowly moving pose.
class ViconStreamer {
 public:
  ViconStreamer(const RigConfig& rig, int port, double rate_hz) : objects_(ViconObjectsOfRig(rig)) {
    ViconPoseOptions pose;
    pose.rotation = rig.vicon.rotation;
    pose.handedness = rig.vicon.handedness;
    auto sender = ViconUdpSender::Open("127.0.0.1", port, pose);
    if (!sender.ok()) return;
    sender_.emplace(std::move(*sender));
    thread_ = std::thread([this, rate_hz] {
      auto due = std::chrono::steady_clock::now();
      std::int64_t frame_number = 1000;
      while (running_.load()) {
        if (!paused_.load()) {
          ViconFrame frame;
          frame.vicon_frame = frame_number;
          for (std::size_t i = 0; i < objects_.size(); ++i) {
            Pose pose = Pose::Identity();
            pose.linear() = Eigen::AngleAxisd(0.001 * frame_number + static_cast<double>(i),
                                              Eigen::Vector3d::UnitZ())
                                .toRotationMatrix();
            pose.translation() =
                Eigen::Vector3d(static_cast<double>(frame_number), 10.0 * i, 1500.0);
            frame.objects.push_back({objects_[i], pose});
          }
          if (sender_->Send(frame).ok()) sent_.fetch_add(1);
        }
        ++frame_number;  // the Vicon keeps counting while the stream is paused
        due += std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz));
        std::this_thread::sleep_until(due);
      }
    });
  }
  ~ViconStreamer() {
    running_ = false;
    if (thread_.joinable()) thread_.join();
  }
  bool ok() const { return sender_.has_value(); }
  void Pause(bool paused) { paused_ = paused; }
  std::uint64_t sent() const { return sent_.load(); }

 private:
  std::vector<std::string> objects_;
  std::optional<ViconUdpSender> sender_;
  std::atomic<bool> running_{true};
  std::atomic<bool> paused_{false};
  std::atomic<std::uint64_t> sent_{0};
  std::thread thread_;
};

}  // namespace lifmcr::test
