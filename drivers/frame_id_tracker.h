#pragma once
// Counts frames missing from a device's frame counter, across its wrap.
//
// GigE Vision 1 block ids are 16 bit and skip 0 (id 0 is reserved), so the
// counter runs ..., 65534, 65535, 1, 2, ...: a ring of 65535 values. A device
// that does deliver id 0 is taken to count on the full 16-bit ring of 65536
// from then on. USB3 Vision and GigE Vision 2 extended ids are 64 bit and do
// not wrap in practice.
//
// A step forward by more than one counts the ids in between as missing. A
// step of zero (the same id again) or backwards (more than half the ring
// forward, for 16-bit ids) is not a loss but a restart or reordering: it is
// counted in `restarts()` and the new id becomes the reference.

#include <cstdint>
#include <optional>

namespace lifmcr {

enum class FrameIdWidth { k16Bit, k64Bit };

class FrameIdTracker {
 public:
  explicit FrameIdTracker(FrameIdWidth width = FrameIdWidth::k16Bit) : width_(width) {}

  // Ids missing between the previous id and `id`; 0 for the first id, a
  // consecutive id, a repeat or a step backwards.
  std::uint64_t Observe(std::uint64_t id);

  // Forget the previous id (after a reconnect the device counter restarts).
  void Reset() { last_.reset(); }

  std::optional<std::uint64_t> last() const { return last_; }
  std::uint64_t missing() const { return missing_; }
  std::uint64_t restarts() const { return restarts_; }

 private:
  FrameIdWidth width_;
  bool zero_seen_ = false;
  std::optional<std::uint64_t> last_;
  std::uint64_t missing_ = 0;
  std::uint64_t restarts_ = 0;
};

}  // namespace lifmcr
