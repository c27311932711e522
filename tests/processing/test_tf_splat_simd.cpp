// The TF depth map's splat kernel (processing/tf_splat_simd.h): Highway's on
// every target this CPU runs against the scalar reference on random rows
// (NaN depths, pixels outside every micro image, splats off the TF grid on
// either side, row widths that leave a partial vector), and both against a
// splat worked out by hand. Both evaluate the same float expressions in the
// same order without FMA contraction: the same TF pixels in the same order,
// weights within 1e-6 relative (for a compiler that reorders).

#include "processing/tf_splat_simd.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <hwy/targets.h>
#include <random>
#include <vector>

namespace lifmcr::processing::detail {
namespace {

bool Close(float a, float b) { return std::abs(a - b) <= 1e-6f * std::max(1.0f, std::abs(b)); }

struct Output {
  std::vector<std::uint32_t> t;
  std::vector<float> w, wz;
  int n = 0;
};

Output Splat(const TfSplatKernels& kernels, const TfSplatRow& row) {
  Output o;
  o.t.assign(row.width + kTfSplatPad, 0xFFFFFFFFu);
  o.w.assign(row.width + kTfSplatPad, -1.0f);
  o.wz.assign(row.width + kTfSplatPad, -1.0f);
  o.n = kernels.row(row, o.t.data(), o.w.data(), o.wz.data());
  return o;
}

class TfSplatKernelsTest : public ::testing::Test {
 protected:
  void TearDown() override { hwy::SetSupportedTargetsForTest(0); }
};

TEST_F(TfSplatKernelsTest, ASplatWorkedOutByHand) {
  // l = (0, 50), v = 2: raw (3, 51) -> x_v = (6, 52) -> (x_v - 0.5) / 2 =
  // (2.75, 25.75) -> TF pixel (3, 26); sigma_z 0.1: weight 100, weight z 50.
  const std::vector<float> lens_xy = {0.0f, 50.0f};
  std::vector<float> v(8, std::nanf("")), sigma(8, 0.1f);
  std::vector<std::int32_t> lens(8, 0);
  v[3] = 2.0f;
  TfSplatRow row;
  row.v = v.data();
  row.sigma_z = sigma.data();
  row.lens = lens.data();
  row.lens_xy = lens_xy.data();
  row.width = 8;
  row.y = 51;
  row.tf_width = 100;
  row.tf_height = 40;
  for (const TfSplatKernels* k : {&ScalarTfSplatKernels(), &SimdTfSplatKernels()}) {
    const Output o = Splat(*k, row);
    ASSERT_EQ(o.n, 1) << k->name;
    EXPECT_EQ(o.t[0], 26u * 100u + 3u) << k->name;
    EXPECT_NEAR(o.w[0], 100.0f, 1e-3f) << k->name;
    EXPECT_NEAR(o.wz[0], 50.0f, 1e-3f) << k->name;
  }
  // The same pixel in a span of the row from x0 = 2: the same splat.
  TfSplatRow span = row;
  span.x0 = 2;
  span.v = v.data() + 2;
  span.sigma_z = sigma.data() + 2;
  span.lens = lens.data() + 2;
  span.width = 4;
  for (const TfSplatKernels* k : {&ScalarTfSplatKernels(), &SimdTfSplatKernels()}) {
    const Output o = Splat(*k, span);
    ASSERT_EQ(o.n, 1) << k->name;
    EXPECT_EQ(o.t[0], 26u * 100u + 3u) << k->name;
  }
  // Its cell of 4 x 4 TF pixels, (26 / 4) 25 + 3 / 4, where cells are asked for.
  TfSplatRow cells = row;
  cells.cell_width = 25;
  for (const TfSplatKernels* k : {&ScalarTfSplatKernels(), &SimdTfSplatKernels()}) {
    const Output o = Splat(*k, cells);
    ASSERT_EQ(o.n, 1) << k->name;
    EXPECT_EQ(o.t[0], 6u * 25u) << k->name;
  }
  // Off the grid below (w = 26 >= tf_height 20): dropped.
  row.tf_height = 20;
  for (const TfSplatKernels* k : {&ScalarTfSplatKernels(), &SimdTfSplatKernels()})
    EXPECT_EQ(Splat(*k, row).n, 0) << k->name;
}

TEST_F(TfSplatKernelsTest, RowsMatchTheScalarReferenceOnEveryTarget) {
  const TfSplatKernels& scalar = ScalarTfSplatKernels();
  const std::vector<std::int64_t> targets = hwy::SupportedAndGeneratedTargets();
  ASSERT_FALSE(targets.empty());
  for (const std::int64_t target : targets) {
    hwy::SetSupportedTargetsForTest(target);
    const TfSplatKernels& simd = SimdTfSplatKernels();
    std::mt19937 rng(31);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    long long splats = 0, pixels = 0;
    for (int trial = 0; trial < 300; ++trial) {
      const int width = std::uniform_int_distribution<int>(1, 200)(rng);
      const int lenses = std::uniform_int_distribution<int>(1, 30)(rng);
      std::vector<float> lens_xy(2 * lenses);
      for (int k = 0; k < lenses; ++k) {
        lens_xy[2 * k] = width * (1.2f * unit(rng) - 0.1f);
        lens_xy[2 * k + 1] = 60.0f * unit(rng);
      }
      std::vector<float> v(width), sigma(width);
      std::vector<std::int32_t> lens(width);
      for (int x = 0; x < width; ++x) {
        v[x] = rng() % 5 == 0 ? std::nanf("") : 1.0f + 8.0f * unit(rng);
        sigma[x] = rng() % 50 == 0 ? 0.0f : 1e-3f + 0.05f * unit(rng);
        lens[x] = rng() % 7 == 0 ? -1 : static_cast<std::int32_t>(rng() % lenses);
      }
      // A third of the rows one micro image's pixels (its l_k read once),
      // with a few of another.
      if (trial % 3 == 0) {
        const std::int32_t one = std::max(0, lens[0]);
        for (int x = 0; x < width; ++x) lens[x] = rng() % 40 == 0 ? (one + 1) % lenses : one;
      }
      TfSplatRow row;
      row.v = v.data();
      row.sigma_z = sigma.data();
      row.lens = lens.data();
      row.lens_xy = lens_xy.data();
      row.width = width;
      // Spans that start inside a row as well as whole rows.
      row.x0 = rng() % 2 == 0 ? 0 : std::uniform_int_distribution<int>(1, 40)(rng);
      row.y = std::uniform_int_distribution<int>(0, 60)(rng);
      // A TF grid smaller than the row's reach: splats off it on either side.
      row.tf_width = std::max(1, static_cast<int>(width * (0.2f + 0.5f * unit(rng))));
      row.tf_height = std::uniform_int_distribution<int>(5, 40)(rng);
      // The cells of 4 x 4 TF pixels in half the trials.
      row.cell_width = trial % 2 == 0 ? 0 : (row.tf_width + 3) / 4;
      const Output a = Splat(scalar, row), b = Splat(simd, row);
      ASSERT_EQ(b.n, a.n) << hwy::TargetName(target) << " trial " << trial;
      for (int i = 0; i < a.n; ++i) {
        ASSERT_EQ(b.t[i], a.t[i]) << hwy::TargetName(target) << " trial " << trial << " splat "
                                  << i;
        ASSERT_TRUE(Close(b.w[i], a.w[i]) && Close(b.wz[i], a.wz[i]))
            << hwy::TargetName(target) << " trial " << trial << " splat " << i << ": " << b.w[i]
            << " " << b.wz[i] << " vs scalar " << a.w[i] << " " << a.wz[i];
        ASSERT_LT(a.t[i], static_cast<std::uint32_t>(
                              row.cell_width > 0 ? row.cell_width * ((row.tf_height + 3) / 4)
                                                 : row.tf_width * row.tf_height));
      }
      splats += a.n;
      pixels += width;
    }
    // Both kinds of pixel occur: splatted, and dropped (NaN, no lens, off the grid).
    EXPECT_GT(splats, pixels / 100) << hwy::TargetName(target);
    EXPECT_LT(splats, pixels / 2) << hwy::TargetName(target);
  }
}

}  // namespace
}  // namespace lifmcr::processing::detail
