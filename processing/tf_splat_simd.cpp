// The TF depth map's splat kernels (tf_splat_simd.h): the scalar reference
// and Highway's, compiled once per target by foreach_target.h.

// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "processing/tf_splat_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// foreach_target.h first (it includes this file again once per target),
// then highway.h.
#include <hwy/highway.h>
// clang-format on

#include "processing/tf_splat_simd.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace lifmcr::processing::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// One vector of pixels at x = x0 + lane (v, sigma_z, lens: the lanes'),
// its splats appended at out; returns the new count.
template <class DF>
HWY_INLINE int SplatVector(DF df, const TfSplatRow& r, int x0, const float* vp, const float* sp,
                           const std::int32_t* kp, std::uint32_t* t_out, float* w_out,
                           float* wz_out, int out) {
  const hn::RebindToSigned<DF> di;
  const hn::RebindToUnsigned<DF> du;
  using VF = hn::Vec<DF>;
  const VF half = hn::Set(df, 0.5f), minus_half = hn::Set(df, -0.5f);
  const VF v = hn::LoadU(df, vp);
  const auto k = hn::LoadU(di, kp);
  auto valid = hn::AndNot(hn::IsNaN(v), hn::RebindMask(df, hn::Gt(k, hn::Set(di, -1))));
  if (hn::AllFalse(df, valid)) return out;
  VF lx, ly;
  const std::int32_t k_first = hn::GetLane(k);
  if (hn::AllTrue(di, hn::Eq(k, hn::Set(di, k_first)))) {
    // One micro image (not -1: some lane is valid): its l_k, not gathered.
    lx = hn::Set(df, r.lens_xy[2 * k_first]);
    ly = hn::Set(df, r.lens_xy[2 * k_first + 1]);
  } else {
    // Lanes without a lens read l_0 and are dropped.
    const auto k2 = hn::IfThenElseZero(hn::RebindMask(di, valid), hn::Add(k, k));
    lx = hn::GatherIndex(df, r.lens_xy, k2);
    ly = hn::GatherIndex(df, r.lens_xy, hn::Add(k2, hn::Set(di, 1)));
  }
  const VF x = hn::Add(hn::Set(df, static_cast<float>(r.x0 + x0)), hn::Iota(df, 0.0f));
  const VF xv = hn::Add(lx, hn::Mul(v, hn::Sub(x, lx)));
  const VF yv = hn::Add(ly, hn::Mul(v, hn::Sub(hn::Set(df, static_cast<float>(r.y)), ly)));
  const VF ua = hn::Mul(hn::Sub(xv, half), half), wa = hn::Mul(hn::Sub(yv, half), half);
  const VF ur = hn::Add(ua, half), wr = hn::Add(wa, half);
  valid = hn::And(valid, hn::And(hn::Gt(ua, minus_half), hn::Gt(wa, minus_half)));
  valid = hn::And(valid, hn::And(hn::Lt(ur, hn::Set(df, static_cast<float>(r.tf_width))),
                                 hn::Lt(wr, hn::Set(df, static_cast<float>(r.tf_height)))));
  const auto u = hn::ConvertTo(di, hn::IfThenElseZero(valid, ur));
  const auto w = hn::ConvertTo(di, hn::IfThenElseZero(valid, wr));
  const VF s = hn::LoadU(df, sp);
  const VF weight_z =
      hn::Div(hn::Set(df, 1.0f), hn::Mul(hn::Max(hn::Set(df, 1e-12f), hn::Mul(s, s)), v));
  const VF weight = hn::Mul(weight_z, v);
  static_assert(TfSplatRow::kCellPx == 4, "the cell's shifts below divide by 4");
  const auto t = hn::BitCast(
      du, r.cell_width > 0 ? hn::Add(hn::Mul(hn::ShiftRight<2>(w), hn::Set(di, r.cell_width)),
                                     hn::ShiftRight<2>(u))
                           : hn::Add(hn::Mul(w, hn::Set(di, r.tf_width)), u));
  // Compressed in registers and stored whole (the arrays have a vector's
  // room beyond `width`): Highway's CompressStore is a masked compress to
  // memory on AVX-512, which AMD Zen 4 runs as microcode, far slower.
  hn::StoreU(hn::Compress(t, hn::RebindMask(du, valid)), du, t_out + out);
  hn::StoreU(hn::Compress(weight, valid), df, w_out + out);
  hn::StoreU(hn::Compress(weight_z, valid), df, wz_out + out);
  return out + static_cast<int>(hn::CountTrue(df, valid));
}

