// SIFT and matching on a synthetic texture seen twice with a known shift:
// the matches must recover the shift, and the ratio test and cross-check must
// drop ambiguous pairs. SIFT finds a blob at its centre on the pixel grid;
// at half scale it maps its keypoints back without bias; spread cells keep keypoints where the texture is weak; a kept
// DescriptorIndex matches as the buffers do; the map's kd-forest finds the
// exact matcher's matches.

#include "registration/features/features.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <set>
#include <thread>
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

// `a` shifted by (dx, dy), grey 128 where nothing is seen.
std::vector<std::uint8_t> Shifted(const std::vector<std::uint8_t>& a, int w, int h, int dx, int dy) {
  std::vector<std::uint8_t> b(a.size(), 128);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const int sx = x - dx, sy = y - dy;
      if (sx >= 0 && sy >= 0 && sx < w && sy < h)
        b[static_cast<std::size_t>(y) * w + x] = a[static_cast<std::size_t>(sy) * w + sx];
    }
  return b;
}

ConstImageView View(const std::vector<std::uint8_t>& img, int w, int h) {
  return {img.data(), w, h, static_cast<std::size_t>(w), PixelFormat::kMono8};
}

TEST(Features, SiftMatchesRecoverAKnownShift) {
  const int w = 320, h = 240, dx = 9, dy = -5;
  const std::vector<std::uint8_t> a = BlobImage(w, h, 3);
  const std::vector<std::uint8_t> b = Shifted(a, w, h, dx, dy);
  Features fa, fb;
  ASSERT_TRUE(DetectSift(View(a, w, h), FeatureOptions{}, &fa));
  ASSERT_TRUE(DetectSift(View(b, w, h), FeatureOptions{}, &fb));
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

TEST(Features, SiftFindsABlobAtItsCentreOnThePixelGrid) {
  // Dark Gaussian blobs centred at known sub-pixel positions (pixel centres
  // at integers): DetectSift reports them there. OpenCV's own positions sit
  // +1/4 px off in x and y (features.h), which this bound excludes.
  const int w = 256, h = 256;
  std::vector<Eigen::Vector2d> centres;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      centres.emplace_back(40 + 58 * i + 0.1 * i, 40 + 58 * j + 0.13 * j);
  std::vector<std::uint8_t> img(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double a = 0;
      for (const Eigen::Vector2d& c : centres)
        a += std::exp(-((x - c.x()) * (x - c.x()) + (y - c.y()) * (y - c.y())) / (2 * 4.0 * 4.0));
      img[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint8_t>(std::lround(220 - 160 * a));
    }
  Features f;
  ASSERT_TRUE(DetectSift(View(img, w, h), FeatureOptions{}, &f));
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  int found = 0;
  for (const Eigen::Vector2d& c : centres) {
    double best = 1.0;
    Eigen::Vector2d d = Eigen::Vector2d::Zero();
    for (const Keypoint& k : f.keypoints)
      if ((k.xy_px.cast<double>() - c).norm() < best) {
        best = (k.xy_px.cast<double>() - c).norm();
        d = k.xy_px.cast<double>() - c;
      }
    if (best < 1.0) sum += d, ++found;
  }
  ASSERT_GE(found, 12);
  const Eigen::Vector2d mean = sum / found;
  std::printf("blobs: %d of %zu found, mean offset (%+.3f, %+.3f) px\n", found, centres.size(),
              mean.x(), mean.y());
  EXPECT_LT(std::abs(mean.x()), 0.05);
  EXPECT_LT(std::abs(mean.y()), 0.05);
}

TEST(Features, HalfScaleSiftMapsItsKeypointsBackToTheImagePixels) {
  // Full scale against half scale: a keypoint mapped back half a pixel off
  // would bias the recovered shift by that much (a mapping that took the
  // block's centre at factor x_s, by 1/2 px).
  const int w = 640, h = 480, dx = 13, dy = -7;
  const std::vector<std::uint8_t> a = BlobImage(w, h, 5);
  const std::vector<std::uint8_t> b = Shifted(a, w, h, dx, dy);
  Features fa, fb;
  FeatureOptions half;
  half.image_scale = 0.5;
  ASSERT_TRUE(DetectSift(View(a, w, h), FeatureOptions{}, &fa));
  ASSERT_TRUE(DetectSift(View(b, w, h), half, &fb));
  const std::vector<Match> matches =
      MatchDescriptors(fa.descriptors.data(), fa.size(), fb.descriptors.data(), fb.size(), {});
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  int good = 0;
  for (const Match& m : matches) {
    const Eigen::Vector2f d = fb.keypoints[m.train].xy_px - fa.keypoints[m.query].xy_px;
    if ((d - Eigen::Vector2f(dx, dy)).norm() > 1.5f) continue;
    sum += d.cast<double>();
    ++good;
  }
  ASSERT_GT(good, 20);
  const Eigen::Vector2d bias = sum / good - Eigen::Vector2d(dx, dy);
  std::printf("half-scale SIFT: %d keypoints (full %d), %d of %zu matches on the shift, bias "
              "(%.3f, %.3f) px\n",
              fb.size(), fa.size(), good, matches.size(), bias.x(), bias.y());
  EXPECT_GE(good, 0.8 * matches.size());
  EXPECT_LT(bias.norm(), 0.2);
  for (const Keypoint& k : fb.keypoints) {
    EXPECT_GE(k.xy_px.x(), 0);
    EXPECT_LT(k.xy_px.x(), w);
  }
  half.image_scale = 0;
  EXPECT_FALSE(half.Check());
}

TEST(Features, SpreadCellsKeepKeypointsWhereTheTextureIsWeak) {
  // Texture at full contrast on the left, at half on the right: the
  // strongest keypoints are mostly on the left.
  const int w = 640, h = 480;
  std::vector<std::uint8_t> img = BlobImage(w, h, 7);
  for (int y = 0; y < h; ++y)
    for (int x = w / 2; x < w; ++x) {
      std::uint8_t& p = img[static_cast<std::size_t>(y) * w + x];
      p = static_cast<std::uint8_t>(128 + (p - 128) / 2);
    }
  const auto right = [&](const Features& f) {
    int n = 0;
    for (const Keypoint& k : f.keypoints) n += k.xy_px.x() >= w / 2 ? 1 : 0;
    return n;
  };
  FeatureOptions options;
  options.max_features = 200;
  Features strongest, spread;
  ASSERT_TRUE(DetectSift(View(img, w, h), options, &strongest));
  options.spread_cells = 4;
  ASSERT_TRUE(DetectSift(View(img, w, h), options, &spread));
  std::printf("200 keypoints: %d on the weak half (strongest), %d (spread over 4 x 4 cells)\n",
              right(strongest), right(spread));
  EXPECT_LE(spread.size(), 200);
  EXPECT_GE(spread.size(), 190);
  EXPECT_GT(right(spread), right(strongest) + 20);
  EXPECT_GE(right(spread), 70);  // of 200, 100 an even split
  ASSERT_EQ(spread.descriptors.size(), static_cast<std::size_t>(spread.size()) * kDescriptorSize);
  options.spread_cells = -1;
  EXPECT_FALSE(options.Check());
}

TEST(Features, AKeptDescriptorIndexMatchesAsTheBuffersDo) {
  // Enough pairs for the kd-trees (approximate search): 3000 train rows,
  // 1500 queries, a third of them noisy copies of train rows.
  std::mt19937 rng(11);
  std::normal_distribution<float> n01(0, 1);
  const int nt = 3000, nq = 1500;
  std::vector<float> train(static_cast<std::size_t>(nt) * kDescriptorSize);
  for (float& x : train) x = std::abs(n01(rng));
  std::vector<float> query(static_cast<std::size_t>(nq) * kDescriptorSize);
  for (int i = 0; i < nq; ++i)
    for (int d = 0; d < kDescriptorSize; ++d)
      query[static_cast<std::size_t>(i) * kDescriptorSize + d] =
          i % 3 == 0 ? train[static_cast<std::size_t>(7 * i % nt) * kDescriptorSize + d] +
                           0.05f * n01(rng)
                     : std::abs(n01(rng));
  MatchOptions options;
  options.kd_tree_checks = 64;
  const std::vector<Match> buffers =
      MatchDescriptors(query.data(), nq, train.data(), nt, options);
  const DescriptorIndex index(train);
  // Two threads at once, then again: the trees are built once and shared.
  std::vector<Match> first, second;
  std::thread other([&] { first = MatchDescriptors(query.data(), nq, index, options); });
  second = MatchDescriptors(query.data(), nq, index, options);
  other.join();
  const std::vector<Match> third = MatchDescriptors(query.data(), nq, index, options);
  int right = 0;
  for (const Match& m : third) right += m.query % 3 == 0 && m.train == 7 * m.query % nt ? 1 : 0;
  std::printf("kept index: %zu matches (%d the planted pairs of %d), buffers %zu\n", third.size(),
              right, nq / 3, buffers.size());
  EXPECT_GE(right, 0.95 * (nq / 3));
  // The same pairs (their order by ratio may differ: the kd-trees are
  // random, so second neighbours, hence ratios, differ slightly); the calls
  // on one index agree exactly.
  const auto pairs = [](std::vector<Match> m) {
    std::vector<std::pair<int, int>> p;
    for (const Match& x : m) p.emplace_back(x.query, x.train);
    std::sort(p.begin(), p.end());
    return p;
  };
  EXPECT_EQ(pairs(third), pairs(buffers));
  EXPECT_EQ(pairs(first), pairs(third));
  EXPECT_EQ(pairs(second), pairs(third));
  EXPECT_EQ(index.size(), nt);
}

TEST(Features, TheMapIndexFindsTheExactMatchersMatches) {
  // Real SIFT descriptors: a "map" of 16 textures' keypoints, queries from
  // two of them seen again shifted. MapMatching()'s kd-forest must find
  // nearly every match brute force finds (recall) and add few it does not
  // (precision: an approximate second neighbour lies farther than the true
  // one, so a few ambiguous pairs pass the ratio test).
  const int w = 640, h = 480;
  std::vector<float> train;
  std::vector<Eigen::Vector2f> train_xy;
  std::vector<int> train_image;
  Features queries;
  std::vector<int> query_image;
  for (int image = 0; image < 16; ++image) {
    const std::vector<std::uint8_t> a = BlobImage(w, h, 20 + image);
    Features f;
    ASSERT_TRUE(DetectSift(View(a, w, h), FeatureOptions{}, &f));
    train.insert(train.end(), f.descriptors.begin(), f.descriptors.end());
    for (const Keypoint& k : f.keypoints) {
      train_xy.push_back(k.xy_px);
      train_image.push_back(image);
    }
    if (image % 8 != 0) continue;
    Features g;
    ASSERT_TRUE(DetectSift(View(Shifted(a, w, h, 11, -6), w, h), FeatureOptions{}, &g));
    queries.keypoints.insert(queries.keypoints.end(), g.keypoints.begin(), g.keypoints.end());
    queries.descriptors.insert(queries.descriptors.end(), g.descriptors.begin(),
                               g.descriptors.end());
    query_image.insert(query_image.end(), g.keypoints.size(), image);
  }
  const int nt = static_cast<int>(train_xy.size());
  const DescriptorIndex index(std::move(train));
  const std::vector<Match> exact =
      MatchDescriptors(queries.descriptors.data(), queries.size(), index, ExactMatching());
  const std::vector<Match> approximate =
      MatchDescriptors(queries.descriptors.data(), queries.size(), index, MapMatching());
  const auto pairs = [](const std::vector<Match>& m) {
    std::set<std::pair<int, int>> p;
    for (const Match& x : m) p.emplace(x.query, x.train);
    return p;
  };
  const std::set<std::pair<int, int>> e = pairs(exact), a = pairs(approximate);
  std::size_t common = 0;
  for (const auto& p : a) common += e.count(p);
  const auto right = [&](const std::vector<Match>& m) {
    int n = 0;
    for (const Match& x : m)
      n += train_image[x.train] == query_image[x.query] &&
                   (queries.keypoints[x.query].xy_px - train_xy[x.train] -
                    Eigen::Vector2f(11, -6)).norm() < 1.0f
               ? 1
               : 0;
    return n;
  };
  const double recall = static_cast<double>(common) / e.size();
  const double precision = static_cast<double>(common) / a.size();
  std::printf("map index (%d trees, %d leaves): %d map descriptors, %d queries; exact %zu "
              "matches (%d right), approximate %zu (%d right): recall %.3f, precision %.3f\n",
              MapMatching().kd_trees, MapMatching().kd_tree_checks, nt, queries.size(),
              exact.size(), right(exact), approximate.size(), right(approximate), recall,
              precision);
  ASSERT_GT(e.size(), 500u);
  EXPECT_GE(recall, 0.97);
  EXPECT_GE(precision, 0.97);
  EXPECT_GE(right(approximate), 0.97 * right(exact));
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
