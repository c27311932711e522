// The per-lens search's kernels (processing/lens_search_simd.h: strip
// samples, costs, the candidate gate's scores), Highway's on every target
// this CPU runs against the scalar reference, on random frames, gains (NaN
// holes included), strips and candidates. Both evaluate the same float
// expressions in the same order without FMA contraction, so the
// stated tolerance (1e-6 relative) is there for a compiler that reorders,
// not for an expected difference; NaN must fall on the same samples.

#include "processing/lens_search_simd.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <hwy/targets.h>
#include <random>
#include <vector>

namespace lifmcr::processing::detail {
namespace {

constexpr double kRelTolerance = 1e-6;

bool Close(float simd, float scalar) {
  if (std::isnan(scalar) || std::isnan(simd)) return std::isnan(scalar) && std::isnan(simd);
  return std::abs(simd - scalar) <= kRelTolerance * std::max(1.0f, std::abs(scalar));
}

struct RandomFrame {
  int width = 0, height = 0, channels = 1;
  std::size_t stride = 0;
  std::vector<std::uint8_t> raw;
  Gain16 gain;              // the per-lens search's 16-bit gain, 0 holes
  std::vector<float> grey;  // a float grey image (the dense search's), NaN holes
  StripSource Source() const {
    return StripSource{raw.data(), stride, channels, gain.q.data(), width, nullptr, gain.scale};
  }
  StripSource GreySource() const {
    return StripSource{nullptr, 0, 1, nullptr, width, grey.data()};
  }
};

// Rows padded past the pixels (stride > width * channels), gains in
// [0.5, 2] with one in 50 NaN (an invalid pixel), in 16 bits.
RandomFrame MakeFrame(std::mt19937& rng, int channels) {
  RandomFrame f;
  f.width = std::uniform_int_distribution<int>(24, 90)(rng);
  f.height = std::uniform_int_distribution<int>(24, 70)(rng);
  f.channels = channels;
  f.stride =
      static_cast<std::size_t>(f.width) * channels + std::uniform_int_distribution<int>(0, 7)(rng);
  f.raw.resize(f.stride * f.height);
  std::uniform_int_distribution<int> byte(0, 255);
  for (std::uint8_t& b : f.raw) b = static_cast<std::uint8_t>(byte(rng));
  std::vector<float> gain(static_cast<std::size_t>(f.width) * f.height);
  std::uniform_real_distribution<float> g(0.5f, 2.0f);
  std::uniform_int_distribution<int> hole(0, 49);
  for (float& x : gain) x = hole(rng) == 0 ? std::nanf("") : g(rng);
  f.gain = Gain16::From(gain, f.width);
  f.grey.resize(gain.size());
  std::uniform_real_distribution<float> level(0.0f, 255.0f);
  for (float& x : f.grey) x = hole(rng) == 0 ? std::nanf("") : level(rng);
  return f;
}

// A line whose samples in [j_lo, j_hi] satisfy the kernels' precondition:
// positions in [1, width - 3) x [1, height - 3).
StripLine MakeLine(std::mt19937& rng, const RandomFrame& f) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  StripLine l;
  for (;;) {
    const float angle = 6.2831853f * u(rng);
    l.e_x = std::cos(angle);
    l.e_y = std::sin(angle);
    const std::array<float, 3> steps{1.0f, 0.5f, 0.25f};
    l.step = steps[std::uniform_int_distribution<int>(0, 2)(rng)];
    const int b = std::uniform_int_distribution<int>(-1, 1)(rng);
    l.b_ey = static_cast<float>(b) * l.e_y;
    l.b_ex = static_cast<float>(b) * l.e_x;
    l.n = std::uniform_int_distribution<int>(3, 48)(rng);
    const float span = (l.n - 1) * l.step;
    l.px = 1.5f + u(rng) * (f.width - 4.5f);
    l.py = 1.5f + u(rng) * (f.height - 4.5f);
    l.along0 = -u(rng) * span;
    l.j_lo = std::uniform_int_distribution<int>(0, l.n - 1)(rng);
    l.j_hi = std::uniform_int_distribution<int>(l.j_lo - 1, l.n - 1)(rng);  // may be empty
    bool inside = true;
    for (int j = l.j_lo; j <= l.j_hi && inside; ++j) {
      const float t = l.along0 + j * l.step;
      const float x = l.px + t * l.e_x - l.b_ey, y = l.py + t * l.e_y + l.b_ex;
      inside = x >= 1 && y >= 1 && x < f.width - 3 && y < f.height - 3;
    }
    if (inside) return l;
  }
}

// Every Highway target this CPU runs, the best first.
std::vector<std::int64_t> Targets() { return hwy::SupportedAndGeneratedTargets(); }

// The 16-bit gain: the largest gain uses the top bit, every gain is kept to
// half a step (scale / 2) and read back exactly as q scale, invalid ones
// (NaN, 0) are 0 and read back NaN.
TEST(Gain16, KeepsTheGainToHalfAStepAndMarksInvalidPixels) {
  const std::vector<float> gain{1.0f, 0.5f, 2.0f, std::nanf(""), 0.0f, 1.2345678f, 0.75f, 1.9999f};
  const Gain16 g = Gain16::From(gain, 4);
  EXPECT_EQ(g.width, 4);
  EXPECT_EQ(g.scale, 1.0f / 16384);  // 2 * 2^14 = 32768 <= 65535 < 2 * 2^15
  ASSERT_EQ(g.q.size(), gain.size());
  EXPECT_EQ(g.q[2], 32768);
  EXPECT_EQ(g.q[3], 0);
  EXPECT_EQ(g.q[4], 0);
  EXPECT_TRUE(std::isnan(g.At(3)));
  EXPECT_TRUE(std::isnan(g.At(4)));
  for (const std::size_t k : {0, 1, 2, 5, 6, 7}) {
    EXPECT_NEAR(g.At(k), gain[k], 0.5 * g.scale) << k;
    EXPECT_EQ(g.At(k), static_cast<float>(g.q[k]) * g.scale) << k;
  }
  // Large gains: a coarser scale, still within half a step.
  const Gain16 big = Gain16::From({100.0f, 3.0f}, 2);
  EXPECT_LE(100.0 / big.scale, 65535.0);
  EXPECT_GT(200.0 / big.scale, 65535.0);
  EXPECT_NEAR(big.At(1), 3.0f, 0.5 * big.scale);
}

class StripKernelsTest : public ::testing::Test {
 protected:
  void TearDown() override { hwy::SetSupportedTargetsForTest(0); }
};

TEST_F(StripKernelsTest, SamplesMatchTheScalarReferenceOnEveryTarget) {
  const StripKernels& scalar = ScalarStripKernels();
  ASSERT_FALSE(Targets().empty());
  for (const std::int64_t target : Targets()) {
    hwy::SetSupportedTargetsForTest(target);
    const StripKernels& simd = SimdStripKernels();
    std::mt19937 rng(17);
    long long compared = 0, nans = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const RandomFrame f = MakeFrame(rng, trial % 2 == 0 ? 3 : 1);
      for (int k = 0; k < 10; ++k) {
        const StripLine l = MakeLine(rng, f);
        std::vector<float> a(l.n + kStripPad, -1.0f), b(l.n + kStripPad, -1.0f);
        scalar.sample(f.Source(), l, a.data());
        simd.sample(f.Source(), l, b.data());
        for (int i = 0; i < l.n; ++i) {
          ASSERT_TRUE(Close(b[i], a[i]))
              << hwy::TargetName(target) << " trial " << trial << " sample " << i << ": " << b[i]
              << " vs scalar " << a[i] << " (channels " << f.channels << ")";
          ++compared;
          nans += std::isnan(a[i]);
        }
      }
    }
    // Both kinds of sample occur: a valid one and a NaN (outside the
    // range, or next to an invalid gain).
    EXPECT_GT(compared - nans, compared / 10) << hwy::TargetName(target);
    EXPECT_GT(nans, 0) << hwy::TargetName(target);
  }
}

