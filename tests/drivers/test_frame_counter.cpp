// The one frame-counter arithmetic (drivers/frame_counter.h) that the
// drivers, acquisition and sync share.

#include "drivers/frame_counter.h"

#include <gtest/gtest.h>

#include <random>

namespace lifmcr {
namespace {

TEST(CounterRing, GigEVisionBlockIdsSkipZeroAcrossTheWrap) {
  const CounterRing ring{16, true};
  EXPECT_EQ(ring.Size(), 65535u);
  EXPECT_EQ(ring.Forward(65535, 1), 1u);
  EXPECT_EQ(ring.Forward(65534, 2), 3u);  // 65535, 1, 2
  EXPECT_EQ(ring.Forward(7, 7), 0u);
  EXPECT_EQ(ring.Delta(1, 65535), -1);  // one behind, across the wrap
  EXPECT_EQ(ring.Delta(10, 5), -5);
  EXPECT_EQ(ring.Delta(5, 10), 5);
}

TEST(CounterRing, FullRingAndWideCounters) {
  const CounterRing full{16, false};
  EXPECT_EQ(full.Size(), 65536u);
  EXPECT_EQ(full.Forward(65535, 0), 1u);
  EXPECT_EQ(full.Delta(0, 65535), -1);
  const CounterRing wide{64, false};
  EXPECT_EQ(wide.Size(), 0u);
  EXPECT_EQ(wide.Forward(70000, 70005), 5u);
  EXPECT_EQ(wide.Delta(70005, 70000), -5);
  const CounterRing small{4, true};  // 1..15
  EXPECT_EQ(small.Forward(15, 1), 1u);
}

// Random walks: the sum of the steps equals the distance travelled.
TEST(CounterRing, StepsAddUpOverManyWraps) {
  for (const bool skips_zero : {true, false}) {
    const CounterRing ring{16, skips_zero};
    std::mt19937 rng(3);
    std::uniform_int_distribution<int> step(1, 300);
    std::uint64_t id = 65400, travelled = 0, counted = 0;
    for (int i = 0; i < 100000; ++i) {
      const int k = step(rng);
      std::uint64_t next = id;
      for (int j = 0; j < k; ++j) {
        next = (next + 1) & 0xFFFF;
        if (skips_zero && next == 0) next = 1;
      }
      counted += static_cast<std::uint64_t>(ring.Delta(id, next));
      travelled += static_cast<std::uint64_t>(k);
      id = next;
    }
    EXPECT_EQ(counted, travelled) << skips_zero;
  }
}

}  // namespace
}  // namespace lifmcr
