#include "drivers/frame_id_tracker.h"

#include <gtest/gtest.h>

#include <random>

namespace lifmcr {
namespace {

TEST(FrameIdTracker, SixteenBitWrapSkipsZero) {
  FrameIdTracker ids(FrameIdWidth::k16Bit);
  EXPECT_EQ(ids.Observe(65534), 0u);
  EXPECT_EQ(ids.Observe(65535), 0u);
  EXPECT_EQ(ids.Observe(1), 0u);  // GigE Vision 1 never sends block id 0
  EXPECT_EQ(ids.Observe(2), 0u);
  EXPECT_EQ(ids.missing(), 0u);
}

TEST(FrameIdTracker, GapAcrossTheWrapCountsTheIdsBetween) {
  FrameIdTracker ids(FrameIdWidth::k16Bit);
  ids.Observe(65533);
  EXPECT_EQ(ids.Observe(3), 4u);  // 65534, 65535, 1, 2
  EXPECT_EQ(ids.missing(), 4u);
}

TEST(FrameIdTracker, DeviceThatSendsZeroCountsOnTheFullRing) {
  FrameIdTracker ids(FrameIdWidth::k16Bit);
  ids.Observe(65535);
  EXPECT_EQ(ids.Observe(0), 0u);
  ids.Observe(65534);  // backwards: a restart, not a loss
  EXPECT_EQ(ids.restarts(), 1u);
  ids.Observe(65535);
  EXPECT_EQ(ids.Observe(1), 1u);  // 0 is a real id now
}

TEST(FrameIdTracker, RepeatsAndStepsBackAreRestartsNotLosses) {
  FrameIdTracker ids(FrameIdWidth::k16Bit);
  ids.Observe(100);
  EXPECT_EQ(ids.Observe(100), 0u);
  EXPECT_EQ(ids.Observe(90), 0u);
  EXPECT_EQ(ids.restarts(), 2u);
  EXPECT_EQ(ids.missing(), 0u);
  ids.Reset();
  EXPECT_EQ(ids.Observe(7), 0u);
}

TEST(FrameIdTracker, SixtyFourBitIdsDoNotWrap) {
  FrameIdTracker ids(FrameIdWidth::k64Bit);
  ids.Observe(65535);
  EXPECT_EQ(ids.Observe(65536), 0u);
  EXPECT_EQ(ids.Observe(65540), 3u);
  EXPECT_EQ(ids.Observe(1), 0u);
  EXPECT_EQ(ids.restarts(), 1u);
}

// Property: random drop patterns over several wraps are counted exactly
// (drops after the last delivered id are not visible yet).
TEST(FrameIdTracker, RandomDropsOverWrapsAreCountedExactly) {
  for (unsigned seed = 1; seed <= 5; ++seed) {
    std::mt19937 rng(seed);
    std::bernoulli_distribution drop(0.05 * seed);
    FrameIdTracker ids(FrameIdWidth::k16Bit);
    std::uint64_t id = 65400;
    std::uint64_t dropped_before_last = 0;
    std::uint64_t dropped_since_last = 0;
    for (int i = 0; i < 300000; ++i) {
      if (i > 0 && drop(rng)) {
        ++dropped_since_last;
      } else {
        ids.Observe(id);
        dropped_before_last += dropped_since_last;
        dropped_since_last = 0;
      }
      id = id == 65535 ? 1 : id + 1;
    }
    EXPECT_EQ(ids.missing(), dropped_before_last) << "seed " << seed;
    EXPECT_EQ(ids.restarts(), 0u);
  }
}

}  // namespace
}  // namespace lifmcr