TEST_F(StripKernelsTest, GreyImageSamplesMatchTheScalarReferenceOnEveryTarget) {
  const StripKernels& scalar = ScalarStripKernels();
  for (const std::int64_t target : Targets()) {
    hwy::SetSupportedTargetsForTest(target);
    const StripKernels& simd = SimdStripKernels();
    std::mt19937 rng(23);
    long long compared = 0, nans = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const RandomFrame f = MakeFrame(rng, 1);
      for (int k = 0; k < 10; ++k) {
        const StripLine l = MakeLine(rng, f);
        std::vector<float> a(l.n + kStripPad, -1.0f), b(l.n + kStripPad, -1.0f);
        scalar.sample(f.GreySource(), l, a.data());
        simd.sample(f.GreySource(), l, b.data());
        for (int i = 0; i < l.n; ++i) {
          ASSERT_TRUE(Close(b[i], a[i])) << hwy::TargetName(target) << " trial " << trial
                                         << " sample " << i << ": " << b[i] << " vs scalar "
                                         << a[i];
          ++compared;
          nans += std::isnan(a[i]);
        }
        // The reference itself: the bilinear grey of the four pixels.
        for (int i = 0; i < l.n; ++i) {
          const int j = l.n - 1 - i;
          if (j < l.j_lo || j > l.j_hi || std::isnan(a[i])) continue;
          const float t = l.along0 + j * l.step;
          const double x = l.px + t * l.e_x - l.b_ey, y = l.py + t * l.e_y + l.b_ex;
          const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
          const double fx = x - x0, fy = y - y0;
          auto at = [&](int xx, int yy) {
            return static_cast<double>(f.grey[static_cast<std::size_t>(yy) * f.width + xx]);
          };
          const double expected = (1 - fx) * (1 - fy) * at(x0, y0) + fx * (1 - fy) * at(x0 + 1, y0) +
                                  (1 - fx) * fy * at(x0, y0 + 1) + fx * fy * at(x0 + 1, y0 + 1);
          ASSERT_NEAR(a[i], expected, 1e-3) << "trial " << trial << " sample " << i;
        }
      }
    }
    EXPECT_GT(compared - nans, compared / 10) << hwy::TargetName(target);
    EXPECT_GT(nans, 0) << hwy::TargetName(target);
  }
}

