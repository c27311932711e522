#pragma once
// Decoding LCM messages that arrive from the network without trusting them.
//
// lcm-gen's C++ decode (LCM 1.4) trusts the length fields of a message: a
// string length of 0 or less becomes std::string::assign(p, -1) (a
// std::length_error, or a read far out of bounds), and an array count such
// as `size` or `num_objects` is passed to std::vector::resize before the
// bytes behind it are checked (2^31 elements from an 8-byte datagram: an
// allocation of gigabytes or std::bad_alloc). A malformed or hostile datagram
// on the multicast group would crash `lifmcr monitor`.
//
// CheckWire walks the encoded message once (linear in its length) with the
// field layout of lcm_types/*.lcm and accepts it only when every string has
// a length of 1 .. bytes left and every array count is >= 0 and fits in the
// bytes left; SafeDecode then calls the generated decode, which can no
// longer over-allocate or over-read. The layouts below must follow the
// .lcm files (tests/lcm_types checks each type's encode passes CheckWire
// and that every truncation fails it).

// GCC 12 sees lcm-gen's `int64_t msg_hash; decode(&msg_hash); if (msg_hash
// ...)` as maybe uninitialised once inlined (the decode returns early on
// error); the warning sits in the generated headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include "lifmcr_lcm/camera_extrinsics_t.hpp"
#include "lifmcr_lcm/camera_pose_t.hpp"
#include "lifmcr_lcm/depth_image_t.hpp"
#include "lifmcr_lcm/pipeline_stats_t.hpp"
#include "lifmcr_lcm/preview_image_t.hpp"
#include "lifmcr_lcm/vicon_frame_t.hpp"
#pragma GCC diagnostic pop

#include <cstddef>
#include <cstdint>
#include <optional>

namespace lifmcr_lcm {

// A cursor over an encoded message; every read checks the bytes left.
class WireCursor {
 public:
  WireCursor(const void* data, std::size_t size)
      : p_(static_cast<const std::uint8_t*>(data)), left_(size) {}
  bool ok() const { return ok_; }
  std::size_t left() const { return left_; }

  void Skip(std::size_t bytes) {
    if (!ok_ || bytes > left_) {
      ok_ = false;
      return;
    }
    p_ += bytes;
    left_ -= bytes;
  }
  // A big-endian int32 (LCM's byte order).
  std::int32_t I32() {
    if (!ok_ || left_ < 4) {
      ok_ = false;
      return 0;
    }
    const std::uint32_t v = (std::uint32_t{p_[0]} << 24) | (std::uint32_t{p_[1]} << 16) |
                            (std::uint32_t{p_[2]} << 8) | std::uint32_t{p_[3]};
    Skip(4);
    return static_cast<std::int32_t>(v);
  }
  // An LCM string: int32 length including the NUL, then the bytes.
  void String() {
    const std::int32_t length = I32();
    if (length < 1) ok_ = false;
    Skip(static_cast<std::size_t>(ok_ ? length : 0));
  }
  // An array count that must be >= 0 and leave room for `count` elements of
  // at least `min_element_bytes` each.
  std::int32_t Count(std::size_t min_element_bytes) {
    const std::int32_t count = I32();
    if (count < 0 || static_cast<std::size_t>(count) * min_element_bytes > left_) ok_ = false;
    return ok_ ? count : 0;
  }

