// LoadRaw's row kernels (processing/frame_smooth_simd.h): Highway's on every
// target this CPU runs against the scalar reference, bit for bit, on random
// rows with NaN (invalid pixels) and random neighbour masks; and LoadRaw's
// one streaming pass (processing/plenoptic_frame.cpp) against whole-frame
// passes written out here (grey, then x, y, x, y, ... over the frame), bit for
// bit, for 0-3 passes, Mono8 and BGR8, frames of 1-200 rows.

#include "processing/frame_smooth_simd.h"
#include "processing/plenoptic_frame.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <hwy/targets.h>
#include <random>
#include <vector>

namespace lifmcr::processing {
namespace {

bool SameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

std::vector<float> RandomRow(std::mt19937& rng, int n) {
  std::uniform_real_distribution<float> grey(0.0f, 400.0f);
  std::vector<float> v(n);
  for (float& x : v) x = rng() % 30 == 0 ? std::nanf("") : grey(rng);
  return v;
}

class FrameSmoothKernelsTest : public ::testing::Test {
 protected:
  void TearDown() override { hwy::SetSupportedTargetsForTest(0); }
};

TEST_F(FrameSmoothKernelsTest, RowsMatchTheScalarReferenceBitForBitOnEveryTarget) {
  const detail::FrameSmoothKernels& scalar = detail::ScalarFrameSmoothKernels();
  const std::vector<std::int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (const std::int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    const detail::FrameSmoothKernels& simd = detail::SimdFrameSmoothKernels();
    std::mt19937 rng(7);
    long long averaged = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const int n = std::uniform_int_distribution<int>(1, 90)(rng);
      std::vector<std::uint8_t> raw(n), mask(n);
      for (std::uint8_t& b : raw) b = static_cast<std::uint8_t>(rng() & 0xFF);
      for (std::uint8_t& b : mask) b = static_cast<std::uint8_t>(rng() & 0xF);
      mask[0] &= ~1u;
      mask[n - 1] &= ~2u;
      const std::vector<float> gain = RandomRow(rng, n), lo = RandomRow(rng, n),
                               row = RandomRow(rng, n), hi = RandomRow(rng, n);
      std::vector<float> a(n, -1.0f), b(n, -2.0f);
      scalar.grey_row(raw.data(), gain.data(), n, a.data());
      simd.grey_row(raw.data(), gain.data(), n, b.data());
      for (int x = 0; x < n; ++x)
        ASSERT_TRUE(SameBits(a[x], b[x])) << hwy::TargetName(target) << " grey x " << x;
      scalar.smooth_x(row.data(), mask.data(), n, a.data());
      simd.smooth_x(row.data(), mask.data(), n, b.data());
      for (int x = 0; x < n; ++x)
        ASSERT_TRUE(SameBits(a[x], b[x])) << hwy::TargetName(target) << " x pass x " << x << ": "
                                          << b[x] << " vs scalar " << a[x];
      scalar.smooth_y(lo.data(), row.data(), hi.data(), mask.data(), n, a.data());
      simd.smooth_y(lo.data(), row.data(), hi.data(), mask.data(), n, b.data());
      for (int x = 0; x < n; ++x) {
        ASSERT_TRUE(SameBits(a[x], b[x])) << hwy::TargetName(target) << " y pass x " << x << ": "
                                          << b[x] << " vs scalar " << a[x];
        averaged += (mask[x] & 12) != 0 && a[x] != row[x];
      }
    }
    EXPECT_GT(averaged, 1000) << hwy::TargetName(target);
  }
}

// The whole-frame passes: grey = raw * gain, then per pass x then y over
// the whole frame, (2 g + taken) / (2 + count).
std::vector<float> WholeFrameGrey(const std::vector<std::uint8_t>& raw, int channels,
                                  const PlenopticFrame& f) {
  const int w = f.width, h = f.height;
  std::vector<float> grey(static_cast<std::size_t>(w) * h), work(grey.size());
  for (std::size_t i = 0; i < grey.size(); ++i) {
    if (channels == 3)
      grey[i] = (raw[3 * i] + raw[3 * i + 1] + raw[3 * i + 2]) * (f.gain[i] * (1.0f / 3.0f));
    else
      grey[i] = raw[i] * f.gain[i];
  }
  for (int pass = 0; pass < f.smooth_passes; ++pass)
    for (int axis = 0; axis < 2; ++axis) {
      const int step = axis == 0 ? 1 : w;
      const unsigned lo_bit = axis == 0 ? 1 : 4, hi_bit = axis == 0 ? 2 : 8;
      for (std::size_t i = 0; i < grey.size(); ++i) {
        const unsigned m = f.smooth_mask[i];
        float sum = 2.0f * grey[i];
        sum += (m & lo_bit) ? grey[i - step] : 0.0f;
        sum += (m & hi_bit) ? grey[i + step] : 0.0f;
        work[i] = sum / (2.0f + static_cast<float>((m & lo_bit) != 0) +
                         static_cast<float>((m & hi_bit) != 0));
      }
      grey.swap(work);
    }
  return grey;
}

TEST(LoadRawStreaming, EqualsWholeFramePassesBitForBit) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 24; ++trial) {
    const int channels = trial % 2 == 0 ? 1 : 3;
    const int w = std::uniform_int_distribution<int>(1, 70)(rng);
    const int h = trial < 4 ? 1 + trial : std::uniform_int_distribution<int>(5, 300)(rng);
    PlenopticFrame f;
    f.width = w;
    f.height = h;
    f.smooth_passes = trial % 4;
    f.geometry_ready = true;
    const std::size_t n = static_cast<std::size_t>(w) * h;
    f.gain = RandomRow(rng, static_cast<int>(n));
    f.smooth_mask.resize(n);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        f.smooth_mask[static_cast<std::size_t>(y) * w + x] = static_cast<std::uint8_t>(
            rng() & ((x > 0 ? 1 : 0) | (x < w - 1 ? 2 : 0) | (y > 0 ? 4 : 0) | (y < h - 1 ? 8 : 0)));
    std::vector<std::uint8_t> raw(n * channels);
    for (std::uint8_t& b : raw) b = static_cast<std::uint8_t>(rng() & 0xFF);
    ConstImageView view;
    view.data = raw.data();
    view.width = w;
    view.height = h;
    view.stride_bytes = static_cast<std::size_t>(w) * channels;
    view.format = channels == 3 ? PixelFormat::kBgr8 : PixelFormat::kMono8;
    const std::vector<float> expected = WholeFrameGrey(raw, channels, f);
    for (const detail::FrameSmoothKernels* k :
         {&detail::ScalarFrameSmoothKernels(), &detail::SimdFrameSmoothKernels()}) {
      ASSERT_TRUE(LoadRaw(view, *k, &f).ok());
      for (std::size_t i = 0; i < n; ++i)
        ASSERT_TRUE(SameBits(f.grey[i], expected[i]))
            << k->name << " " << w << "x" << h << " passes " << f.smooth_passes << " channels "
            << channels << " pixel " << i << ": " << f.grey[i] << " vs " << expected[i];
    }
  }
}

}  // namespace
}  // namespace lifmcr::processing
