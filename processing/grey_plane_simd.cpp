// The grey plane's row kernel (grey_plane_simd.h): the scalar reference and
// Highway's, compiled once per target by foreach_target.h.

// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "processing/grey_plane_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// foreach_target.h first (it includes this file again once per target),
// then highway.h.
#include <hwy/highway.h>
// clang-format on

#include "processing/grey_plane_simd.h"

#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace lifmcr::processing::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// floor(s / 3) = (s 43691) >> 17 for 0 <= s < 98304 (43691 / 2^17 exceeds
// 1/3 by 2.5e-6 of s, less than the 1/3 between the multiples of 1/3):
// with s = b + g + r + 1 <= 766, the high 16 bits of the 16-bit product,
// shifted once more.
void GreyOfBgrRow(const std::uint8_t* bgr, int n, std::uint8_t* grey) {
  // As many bytes as 16-bit lanes: the channels widened in one step.
  const hn::ScalableTag<std::uint16_t> d16;
  const hn::Rebind<std::uint8_t, decltype(d16)> d8;
  const hn::Rebind<std::int16_t, decltype(d16)> di16;
  const int lanes = static_cast<int>(hn::Lanes(d16));
  const auto one = hn::Set(d16, 1);
  const auto third = hn::Set(d16, 43691);
  int x = 0;
  for (; x + lanes <= n; x += lanes) {
    hn::Vec<decltype(d8)> b, g, r;
    hn::LoadInterleaved3(d8, bgr + 3 * static_cast<std::size_t>(x), b, g, r);
    const auto s = hn::Add(
        hn::Add(hn::Add(hn::PromoteTo(d16, b), hn::PromoteTo(d16, g)), hn::PromoteTo(d16, r)), one);
    hn::StoreU(hn::DemoteTo(d8, hn::BitCast(di16, hn::ShiftRight<1>(hn::MulHigh(s, third)))), d8,
               grey + x);
  }
  for (; x < n; ++x) {
    const unsigned s = 1u + bgr[3 * x] + bgr[3 * x + 1] + bgr[3 * x + 2];
    grey[x] = static_cast<std::uint8_t>((s * 43691u) >> 17);
  }
}

}  // namespace HWY_NAMESPACE
}  // namespace lifmcr::processing::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lifmcr::processing::detail {

HWY_EXPORT(GreyOfBgrRow);

namespace {

void ScalarGreyOfBgrRow(const std::uint8_t* bgr, int n, std::uint8_t* grey) {
  for (int x = 0; x < n; ++x)
    grey[x] = static_cast<std::uint8_t>((bgr[3 * x] + bgr[3 * x + 1] + bgr[3 * x + 2] + 1) / 3);
}

void DispatchedGreyOfBgrRow(const std::uint8_t* bgr, int n, std::uint8_t* grey) {
  HWY_DYNAMIC_DISPATCH(GreyOfBgrRow)(bgr, n, grey);
}

}  // namespace

const GreyPlaneKernels& ScalarGreyPlaneKernels() {
  static const GreyPlaneKernels kernels{ScalarGreyOfBgrRow, "scalar"};
  return kernels;
}

const GreyPlaneKernels& SimdGreyPlaneKernels() {
  // The target this CPU runs (hwy/targets.h): the best one compiled in.
  static const GreyPlaneKernels kernels{DispatchedGreyOfBgrRow,
                                        hwy::TargetName(hwy::SupportedAndGeneratedTargets()[0])};
  return kernels;
}

}  // namespace lifmcr::processing::detail
#endif  // HWY_ONCE