 private:
  const std::uint8_t* p_;
  std::size_t left_;
  bool ok_ = true;
};

namespace wire {

inline void ViconObject(WireCursor& c) {
  c.String();                  // name
  c.Skip(1 + 3 * 8 + 4 * 8);   // occluded, t_mm[3], q_wxyz[4]
}
inline void StageStats(WireCursor& c) {
  c.String();                  // name
  c.Skip(8 + 4 + 4 + 8 + 8 + 8 + 8);
}
inline void DropCount(WireCursor& c) {
  c.String();  // kind
  c.Skip(8);
}

}  // namespace wire

// True when `data` can be decoded as T without over-reading or
// over-allocating (the hash is checked by T::decode itself).
template <typename T>
bool CheckWire(const void* data, std::size_t size);

template <>
inline bool CheckWire<preview_image_t>(const void* data, std::size_t size) {
  WireCursor c(data, size);
  c.Skip(8 + 8);  // hash, utime
  c.String();     // serial
  c.Skip(8 + 8 + 5 * 4 + 1 + 1);
  c.Skip(static_cast<std::size_t>(c.Count(1)));  // data[size]
  return c.ok();
}

template <>
inline bool CheckWire<depth_image_t>(const void* data, std::size_t size) {
  WireCursor c(data, size);
  c.Skip(8 + 8);  // hash, utime
  c.String();     // serial
  c.Skip(8 + 8 + 1 + 1 + 4 + 4 + 5 * 4 + 1);
  c.Skip(4 * 4 + 6 * 8 + 1 + 8 + 2 * 8);         // raw size, lens grid, lambda, principal point
  c.Skip(static_cast<std::size_t>(c.Count(1)));  // data[size]
  return c.ok();
}

template <>
inline bool CheckWire<camera_extrinsics_t>(const void* data, std::size_t size) {
  WireCursor c(data, size);
  c.Skip(8 + 8);  // hash, utime
  c.String();     // reference_serial
  c.String();     // serial
  c.Skip(8);      // trigger_index
  c.String();     // method
  c.String();     // localisation
  c.Skip((3 + 4 + 36) * 8 + 4 + 8);
  c.String();                       // status
  c.Skip(1 + 8 + 4 + (3 + 4) * 8);  // change_state, departure, departures_in_row, running pose
  return c.ok();
}

template <>
inline bool CheckWire<camera_pose_t>(const void* data, std::size_t size) {
  WireCursor c(data, size);
  c.Skip(8 + 8);                     // hash, utime
  c.String();                        // serial
  c.String();                        // reference_serial
  c.Skip(8 + 8 + 8 + 8);             // trigger_index, pass, frame_id, arrival_utime
  c.String();                        // method
  c.String();                        // localisation
  c.Skip((3 + 4 + 36) * 8 + 4 + 8);  // t_mm, q_wxyz, covariance, inliers, rmse_px
  c.String();                        // status
  return c.ok();
}

template <>
inline bool CheckWire<vicon_frame_t>(const void* data, std::size_t size) {
  WireCursor c(data, size);
  c.Skip(8 + 8 + 8 + 1);  // hash, utime, vicon_frame, is_trigger
  const std::int32_t objects = c.Count(4 + 1 + 1 + 56);
  for (std::int32_t i = 0; i < objects && c.ok(); ++i) wire::ViconObject(c);
  return c.ok();
}

template <>
inline bool CheckWire<pipeline_stats_t>(const void* data, std::size_t size) {
  WireCursor c(data, size);
  c.Skip(8 + 8);  // hash, utime
  c.String();     // source
  c.String();     // cameras
  const std::int32_t stages = c.Count(4 + 1 + 48);
  for (std::int32_t i = 0; i < stages && c.ok(); ++i) wire::StageStats(c);
  const std::int32_t drops = c.Count(4 + 1 + 8);
  for (std::int32_t i = 0; i < drops && c.ok(); ++i) wire::DropCount(c);
  return c.ok();
}

// The decoded message, or nothing when it is malformed (CheckWire) or of
// another type (hash).
template <typename T>
std::optional<T> SafeDecode(const void* data, std::size_t size) {
  if (size > static_cast<std::size_t>(INT32_MAX) || !CheckWire<T>(data, size)) return std::nullopt;
  T message;
  if (message.decode(data, 0, static_cast<int>(size)) < 0) return std::nullopt;
  return message;
}

}  // namespace lifmcr_lcm
