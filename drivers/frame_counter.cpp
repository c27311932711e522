// Frame counter ring arithmetic (frame_counter.h).

#include "drivers/frame_counter.h"

namespace lifmcr {

std::uint64_t CounterRing::Size() const {
  if (bits >= 64) return 0;
  const std::uint64_t values = std::uint64_t{1} << bits;
  return skips_zero ? values - 1 : values;
}

std::uint64_t CounterRing::Forward(std::uint64_t from, std::uint64_t to) const {
  if (bits >= 64) return to - from;
  const std::uint64_t mask = (std::uint64_t{1} << bits) - 1;
  const std::uint64_t size = Size();
  const std::uint64_t offset = skips_zero ? size - 1 : 0;  // p(1) = 0 when 0 is skipped
  const std::uint64_t p_from = ((from & mask) + offset) % size;
  const std::uint64_t p_to = ((to & mask) + offset) % size;
  return (p_to + size - p_from) % size;
}

std::int64_t CounterRing::Delta(std::uint64_t from, std::uint64_t to) const {
  if (bits >= 64) return static_cast<std::int64_t>(to - from);
  const std::uint64_t size = Size();
  const std::uint64_t forward = Forward(from, to);
  return forward > size / 2 ? static_cast<std::int64_t>(forward) - static_cast<std::int64_t>(size)
                            : static_cast<std::int64_t>(forward);
}

}  // namespace lifmcr
