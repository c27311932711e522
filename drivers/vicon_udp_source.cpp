#include "drivers/vicon_udp_source.h"

#include "drivers/host_clock.h"
#include "drivers/vicon_tracker_packet.h"

#include <arpa/inet.h>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

namespace lifmcr {
namespace {

std::string Endpoint(const std::string& address, int port) {
  return "Vicon UDP " + address + ":" + std::to_string(port);
}

}  // namespace

ViconUdpSourceOptions ViconUdpSourceOptions::FromRig(const RigConfig& rig) {
  ViconUdpSourceOptions options;
  options.address = rig.vicon.udp.address;
  options.port = rig.vicon.udp.port;
  options.pose.rotation = rig.vicon.rotation;
  options.pose.handedness = rig.vicon.handedness;
  options.objects = ViconObjectsOfRig(rig);
  return options;
}

std::vector<std::string> ViconObjectsOfRig(const RigConfig& rig) {
  std::vector<std::string> objects;
  if (!rig.vicon.plate_object.empty()) objects.push_back(rig.vicon.plate_object);
  for (const CameraConfig& camera : rig.cameras) {
    if (!camera.vicon_object.empty()) objects.push_back(camera.vicon_object);
  }
  return objects;
}

ViconUdpSource::ViconUdpSource(ViconUdpSourceOptions options)
    : options_(std::move(options)), datagram_(kMaxUdpPayloadBytes + 1) {}

ViconUdpSource::~ViconUdpSource() { (void)Stop(); }

Status ViconUdpSourceOptions::Check() const {
  in_addr parsed{};
  if (inet_pton(AF_INET, address.c_str(), &parsed) != 1)
    return Error{"Vicon UDP source: address: expected an IPv4 address, got '" + address + "'"};
  if (port < 0 || port > 65535) return Error{"Vicon UDP source: port: expected 0..65535"};
  if (receive_buffer_bytes <= 0)
    return Error{"Vicon UDP source: receive_buffer_bytes: expected > 0"};
  // pose: enumerations; objects: any names (empty: the datagram's).
  return Status::Ok();
}

Status ViconUdpSource::Start() {
  const std::string where = Endpoint(options_.address, options_.port);
  if (socket_ >= 0) return Status::Ok();
  if (Status s = options_.Check(); !s) return Error{where + ": " + s.error().message};
  sockaddr_in local{};
  local.sin_family = AF_INET;
  local.sin_port = htons(static_cast<std::uint16_t>(options_.port));
  (void)inet_pton(AF_INET, options_.address.c_str(), &local.sin_addr);  // checked above
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) return Error{where + ": socket: " + std::strerror(errno)};
  // A larger buffer absorbs scheduling hiccups of the grab thread; failure
  // to get it is not fatal (the kernel caps it at net.core.rmem_max).
  const int buffer = options_.receive_buffer_bytes;
  (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &buffer, sizeof(buffer));
  if (bind(fd, reinterpret_cast<const sockaddr*>(&local), sizeof(local)) != 0) {
    const std::string why = std::strerror(errno);
    close(fd);
    return Error{where + ": bind: " + why};
  }
  sockaddr_in bound{};
  socklen_t length = sizeof(bound);
  getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &length);
  bound_port_ = ntohs(bound.sin_port);
  socket_ = fd;
  return Status::Ok();
}

Status ViconUdpSource::Stop() {
  if (socket_ >= 0) close(socket_);
  socket_ = -1;
  return Status::Ok();
}

ViconSourceStats ViconUdpSource::Stats() const {
  ViconSourceStats stats;
  stats.frames = frames_.load();
  stats.malformed = malformed_.load();
  stats.gaps = gaps_.load();
  stats.out_of_order = out_of_order_.load();
  return stats;
}

std::string ViconUdpSource::LastError() const {
  std::lock_guard lock(error_mutex_);
  return last_error_;
}

void ViconUdpSource::CountMalformed(const std::string& why) {
  malformed_.fetch_add(1);
  std::lock_guard lock(error_mutex_);
  last_error_ = why;
}

Expected<ViconFrame> ViconUdpSource::Convert(std::span<const std::uint8_t> datagram,
                                             std::int64_t host_ns) const {
  auto packet = ParseTrackerPacket(datagram);
  if (!packet) return packet.error();
  ViconFrame frame;
  frame.vicon_frame = packet->frame_number;
  frame.host_ns = host_ns;
  std::vector<ViconObjectPose> received;
  received.reserve(packet->objects.size());
  for (const TrackerObject& object : packet->objects) {
    const Eigen::Vector3d r(object.rotation[0], object.rotation[1], object.rotation[2]);
    const Eigen::Vector3d t(object.translation_mm[0], object.translation_mm[1],
                            object.translation_mm[2]);
    auto pose = ViconToRightHanded(options_.pose.handedness,
                                   RotationFromVicon(options_.pose.rotation, r), t);
    if (!pose)
      return Error{"Vicon frame " + std::to_string(frame.vicon_frame) + ": object '" + object.name +
                   "': " + pose.error().message};
    received.push_back({object.name, *pose});
  }
  if (options_.objects.empty()) {
    frame.objects = std::move(received);
    return frame;
  }
  frame.objects.reserve(options_.objects.size());
  for (const std::string& name : options_.objects) {
    ViconObjectPose pose{name, std::nullopt};
    for (const ViconObjectPose& candidate : received) {
      if (candidate.name == name) pose.vicon_from_marker = candidate.vicon_from_marker;
    }
    frame.objects.push_back(std::move(pose));
  }
  return frame;
}

Expected<std::optional<ViconFrame>> ViconUdpSource::Next(std::chrono::milliseconds timeout) {
  const std::string where = Endpoint(options_.address, bound_port_);
  if (socket_ < 0) return Error{where + ": Next before Start"};
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (true) {
    const ssize_t received = recv(socket_, datagram_.data(), datagram_.size(), MSG_DONTWAIT);
    if (received < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK)
        return Error{where + ": recv: " + std::strerror(errno)};
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return std::optional<ViconFrame>();
      pollfd wait{socket_, POLLIN, 0};
      if (poll(&wait, 1, static_cast<int>(left.count())) < 0 && errno != EINTR)
        return Error{where + ": poll: " + std::strerror(errno)};
      continue;
    }
    const std::int64_t host_ns = HostRealtimeNs();
    auto frame =
        Convert(std::span<const std::uint8_t>(datagram_.data(), static_cast<std::size_t>(received)),
                host_ns);
    if (!frame) {
      CountMalformed(frame.error().message);
      continue;
    }
    if (frame->vicon_frame <= last_frame_) {
      out_of_order_.fetch_add(1);
      continue;
    }
    if (last_frame_ >= 0 && frame->vicon_frame > last_frame_ + 1)
      gaps_.fetch_add(static_cast<std::uint64_t>(frame->vicon_frame - last_frame_ - 1));
    last_frame_ = frame->vicon_frame;
    frames_.fetch_add(1);
    return std::optional<ViconFrame>(std::move(*frame));
  }
}

}  // namespace lifmcr
