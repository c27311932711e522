#pragma once
// The Vicon Tracker "UDP Object Stream" datagram (Vicon Tracker user guide):
// one datagram per Vicon frame, little-endian, packed:
//   uint32 FrameNumber
//   uint8  ItemsInBlock
//   ItemsInBlock times:
//     uint8  ItemID        0 = object
//     uint16 ItemDataSize  bytes after this field: 72 for an object
//     char   ItemName[24]  NUL-terminated within the 24 bytes, NUL-padded
//     double TransX, TransY, TransZ   mm, Vicon frame
//     double RotX, RotY, RotZ         as Tracker is set (rig file: vicon.rotation)
// The stream carries no timestamp: the frame number is the time axis.
//
// ParseTrackerPacket is the only code that reads datagram bytes. It checks
// every length against the bytes actually received and never reads past
// them; EncodeTrackerPacket is its exact inverse (used by the test sender).

#include "config/error.h"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace lifmcr {

inline constexpr std::size_t kTrackerHeaderBytes = 5;       // FrameNumber + ItemsInBlock
inline constexpr std::size_t kTrackerItemHeaderBytes = 3;   // ItemID + ItemDataSize
inline constexpr std::size_t kTrackerNameBytes = 24;        // ItemName, NUL included
inline constexpr std::size_t kTrackerObjectDataBytes = 72;  // name + 6 doubles
inline constexpr std::uint8_t kTrackerObjectItemId = 0;
// The largest UDP payload over IPv4: a datagram can never be longer.
inline constexpr std::size_t kMaxUdpPayloadBytes = 65507;

struct TrackerObject {
  std::string name;                        // at most 23 bytes, no NUL
  std::array<double, 3> translation_mm{};  // TransX, TransY, TransZ
  std::array<double, 3> rotation{};        // RotX, RotY, RotZ (representation from the rig file)
  bool operator==(const TrackerObject&) const = default;
};

struct TrackerPacket {
  std::uint32_t frame_number = 0;
  std::vector<TrackerObject> objects;  // items of ItemID 0, in datagram order
  // Items with another ItemID, skipped by their ItemDataSize (none in Tracker
  // 3.x streams; counted so a changed stream does not go unnoticed).
  std::uint32_t skipped_items = 0;
  bool operator==(const TrackerPacket&) const = default;
};

// Parses one datagram. Errors (the message names the byte offset and the
// field): shorter than the header; an item header, item data or name running
// past the datagram; an object whose ItemDataSize is not 72; a name that is
// empty or has no NUL within 24 bytes; a non-finite value; bytes after the
// last item that are not zero padding (ItemsInBlock too small).
Expected<TrackerPacket> ParseTrackerPacket(std::span<const std::uint8_t> datagram);

// The datagram ParseTrackerPacket reads back equal (skipped_items must be 0).
// Errors: more than 255 objects, a name empty, longer than 23 bytes or with
// a NUL, a non-finite value.
Expected<std::vector<std::uint8_t>> EncodeTrackerPacket(const TrackerPacket& packet);

}  // namespace lifmcr
