// ClockModel on generated device/host pairs: offset, drift and jitter are
// recovered; late frames are outliers that do not bend the fit; a jump is
// detected once and the model follows it.
#include "sync/clock_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace lifmcr {
namespace {

TEST(ClockModel, RecoversOffsetDriftAndJitter) {
  for (unsigned seed = 1; seed <= 30; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::normal_distribution<double> noise(0.0, 1.0);
    const double drift_ppm = (unit(rng) * 2 - 1) * 100.0;
    const double sigma_ns = 50'000 + unit(rng) * 200'000;  // 50-250 us
    const std::int64_t host0 = 1'763'800'000'000'000'000;
    const std::int64_t device0 = static_cast<std::int64_t>(unit(rng) * 1e12);
    ClockModel model;
    int late = 0;
    for (int i = 0; i < 600; ++i) {
      const std::int64_t device = device0 + i * 100'000'000LL;
      std::int64_t host = host0 +
                          static_cast<std::int64_t>((device - device0) * (1 + drift_ppm * 1e-6)) +
                          1'700'000 + static_cast<std::int64_t>(noise(rng) * sigma_ns);
      const bool is_late = i > 10 && unit(rng) < 0.02;
      if (is_late) {
        host += 15'000'000 + static_cast<std::int64_t>(unit(rng) * 45e6);  // held up 15-60 ms
        ++late;
      }
      const ClockUpdate update = model.Add(device, host);
      if (i > 10) {
        EXPECT_EQ(update.outlier, is_late) << i;
      }
      EXPECT_FALSE(update.jump);
    }
    EXPECT_NEAR(model.drift_ppm(), drift_ppm, 10.0);
    EXPECT_NEAR(model.jitter_ns(), sigma_ns, 0.35 * sigma_ns);
    EXPECT_EQ(model.outliers(), static_cast<std::uint64_t>(late));
    EXPECT_EQ(model.jumps(), 0u);
    const std::int64_t device = device0 + 600 * 100'000'000LL;
    const double expected = host0 + (device - device0) * (1 + drift_ppm * 1e-6) + 1'700'000.0;
    EXPECT_NEAR(static_cast<double>(model.HostFromDevice(device)), expected, 3 * sigma_ns);
  }
}

TEST(ClockModel, DetectsAJumpAndFollowsIt) {
  ClockModel model;
  const std::int64_t host0 = 1'763'800'000'000'000'000;
  int jumps_seen = 0;
  for (int i = 0; i < 200; ++i) {
    std::int64_t device = 5'000'000'000LL + i * 100'000'000LL;
    if (i >= 100) device -= 40'000'000'000LL;  // the camera's clock was reset
    const ClockUpdate update = model.Add(device, host0 + i * 100'000'000LL + 2'000'000);
    jumps_seen += update.jump;
    if (i == 100 || i == 101) {
      EXPECT_TRUE(update.outlier);
    }
  }
  EXPECT_EQ(jumps_seen, 1);
  EXPECT_EQ(model.jumps(), 1u);
  EXPECT_EQ(model.outliers(), 0u);  // the two before the confirmation were the jump
  const std::int64_t device = 5'000'000'000LL + 250 * 100'000'000LL - 40'000'000'000LL;
  EXPECT_NEAR(static_cast<double>(model.HostFromDevice(device)),
              static_cast<double>(host0 + 250 * 100'000'000LL + 2'000'000), 1000.0);
  EXPECT_NE(model.OneLine().find("1 jumps"), std::string::npos) << model.OneLine();
}

TEST(ClockModel, SingleSampleGivesTheOffset) {
  ClockModel model;
  EXPECT_FALSE(model.valid());
  (void)model.Add(1000, 5000);
  EXPECT_TRUE(model.valid());
  EXPECT_EQ(model.HostFromDevice(2000), 6000);
  EXPECT_EQ(model.offset_ns(), 4000);
}

}  // namespace
}  // namespace lifmcr