int SplatRow(const TfSplatRow& r, std::uint32_t* t_out, float* w_out, float* wz_out) {
  const hn::ScalableTag<float> df;
  const int lanes = static_cast<int>(hn::Lanes(df));
  int out = 0, x0 = 0;
  for (; x0 + lanes <= r.width; x0 += lanes)
    out = SplatVector(df, r, x0, r.v + x0, r.sigma_z + x0, r.lens + x0, t_out, w_out, wz_out, out);
  if (x0 < r.width) {
    // The tail through a full vector: padding without a lens.
    constexpr int kMax = HWY_MAX_BYTES / sizeof(float);
    HWY_ALIGN float v[kMax], s[kMax];
    HWY_ALIGN std::int32_t k[kMax];
    for (int q = 0; q < lanes; ++q) {
      const bool in = x0 + q < r.width;
      v[q] = in ? r.v[x0 + q] : 0.0f;
      s[q] = in ? r.sigma_z[x0 + q] : 1.0f;
      k[q] = in ? r.lens[x0 + q] : -1;
    }
    out = SplatVector(df, r, x0, v, s, k, t_out, w_out, wz_out, out);
  }
  return out;
}

}  // namespace HWY_NAMESPACE
}  // namespace lifmcr::processing::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lifmcr::processing::detail {

HWY_EXPORT(SplatRow);

namespace {

int ScalarSplatRow(const TfSplatRow& r, std::uint32_t* t_out, float* w_out, float* wz_out) {
  const float y = static_cast<float>(r.y);
  const float tw = static_cast<float>(r.tf_width), th = static_cast<float>(r.tf_height);
  int out = 0;
  for (int x = 0; x < r.width; ++x) {
    const float v = r.v[x];
    const int k = r.lens[x];
    if (std::isnan(v) || k < 0) continue;
    const float lx = r.lens_xy[2 * k], ly = r.lens_xy[2 * k + 1];
    const float xv = lx + v * (static_cast<float>(r.x0 + x) - lx);
    const float yv = ly + v * (y - ly);
    const float ua = (xv - 0.5f) * 0.5f, wa = (yv - 0.5f) * 0.5f;
    const float ur = ua + 0.5f, wr = wa + 0.5f;
    if (!(ua > -0.5f && wa > -0.5f && ur < tw && wr < th)) continue;
    const int u = static_cast<int>(ur), w = static_cast<int>(wr);
    const float s = r.sigma_z[x];
    const float weight_z = 1.0f / (std::max(1e-12f, s * s) * v);
    constexpr int kCell = TfSplatRow::kCellPx;
    t_out[out] = static_cast<std::uint32_t>(
        r.cell_width > 0 ? (w / kCell) * r.cell_width + u / kCell : w * r.tf_width + u);
    w_out[out] = weight_z * v;
    wz_out[out] = weight_z;
    ++out;
  }
  return out;
}

int DispatchedSplatRow(const TfSplatRow& r, std::uint32_t* t, float* w, float* wz) {
  return HWY_DYNAMIC_DISPATCH(SplatRow)(r, t, w, wz);
}

}  // namespace

const TfSplatKernels& ScalarTfSplatKernels() {
  static const TfSplatKernels kernels{ScalarSplatRow, "scalar"};
  return kernels;
}

const TfSplatKernels& SimdTfSplatKernels() {
  static const TfSplatKernels kernels{DispatchedSplatRow,
                                      hwy::TargetName(hwy::SupportedAndGeneratedTargets()[0])};
  return kernels;
}

}  // namespace lifmcr::processing::detail
#endif  // HWY_ONCE
