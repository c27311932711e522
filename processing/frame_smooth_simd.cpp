// LoadRaw's row kernels (frame_smooth_simd.h): the scalar reference and
// Highway's, compiled once per target by foreach_target.h.

// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "processing/frame_smooth_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// foreach_target.h first (it includes this file again once per target),
// then highway.h.
#include <hwy/highway.h>
// clang-format on

#include "processing/frame_smooth_simd.h"

#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace lifmcr::processing::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// One pixel of the smoothing, the scalar reference's expression (also the
// vector loops' tails).
HWY_INLINE float SmoothOne(float lo, float g, float hi, unsigned m, unsigned lo_bit,
                           unsigned hi_bit) {
  float sum = 2.0f * g;
  sum += (m & lo_bit) ? lo : 0.0f;
  sum += (m & hi_bit) ? hi : 0.0f;
  const float weight =
      2.0f + static_cast<float>((m & lo_bit) != 0) + static_cast<float>((m & hi_bit) != 0);
  return sum / weight;
}

void GreyRow(const std::uint8_t* raw, const float* gain, int n, float* grey) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const hn::Rebind<std::uint8_t, decltype(df)> d8;
  const int lanes = static_cast<int>(hn::Lanes(df));
  int x = 0;
  for (; x + lanes <= n; x += lanes) {
    const auto v = hn::ConvertTo(df, hn::PromoteTo(di, hn::LoadU(d8, raw + x)));
    hn::StoreU(hn::Mul(v, hn::LoadU(df, gain + x)), df, grey + x);
  }
  for (; x < n; ++x) grey[x] = raw[x] * gain[x];
}

// out over [x0, x1) from lo, row, hi at the same x, the mask's bits lo_bit
// and hi_bit choosing the neighbours.
HWY_INLINE void SmoothSpan(const float* lo, const float* row, const float* hi,
                           const std::uint8_t* mask, unsigned lo_bit, unsigned hi_bit, int x0,
                           int x1, float* out) {
  const hn::ScalableTag<float> df;
  const hn::RebindToUnsigned<decltype(df)> du;
  const hn::Rebind<std::uint8_t, decltype(df)> d8;
  const int lanes = static_cast<int>(hn::Lanes(df));
  const auto vlo_bit = hn::Set(du, lo_bit), vhi_bit = hn::Set(du, hi_bit);
  const auto two = hn::Set(df, 2.0f), one = hn::Set(df, 1.0f);
  int x = x0;
  for (; x + lanes <= x1; x += lanes) {
    const auto m = hn::PromoteTo(du, hn::LoadU(d8, mask + x));
    const auto take_lo = hn::RebindMask(df, hn::TestBit(m, vlo_bit));
    const auto take_hi = hn::RebindMask(df, hn::TestBit(m, vhi_bit));
    auto sum = hn::Mul(two, hn::LoadU(df, row + x));
    sum = hn::Add(sum, hn::IfThenElseZero(take_lo, hn::LoadU(df, lo + x)));
    sum = hn::Add(sum, hn::IfThenElseZero(take_hi, hn::LoadU(df, hi + x)));
    const auto weight =
        hn::Add(hn::Add(two, hn::IfThenElseZero(take_lo, one)), hn::IfThenElseZero(take_hi, one));
    hn::StoreU(hn::Div(sum, weight), df, out + x);
  }
  for (; x < x1; ++x) out[x] = SmoothOne(lo[x], row[x], hi[x], mask[x], lo_bit, hi_bit);
}

void SmoothXRow(const float* row, const std::uint8_t* mask, int n, float* out) {
  if (n == 1) {
    out[0] = row[0];
    return;
  }
  // x = 0 and x = n - 1 would read past the row: only their taken side.
  out[0] = SmoothOne(0.0f, row[0], row[1], mask[0] & 2u, 1, 2);
  SmoothSpan(row - 1, row, row + 1, mask, 1, 2, 1, n - 1, out);
  out[n - 1] = SmoothOne(row[n - 2], row[n - 1], 0.0f, mask[n - 1] & 1u, 1, 2);
}

void SmoothYRow(const float* lo, const float* row, const float* hi, const std::uint8_t* mask,
                int n, float* out) {
  SmoothSpan(lo, row, hi, mask, 4, 8, 0, n, out);
}

}  // namespace HWY_NAMESPACE
}  // namespace lifmcr::processing::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lifmcr::processing::detail {

HWY_EXPORT(GreyRow);
HWY_EXPORT(SmoothXRow);
HWY_EXPORT(SmoothYRow);

namespace {

unsigned Bit(bool b) { return b ? 1u : 0u; }

// The reference: the expressions of the vector loops, pixel by pixel.
float ScalarOne(float lo, float g, float hi, unsigned m, unsigned lo_bit, unsigned hi_bit) {
  float sum = 2.0f * g;
  sum += (m & lo_bit) ? lo : 0.0f;
  sum += (m & hi_bit) ? hi : 0.0f;
  const float weight = 2.0f + static_cast<float>(Bit(m & lo_bit)) +
                       static_cast<float>(Bit(m & hi_bit));
  return sum / weight;
}

void ScalarGreyRow(const std::uint8_t* raw, const float* gain, int n, float* grey) {
  for (int x = 0; x < n; ++x) grey[x] = raw[x] * gain[x];
}

void ScalarSmoothXRow(const float* row, const std::uint8_t* mask, int n, float* out) {
  for (int x = 0; x < n; ++x) {
    const unsigned m = mask[x] & ((x > 0 ? 1u : 0u) | (x < n - 1 ? 2u : 0u));
    out[x] = ScalarOne(x > 0 ? row[x - 1] : 0.0f, row[x], x < n - 1 ? row[x + 1] : 0.0f, m, 1, 2);
  }
}

void ScalarSmoothYRow(const float* lo, const float* row, const float* hi,
                      const std::uint8_t* mask, int n, float* out) {
  for (int x = 0; x < n; ++x) out[x] = ScalarOne(lo[x], row[x], hi[x], mask[x], 4, 8);
}

void DispatchedGreyRow(const std::uint8_t* raw, const float* gain, int n, float* grey) {
  HWY_DYNAMIC_DISPATCH(GreyRow)(raw, gain, n, grey);
}
void DispatchedSmoothXRow(const float* row, const std::uint8_t* mask, int n, float* out) {
  HWY_DYNAMIC_DISPATCH(SmoothXRow)(row, mask, n, out);
}
void DispatchedSmoothYRow(const float* lo, const float* row, const float* hi,
                          const std::uint8_t* mask, int n, float* out) {
  HWY_DYNAMIC_DISPATCH(SmoothYRow)(lo, row, hi, mask, n, out);
}

}  // namespace

const FrameSmoothKernels& ScalarFrameSmoothKernels() {
  static const FrameSmoothKernels kernels{ScalarGreyRow, ScalarSmoothXRow, ScalarSmoothYRow,
                                          "scalar"};
  return kernels;
}

const FrameSmoothKernels& SimdFrameSmoothKernels() {
  // The target this CPU runs (hwy/targets.h): the best one compiled in.
  static const FrameSmoothKernels kernels{DispatchedGreyRow, DispatchedSmoothXRow,
                                          DispatchedSmoothYRow,
                                          hwy::TargetName(hwy::SupportedAndGeneratedTargets()[0])};
  return kernels;
}

}  // namespace lifmcr::processing::detail
#endif  // HWY_ONCE
