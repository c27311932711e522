#pragma once
// The arithmetic of a device's frame counter, in one place: the drivers'
// loss counting (frame_id_tracker.h), acquisition's run-relative numbering
// (acquisition/frame_id_unwrapper.h) and sync's trigger association
// (sync/trigger_tracker.h) all step through a CounterRing.
//
// A counter of `bits` bits holds 2^bits values; GigE Vision 1 block ids are
// 16 bit and skip 0 (..., 65534, 65535, 1, 2, ...), a ring of 2^16 - 1
// values. A counter of 64 bits does not wrap in practice (GigE Vision 2
// extended ids, USB3 Vision, GenTL, replay).
//
// Position of id on the ring: p(id) = id mod 2^bits, or with skips_zero
// (id mod 2^bits - 1) mod (2^bits - 1) (so 1 is 0 and a stray 0 sits where
// 2^bits - 1 would).

#include <cstdint>

namespace lifmcr {

struct CounterRing {
  int bits = 16;            // 2..64
  bool skips_zero = true;   // the ring leaves 0 out

  // Values on the ring; 0 for 64 bits (no wrap).
  std::uint64_t Size() const;
  // Steps forward from `from` to `to`, modulo the ring: 0 .. Size() - 1
  // (equal ids: 0; a whole turn cannot be told apart). 64 bits: to - from.
  std::uint64_t Forward(std::uint64_t from, std::uint64_t to) const;
  // The same, signed: in (-Size/2, Size/2], negative when `to` is behind
  // `from` (a repeated or late frame, or a restarted counter).
  std::int64_t Delta(std::uint64_t from, std::uint64_t to) const;
};

}  // namespace lifmcr
