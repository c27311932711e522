// The grey plane's row kernel (processing/grey_plane_simd.h): Highway's on
// every target this CPU runs against the scalar reference, exactly (integers),
// on random rows of 1-200 pixels (the vector loop and its scalar tail), and
// the reference against the rounded channel mean for every channel sum.

#include "processing/grey_plane_simd.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <hwy/targets.h>
#include <random>
#include <vector>

namespace lifmcr::processing::detail {
namespace {

class GreyPlaneKernelsTest : public ::testing::Test {
 protected:
  void TearDown() override { hwy::SetSupportedTargetsForTest(0); }
};

TEST_F(GreyPlaneKernelsTest, RowsMatchTheScalarReferenceExactlyOnEveryTarget) {
  const GreyPlaneKernels& scalar = ScalarGreyPlaneKernels();
  const std::vector<std::int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (const std::int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    const GreyPlaneKernels& simd = SimdGreyPlaneKernels();
    std::mt19937 rng(11);
    for (int trial = 0; trial < 400; ++trial) {
      const int n = std::uniform_int_distribution<int>(1, 200)(rng);
      std::vector<std::uint8_t> bgr(3 * static_cast<std::size_t>(n));
      // Saturated and dark pixels often: the ends of the sum's range.
      for (std::uint8_t& b : bgr) {
        const unsigned r = rng();
        b = static_cast<std::uint8_t>(r % 7 == 0 ? 255 : r % 7 == 1 ? 0 : (r >> 8) & 0xFF);
      }
      // One guard byte each side of the output: written nowhere else.
      std::vector<std::uint8_t> a(n + 2, 0xA5), b(n + 2, 0x5A);
      scalar.row(bgr.data(), n, a.data() + 1);
      simd.row(bgr.data(), n, b.data() + 1);
      for (int x = 0; x < n; ++x)
        ASSERT_EQ(a[x + 1], b[x + 1]) << hwy::TargetName(target) << " n " << n << " x " << x;
      EXPECT_EQ(b[0], 0x5A) << hwy::TargetName(target);
      EXPECT_EQ(b[n + 1], 0x5A) << hwy::TargetName(target);
    }
  }
}

TEST_F(GreyPlaneKernelsTest, EveryChannelSumGivesItsRoundedMeanOnEveryTarget) {
  // Every sum 0..765 (b + g + r), as many pixels as a few vectors hold.
  std::vector<std::uint8_t> bgr;
  std::vector<int> sums;
  for (int s = 0; s <= 765; ++s) {
    const int b = std::min(s, 255), g = std::min(s - b, 255), r = s - b - g;
    bgr.insert(bgr.end(), {static_cast<std::uint8_t>(b), static_cast<std::uint8_t>(g),
                           static_cast<std::uint8_t>(r)});
    sums.push_back(s);
  }
  const int n = static_cast<int>(sums.size());
  std::vector<const GreyPlaneKernels*> kernels{&ScalarGreyPlaneKernels()};
  for (const std::int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    std::vector<std::uint8_t> grey(n);
    SimdGreyPlaneKernels().row(bgr.data(), n, grey.data());
    for (int x = 0; x < n; ++x)
      ASSERT_EQ(grey[x], static_cast<int>(std::lround(sums[x] / 3.0)))
          << hwy::TargetName(target) << " sum " << sums[x];
  }
  std::vector<std::uint8_t> grey(n);
  ScalarGreyPlaneKernels().row(bgr.data(), n, grey.data());
  for (int x = 0; x < n; ++x) ASSERT_EQ(grey[x], static_cast<int>(std::lround(sums[x] / 3.0)));
}

}  // namespace
}  // namespace lifmcr::processing::detail
