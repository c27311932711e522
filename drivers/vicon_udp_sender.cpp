#include "drivers/vicon_udp_sender.h"

#include "drivers/vicon_tracker_packet.h"

#include <arpa/inet.h>
#include <cerrno>
#include <cstring>
#include <limits>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>
#include <utility>

namespace lifmcr {

static_assert(sizeof(sockaddr_in) == 16, "ViconUdpSender::remote_ holds a sockaddr_in");

Expected<ViconUdpSender> ViconUdpSender::Open(const std::string& address, int port,
                                              const ViconPoseOptions& encoding) {
  const std::string destination = address + ":" + std::to_string(port);
  sockaddr_in remote{};
  remote.sin_family = AF_INET;
  if (port <= 0 || port > 65535)
    return Error{"Vicon UDP sender " + destination + ": port must be 1..65535"};
  remote.sin_port = htons(static_cast<std::uint16_t>(port));
  if (inet_pton(AF_INET, address.c_str(), &remote.sin_addr) != 1)
    return Error{"Vicon UDP sender " + destination + ": not an IPv4 address"};
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return Error{"Vicon UDP sender " + destination + ": socket: " + std::strerror(errno)};
  // Not connect()ed: a connected UDP socket reports the ICMP "port
  // unreachable" of a receiver not started yet as a failed send, and a Tracker
  // does not care whether anyone listens.
  ViconUdpSender sender(fd, destination, encoding);
  std::memcpy(sender.remote_, &remote, sizeof(remote));
  return sender;
}

ViconUdpSender::~ViconUdpSender() {
  if (socket_ >= 0) close(socket_);
}

ViconUdpSender::ViconUdpSender(ViconUdpSender&& other) noexcept
    : socket_(std::exchange(other.socket_, -1)),
      destination_(std::move(other.destination_)),
      encoding_(other.encoding_),
      sent_(other.sent_) {
  std::memcpy(remote_, other.remote_, sizeof(remote_));
}

ViconUdpSender& ViconUdpSender::operator=(ViconUdpSender&& other) noexcept {
  if (this != &other) {
    if (socket_ >= 0) close(socket_);
    socket_ = std::exchange(other.socket_, -1);
    destination_ = std::move(other.destination_);
    encoding_ = other.encoding_;
    sent_ = other.sent_;
    std::memcpy(remote_, other.remote_, sizeof(remote_));
  }
  return *this;
}

Status ViconUdpSender::Send(const ViconFrame& frame) {
  if (frame.vicon_frame < 0 || frame.vicon_frame > std::numeric_limits<std::uint32_t>::max())
    return Error{"Vicon UDP sender " + destination_ + ": frame number " +
                 std::to_string(frame.vicon_frame) + " does not fit 32 bits"};
  TrackerPacket packet;
  packet.frame_number = static_cast<std::uint32_t>(frame.vicon_frame);
  for (const ViconObjectPose& object : frame.objects) {
    if (!object.vicon_from_marker) continue;
    Eigen::Matrix3d rotation;
    Eigen::Vector3d translation_mm;
    RightHandedToVicon(encoding_.handedness, *object.vicon_from_marker, &rotation, &translation_mm);
    const Eigen::Vector3d r = RotationToVicon(encoding_.rotation, rotation);
    packet.objects.push_back({object.name,
                              {translation_mm.x(), translation_mm.y(), translation_mm.z()},
                              {r.x(), r.y(), r.z()}});
  }
  auto bytes = EncodeTrackerPacket(packet);
  if (!bytes) return Error{"Vicon UDP sender " + destination_ + ": " + bytes.error().message};
  return SendBytes(*bytes);
}

Status ViconUdpSender::SendBytes(std::span<const std::uint8_t> datagram) {
  if (socket_ < 0) return Error{"Vicon UDP sender " + destination_ + ": not open"};
  const ssize_t sent = sendto(socket_, datagram.data(), datagram.size(), 0,
                              reinterpret_cast<const sockaddr*>(remote_), sizeof(sockaddr_in));
  if (sent < 0 || static_cast<std::size_t>(sent) != datagram.size())
    return Error{"Vicon UDP sender " + destination_ + ": send: " + std::strerror(errno)};
  ++sent_;
  return Status::Ok();
}

}  // namespace lifmcr
