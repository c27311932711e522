// The TF blend's row kernel (processing/tf_blend_simd.h): Highway's on every
// target this CPU runs against the scalar reference, on random frames
// (Mono8 and BGR8, padded rows), gains with holes (float NaN, 16-bit 0),
// lattices, lens-type tables, barycentric floors, steps and runs of depths. Both evaluate the same float expressions in
// the same order without FMA contraction (BGR with the 16-bit gain: the
// same integers of the fixed-point blend) and read the same pixels, so the
// stated tolerance (1e-5 relative to the larger of 1 and the value) is there
// for a compiler that reorders, not for an expected difference; the
// fixed-point blend against the float rule has its own test below.

#include "processing/tf_blend_simd.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <hwy/targets.h>
#include <random>
#include <string>
#include <vector>

namespace lifmcr::processing::detail {
namespace {

constexpr double kRelTolerance = 1e-5;

bool Close(float simd, float scalar) {
  return std::abs(simd - scalar) <= kRelTolerance * std::max(1.0f, std::abs(scalar));
}

struct RandomCase {
  std::vector<std::uint8_t> raw;
  std::vector<float> gain;
  std::vector<std::uint16_t> gain16;
  std::vector<std::int32_t> types;
  TfBlendGeometry g;
  TfBlendSource s;
};

// A triangular lattice of pitch 8-14 px, slightly rotated, over a frame of
// 40-120 x 30-90 pixels (`large`: pitch 28-40 px over 150-300 x 80-160, an
// R32's micro images); lens type (i - j) mod 3; gains in [0.5, 2] with one
// in 40 NaN; a type table of random types.
// With `in_16_bits` the gain is read from 16 bits (0: invalid), as the
// per-lens estimator keeps it.
RandomCase MakeCase(std::mt19937& rng, int channels, bool in_16_bits, bool large = false) {
  RandomCase c;
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  TfBlendGeometry& g = c.g;
  g.width = large ? std::uniform_int_distribution<int>(150, 300)(rng)
                  : std::uniform_int_distribution<int>(40, 120)(rng);
  g.height = large ? std::uniform_int_distribution<int>(80, 160)(rng)
                   : std::uniform_int_distribution<int>(30, 90)(rng);
  const std::size_t stride =
      static_cast<std::size_t>(g.width) * channels + std::uniform_int_distribution<int>(0, 5)(rng);
  c.raw.resize(stride * g.height);
  for (std::uint8_t& b : c.raw) b = static_cast<std::uint8_t>(rng() & 0xFF);
  c.gain.resize(static_cast<std::size_t>(g.width) * g.height);
  for (float& x : c.gain) x = rng() % 40 == 0 ? std::nanf("") : 0.5f + 1.5f * unit(rng);
  const float pitch = large ? 28.0f + 12.0f * unit(rng) : 8.0f + 6.0f * unit(rng);
  const float angle = 0.05f * (unit(rng) - 0.5f);
  // Steps of i and j (columns of A), then A (1, 1) and A (2, -1).
  const float ix = pitch * std::cos(angle), iy = pitch * std::sin(angle);
  const float jx = pitch * std::cos(angle + 2.0943951f), jy = pitch * std::sin(angle + 2.0943951f);
  g.sxa = ix + jx, g.sya = iy + jy, g.sxb = 2 * ix - jx, g.syb = 2 * iy - jy;
  const float det = g.sxa * g.syb - g.sxb * g.sya;
  const float ref_x = g.width * unit(rng), ref_y = g.height * unit(rng);
  for (int t = 0; t < 3; ++t) {
    g.ox[t] = ref_x + t * ix;  // lens (t, 0) has type t
    g.oy[t] = ref_y + t * iy;
    g.fxx[t] = g.syb / det, g.fxy[t] = -g.sxb / det;
    g.fyx[t] = -g.sya / det, g.fyy[t] = g.sxa / det;
  }
  g.cx = (g.width - 1) / 2.0f, g.cy = (g.height - 1) / 2.0f;
  g.lambda = 0.95f + 0.05f * unit(rng);
  const float r = pitch / 2 - 0.5f;
  g.r2 = r * r;
  g.type_per_unit = 8;
  g.type_size = 64 * 8;
  c.types.resize(g.type_size);
  if (rng() % 2 == 0) {
    // Random types (gathered by the kernel), or runs of one type, 1 to
    // kMaxTypeRuns of them, as the sharp type's table has (compares).
    for (std::int32_t& t : c.types) t = static_cast<std::int32_t>(rng() % 3);
  } else {
    // Their starts within v 1..10 (the runs' depths).
    const int runs = 1 + static_cast<int>(rng() % TfBlendGeometry::kMaxTypeRuns);
    std::vector<int> starts;
    while (static_cast<int>(starts.size()) < runs - 1) {
      const int at = std::uniform_int_distribution<int>(g.type_per_unit, 10 * g.type_per_unit)(rng);
      if (std::find(starts.begin(), starts.end(), at) == starts.end()) starts.push_back(at);
    }
    std::sort(starts.begin(), starts.end());
    std::int32_t type = static_cast<std::int32_t>(rng() % 3);
    std::size_t next = 0;
    for (int i = 0; i < g.type_size; ++i) {
      if (next < starts.size() && i == starts[next]) {
        type = (type + 1 + static_cast<std::int32_t>(rng() % 2)) % 3;
        ++next;
      }
      c.types[i] = type;
    }
  }
  g.type_of_v = c.types.data();
  SetTypeRuns(&g);
  // The plain barycentric weights in a third of the cases, else a floor
  // (the TF image's) in (0, 0.3).
  g.bary_floor = rng() % 3 == 0 ? 0.0f : 0.3f * unit(rng);
  c.s = TfBlendSource{c.raw.data(), stride, channels, c.gain.data()};
  if (in_16_bits) {
    c.gain16.resize(c.gain.size());
    for (std::uint16_t& q : c.gain16)
      q = rng() % 40 == 0 ? 0 : static_cast<std::uint16_t>(8192 + rng() % 24576);
    c.s.gain = nullptr;
    c.s.gain16 = c.gain16.data();
    c.s.gain16_scale = 1.0f / 16384;
  }
  return c;
}

class TfBlendKernelsTest : public ::testing::Test {
 protected:
  void TearDown() override { hwy::SetSupportedTargetsForTest(0); }
};

// One run of n pixels from x0 at step dx on row y, depths v: Highway's sums
// against the scalar reference's; `compared` and `seen` count the pixels
// and those some lens saw.
void ExpectRunMatches(const TfBlendKernels& simd, const RandomCase& c, int channels, float x0,
                      float dx, float y, const std::vector<float>& v, const char* what,
                      long long* compared, long long* seen) {
  const int n = static_cast<int>(v.size());
  std::vector<float> a_acc(channels * n, -1.0f), b_acc(channels * n, -2.0f);
  std::vector<float> a_sw(n, -1.0f), b_sw(n, -2.0f);
  ScalarTfBlendKernels().row(c.g, c.s, x0, dx, y, v.data(), n, a_acc.data(), a_sw.data());
  simd.row(c.g, c.s, x0, dx, y, v.data(), n, b_acc.data(), b_sw.data());
  for (int i = 0; i < n; ++i) {
    ASSERT_TRUE(Close(b_sw[i], a_sw[i]))
        << simd.name << " " << what << " pixel " << i << ": sw " << b_sw[i] << " vs scalar "
        << a_sw[i] << " (channels " << channels << ")";
    for (int ch = 0; ch < channels; ++ch)
      ASSERT_TRUE(Close(b_acc[ch * n + i], a_acc[ch * n + i]))
          << simd.name << " " << what << " pixel " << i << " channel " << ch << ": "
          << b_acc[ch * n + i] << " vs scalar " << a_acc[ch * n + i];
    ++*compared;
    *seen += a_sw[i] > 0;
  }
}

// Runs `body` with Highway's kernels on every target this CPU runs.
template <class Body>
void OnEveryTarget(Body&& body) {
  for (const std::int64_t target : hwy::SupportedAndGeneratedTargets()) {
    hwy::SetSupportedTargetsForTest(target);
    body(SimdTfBlendKernels());
  }
}

TEST_F(TfBlendKernelsTest, RowsMatchTheScalarReferenceOnEveryTarget) {
  const std::vector<std::int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (const std::int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    const TfBlendKernels& simd = SimdTfBlendKernels();
    std::mt19937 rng(29);
    long long compared = 0, seen = 0;
    for (int trial = 0; trial < 200; ++trial) {
      const int channels = trial % 2 == 0 ? 3 : 1;
      const RandomCase c = MakeCase(rng, channels, trial % 4 >= 2);
      for (int k = 0; k < 8; ++k) {
        // A run of n pixels from x0 (possibly off the frame's left edge) at
        // depths in [1.05, 9], some runs at one depth.
        const int n = std::uniform_int_distribution<int>(1, 70)(rng);
        const float x0 = std::uniform_real_distribution<float>(-10.0f, c.g.width)(rng);
        const float y = std::uniform_real_distribution<float>(-2.0f, c.g.height + 2.0f)(rng);
        // The TF image's step (2 raw pixels) or a preview's (any).
        const float dx = k % 2 == 0 ? 2.0f : std::uniform_real_distribution<float>(0.3f, 9.0f)(rng);
        std::uniform_real_distribution<float> depth(1.05f, 9.0f);
        std::vector<float> v(n);
        const float v_all = depth(rng);
        for (float& x : v) x = k % 3 == 0 ? v_all : depth(rng);
        const std::string what = "trial " + std::to_string(trial);
        ExpectRunMatches(simd, c, channels, x0, dx, y, v, what.c_str(), &compared, &seen);
        if (HasFatalFailure()) return;
      }
    }
    // Both kinds of pixel occur: seen by some lens of its triangle, and by
    // none (off the frame, beyond r, next to a NaN gain).
    EXPECT_GT(seen, compared / 4) << hwy::TargetName(target);
    EXPECT_LT(seen, compared) << hwy::TargetName(target);
  }
}

// Micro images of an R32's size, BGR with the 16-bit gain (the TF image's
// case): a vector's lanes then often sample one micro image on one row
// pair, which the AVX-512 kernel reads from a 64-byte window of each row
// instead of gathers. Runs at the TF image's step and at small steps (all
// lanes in one micro image), over the whole frame: its first and last rows
// and columns, where a window would reach past the buffers.
TEST_F(TfBlendKernelsTest, RowsOfLargeMicroImagesMatchTheScalarReferenceOnEveryTarget) {
  OnEveryTarget([&](const TfBlendKernels& simd) {
    std::mt19937 rng(37);
    long long compared = 0, seen = 0;
    for (int trial = 0; trial < 40; ++trial) {
      RandomCase c = MakeCase(rng, 3, true, true);
      c.g.bary_floor = trial % 2 == 0 ? 0.0f : c.g.bary_floor;
      std::uniform_real_distribution<float> depth(1.5f, 8.0f);
      for (int k = 0; k < 24; ++k) {
        const int n = std::uniform_int_distribution<int>(16, 120)(rng);
        const float dx = k % 3 == 0 ? 2.0f : std::uniform_real_distribution<float>(0.1f, 1.0f)(rng);
        // Rows anywhere, a quarter of them in the last four; runs from
        // anywhere, a quarter of them ending at the right edge.
        const float y = k % 4 == 0 ? c.g.height - 4.0f * std::uniform_real_distribution<float>(0, 1)(rng)
                                   : std::uniform_real_distribution<float>(0.0f, c.g.height)(rng);
        const float x0 = k % 4 == 1 ? c.g.width - dx * n + std::uniform_real_distribution<float>(-3, 3)(rng)
                                    : std::uniform_real_distribution<float>(-4.0f, c.g.width)(rng);
        std::vector<float> v(n);
        const float v_all = depth(rng);
        for (int i = 0; i < n; ++i)
          v[i] = k % 2 == 0 ? v_all : v_all * (1.0f + 0.002f * static_cast<float>(i));
        const std::string what = "large trial " + std::to_string(trial);
        ExpectRunMatches(simd, c, 3, x0, dx, y, v, what.c_str(), &compared, &seen);
        if (HasFatalFailure()) return;
      }
    }
    EXPECT_GT(seen, compared / 2) << simd.name;
  });
}

// BGR with the 16-bit gain blends in fixed point (tf_blend_simd.h): its
// colour per unit weight, acc / sw, within 0.1 of the float rule's (the
// same gains in float; 0.02 on average) on R32-sized micro images of random
// pixels 0-255 and gains of 0.5-2 (q 8192-32767: a weight's rounding is
// at most 1 / 8192 of the sum of the four); the same weights (sw) and the
// same samples dropped next to an invalid gain. The rule's own error, not
// the kernels' (they agree with the reference above). Measured: worst
// 0.061, mean 0.009.
TEST(TfBlendFixedPoint, ColoursWithinTheirToleranceOfTheFloatRule) {
  const TfBlendKernels& scalar = ScalarTfBlendKernels();
  std::mt19937 rng(41);
  double worst = 0, sum_err = 0;
  long long seen = 0;
  for (int trial = 0; trial < 20; ++trial) {
    RandomCase c = MakeCase(rng, 3, true, true);
    c.g.bary_floor = 0;
    // The same gains in float (NaN where the 16-bit one is invalid).
    std::vector<float> gain(c.gain16.size());
    for (std::size_t i = 0; i < gain.size(); ++i)
      gain[i] =
          c.gain16[i] == 0 ? std::nanf("") : static_cast<float>(c.gain16[i]) * c.s.gain16_scale;
    TfBlendSource in_float = c.s;
    in_float.gain16 = nullptr;
    in_float.gain = gain.data();
    for (int k = 0; k < 16; ++k) {
      const int n = 100;
      const float y = std::uniform_real_distribution<float>(0.0f, c.g.height)(rng);
      const float dx = k % 2 == 0 ? 2.0f : 0.37f;
      std::vector<float> v(n, std::uniform_real_distribution<float>(1.5f, 8.0f)(rng));
      std::vector<float> a_acc(3 * n), b_acc(3 * n), a_sw(n), b_sw(n);
      scalar.row(c.g, c.s, -4.0f, dx, y, v.data(), n, a_acc.data(), a_sw.data());
      scalar.row(c.g, in_float, -4.0f, dx, y, v.data(), n, b_acc.data(), b_sw.data());
      for (int i = 0; i < n; ++i) {
        ASSERT_EQ(a_sw[i], b_sw[i]) << "trial " << trial << " pixel " << i;
        if (a_sw[i] <= 0) continue;
        ++seen;
        for (int ch = 0; ch < 3; ++ch) {
          const double err = std::abs(a_acc[ch * n + i] - b_acc[ch * n + i]) / a_sw[i];
          worst = std::max(worst, err);
          sum_err += err;
        }
      }
    }
  }
  ASSERT_GT(seen, 1000);
  EXPECT_LT(worst, 0.1);
  EXPECT_LT(sum_err / (3.0 * seen), 0.02);
}

// The 8-bit pixels of a run: Highway's equal to the scalar reference byte
// for byte on every target (the same float expressions), over runs of
// random sums with pixels no lens saw (sw 0), values below 0 and above 255.
TEST_F(TfBlendKernelsTest, BytesMatchTheScalarReferenceOnEveryTarget) {
  const TfBlendKernels& scalar = ScalarTfBlendKernels();
  OnEveryTarget([&](const TfBlendKernels& simd) {
    std::mt19937 rng(31);
    long long clipped = 0, unseen = 0;
    for (int trial = 0; trial < 200; ++trial) {
      const int channels = trial % 2 == 0 ? 3 : 1;
      const int n = std::uniform_int_distribution<int>(1, 300)(rng);
      const float gain = std::uniform_real_distribution<float>(0.5f, 2.0f)(rng);
      std::vector<float> acc(static_cast<std::size_t>(channels) * n), sw(n);
      for (float& w : sw)
        w = rng() % 10 == 0 ? 0.0f : std::uniform_real_distribution<float>(0.01f, 2.0f)(rng);
      for (float& a : acc) a = std::uniform_real_distribution<float>(-20.0f, 400.0f)(rng);
      std::vector<std::uint8_t> a_out(static_cast<std::size_t>(channels) * n, 1),
          b_out(a_out.size(), 2);
      scalar.bytes(acc.data(), sw.data(), n, channels, gain, a_out.data());
      simd.bytes(acc.data(), sw.data(), n, channels, gain, b_out.data());
      for (std::size_t q = 0; q < a_out.size(); ++q) {
        ASSERT_EQ(b_out[q], a_out[q])
            << simd.name << " trial " << trial << " byte " << q;
        clipped += a_out[q] == 255;
      }
      for (int i = 0; i < n; ++i) unseen += sw[i] == 0;
    }
    EXPECT_GT(clipped, 0) << simd.name;
    EXPECT_GT(unseen, 0) << simd.name;
  });
}

// The type table as runs (TfBlendGeometry::type_runs): the starts and types
// of a table of few runs, none for a table of more than kMaxTypeRuns.
TEST(TfBlendTypeRuns, RunsOfTheTableOrNone) {
  std::vector<std::int32_t> types(64, 2);
  std::fill(types.begin() + 10, types.begin() + 30, 0);
  std::fill(types.begin() + 30, types.end(), 1);
  TfBlendGeometry g;
  g.type_of_v = types.data();
  g.type_size = static_cast<int>(types.size());
  SetTypeRuns(&g);
  ASSERT_EQ(g.type_runs, 3);
  EXPECT_EQ(g.type_run_start[0], 0);
  EXPECT_EQ(g.type_run_value[0], 2);
  EXPECT_EQ(g.type_run_start[1], 10);
  EXPECT_EQ(g.type_run_value[1], 0);
  EXPECT_EQ(g.type_run_start[2], 30);
  EXPECT_EQ(g.type_run_value[2], 1);
  for (int i = 0; i < 2 * TfBlendGeometry::kMaxTypeRuns; ++i) types[i] = i % 3;
  SetTypeRuns(&g);
  EXPECT_EQ(g.type_runs, 0);
}

}  // namespace
}  // namespace lifmcr::processing::detail