TEST_F(StripKernelsTest, CostsMatchTheScalarReferenceOnEveryTarget) {
  const StripKernels& scalar = ScalarStripKernels();
  for (const std::int64_t target : Targets()) {
    hwy::SetSupportedTargetsForTest(target);
    const StripKernels& simd = SimdStripKernels();
    std::mt19937 rng(29);
    std::uniform_real_distribution<float> grey(0.0f, 255.0f);
    std::uniform_int_distribution<int> hole(0, 99);
    for (int trial = 0; trial < 400; ++trial) {
      const int n_lines = trial % 2 == 0 ? 1 : 3;
      const int spp = 1 << std::uniform_int_distribution<int>(0, 2)(rng);
      const int steps = std::uniform_int_distribution<int>(3, 256)(rng);
      std::vector<std::vector<float>> lines(n_lines,
                                            std::vector<float>(steps + 4 * spp + kStripPad));
      for (auto& line : lines)
        for (float& x : line) x = hole(rng) == 0 ? std::nanf("") : grey(rng);
      std::array<const float*, 3> pointers{};
      for (int b = 0; b < n_lines; ++b) pointers[b] = lines[b].data();
      std::array<float, 15> ref{};
      for (float& x : ref) x = grey(rng);
      std::vector<float> a(steps + kStripPad), c(steps + kStripPad);
      scalar.costs(pointers.data(), n_lines, ref.data(), spp, steps, a.data());
      simd.costs(pointers.data(), n_lines, ref.data(), spp, steps, c.data());
      for (int k = 0; k < steps; ++k)
        ASSERT_TRUE(Close(c[k], a[k])) << hwy::TargetName(target) << " trial " << trial << " step "
                                       << k << ": " << c[k] << " vs " << a[k];
    }
  }
}

TEST_F(StripKernelsTest, CandidateScoresMatchTheScalarReferenceOnEveryTarget) {
  const StripKernels& scalar = ScalarStripKernels();
  for (const std::int64_t target : Targets()) {
    hwy::SetSupportedTargetsForTest(target);
    const StripKernels& simd = SimdStripKernels();
    std::mt19937 rng(41);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    long long above_zero = 0, compared = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const RandomFrame f = MakeFrame(rng, trial % 2 == 0 ? 3 : 1);
      // Candidates within `reach` of a centre that keeps them in
      // [2, width - 3] x [2, height - 3].
      const int reach = std::uniform_int_distribution<int>(0, 9)(rng);
      const int cx = std::uniform_int_distribution<int>(2 + reach, f.width - 3 - reach)(rng);
      const int cy = std::uniform_int_distribution<int>(2 + reach, f.height - 3 - reach)(rng);
      const int n = std::uniform_int_distribution<int>(1, 200)(rng);
      std::vector<std::int32_t> dx(n + kStripPad, 0), dy(n + kStripPad, 0);
      std::uniform_int_distribution<int> offset(-reach, reach);
      for (int q = 0; q < n; ++q) {
        dx[q] = offset(rng);
        dy[q] = offset(rng);
      }
      float ax[3], ay[3];
      for (int d = 0; d < 3; ++d) {
        const float angle = 6.2831853f * u(rng);
        ax[d] = std::cos(angle);
        ay[d] = std::sin(angle);
      }
      const unsigned mask = static_cast<unsigned>(std::uniform_int_distribution<int>(0, 7)(rng));
      const float to_grey = 0.5f * (0.5f + u(rng)) / f.channels;
      std::vector<float> sa(n + kStripPad), sb(n + kStripPad);
      std::vector<std::int32_t> aa(n + kStripPad), ab(n + kStripPad);
      scalar.scores(f.Source(), cx, cy, dx.data(), dy.data(), n, to_grey, ax, ay, mask, sa.data(),
                    aa.data());
      simd.scores(f.Source(), cx, cy, dx.data(), dy.data(), n, to_grey, ax, ay, mask, sb.data(),
                  ab.data());
      for (int q = 0; q < n; ++q) {
        ASSERT_TRUE(Close(sb[q], sa[q])) << hwy::TargetName(target) << " trial " << trial
                                         << " candidate " << q << ": " << sb[q] << " vs " << sa[q];
        ASSERT_EQ(ab[q], aa[q]) << hwy::TargetName(target) << " trial " << trial << " candidate "
                                << q;  // an integer: exact
        above_zero += sa[q] > 0;
        ++compared;
      }
    }
    EXPECT_GT(above_zero, compared / 2) << hwy::TargetName(target);
  }
}

