// LCM messages as `lifmcr monitor` decodes them (lcm_types/safe_decode.h):
// the first byte picks the type, the rest is the datagram payload. The hash
// of the chosen type is put in front half of the time so decoding goes past
// it.

#include "lcm_types/safe_decode.h"
#include "tests/fuzz/fuzz_util.h"

#include <cstring>
#include <vector>

namespace {

template <typename T>
void Decode(const std::uint8_t* data, std::size_t size, bool with_hash) {
  std::vector<std::uint8_t> buffer;
  if (with_hash) {
    const std::int64_t hash = T::getHash();
    for (int i = 7; i >= 0; --i) buffer.push_back(static_cast<std::uint8_t>(hash >> (8 * i)));
  }
  buffer.insert(buffer.end(), data, data + size);
  std::optional<T> message = lifmcr_lcm::SafeDecode<T>(buffer.data(), buffer.size());
  if (!message) return;
  // lcm-gen encodes strings up to their first NUL, so the length may shrink.
  std::vector<std::uint8_t> again(static_cast<std::size_t>(message->getEncodedSize()));
  const int written = message->encode(again.data(), 0, static_cast<int>(again.size()));
  lifmcr::fuzz::Require(written > 0, "a decoded message encodes");
  lifmcr::fuzz::Require(
      lifmcr_lcm::SafeDecode<T>(again.data(), static_cast<std::size_t>(written)).has_value(),
      "an encoded message decodes");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const bool with_hash = (data[0] & 0x80) == 0;
  switch (data[0] % 6) {
    case 0:
      Decode<lifmcr_lcm::preview_image_t>(data + 1, size - 1, with_hash);
      break;
    case 1:
      Decode<lifmcr_lcm::depth_image_t>(data + 1, size - 1, with_hash);
      break;
    case 2:
      Decode<lifmcr_lcm::camera_extrinsics_t>(data + 1, size - 1, with_hash);
      break;
    case 3:
      Decode<lifmcr_lcm::vicon_frame_t>(data + 1, size - 1, with_hash);
      break;
    case 4:
      Decode<lifmcr_lcm::camera_pose_t>(data + 1, size - 1, with_hash);
      break;
    default:
      Decode<lifmcr_lcm::pipeline_stats_t>(data + 1, size - 1, with_hash);
  }
  return 0;
}
