// ParseTrackerPacket on hand-built datagrams: the layout, every length
// check, and no read past the datagram for any truncation or mutation.
#include "drivers/vicon_tracker_packet.h"

#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

// Appends little-endian bytes by hand, independently of the encoder.
struct Bytes {
  std::vector<std::uint8_t> data;
  template <typename T>
  Bytes& Put(T value) {
    std::uint8_t raw[sizeof(T)];
    std::memcpy(raw, &value, sizeof(T));
    data.insert(data.end(), raw, raw + sizeof(T));
    return *this;
  }
  Bytes& Name(const std::string& name, std::size_t field = 24) {
    std::vector<std::uint8_t> padded(field, 0);
    std::memcpy(padded.data(), name.data(), std::min(name.size(), field));
    data.insert(data.end(), padded.begin(), padded.end());
    return *this;
  }
  Bytes& Object(const std::string& name, double base, std::uint16_t data_size = 72) {
    Put<std::uint8_t>(0).Put<std::uint16_t>(data_size).Name(name);
    for (int i = 0; i < 6; ++i) Put<double>(base + i);
    return *this;
  }
};

std::vector<std::uint8_t> TwoObjects() {
  Bytes bytes;
  bytes.Put<std::uint32_t>(123456).Put<std::uint8_t>(2).Object("cam0", 10.0).Object("plate", 20.0);
  return bytes.data;
}

TEST(TrackerPacket, ParsesTheDocumentedLayout) {
  const std::vector<std::uint8_t> bytes = TwoObjects();
  ASSERT_EQ(bytes.size(), 5u + 2 * 75u);
  auto packet = ParseTrackerPacket(bytes);
  ASSERT_TRUE(packet.ok()) << packet.error().message;
  EXPECT_EQ(packet->frame_number, 123456u);
  ASSERT_EQ(packet->objects.size(), 2u);
  EXPECT_EQ(packet->objects[0].name, "cam0");
  EXPECT_EQ(packet->objects[0].translation_mm, (std::array<double, 3>{10, 11, 12}));
  EXPECT_EQ(packet->objects[0].rotation, (std::array<double, 3>{13, 14, 15}));
  EXPECT_EQ(packet->objects[1].name, "plate");
  EXPECT_EQ(packet->objects[1].rotation[2], 25.0);
  // The encoder writes exactly these bytes back.
  auto encoded = EncodeTrackerPacket(*packet);
  ASSERT_TRUE(encoded.ok());
  EXPECT_EQ(*encoded, bytes);
}

TEST(TrackerPacket, EmptyFrameAndZeroPaddingAreValid) {
  Bytes bytes;
  bytes.Put<std::uint32_t>(7).Put<std::uint8_t>(0);
  auto empty = ParseTrackerPacket(bytes.data);
  ASSERT_TRUE(empty.ok());
  EXPECT_EQ(empty->frame_number, 7u);
  EXPECT_TRUE(empty->objects.empty());
  std::vector<std::uint8_t> padded = TwoObjects();
  padded.resize(512, 0);  // some senders pad datagrams to a fixed size
  auto parsed = ParseTrackerPacket(padded);
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(parsed->objects.size(), 2u);
}

TEST(TrackerPacket, EveryTruncationIsRejected) {
  const std::vector<std::uint8_t> bytes = TwoObjects();
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    // A fresh heap copy of exactly `length` bytes, so a read past it would be
    // an overflow that sanitizer builds catch.
    std::vector<std::uint8_t> cut(bytes.begin(), bytes.begin() + length);
    auto packet = ParseTrackerPacket(cut);
    EXPECT_FALSE(packet.ok()) << "accepted a datagram cut at " << length;
  }
}

TEST(TrackerPacket, WrongItemCountsAreRejected) {
  std::vector<std::uint8_t> bytes = TwoObjects();
  bytes[4] = 3;  // more items than bytes
  auto more = ParseTrackerPacket(bytes);
  ASSERT_FALSE(more.ok());
  EXPECT_NE(more.error().message.find("item 2 of 3"), std::string::npos) << more.error().message;
  bytes[4] = 1;  // fewer: the second object is left over
  auto fewer = ParseTrackerPacket(bytes);
  ASSERT_FALSE(fewer.ok());
  EXPECT_NE(fewer.error().message.find("after the last of 1 items"), std::string::npos);
  bytes[4] = 255;
  EXPECT_FALSE(ParseTrackerPacket(bytes).ok());
}

