// SIFT and matching on a synthetic texture seen twice with a known shift:
// the matches must recover the shift, and the ratio test and cross-check must
// drop ambiguous pairs.

#include "registration/features.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace lifmcr::registration {
namespace {

// Smooth multi-scale blobs (sum of Gaussian bumps), 8-bit grey.
std::vector<std::uint8_t> BlobImage(int w, int h, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(0, w), uy(0, h), us(2.0, 9.0), ua(-1, 1);
  std::vector<double> acc(static_cast<std::size_t>(w) * h, 0.0);
  for (int n = 0; n < 500; ++n) {
    const double cx = ux(rng), cy = uy(rng), s = us(rng), a = ua(rng);
    const int r = static_cast<int>(3 * s);
    for (int y = std::max(0, static_cast<int>(cy) - r); y < std::min(h, static_cast<int>(cy) + r);
         ++y)
      for (int x = std::max(0, static_cast<int>(cx) - r);
           x < std::min(w, static_cast<int>(cx) + r); ++x)
        acc[static_cast<std::size_t>(y) * w + x] +=
            a * std::exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (2 * s * s));
  }
  std::vector<std::uint8_t> img(acc.size());
  for (std::size_t i = 0; i < acc.size(); ++i)
    img[i] = static_cast<std::uint8_t>(std::clamp(128 + 90 * acc[i], 0.0, 255.0));
  return img;
}

TEST(Features, SiftMatchesRecoverAKnownShift) {
  const int w = 320, h = 240, dx = 9, dy = -5;
  const std::vector<std::uint8_t> a = BlobImage(w, h, 3);
  std::vector<std::uint8_t> b(a.size(), 128);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int sx = x - dx, sy = y - dy;
      if (sx >= 0 && sy >= 0 && sx < w && sy < h)
        b[static_cast<std::size_t>(y) * w + x] = a[static_cast<std::size_t>(sy) * w + sx];
    }
  Features fa, fb;
  ASSERT_TRUE(DetectSift({a.data(), w, h, static_cast<std::size_t>(w), PixelFormat::kMono8},
                         FeatureOptions{}, &fa));
  ASSERT_TRUE(DetectSift({b.data(), w, h, static_cast<std::size_t>(w), PixelFormat::kMono8},
                         FeatureOptions{}, &fb));
  EXPECT_GT(fa.size(), 100);
  ASSERT_EQ(fa.descriptors.size(), static_cast<std::size_t>(fa.size()) * kDescriptorSize);
  const std::vector<Match> matches =
      MatchDescriptors(fa.descriptors.data(), fa.size(), fb.descriptors.data(), fb.size(), {});
  int good = 0;
  for (const Match& m : matches) {
    const Eigen::Vector2f d = fb.keypoints[m.train].xy_px - fa.keypoints[m.query].xy_px;
    if ((d - Eigen::Vector2f(dx, dy)).norm() < 1.0f) ++good;
  }
  std::printf("SIFT: %d and %d keypoints, %zu matches, %d on the true shift\n", fa.size(),
              fb.size(), matches.size(), good);
  EXPECT_GT(matches.size(), 60u);
  EXPECT_GE(good, 0.95 * matches.size());
  for (std::size_t i = 1; i < matches.size(); ++i)
    EXPECT_LE(matches[i - 1].ratio, matches[i].ratio);
}

TEST(Features, CrossCheckKeepsOnlyMutualNearestNeighbours) {
  // Two train descriptors near one query; a second query nearer to the first
  // train: the first query's match is not mutual and must be dropped.
  std::vector<float> q(2 * kDescriptorSize, 0.f), t(3 * kDescriptorSize, 0.f);
  q[0] = 1.0f;                        // q0 = e0
  q[kDescriptorSize + 0] = 1.05f;     // q1 close to t0
  t[0] = 1.06f;                       // t0
  t[kDescriptorSize + 1] = 1.0f;      // t1 far
  t[2 * kDescriptorSize + 2] = 1.0f;  // t2 far
  MatchOptions options;
  options.ratio = 0.9;
  const std::vector<Match> with = MatchDescriptors(q.data(), 2, t.data(), 3, options);
  ASSERT_EQ(with.size(), 1u);
  EXPECT_EQ(with[0].query, 1);
  EXPECT_EQ(with[0].train, 0);
  options.cross_check = false;
  EXPECT_EQ(MatchDescriptors(q.data(), 2, t.data(), 3, options).size(), 2u);
  options.ratio = 1.5;
  EXPECT_FALSE(options.Check());
}

}  // namespace
}  // namespace lifmcr::registration
