#pragma once
// Live Vicon poses from the Tracker UDP object stream (one datagram per Vicon
// frame, drivers/vicon_tracker_packet.h).
//
// The socket is non-blocking and Next waits with poll, so a grab loop can
// stop it within one timeout. Every datagram is parsed by ParseTrackerPacket;
// a malformed one is counted (Stats().malformed, LastError()) and skipped,
// never read past. Frame numbers that skip ahead are counted as gaps (the
// number of frames skipped); a frame number not above the last delivered one
// (a duplicate or a reordered datagram) is counted as out_of_order and
// dropped, so delivered frames strictly increase.
//
// Poses are converted once, here: RX RY RZ with options.pose.rotation, then
// to right-handed with options.pose.handedness (config/frames.h). A rotation
// that is not a rotation after conversion makes the datagram malformed.
//
// Thread safety: Start, Stop and Next from one thread; Stats and LastError
// from any thread.

#include "config/rig_config.h"
#include "drivers/vicon_source.h"
#include "replay/vicon_poses.h"

#include <atomic>
#include <cstdint>
#include <mutex>
#include <span>
#include <string>
#include <vector>

namespace lifmcr {

struct ViconUdpSourceOptions {
  std::string address = "0.0.0.0";  // local IPv4 address to bind
  int port = 51001;                 // 0 = any free port (tests; see BoundPort)
  ViconPoseOptions pose;            // how the stream writes rotations, and its handedness
  // When not empty, every delivered frame lists exactly these objects in this
  // order, an object absent from the datagram as untracked (no pose), and
  // objects of the datagram not listed are left out. Empty: the datagram's
  // objects as they come.
  std::vector<std::string> objects;
  int receive_buffer_bytes = 4 << 20;  // SO_RCVBUF request (the kernel caps it at rmem_max), > 0
  Status Check() const;                // every field; the message names the field

  // From the rig file: vicon.udp, vicon.rotation, vicon.handedness and the
  // rig's objects (ViconObjectsOfRig).
  static ViconUdpSourceOptions FromRig(const RigConfig& rig);
};

// The Vicon objects a rig tracks: vicon.plate_object first, then every
// camera's vicon_object that is not empty, in camera order.
std::vector<std::string> ViconObjectsOfRig(const RigConfig& rig);

class ViconUdpSource : public ViconSource {
 public:
  explicit ViconUdpSource(ViconUdpSourceOptions options);
  ~ViconUdpSource() override;
  ViconUdpSource(const ViconUdpSource&) = delete;
  ViconUdpSource& operator=(const ViconUdpSource&) = delete;

  // Binds the socket. Errors name the address and port (in use, no such address).
  Status Start() override;
  Status Stop() override;
  // The next well-formed, in-order frame within `timeout` (malformed and
  // out-of-order datagrams are counted and skipped while waiting), nullopt on
  // timeout. An error when the source is not started or the socket fails.
  Expected<std::optional<ViconFrame>> Next(std::chrono::milliseconds timeout) override;
  bool Finished() const override { return false; }  // a live stream never ends
  ViconSourceStats Stats() const override;

  // The port actually bound (the chosen one when options.port is 0); 0 before Start.
  int BoundPort() const { return bound_port_; }
  // Why the last malformed datagram was rejected; empty when none was.
  std::string LastError() const;

 private:
  // Converts a parsed datagram, or explains why it cannot be.
  Expected<ViconFrame> Convert(std::span<const std::uint8_t> datagram, std::int64_t host_ns) const;
  void CountMalformed(const std::string& why);

  ViconUdpSourceOptions options_;
  int socket_ = -1;
  int bound_port_ = 0;
  std::int64_t last_frame_ = -1;
  std::vector<std::uint8_t> datagram_;
  std::atomic<std::uint64_t> frames_{0}, malformed_{0}, gaps_{0}, out_of_order_{0};
  mutable std::mutex error_mutex_;
  std::string last_error_;
};

}  // namespace lifmcr
