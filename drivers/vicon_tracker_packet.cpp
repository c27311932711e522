#include "drivers/vicon_tracker_packet.h"

#include <bit>
#include <cmath>
#include <cstring>
#include <string_view>

namespace lifmcr {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the Tracker stream is little-endian; add byte swapping for this host");

Error PacketError(std::size_t offset, const std::string& what) {
  return Error{"Vicon Tracker packet: byte " + std::to_string(offset) + ": " + what};
}

// Reads a little-endian value at `offset`; the caller has checked the bounds.
template <typename T>
T Load(std::span<const std::uint8_t> bytes, std::size_t offset) {
  T value;
  std::memcpy(&value, bytes.data() + offset, sizeof(T));
  return value;
}

template <typename T>
void Store(std::vector<std::uint8_t>* bytes, T value) {
  const auto* raw = reinterpret_cast<const std::uint8_t*>(&value);
  bytes->insert(bytes->end(), raw, raw + sizeof(T));
}

Expected<TrackerObject> ParseObject(std::span<const std::uint8_t> data, std::size_t offset) {
  TrackerObject object;
  const auto* name = reinterpret_cast<const char*>(data.data());
  const std::size_t length = strnlen(name, kTrackerNameBytes);
  if (length == kTrackerNameBytes)
    return PacketError(offset, "object name has no NUL within its 24 bytes");
  if (length == 0) return PacketError(offset, "object name is empty");
  object.name.assign(name, length);
  std::size_t at = kTrackerNameBytes;
  for (double& value : object.translation_mm) {
    value = Load<double>(data, at);
    at += sizeof(double);
  }
  for (double& value : object.rotation) {
    value = Load<double>(data, at);
    at += sizeof(double);
  }
  for (std::size_t i = 0; i < 3; ++i) {
    if (!std::isfinite(object.translation_mm[i]) || !std::isfinite(object.rotation[i]))
      return PacketError(offset, "object '" + object.name + "' has a non-finite value");
  }
  return object;
}

}  // namespace

Expected<TrackerPacket> ParseTrackerPacket(std::span<const std::uint8_t> datagram) {
  if (datagram.size() < kTrackerHeaderBytes)
    return PacketError(0, "expected at least 5 bytes (frame number, item count), got " +
                              std::to_string(datagram.size()));
  TrackerPacket packet;
  packet.frame_number = Load<std::uint32_t>(datagram, 0);
  const int item_count = datagram[4];
  std::size_t offset = kTrackerHeaderBytes;
  for (int item = 0; item < item_count; ++item) {
    const std::string which = "item " + std::to_string(item) + " of " + std::to_string(item_count);
    if (datagram.size() - offset < kTrackerItemHeaderBytes)
      return PacketError(offset, which + ": item header runs past the datagram (" +
                                     std::to_string(datagram.size()) + " bytes)");
    const std::uint8_t item_id = datagram[offset];
    const std::size_t data_size = Load<std::uint16_t>(datagram, offset + 1);
    offset += kTrackerItemHeaderBytes;
    if (datagram.size() - offset < data_size)
      return PacketError(offset, which + ": ItemDataSize " + std::to_string(data_size) +
                                     " runs past the datagram (" +
                                     std::to_string(datagram.size() - offset) + " bytes left)");
    if (item_id != kTrackerObjectItemId) {
      ++packet.skipped_items;
      offset += data_size;
      continue;
    }
    if (data_size != kTrackerObjectDataBytes)
      return PacketError(
          offset, which + ": object ItemDataSize must be 72, got " + std::to_string(data_size));
    auto object = ParseObject(datagram.subspan(offset, data_size), offset);
    if (!object) return object.error();
    packet.objects.push_back(std::move(*object));
    offset += data_size;
  }
  for (std::size_t i = offset; i < datagram.size(); ++i) {
    if (datagram[i] != 0)
      return PacketError(i, "non-zero bytes after the last of " + std::to_string(item_count) +
                                " items (ItemsInBlock too small?)");
  }
  return packet;
}

Expected<std::vector<std::uint8_t>> EncodeTrackerPacket(const TrackerPacket& packet) {
  if (packet.objects.size() > 255)
    return Error{"Vicon Tracker packet: at most 255 objects, got " +
                 std::to_string(packet.objects.size())};
  if (packet.skipped_items != 0) return Error{"Vicon Tracker packet: cannot encode skipped items"};
  std::vector<std::uint8_t> bytes;
  bytes.reserve(kTrackerHeaderBytes +
                packet.objects.size() * (kTrackerItemHeaderBytes + kTrackerObjectDataBytes));
  Store(&bytes, packet.frame_number);
  Store(&bytes, static_cast<std::uint8_t>(packet.objects.size()));
  for (const TrackerObject& object : packet.objects) {
    if (object.name.empty() || object.name.size() >= kTrackerNameBytes ||
        object.name.find('\0') != std::string::npos)
      return Error{"Vicon Tracker packet: object name '" + object.name +
                   "' must have 1 to 23 bytes and no NUL"};
    for (std::size_t i = 0; i < 3; ++i) {
      if (!std::isfinite(object.translation_mm[i]) || !std::isfinite(object.rotation[i]))
        return Error{"Vicon Tracker packet: object '" + object.name + "' has a non-finite value"};
    }
    Store(&bytes, kTrackerObjectItemId);
    Store(&bytes, static_cast<std::uint16_t>(kTrackerObjectDataBytes));
    char name[kTrackerNameBytes] = {};
    std::memcpy(name, object.name.data(), object.name.size());
    bytes.insert(bytes.end(), name, name + kTrackerNameBytes);
    for (double value : object.translation_mm) Store(&bytes, value);
    for (double value : object.rotation) Store(&bytes, value);
  }
  return bytes;
}

}  // namespace lifmcr
