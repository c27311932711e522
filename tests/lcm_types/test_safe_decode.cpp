// lcm_types/safe_decode.h: every message lifmcr encodes passes CheckWire and
// decodes; every truncation and every hostile length field is refused before
// lcm-gen's decode could over-allocate or read out of bounds.

#include "lcm_types/safe_decode.h"

#include <gtest/gtest.h>

#include <cstring>
#include <vector>

namespace {

template <typename T>
std::vector<std::uint8_t> Encode(const T& message) {
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(message.getEncodedSize()));
  EXPECT_EQ(message.encode(buffer.data(), 0, static_cast<int>(buffer.size())),
            static_cast<int>(buffer.size()));
  return buffer;
}

template <typename T>
void ExpectSafe(const T& message) {
  const std::vector<std::uint8_t> bytes = Encode(message);
  EXPECT_TRUE(lifmcr_lcm::SafeDecode<T>(bytes.data(), bytes.size()).has_value());
  for (std::size_t n = 0; n < bytes.size(); ++n)
    EXPECT_FALSE(lifmcr_lcm::CheckWire<T>(bytes.data(), n)) << "truncated to " << n;
}

void PutBigEndian32(std::vector<std::uint8_t>* bytes, std::size_t at, std::int32_t value) {
  const auto v = static_cast<std::uint32_t>(value);
  for (int k = 0; k < 4; ++k) (*bytes)[at + k] = static_cast<std::uint8_t>(v >> (24 - 8 * k));
}

TEST(SafeDecode, EveryTypeDecodesAndEveryTruncationIsRefused) {
  lifmcr_lcm::preview_image_t preview{};
  preview.serial = "40398678";
  preview.size = 5;
  preview.data = {1, 2, 3, 4, 5};
  ExpectSafe(preview);
  lifmcr_lcm::depth_image_t depth{};
  depth.serial = "1";
  depth.size = 3;
  depth.data = {7, 8, 9};
  ExpectSafe(depth);
  lifmcr_lcm::camera_extrinsics_t extrinsics{};
  extrinsics.reference_serial = "a";
  extrinsics.serial = "b";
  extrinsics.method = "pnp";
  extrinsics.status = "ok";
  ExpectSafe(extrinsics);
  lifmcr_lcm::camera_pose_t pose{};
  pose.serial = "b";
  pose.reference_serial = "a";
  pose.method = "pnp";
  pose.localisation = "tracked";
  pose.status = "ok";
  ExpectSafe(pose);
  lifmcr_lcm::vicon_frame_t vicon{};
  vicon.num_objects = 2;
  vicon.objects.resize(2);
  vicon.objects[0].name = "cam0";
  vicon.objects[1].name = "plate";
  ExpectSafe(vicon);
  lifmcr_lcm::pipeline_stats_t stats{};
  stats.num_stages = 1;
  stats.stages.resize(1);
  stats.stages[0].name = "depth";
  stats.num_drops = 1;
  stats.drops.resize(1);
  stats.drops[0].kind = "vicon_gap";
  ExpectSafe(stats);
}

// The lengths lcm-gen's decode trusts: a string length of 0 or less (it
// calls assign(p, length - 1)) and array counts far beyond the datagram.
TEST(SafeDecode, HostileLengthsAreRefused) {
  lifmcr_lcm::preview_image_t preview{};
  preview.serial = "x";
  std::vector<std::uint8_t> bytes = Encode(preview);
  const std::size_t serial_at = 16;  // hash, utime
  for (const std::int32_t length : {0, -1, -100, 1 << 30}) {
    std::vector<std::uint8_t> bad = bytes;
    PutBigEndian32(&bad, serial_at, length);
    EXPECT_FALSE(lifmcr_lcm::SafeDecode<lifmcr_lcm::preview_image_t>(bad.data(), bad.size()))
        << "serial length " << length;
  }
  const std::size_t size_at = bytes.size() - 4;  // the last field before data[]
  for (const std::int32_t size : {-1, 1 << 30, 0x7fffffff}) {
    std::vector<std::uint8_t> bad = bytes;
    PutBigEndian32(&bad, size_at, size);
    EXPECT_FALSE(lifmcr_lcm::SafeDecode<lifmcr_lcm::preview_image_t>(bad.data(), bad.size()))
        << "size " << size;
  }
  lifmcr_lcm::vicon_frame_t vicon{};
  std::vector<std::uint8_t> frame = Encode(vicon);
  for (const std::int32_t count : {-5, 1000000, 0x7fffffff}) {
    std::vector<std::uint8_t> bad = frame;
    PutBigEndian32(&bad, frame.size() - 4, count);
    EXPECT_FALSE(lifmcr_lcm::SafeDecode<lifmcr_lcm::vicon_frame_t>(bad.data(), bad.size()))
        << "num_objects " << count;
  }
}

}  // namespace