TEST(TrackerPacket, ItemDataSizeIsChecked) {
  for (std::uint16_t size : {0, 1, 71, 73, 150, 0xffff}) {
    Bytes bytes;
    bytes.Put<std::uint32_t>(1).Put<std::uint8_t>(1).Object("cam0", 0.0, size);
    if (size > 72) bytes.data.resize(bytes.data.size() + std::min<int>(size - 72, 100), 0);
    auto packet = ParseTrackerPacket(bytes.data);
    EXPECT_FALSE(packet.ok()) << "ItemDataSize " << size;
  }
}

TEST(TrackerPacket, UnknownItemsAreSkippedByTheirSize) {
  Bytes bytes;
  bytes.Put<std::uint32_t>(9).Put<std::uint8_t>(2);
  bytes.Put<std::uint8_t>(7).Put<std::uint16_t>(4).Put<std::uint32_t>(0xdeadbeef);
  bytes.Object("cam1", 1.0);
  auto packet = ParseTrackerPacket(bytes.data);
  ASSERT_TRUE(packet.ok()) << packet.error().message;
  EXPECT_EQ(packet->skipped_items, 1u);
  ASSERT_EQ(packet->objects.size(), 1u);
  EXPECT_EQ(packet->objects[0].name, "cam1");
}

TEST(TrackerPacket, NamesMustBeTerminatedAndNotEmpty) {
  {
    Bytes bytes;  // 24 name bytes, no NUL
    bytes.Put<std::uint32_t>(1).Put<std::uint8_t>(1).Object(std::string(24, 'x'), 0.0);
    auto packet = ParseTrackerPacket(bytes.data);
    ASSERT_FALSE(packet.ok());
    EXPECT_NE(packet.error().message.find("no NUL"), std::string::npos);
  }
  {
    Bytes bytes;  // 23 bytes + NUL: the longest name
    bytes.Put<std::uint32_t>(1).Put<std::uint8_t>(1).Object(std::string(23, 'y'), 0.0);
    auto packet = ParseTrackerPacket(bytes.data);
    ASSERT_TRUE(packet.ok());
    EXPECT_EQ(packet->objects[0].name, std::string(23, 'y'));
  }
  {
    Bytes bytes;
    bytes.Put<std::uint32_t>(1).Put<std::uint8_t>(1).Object("", 0.0);
    EXPECT_FALSE(ParseTrackerPacket(bytes.data).ok());
  }
}

TEST(TrackerPacket, NonFiniteValuesAreRejected) {
  Bytes bytes;
  bytes.Put<std::uint32_t>(1).Put<std::uint8_t>(1).Object("cam0", 0.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(bytes.data.data() + 5 + 3 + 24 + 8, &nan, sizeof(nan));
  EXPECT_FALSE(ParseTrackerPacket(bytes.data).ok());
}

TEST(TrackerPacket, RandomMutationsNeverCrashAndValidResultsReencode) {
  std::mt19937 rng(20261122);
  const std::vector<std::uint8_t> base = TwoObjects();
  int accepted = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    std::vector<std::uint8_t> bytes = base;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      switch (rng() % 3) {
        case 0:
          bytes[rng() % bytes.size()] = static_cast<std::uint8_t>(rng());
          break;
        case 1:
          bytes.resize(rng() % (bytes.size() + 1));
          break;
        default:
          bytes.insert(bytes.begin() + static_cast<long>(rng() % (bytes.size() + 1)),
                       static_cast<std::uint8_t>(rng()));
      }
      if (bytes.empty()) break;
    }
    auto packet = ParseTrackerPacket(bytes);
    if (!packet.ok()) continue;
    ++accepted;
    if (packet->skipped_items != 0) continue;
    auto encoded = EncodeTrackerPacket(*packet);
    ASSERT_TRUE(encoded.ok()) << encoded.error().message;
    auto again = ParseTrackerPacket(*encoded);
    ASSERT_TRUE(again.ok());
    EXPECT_EQ(*again, *packet);
  }
  EXPECT_GT(accepted, 0);  // value-only edits (frame number, poses) stay valid
}

TEST(TrackerPacket, EncoderRefusesWhatTheStreamCannotCarry) {
  TrackerPacket packet;
  packet.objects.push_back({std::string(24, 'n'), {}, {}});
  EXPECT_FALSE(EncodeTrackerPacket(packet).ok());
  packet.objects[0].name = std::string("a\0b", 3);
  EXPECT_FALSE(EncodeTrackerPacket(packet).ok());
  packet.objects[0].name = "ok";
  packet.objects[0].rotation[1] = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(EncodeTrackerPacket(packet).ok());
  packet.objects.assign(256, TrackerObject{"o", {}, {}});
  EXPECT_FALSE(EncodeTrackerPacket(packet).ok());
  packet.objects.resize(255);
  EXPECT_TRUE(EncodeTrackerPacket(packet).ok());
}

}  // namespace
}  // namespace lifmcr
