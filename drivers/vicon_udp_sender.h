#pragma once
// Emits the Tracker UDP object stream (drivers/vicon_tracker_packet.h) for
// given poses: the test stand-in for a Vicon Tracker, used by the source's
// tests, the recorder's integration tests, bench_sync and dev tools.
//
// Send is the inverse of ViconUdpSource: a right-handed vicon_from_marker
// goes back to the stream's handedness (RightHandedToVicon) and rotation
// representation (RotationToVicon), so a source with the same options gets
// the same poses back. Untracked objects (no pose) are left out of the
// datagram, which is what a source listing its objects reads as untracked.

#include "config/error.h"
#include "drivers/vicon_source.h"
#include "replay/vicon_poses.h"

#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace lifmcr {

class ViconUdpSender {
 public:
  // A socket sending to address:port (IPv4). Errors name the destination.
  static Expected<ViconUdpSender> Open(const std::string& address, int port,
                                       const ViconPoseOptions& encoding = {});
  ~ViconUdpSender();
  ViconUdpSender(ViconUdpSender&& other) noexcept;
  ViconUdpSender& operator=(ViconUdpSender&& other) noexcept;
  ViconUdpSender(const ViconUdpSender&) = delete;
  ViconUdpSender& operator=(const ViconUdpSender&) = delete;

  // One datagram for `frame` (vicon_frame must fit 32 bits; host_ns is not
  // sent: the stream has no timestamp). Errors: a frame number out of range,
  // an object the packet cannot hold (name of 0 or more than 23 bytes, more
  // than 255 objects), a send failure.
  Status Send(const ViconFrame& frame);
  // Any bytes as one datagram (malformed-packet tests).
  Status SendBytes(std::span<const std::uint8_t> datagram);

  std::uint64_t sent() const { return sent_; }

 private:
  ViconUdpSender(int socket, std::string destination, ViconPoseOptions encoding)
      : socket_(socket), destination_(std::move(destination)), encoding_(encoding) {}
  int socket_ = -1;
  std::string destination_;  // "address:port", for messages
  ViconPoseOptions encoding_;
  std::uint64_t sent_ = 0;
  alignas(8) unsigned char remote_[16] = {};  // sockaddr_in, kept opaque to keep <netinet/in.h> out
};

}  // namespace lifmcr