// The patch kernel gives, on every target and in the scalar reference,
// exactly the samples of the strip lines {p, e, b e_y, b e_x, -2, 1, 5}
// read reversed (lens_search_simd.h, SamplePatchFn): the reference patches
// of the per-lens search do not change with it.
TEST_F(StripKernelsTest, PatchesAreTheirStripLinesOnEveryTarget) {
  const StripKernels& scalar = ScalarStripKernels();
  for (const std::int64_t target : Targets()) {
    hwy::SetSupportedTargetsForTest(target);
    const StripKernels& simd = SimdStripKernels();
    std::mt19937 rng(57);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    long long compared = 0, nans = 0;
    for (int trial = 0; trial < 600; ++trial) {
      const RandomFrame f = MakeFrame(rng, trial % 2 == 0 ? 3 : 1);
      const int lines = trial % 4 < 2 ? 3 : 1, half = lines / 2;
      const float angle = 6.2831853f * u(rng);
      const float e_x = std::cos(angle), e_y = std::sin(angle);
      // p at least 2 * sqrt(2) + 1 px from the border: every sample inside
      // [1, width - 3) x [1, height - 3).
      const float px = 4.0f + u(rng) * (f.width - 11.0f), py = 4.0f + u(rng) * (f.height - 11.0f);
      std::vector<float> a(5 * lines + kStripPad, -1.0f), b(5 * lines + kStripPad, -1.0f);
      scalar.patch(f.Source(), px, py, e_x, e_y, lines, a.data());
      simd.patch(f.Source(), px, py, e_x, e_y, lines, b.data());
      for (int line = -half; line <= half; ++line) {
        StripLine l;
        l.px = px;
        l.py = py;
        l.e_x = e_x;
        l.e_y = e_y;
        l.b_ey = static_cast<float>(line) * e_y;
        l.b_ex = static_cast<float>(line) * e_x;
        l.along0 = -2;
        l.step = 1;
        l.n = 5;
        l.j_lo = 0;
        l.j_hi = 4;
        std::vector<float> strip(5 + kStripPad);
        scalar.sample(f.Source(), l, strip.data());
        for (int col = -2; col <= 2; ++col) {
          const int m = 5 * (line + half) + col + 2;
          const float want = strip[2 - col];
          ASSERT_TRUE(std::isnan(want) ? std::isnan(a[m]) : a[m] == want)
              << "scalar trial " << trial << " sample " << m << ": " << a[m] << " vs " << want;
          ASSERT_TRUE(std::isnan(want) ? std::isnan(b[m]) : b[m] == want)
              << hwy::TargetName(target) << " trial " << trial << " sample " << m << ": " << b[m]
              << " vs " << want;
          ++compared;
          nans += std::isnan(want);
        }
      }
    }
    EXPECT_GT(compared - nans, compared / 2) << hwy::TargetName(target);
    EXPECT_GT(nans, 0) << hwy::TargetName(target);
  }
}

TEST(StripKernels, DispatchNamesItsTarget) {
  EXPECT_STREQ(ScalarStripKernels().name, "scalar");
  EXPECT_STRNE(SimdStripKernels().name, "");
}

}  // namespace
}  // namespace lifmcr::processing::detail
