// The TF blend's kernels (tf_blend_simd.h): the scalar reference and
// Highway's, compiled once per target by foreach_target.h.

// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "processing/tf_blend_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// foreach_target.h first (it includes this file again once per target),
// then highway.h.
#include <hwy/highway.h>
// clang-format on

#include "processing/tf_blend_simd.h"

#include <hwy/cache_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>
#include <utility>

#ifndef LIFMCR_TF_BLEND_FIXED_ONCE
#define LIFMCR_TF_BLEND_FIXED_ONCE
namespace lifmcr::processing::detail {

// The widest frame of the fixed-point blend (its positions in 2^-16 px fit
// 32 bits); a wider one blends in float.
constexpr int kFixedMaxWidth = 32768;
// A fraction's 1 (the largest signed word), and what FixedSums' products by
// 2^-15 leave out of two such factors: (32768 / 32767)^2.
constexpr std::int32_t kFixedOne = 32767;
constexpr float kFixedRescale = static_cast<float>((32768.0 / 32767.0) * (32768.0 / 32767.0));

// a b / 2^15 rounded (x86's pmulhrsw, Highway's MulFixedPoint15) for the
// non-negative operands of FixedSums.
inline std::int32_t MulQ15(std::int32_t a, std::int32_t b) { return (a * b + 16384) >> 15; }

// The fixed-point blend of a BGR sample with the 16-bit gain (the rule of
// the Highway kernel's weights in BlendVector and FixedColours, written once
// for the scalar reference and the one-lane target): at raw position (pxq,
// pyq) in units of 2^-16 px, the weights w_ij = q_ij / 2 (1 - f | f)_x (1 -
// f | f)_y, each fraction f = (pxq mod 2^16) / 2 in units of 1 / 32767 (so 1
// - f fits a signed word), each product by MulQ15 (so a weight carries
// kFixedRescale^-1), q halved first; per colour sums[ch] = sum w_ij c_ij in
// 32-bit integers (at most 4 x 255 x 32767); false where a gain is 0.
inline bool FixedSums(const TfBlendSource& s, int width, std::int32_t pxq, std::int32_t pyq,
                      std::int32_t sums[3]) {
  const int ix = pxq >> 16, iy = pyq >> 16;
  const std::int32_t fx = (pxq & 0xFFFF) >> 1, fy = (pyq & 0xFFFF) >> 1;
  const std::int32_t bx[2] = {kFixedOne - fx, fx}, by[2] = {kFixedOne - fy, fy};
  const std::size_t at = static_cast<std::size_t>(iy) * width + ix;
  const std::uint16_t* q[2] = {s.gain16 + at, s.gain16 + at + width};
  if (q[0][0] == 0 || q[0][1] == 0 || q[1][0] == 0 || q[1][1] == 0) return false;
  const std::uint8_t* r[2] = {
      s.raw + static_cast<std::size_t>(iy) * s.stride_bytes + static_cast<std::size_t>(ix) * 3,
      nullptr};
  r[1] = r[0] + s.stride_bytes;
  std::int32_t w[2][2];
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 2; ++i) w[j][i] = MulQ15(MulQ15(q[j][i] >> 1, bx[i]), by[j]);
  for (int ch = 0; ch < 3; ++ch)
    sums[ch] =
        w[0][0] * r[0][ch] + w[0][1] * r[0][3 + ch] + w[1][0] * r[1][ch] + w[1][1] * r[1][3 + ch];
  return true;
}

}  // namespace lifmcr::processing::detail
#endif  // LIFMCR_TF_BLEND_FIXED_ONCE

HWY_BEFORE_NAMESPACE();
namespace lifmcr::processing::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// ConvertTo for lanes known to lie in [0, 2^31) (every caller's here): on
// x86 the same integers without its overflow fix-up (four instructions a
// vector on AVX2, two on AVX-512; seven conversions a vector of pixels).
template <class DI, class VF>
HWY_INLINE hn::Vec<DI> TruncInRange(DI di, VF v) {
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX3_DL
  if constexpr (std::is_same_v<VF, hn::Vec512<float>>) {
    (void)di;
    return hn::Vec<DI>{_mm512_cvttps_epi32(v.raw)};
  } else
#elif HWY_TARGET == HWY_AVX2
  if constexpr (std::is_same_v<VF, hn::Vec256<float>>) {
    (void)di;
    return hn::Vec<DI>{_mm256_cvttps_epi32(v.raw)};
  } else
#endif
  {
    return hn::ConvertTo(di, v);
  }
}

#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX3_DL
// The samples of a lens slot read from 64-byte windows of the rows instead
// of gathers (BlendVector): on AVX-512 a permute of 16-bit words
// (AVX512BW) picks each lane's bytes out of a window.
using VU16 = hn::Vec512<std::uint32_t>;
// Per 32-bit lane the words w and w + 1 of the 64 bytes at `table` (w in
// the lane's low 16 bits, w + 1 in its high 16 bits of `pair`).
HWY_INLINE VU16 WordPairs(const void* table, VU16 pair) {
  return VU16{_mm512_permutexvar_epi16(pair.raw, _mm512_loadu_si512(table))};
}

// The window of raw pixel (ix0, iy0), ix0 >= 2: the 16-bit gains of row
// iy0 from ix0 - 2 and the BGR bytes from byte 3 ix0 - 6 made even (64
// bytes of each row, iy0 and iy0 + 1); it holds a lane's sample (x0, iy0)
// with rel = x0 - ix0 + 2 in [0, 18].
struct SampleWindow {
  const std::uint16_t* gain = nullptr;
  const std::uint8_t* raw = nullptr;
  int odd = 0;  // ix0 odd: the window starts a byte before 3 ix0 - 6
};

// Whether the window of (ix0, iy0) lies within the frame's buffers (rows
// iy0 and iy0 + 1: the last row ends at (height - 1) stride + 3 width of
// the raw, width height of the gain).
HWY_INLINE bool MakeWindow(const TfBlendGeometry& g, const TfBlendSource& s, int ix0, int iy0,
                           SampleWindow* w) {
  const long long stride = static_cast<long long>(s.stride_bytes);
  const long long raw_start = 3LL * ix0 - 6 - (ix0 & 1);
  if (ix0 < 2 || iy0 < 0 ||
      (iy0 + 1LL) * g.width + ix0 - 2 + 32 > static_cast<long long>(g.width) * g.height ||
      (iy0 + 1LL) * stride + raw_start + 64 > (g.height - 1LL) * stride + 3LL * g.width)
    return false;
  w->gain = s.gain16 + static_cast<std::size_t>(iy0) * g.width + (ix0 - 2);
  w->raw = s.raw + static_cast<std::size_t>(iy0) * s.stride_bytes + raw_start;
  w->odd = ix0 & 1;
  // The row the next TF rows sample after this pair (they move down by
  // 2 / v raw rows per TF row): prefetched while this one is blended.
  if (iy0 + 3 < g.height) {
    const std::uint8_t* raw_next = w->raw + 2 * s.stride_bytes;
    const auto* gain_next = reinterpret_cast<const std::uint8_t*>(w->gain + 2 * g.width);
    hwy::Prefetch(raw_next);
    hwy::Prefetch(raw_next + 63);
    hwy::Prefetch(gain_next);
    hwy::Prefetch(gain_next + 63);
  }
  return true;
}

// The samples' words of a window (rel per lane): q0 / q1 the gain pairs of
// rows iy0 / iy0 + 1 (as the gathers read them), a_lo / a_hi and b_lo /
// b_hi the bytes B0 G0 R0 B1 / G1 R1 of the two rows. Lane i's bytes
// start at o = 3 rel + odd in the window: words o / 2 .. o / 2 + 3 hold
// them, shifted down a byte where o is odd. kTwo: the lanes of two windows
// wa and wb at once, those of wb (`second` 0x00200020, else 0) indexing the
// second table of a two-source permute (bit 5 of a word index; every index
// here is below 32), one permute per row and kind instead of one per
// window and a blend; `odd` per lane its window's.
struct WindowWords {
  VU16 q0, q1, a_lo, a_hi, b_lo, b_hi;
};
template <bool kTwo>
HWY_INLINE WindowWords ReadWindows(const TfBlendGeometry& g, const TfBlendSource& s,
                                   const SampleWindow& wa, const SampleWindow& wb, VU16 rel,
                                   VU16 odd_in, VU16 second) {
  const hn::DFromV<VU16> du;
  const VU16 one = hn::Set(du, 1u);
  auto words_of = [](const void* a, const void* b, VU16 pair) {
    if constexpr (kTwo) {
      return VU16{_mm512_permutex2var_epi16(_mm512_loadu_si512(a), pair.raw,
                                            _mm512_loadu_si512(b))};
    } else {
      (void)b;
      return WordPairs(a, pair);
    }
  };
  WindowWords r;
  const VU16 pair = hn::Add(hn::Or(rel, hn::ShiftLeft<16>(hn::Add(rel, one))), second);
  r.q0 = words_of(wa.gain, wb.gain, pair);
  r.q1 = words_of(wa.gain + g.width, wb.gain + g.width, pair);
  const VU16 o = hn::Add(hn::Mul(rel, hn::Set(du, 3u)), odd_in);
  const VU16 words = hn::ShiftRight<1>(o);
  const VU16 pair_a = hn::Add(hn::Or(words, hn::ShiftLeft<16>(hn::Add(words, one))), second);
  const VU16 pair_b = hn::Add(pair_a, hn::Set(du, 0x00020002u));
  const auto odd = hn::Eq(hn::And(o, one), one);
  auto row = [&](const std::uint8_t* bytes_a, const std::uint8_t* bytes_b, VU16* lo, VU16* hi) {
    const VU16 a = words_of(bytes_a, bytes_b, pair_a), b = words_of(bytes_a, bytes_b, pair_b);
    *lo = hn::IfThenElse(odd, hn::Or(hn::ShiftRight<8>(a), hn::ShiftLeft<24>(b)), a);
    *hi = hn::IfThenElse(odd, hn::ShiftRight<8>(b), b);
  };
  row(wa.raw, wb.raw, &r.a_lo, &r.a_hi);
  row(wa.raw + s.stride_bytes, wb.raw + s.stride_bytes, &r.b_lo, &r.b_hi);
  return r;
}
#endif

// Whether the per-type values are looked up in a vector (TypeTables).
template <class DF>
constexpr bool kTypeLookup = hn::MaxLanes(DF()) >= 4;

// The per-type values of TfBlendGeometry (o_t, F_t), each in a vector's
// first three lanes: made once per run of a row, read by every vector of it.
struct TypeTables {
  // A vector's floats, at least the three types' (HWY_SCALAR's vector holds one).
  static constexpr int kMax = std::max<int>(3, HWY_MAX_BYTES / sizeof(float));
  HWY_ALIGN float v[6][kMax] = {};
  explicit TypeTables(const TfBlendGeometry& g) {
    const float* per_type[6] = {g.ox, g.oy, g.fxx, g.fxy, g.fyx, g.fyy};
    for (int i = 0; i < 6; ++i) std::copy(per_type[i], per_type[i] + 3, v[i]);
  }
  enum Field { kOx, kOy, kFxx, kFxy, kFyx, kFyy };
};

#if HWY_TARGET != HWY_SCALAR
// The byte picks of FixedColours per 32-bit lane j of a 16-byte block (0x80:
// a zero byte): from a row's lo word (B0 G0 R0 B1) and hi word (G1 R1 - -)
// the words (c0, c1) of one colour of the sample's two pixels.
HWY_ALIGN constexpr std::uint8_t kPick[5][16] = {
    {0, 0x80, 3, 0x80, 4, 0x80, 7, 0x80, 8, 0x80, 11, 0x80, 12, 0x80, 15, 0x80},  // B from lo
    {1, 0x80, 0x80, 0x80, 5, 0x80, 0x80, 0x80, 9, 0x80, 0x80, 0x80, 13, 0x80, 0x80, 0x80},   // G0
    {0x80, 0x80, 0, 0x80, 0x80, 0x80, 4, 0x80, 0x80, 0x80, 8, 0x80, 0x80, 0x80, 12, 0x80},   // G1
    {2, 0x80, 0x80, 0x80, 6, 0x80, 0x80, 0x80, 10, 0x80, 0x80, 0x80, 14, 0x80, 0x80, 0x80},  // R0
    {0x80, 0x80, 1, 0x80, 0x80, 0x80, 5, 0x80, 0x80, 0x80, 9, 0x80, 0x80, 0x80, 13, 0x80}};  // R1

// The three colours of a BGR sample (rows a and b: lo B0 G0 R0 B1, hi G1
// R1 in its low bytes) with the fixed-point weights wa (w00, w01) and wb
// (w10, w11): w00 c00 + w01 c01 + w10 c10 + w11 c11 in 32-bit integers
// (pairwise 16-bit products, exact), then in float.
template <class DF, class VU>
HWY_INLINE void FixedColours(DF df, VU lo_a, VU hi_a, VU lo_b, VU hi_b, VU wa, VU wb,
                             hn::Vec<DF>* col) {
  const hn::RebindToSigned<DF> di;
  const hn::Repartition<std::uint8_t, DF> d8;
  const hn::Repartition<std::int16_t, DF> d16;
  auto pick = [&](VU v, int k) {
    return hn::BitCast(d16,
                       hn::TableLookupBytesOr0(hn::BitCast(d8, v), hn::LoadDup128(d8, kPick[k])));
  };
  auto pick2 = [&](VU lo, VU hi, int k) { return hn::Or(pick(lo, k), pick(hi, k + 1)); };
  auto dot = [&](hn::Vec<decltype(d16)> pa, hn::Vec<decltype(d16)> pb) {
    auto s1 = hn::Zero(di);
    auto s0 = hn::ReorderWidenMulAccumulate(di, pa, hn::BitCast(d16, wa), hn::Zero(di), s1);
    s0 = hn::ReorderWidenMulAccumulate(di, pb, hn::BitCast(d16, wb), s0, s1);
    return hn::ConvertTo(df, hn::RearrangeToOddPlusEven(s0, s1));
  };
  col[0] = dot(pick(lo_a, 0), pick(lo_b, 0));
  col[1] = dot(pick2(lo_a, hi_a, 1), pick2(lo_b, hi_b, 1));
  col[2] = dot(pick2(lo_a, hi_a, 3), pick2(lo_b, hi_b, 3));
}
#endif

// One vector of pixels (lanes) at raw x, y and depth v: the blend of the
// three lenses of their triangles, in the order of ScalarBlendRow below.
template <int kChannels, class DF>
HWY_INLINE void BlendVector(DF df, const TfBlendGeometry& g, const TfBlendSource& s,
                            const TypeTables* types, hn::Vec<DF> x, hn::Vec<DF> y,
                            hn::Vec<DF> v, hn::Vec<DF>* acc, hn::Vec<DF>* sw) {
  const hn::RebindToSigned<DF> di;
  const hn::RebindToUnsigned<DF> du;
  using VF = hn::Vec<DF>;
  const VF one = hn::Set(df, 1.0f), zero = hn::Zero(df);
  const VF lambda = hn::Set(df, g.lambda), cx = hn::Set(df, g.cx), cy = hn::Set(df, g.cy);
  const VF inv_v = hn::Div(one, v);
  const VF k = hn::Div(one, hn::Add(lambda, hn::Mul(v, hn::Set(df, 1.0f - g.lambda))));
  const VF qx = hn::Add(cx, hn::Mul(hn::Sub(x, cx), k));
  const VF qy = hn::Add(cy, hn::Mul(hn::Sub(y, cy), k));
  const VF tv = hn::Min(hn::Mul(v, hn::Set(df, static_cast<float>(g.type_per_unit))),
                        hn::Set(df, static_cast<float>(g.type_size - 1)));
  const auto t_index = TruncInRange(di, tv);
  hn::Vec<decltype(di)> t;
  if (g.type_runs > 0) {
    // The table's runs (TfBlendGeometry::type_runs): the same type.
    t = hn::Set(di, g.type_run_value[0]);
    for (int r = 1; r < g.type_runs; ++r)
      t = hn::IfThenElse(hn::Gt(t_index, hn::Set(di, g.type_run_start[r] - 1)),
                         hn::Set(di, g.type_run_value[r]), t);
  } else {
    t = hn::GatherIndex(di, g.type_of_v, t_index);
  }
  const auto is1 = hn::Eq(t, hn::Set(di, 1));
  const auto is2 = hn::Eq(t, hn::Set(di, 2));
  // Type 2, 1, or 0 for any other: where a vector holds the three, a
  // lookup in the row's table of the value (one permute instead of two
  // blends of two broadcasts).
  const auto type = hn::IfThenElseZero(hn::Or(is1, is2), t);
  auto select = [&](TypeTables::Field field, const float* per_type) {
    if constexpr (kTypeLookup<DF>) {
      (void)per_type;
      return hn::TableLookupLanes(hn::Load(df, types->v[field]), hn::IndicesFromVec(df, type));
    } else {
      return hn::IfThenElse(
          hn::RebindMask(df, is2), hn::Set(df, per_type[2]),
          hn::IfThenElse(hn::RebindMask(df, is1), hn::Set(df, per_type[1]), hn::Set(df, per_type[0])));
    }
  };
  const VF ox = select(TypeTables::kOx, g.ox), oy = select(TypeTables::kOy, g.oy);
  const VF dqx = hn::Sub(qx, ox), dqy = hn::Sub(qy, oy);
  const VF ax = hn::Add(hn::Mul(select(TypeTables::kFxx, g.fxx), dqx),
                        hn::Mul(select(TypeTables::kFxy, g.fxy), dqy));
  const VF ay = hn::Add(hn::Mul(select(TypeTables::kFyx, g.fyx), dqx),
                        hn::Mul(select(TypeTables::kFyy, g.fyy), dqy));
  const VF m = hn::Floor(ax), n = hn::Floor(ay);
  const VF fa = hn::Sub(ax, m), fb = hn::Sub(ay, n);
  const auto upper = hn::Ge(hn::Add(fa, fb), one);
  VF bary[3] = {
      hn::IfThenElse(upper, hn::Sub(one, fb), fa), hn::IfThenElse(upper, hn::Sub(one, fa), fb),
      hn::IfThenElse(upper, hn::Sub(hn::Add(fa, fb), one), hn::Sub(hn::Sub(one, fa), fb))};
  const VF sxa = hn::Set(df, g.sxa), sxb = hn::Set(df, g.sxb);
  const VF sya = hn::Set(df, g.sya), syb = hn::Set(df, g.syb);
  // The triangle's lens centres from that of lens (m, n): + A (1, 1) for
  // (m + 1, n), + A (2, -1) for (m, n + 1), + both for (m + 1, n + 1).
  const VF bx = hn::Add(hn::Add(ox, hn::Mul(sxa, m)), hn::Mul(sxb, n));
  const VF by = hn::Add(hn::Add(oy, hn::Mul(sya, m)), hn::Mul(syb, n));
  VF centre_x[3] = {hn::Add(bx, sxa), hn::Add(bx, sxb),
                    hn::IfThenElse(upper, hn::Add(bx, hn::Set(df, g.sxa + g.sxb)), bx)};
  VF centre_y[3] = {hn::Add(by, sya), hn::Add(by, syb),
                    hn::IfThenElse(upper, hn::Add(by, hn::Set(df, g.sya + g.syb)), by)};
  if (g.bary_floor > 0) {
    // Weights max(0, bary - floor), the lens of the smallest one moved to
    // the last slot (tf_blend_simd.h): skipped where no lane needs it.
    const VF floor_v = hn::Set(df, g.bary_floor);
    for (int c = 0; c < 3; ++c) bary[c] = hn::Max(hn::Sub(bary[c], floor_v), zero);
    for (int c = 0; c < 2; ++c) {
      const auto swap = hn::Lt(bary[c], bary[2]);
      const VF b = bary[c], ccx = centre_x[c], ccy = centre_y[c];
      bary[c] = hn::IfThenElse(swap, bary[2], b);
      bary[2] = hn::IfThenElse(swap, b, bary[2]);
      centre_x[c] = hn::IfThenElse(swap, centre_x[2], ccx);
      centre_x[2] = hn::IfThenElse(swap, ccx, centre_x[2]);
      centre_y[c] = hn::IfThenElse(swap, centre_y[2], ccy);
      centre_y[2] = hn::IfThenElse(swap, ccy, centre_y[2]);
    }
  }
  const VF r2 = hn::Set(df, g.r2), inv_r2 = hn::Set(df, 1.0f / g.r2);
  const VF wm1 = hn::Set(df, static_cast<float>(g.width - 1));
  const VF hm1 = hn::Set(df, static_cast<float>(g.height - 1));
  const auto width = hn::Set(di, g.width);
  const auto stride = hn::Set(di, static_cast<std::int32_t>(s.stride_bytes));
  const auto* words = reinterpret_cast<const std::uint32_t*>(s.raw);
  const auto byte = hn::Set(du, 0xFFu);
  // BGR with the 16-bit gain: the bilinear weights times the gain in 16-bit
  // fixed point and each colour's four products summed in integers
  // (FixedColours; the scalar reference the same integers).
  constexpr bool kFixed = kChannels == 3;
  const bool fixed = kFixed && s.gain16 != nullptr && g.width <= kFixedMaxWidth;
  const VF fixed_scale = hn::Set(df, 2.0f * s.gain16_scale * kFixedRescale);
  for (int c = 0; c < 3; ++c) {
    const VF ccx = centre_x[c], ccy = centre_y[c];
    const VF lx = hn::Add(cx, hn::Mul(hn::Sub(ccx, cx), lambda));
    const VF ly = hn::Add(cy, hn::Mul(hn::Sub(ccy, cy), lambda));
    const VF px = hn::Add(lx, hn::Mul(hn::Sub(x, lx), inv_v));
    const VF py = hn::Add(ly, hn::Mul(hn::Sub(y, ly), inv_v));
    const VF dx = hn::Sub(px, ccx), dy = hn::Sub(py, ccy);
    const VF d2 = hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy));
    auto valid = hn::And(hn::Gt(bary[c], zero), hn::Le(d2, r2));
    valid = hn::And(valid, hn::And(hn::Ge(px, zero), hn::Ge(py, zero)));
    valid = hn::And(valid, hn::And(hn::Lt(px, wm1), hn::Lt(py, hm1)));
    if (hn::AllFalse(df, valid)) continue;
    // Lanes off the frame read pixel (0, 0) and are dropped below.
    const VF pxs = hn::IfThenElseZero(valid, px), pys = hn::IfThenElseZero(valid, py);
    // BGR with the 16-bit gain (the TF image's case): the bilinear weights
    // in 16-bit fixed point (`fixed`), so the position in units of 2^-16 px
    // (exact: a product by a power of two; below 2^31 for px < 32767), its
    // pixel and its fraction.
    hn::Vec<decltype(di)> ix, iy, fxq = hn::Zero(di), fyq = hn::Zero(di);
    VF ffx = zero, ffy = zero;
    if (fixed) {
      const VF k16 = hn::Set(df, 65536.0f);
      const auto pxq = TruncInRange(di, hn::Mul(pxs, k16));
      const auto pyq = TruncInRange(di, hn::Mul(pys, k16));
      ix = hn::ShiftRight<16>(pxq);
      iy = hn::ShiftRight<16>(pyq);
      fxq = hn::And(pxq, hn::Set(di, 0xFFFF));
      fyq = hn::And(pyq, hn::Set(di, 0xFFFF));
    } else {
      ix = TruncInRange(di, pxs);
      iy = TruncInRange(di, pys);
      ffx = hn::Sub(pxs, hn::ConvertTo(df, ix));
      ffy = hn::Sub(pys, hn::ConvertTo(df, iy));
    }
    const auto at = hn::Add(hn::Mul(iy, width), ix);
    // Windows instead of gathers (AVX-512, BGR, the 16-bit gain): where
    // every lane is valid and lies in the window of lane 0's sample or of
    // the first lane's outside it (its row pair, x0 within [ix0 - 2, ix0 +
    // 16]: the lanes of one or two micro images; 83 % of the lens slots'
    // vectors of the r32 TF image, 38 % with one window), the gains and the
    // BGR bytes are picked out of one 64-byte load per row and window
    // (SampleWindow) instead of six gathers of 96 elements: the same
    // values. On this kind of CPU (AMD Zen 4) a gather costs by the element
    // wherever the data lies (docs/processing.md, "The lens samples from
    // windows of the rows").
    [[maybe_unused]] bool windowed = false;
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX3_DL
    WindowWords win;
    if constexpr (kChannels == 3) {
      if (s.gain16 != nullptr && hn::AllTrue(df, valid)) {
        const int ix_a = hn::GetLane(ix), iy_a = hn::GetLane(iy);
        const VU16 rel_a = hn::BitCast(du, hn::Add(hn::Sub(ix, hn::Set(di, ix_a)), hn::Set(di, 2)));
        const auto in_a = hn::And(hn::RebindMask(du, hn::Eq(iy, hn::Set(di, iy_a))),
                                  hn::Lt(rel_a, hn::Set(du, 19u)));
        SampleWindow wa, wb;
        if (hn::AllTrue(du, in_a)) {
          windowed = MakeWindow(g, s, ix_a, iy_a, &wa);
          if (windowed)
            win = ReadWindows<false>(g, s, wa, wa, rel_a,
                                     hn::Set(du, static_cast<std::uint32_t>(wa.odd)), hn::Zero(du));
        } else {
          // The first lane outside: compressed to lane 0 (in registers,
          // not through memory as a variable lane index would be).
          const auto out_a = hn::RebindMask(di, hn::Not(in_a));
          const int ix_b = hn::GetLane(hn::Compress(ix, out_a));
          const int iy_b = hn::GetLane(hn::Compress(iy, out_a));
          const VU16 rel_b =
              hn::BitCast(du, hn::Add(hn::Sub(ix, hn::Set(di, ix_b)), hn::Set(di, 2)));
          const auto in_b = hn::And(hn::RebindMask(du, hn::Eq(iy, hn::Set(di, iy_b))),
                                    hn::Lt(rel_b, hn::Set(du, 19u)));
          windowed = hn::AllTrue(du, hn::Or(in_a, in_b)) && MakeWindow(g, s, ix_a, iy_a, &wa) &&
                     MakeWindow(g, s, ix_b, iy_b, &wb);
          if (windowed) {
            // Each lane its window's rel, byte parity and table.
            const VU16 rel = hn::IfThenElse(in_a, rel_a, rel_b);
            const VU16 odd_in = hn::IfThenElse(in_a, hn::Set(du, static_cast<std::uint32_t>(wa.odd)),
                                               hn::Set(du, static_cast<std::uint32_t>(wb.odd)));
            const VU16 second = hn::IfThenZeroElse(in_a, hn::Set(du, 0x00200020u));
            win = ReadWindows<true>(g, s, wa, wb, rel, odd_in, second);
          }
        }
      }
    }
#endif
    VF g00, g01, g10, g11;
    // The fixed-point weights (FixedSums): per lane the words (w00, w01)
    // of raw row iy and (w10, w11) of iy + 1, signed 16-bit factors of the
    // products with the pixels' words.
    [[maybe_unused]] hn::Vec<decltype(du)> wa = hn::Zero(du), wb = hn::Zero(du);
    if (s.gain16 != nullptr) {
      // The 16-bit gains of x0 and x0 + 1 in one word (byte offset 2 at).
      // An invalid pixel (q = 0, gain NaN in the scalar reference, which
      // then drops the sample) drops the lane here: the colour is finite.
      const auto* gw = reinterpret_cast<const std::uint32_t*>(s.gain16);
      const auto two_at = hn::Add(at, at);
      hn::Vec<decltype(du)> q0, q1;
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX3_DL
      if (windowed) {
        q0 = win.q0;
        q1 = win.q1;
      } else
#endif
      {
        q0 = hn::GatherOffset(du, gw, two_at);
        q1 = hn::GatherOffset(du, gw, hn::Add(two_at, hn::Add(width, width)));
      }
      const auto half = hn::Set(du, 0xFFFFu);
      if constexpr (kFixed && HWY_TARGET != HWY_SCALAR) {
        // FixedSums' weights: the words (1 - f | f) in units of 1 / 32767,
        // q halved (signed 16 bits), rounded products by MulFixedPoint15.
        const hn::Repartition<std::uint16_t, DF> d16u;
        const hn::Repartition<std::int16_t, DF> d16;
        const auto k1 = hn::Set(di, kFixedOne);
        const auto fx = hn::ShiftRight<1>(fxq), fy = hn::ShiftRight<1>(fyq);
        const auto bx = hn::BitCast(d16, hn::Or(hn::Sub(k1, fx), hn::ShiftLeft<16>(fx)));
        const auto omy = hn::Sub(k1, fy);
        const auto by0 = hn::BitCast(d16, hn::Or(omy, hn::ShiftLeft<16>(omy)));
        const auto by1 = hn::BitCast(d16, hn::Or(fy, hn::ShiftLeft<16>(fy)));
        auto halved = [&](hn::Vec<decltype(du)> q) {
          return hn::BitCast(d16, hn::ShiftRight<1>(hn::BitCast(d16u, q)));
        };
        wa = hn::BitCast(du, hn::MulFixedPoint15(hn::MulFixedPoint15(halved(q0), bx), by0));
        wb = hn::BitCast(du, hn::MulFixedPoint15(hn::MulFixedPoint15(halved(q1), bx), by1));
        const auto m = hn::BitCast(du, hn::Min(hn::BitCast(d16u, q0), hn::BitCast(d16u, q1)));
        const auto low = hn::Min(hn::And(m, half), hn::ShiftRight<16>(m));
        valid = hn::AndNot(hn::RebindMask(df, hn::Eq(low, hn::Zero(du))), valid);
      } else {
        const VF scale = hn::Set(df, s.gain16_scale);
        const auto q00 = hn::And(q0, half), q01 = hn::ShiftRight<16>(q0);
        const auto q10 = hn::And(q1, half), q11 = hn::ShiftRight<16>(q1);
        auto gain_of = [&](hn::Vec<decltype(du)> q) {
          return hn::Mul(hn::ConvertTo(df, hn::BitCast(di, q)), scale);
        };
        g00 = gain_of(q00);
        g01 = gain_of(q01);
        g10 = gain_of(q10);
        g11 = gain_of(q11);
        const auto low = hn::Min(hn::Min(q00, q01), hn::Min(q10, q11));
        valid = hn::AndNot(hn::RebindMask(df, hn::Eq(low, hn::Zero(du))), valid);
      }
    } else {
      g00 = hn::GatherIndex(df, s.gain, at);
      g01 = hn::GatherIndex(df, s.gain, hn::Add(at, hn::Set(di, 1)));
      g10 = hn::GatherIndex(df, s.gain, hn::Add(at, width));
      g11 = hn::GatherIndex(df, s.gain, hn::Add(hn::Add(at, width), hn::Set(di, 1)));
    }
    VF w00 = zero, w01 = zero, w10 = zero, w11 = zero;
    if (!fixed) {
      const VF omx = hn::Sub(one, ffx), omy = hn::Sub(one, ffy);
      w00 = hn::Mul(hn::Mul(omx, omy), g00);
      w01 = hn::Mul(hn::Mul(ffx, omy), g01);
      w10 = hn::Mul(hn::Mul(omx, ffy), g10);
      w11 = hn::Mul(hn::Mul(ffx, ffy), g11);
    }
    VF col[kChannels];
    auto to_f = [&](hn::Vec<decltype(du)> u) { return hn::ConvertTo(df, hn::BitCast(di, u)); };
    auto mix = [&](VF q00, VF q01, VF q10, VF q11) {
      return hn::Add(hn::Add(hn::Add(hn::Mul(w00, q00), hn::Mul(w01, q01)), hn::Mul(w10, q10)),
                     hn::Mul(w11, q11));
    };
    if constexpr (kChannels == 3) {
#if HWY_TARGET != HWY_SCALAR
      // BGR: one 64-bit word per raw row holds both pixels, B G R of x0 and
      // of x0 + 1: the word at 3 x0 - 2 shifted down by two bytes (x0 >= 1),
      // or the word at 3 x0 (x0 = 0, a row of width >= 8); neither reads
      // outside its row. Gathered a half vector at a time (64-bit offsets),
      // then split into the words' low and high 32 bits (ConcatEven /
      // ConcatOdd keep the lanes' order): B0 G0 R0 B1 | G1 R1 - -.
      const hn::Repartition<std::uint64_t, DF> du64;
      const hn::Repartition<std::int64_t, DF> di64;
      const hn::Half<decltype(di)> dh;
      const auto inner = hn::Gt(ix, hn::Zero(di));
      const auto off0 = hn::Add(hn::Mul(iy, stride),
                                hn::Sub(hn::Mul(ix, hn::Set(di, 3)),
                                        hn::IfThenElseZero(inner, hn::Set(di, 2))));
      const auto shift32 = hn::IfThenElseZero(inner, hn::Set(di, 16));
      const auto shift_lo = hn::BitCast(du64, hn::PromoteTo(di64, hn::LowerHalf(dh, shift32)));
      const auto shift_hi = hn::BitCast(du64, hn::PromoteTo(di64, hn::UpperHalf(dh, shift32)));
      const auto* row_words = reinterpret_cast<const std::uint64_t*>(s.raw);
      auto load_row = [&](hn::Vec<decltype(di)> off, hn::Vec<decltype(du)>* lo,
                          hn::Vec<decltype(du)>* hi) {
        const auto w_lo =
            hn::GatherOffset(du64, row_words, hn::PromoteTo(di64, hn::LowerHalf(dh, off))) >>
            shift_lo;
        const auto w_hi =
            hn::GatherOffset(du64, row_words, hn::PromoteTo(di64, hn::UpperHalf(dh, off))) >>
            shift_hi;
        *lo = hn::ConcatEven(du, hn::BitCast(du, w_hi), hn::BitCast(du, w_lo));
        *hi = hn::ConcatOdd(du, hn::BitCast(du, w_hi), hn::BitCast(du, w_lo));
      };
      hn::Vec<decltype(du)> a_lo, a_hi, b_lo, b_hi;
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX3_DL
      if (windowed) {
        a_lo = win.a_lo;
        a_hi = win.a_hi;
        b_lo = win.b_lo;
        b_hi = win.b_hi;
      } else
#endif
      {
        load_row(off0, &a_lo, &a_hi);
        load_row(hn::Add(off0, stride), &b_lo, &b_hi);
      }
      if (fixed) {
        FixedColours(df, a_lo, a_hi, b_lo, b_hi, wa, wb, col);
      } else {
        col[0] = mix(to_f(hn::And(a_lo, byte)), to_f(hn::ShiftRight<24>(a_lo)),
                     to_f(hn::And(b_lo, byte)), to_f(hn::ShiftRight<24>(b_lo)));
        col[1] = mix(to_f(hn::And(hn::ShiftRight<8>(a_lo), byte)), to_f(hn::And(a_hi, byte)),
                     to_f(hn::And(hn::ShiftRight<8>(b_lo), byte)), to_f(hn::And(b_hi, byte)));
        col[2] = mix(to_f(hn::And(hn::ShiftRight<16>(a_lo), byte)),
                     to_f(hn::And(hn::ShiftRight<8>(a_hi), byte)),
                     to_f(hn::And(hn::ShiftRight<16>(b_lo), byte)),
                     to_f(hn::And(hn::ShiftRight<8>(b_hi), byte)));
      }
#else
      // BGR: the word at 3 x0 holds B G R of x0 in its low three bytes, the
      // word at 3 x0 + 2 those of x0 + 1 in its high three; neither reads
      // past pixel x0 + 1 of its row.
      const auto off0 = hn::Add(hn::Mul(iy, stride), hn::Mul(ix, hn::Set(di, 3)));
      const auto off1 = hn::Add(off0, stride);
      const auto two = hn::Set(di, 2);
      const auto a0 = hn::GatherOffset(du, words, off0);
      const auto a1 = hn::GatherOffset(du, words, hn::Add(off0, two));
      const auto b0 = hn::GatherOffset(du, words, off1);
      const auto b1 = hn::GatherOffset(du, words, hn::Add(off1, two));
      if (fixed) {
        // One lane: FixedSums itself.
        std::int32_t sums[3] = {0, 0, 0};
        if (hn::AllTrue(df, valid) &&
            !FixedSums(s, g.width, hn::GetLane(hn::Add(hn::ShiftLeft<16>(ix), fxq)),
                       hn::GetLane(hn::Add(hn::ShiftLeft<16>(iy), fyq)), sums))
          valid = hn::And(valid, hn::Lt(one, zero));
        for (int ch = 0; ch < 3; ++ch) col[ch] = hn::Set(df, static_cast<float>(sums[ch]));
      } else {
        col[0] = mix(to_f(hn::And(a0, byte)), to_f(hn::And(hn::ShiftRight<8>(a1), byte)),
                     to_f(hn::And(b0, byte)), to_f(hn::And(hn::ShiftRight<8>(b1), byte)));
        col[1] = mix(to_f(hn::And(hn::ShiftRight<8>(a0), byte)),
                     to_f(hn::And(hn::ShiftRight<16>(a1), byte)),
                     to_f(hn::And(hn::ShiftRight<8>(b0), byte)),
                     to_f(hn::And(hn::ShiftRight<16>(b1), byte)));
        col[2] = mix(to_f(hn::And(hn::ShiftRight<16>(a0), byte)), to_f(hn::ShiftRight<24>(a1)),
                     to_f(hn::And(hn::ShiftRight<16>(b0), byte)), to_f(hn::ShiftRight<24>(b1)));
      }
#endif
    } else {
      // Mono8: the word at x0 - 2 holds x0 and x0 + 1 in its high two bytes
      // and reads nothing past x0 + 1 (x0 >= 2; below, the word at x0, its
      // low two bytes, inside a row of width >= 8).
      const auto shifted = hn::Gt(ix, hn::Set(di, 1));
      const auto o = hn::IfThenElse(shifted, hn::Sub(ix, hn::Set(di, 2)), ix);
      const auto off0 = hn::Add(hn::Mul(iy, stride), o);
      const auto a = hn::GatherOffset(du, words, off0);
      const auto b = hn::GatherOffset(du, words, hn::Add(off0, stride));
      const auto hi = hn::RebindMask(du, shifted);
      auto first = [&](hn::Vec<decltype(du)> w) {
        return to_f(hn::IfThenElse(hi, hn::And(hn::ShiftRight<16>(w), byte), hn::And(w, byte)));
      };
      auto second = [&](hn::Vec<decltype(du)> w) {
        return to_f(
            hn::IfThenElse(hi, hn::ShiftRight<24>(w), hn::And(hn::ShiftRight<8>(w), byte)));
      };
      col[0] = mix(first(a), second(a), first(b), second(b));
    }
    if (s.gain16 == nullptr) {
      // A NaN gain (an invalid pixel) drops the sample.
      VF check = col[0];
      for (int ch = 1; ch < kChannels; ++ch) check = hn::Add(check, col[ch]);
      valid = hn::AndNot(hn::IsNaN(check), valid);
    }
    const VF wq = hn::Mul(bary[c], hn::Sub(one, hn::Mul(d2, inv_r2)));
    // The fixed-point colours are q / 2 kFixedRescale^-1 times the float ones.
    const VF wc = fixed ? hn::Mul(wq, fixed_scale) : wq;
    for (int ch = 0; ch < kChannels; ++ch)
      acc[ch] = hn::Add(acc[ch], hn::IfThenElseZero(valid, hn::Mul(wc, col[ch])));
    *sw = hn::Add(*sw, hn::IfThenElseZero(valid, wq));
  }
}

template <int kChannels>
void BlendRowT(const TfBlendGeometry& g, const TfBlendSource& s, float x0, float dx, float y,
               const float* v, int n, float* acc, float* sw) {
  const hn::ScalableTag<float> df;
  using VF = hn::Vec<decltype(df)>;
  const int lanes = static_cast<int>(hn::Lanes(df));
  const VF vy = hn::Set(df, y), vx0 = hn::Set(df, x0), step = hn::Set(df, dx);
  const TypeTables types(g);
  auto run = [&](int i, const float* vin, float* const* out_acc, float* out_sw) {
    VF a[kChannels];
    for (int ch = 0; ch < kChannels; ++ch) a[ch] = hn::Zero(df);
    VF w = hn::Zero(df);
    const VF x = hn::Add(vx0, hn::Mul(step, hn::Iota(df, static_cast<float>(i))));
    BlendVector<kChannels>(df, g, s, &types, x, vy, hn::LoadU(df, vin), a, &w);
    for (int ch = 0; ch < kChannels; ++ch) hn::StoreU(a[ch], df, out_acc[ch]);
    hn::StoreU(w, df, out_sw);
  };
  int i = 0;
  for (; i + lanes <= n; i += lanes) {
    float* out_acc[kChannels];
    for (int ch = 0; ch < kChannels; ++ch) out_acc[ch] = acc + static_cast<std::size_t>(ch) * n + i;
    run(i, v + i, out_acc, sw + i);
  }
  if (i < n) {
    // The tail through a full vector: depths padded with the last one,
    // results of the padding dropped.
    constexpr int kMax = HWY_MAX_BYTES / sizeof(float);
    HWY_ALIGN float vin[kMax], a_buf[kChannels][kMax], w_buf[kMax];
    for (int q = 0; q < lanes; ++q) vin[q] = v[std::min(i + q, n - 1)];
    float* out_acc[kChannels];
    for (int ch = 0; ch < kChannels; ++ch) out_acc[ch] = a_buf[ch];
    run(i, vin, out_acc, w_buf);
    for (int q = 0; i + q < n; ++q) {
      for (int ch = 0; ch < kChannels; ++ch)
        acc[static_cast<std::size_t>(ch) * n + i + q] = a_buf[ch][q];
      sw[i + q] = w_buf[q];
    }
  }
}

void BlendRow(const TfBlendGeometry& g, const TfBlendSource& s, float x0, float dx, float y,
              const float* v, int n, float* acc, float* sw) {
  if (s.channels == 3)
    BlendRowT<3>(g, s, x0, dx, y, v, n, acc, sw);
  else
    BlendRowT<1>(g, s, x0, dx, y, v, n, acc, sw);
}

// A vector of pixels at a time, the tail as the scalar reference (below).
template <int kChannels>
void BytesT(const float* acc, const float* sw, int n, float gain, std::uint8_t* out) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const hn::Rebind<std::uint8_t, decltype(df)> d8;
  using VF = hn::Vec<decltype(df)>;
  const int lanes = static_cast<int>(hn::Lanes(df));
  const VF zero = hn::Zero(df), half = hn::Set(df, 0.5f), top = hn::Set(df, 255.0f);
  const VF vgain = hn::Set(df, gain);
  int i = 0;
  for (; i + lanes <= n; i += lanes) {
    const VF w = hn::LoadU(df, sw + i);
    const VF scale = hn::IfThenElseZero(hn::Gt(w, zero), hn::Div(vgain, w));
    hn::Vec<decltype(d8)> b[kChannels];
    for (int ch = 0; ch < kChannels; ++ch) {
      const VF a = hn::LoadU(df, acc + static_cast<std::size_t>(ch) * n + i);
      const VF x = hn::Min(hn::Max(hn::Add(hn::Mul(a, scale), half), zero), top);
      b[ch] = hn::DemoteTo(d8, hn::ConvertTo(di, x));
    }
    if constexpr (kChannels == 3)
      hn::StoreInterleaved3(b[0], b[1], b[2], d8, out + 3 * static_cast<std::size_t>(i));
    else
      hn::StoreU(b[0], d8, out + i);
  }
  for (; i < n; ++i) {
    const float scale = sw[i] > 0 ? gain / sw[i] : 0.0f;
    for (int ch = 0; ch < kChannels; ++ch) {
      const float x = acc[static_cast<std::size_t>(ch) * n + i] * scale + 0.5f;
      out[static_cast<std::size_t>(i) * kChannels + ch] =
          static_cast<std::uint8_t>(static_cast<int>(std::min(std::max(x, 0.0f), 255.0f)));
    }
  }
}

void Bytes(const float* acc, const float* sw, int n, int channels, float gain, std::uint8_t* out) {
  if (channels == 3)
    BytesT<3>(acc, sw, n, gain, out);
  else
    BytesT<1>(acc, sw, n, gain, out);
}

}  // namespace HWY_NAMESPACE
}  // namespace lifmcr::processing::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lifmcr::processing::detail {

HWY_EXPORT(BlendRow);
HWY_EXPORT(Bytes);

namespace {

template <int kChannels>
void ScalarBlendRowT(const TfBlendGeometry& g, const TfBlendSource& s, float x0, float dx, float y,
                     const float* v, int n, float* acc, float* sw) {
  const float wm1 = static_cast<float>(g.width - 1), hm1 = static_cast<float>(g.height - 1);
  const float type_max = static_cast<float>(g.type_size - 1);
  const float inv_r2 = 1.0f / g.r2;
  for (int i = 0; i < n; ++i) {
    const float x = x0 + dx * static_cast<float>(i);
    const float vi = v[i];
    const float inv_v = 1.0f / vi;
    const float k = 1.0f / (g.lambda + vi * (1.0f - g.lambda));
    const float qx = g.cx + (x - g.cx) * k, qy = g.cy + (y - g.cy) * k;
    const int t =
        g.type_of_v[static_cast<int>(std::min(vi * static_cast<float>(g.type_per_unit), type_max))];
    const float dqx = qx - g.ox[t], dqy = qy - g.oy[t];
    const float ax = g.fxx[t] * dqx + g.fxy[t] * dqy;
    const float ay = g.fyx[t] * dqx + g.fyy[t] * dqy;
    const float m = std::floor(ax), nn = std::floor(ay);
    const float fa = ax - m, fb = ay - nn;
    const bool upper = fa + fb >= 1.0f;
    const float bx = (g.ox[t] + g.sxa * m) + g.sxb * nn;
    const float by = (g.oy[t] + g.sya * m) + g.syb * nn;
    float centre_x[3] = {bx + g.sxa, bx + g.sxb, upper ? bx + (g.sxa + g.sxb) : bx};
    float centre_y[3] = {by + g.sya, by + g.syb, upper ? by + (g.sya + g.syb) : by};
    float bary[3] = {upper ? 1.0f - fb : fa, upper ? 1.0f - fa : fb,
                     upper ? (fa + fb) - 1.0f : (1.0f - fa) - fb};
    if (g.bary_floor > 0) {
      for (int c = 0; c < 3; ++c) bary[c] = std::max(bary[c] - g.bary_floor, 0.0f);
      for (int c = 0; c < 2; ++c)
        if (bary[c] < bary[2]) {
          std::swap(bary[c], bary[2]);
          std::swap(centre_x[c], centre_x[2]);
          std::swap(centre_y[c], centre_y[2]);
        }
    }
    float a[kChannels] = {};
    float w = 0;
    for (int c = 0; c < 3; ++c) {
      const float ccx = centre_x[c], ccy = centre_y[c];
      const float lx = g.cx + (ccx - g.cx) * g.lambda, ly = g.cy + (ccy - g.cy) * g.lambda;
      const float px = lx + (x - lx) * inv_v, py = ly + (y - ly) * inv_v;
      const float dx = px - ccx, dy = py - ccy;
      const float d2 = dx * dx + dy * dy;
      if (!(bary[c] > 0 && d2 <= g.r2 && px >= 0 && py >= 0 && px < wm1 && py < hm1)) continue;
      const float wq = bary[c] * (1.0f - d2 * inv_r2);
      if (kChannels == 3 && s.gain16 != nullptr && g.width <= kFixedMaxWidth) {
        // BGR with the 16-bit gain: the weights in 16-bit fixed point, the
        // products in integers (FixedSums, the Highway kernel's rule).
        std::int32_t sums[3];
        if (!FixedSums(s, g.width, static_cast<std::int32_t>(px * 65536.0f),
                       static_cast<std::int32_t>(py * 65536.0f), sums))
          continue;
        const float wc = wq * (2.0f * s.gain16_scale * kFixedRescale);
        for (int ch = 0; ch < kChannels; ++ch) a[ch] = a[ch] + wc * static_cast<float>(sums[ch]);
        w = w + wq;
        continue;
      }
      const int ix = static_cast<int>(px), iy = static_cast<int>(py);
      const float ffx = px - static_cast<float>(ix), ffy = py - static_cast<float>(iy);
      const std::size_t at = static_cast<std::size_t>(iy) * g.width + ix;
      float g00, g01, g10, g11;
      if (s.gain16 != nullptr) {
        auto gain_of = [&](std::size_t q) {
          return s.gain16[q] == 0 ? std::numeric_limits<float>::quiet_NaN()
                                  : static_cast<float>(s.gain16[q]) * s.gain16_scale;
        };
        g00 = gain_of(at), g01 = gain_of(at + 1);
        g10 = gain_of(at + g.width), g11 = gain_of(at + g.width + 1);
      } else {
        const float* g0 = s.gain + at;
        const float* g1 = g0 + g.width;
        g00 = g0[0], g01 = g0[1], g10 = g1[0], g11 = g1[1];
      }
      const float omx = 1.0f - ffx, omy = 1.0f - ffy;
      const float w00 = (omx * omy) * g00, w01 = (ffx * omy) * g01;
      const float w10 = (omx * ffy) * g10, w11 = (ffx * ffy) * g11;
      const std::uint8_t* r0 = s.raw + static_cast<std::size_t>(iy) * s.stride_bytes +
                               static_cast<std::size_t>(ix) * kChannels;
      const std::uint8_t* r1 = r0 + s.stride_bytes;
      float col[kChannels];
      for (int ch = 0; ch < kChannels; ++ch)
        col[ch] = ((w00 * static_cast<float>(r0[ch]) + w01 * static_cast<float>(r0[kChannels + ch])) +
                   w10 * static_cast<float>(r1[ch])) +
                  w11 * static_cast<float>(r1[kChannels + ch]);
      float check = col[0];
      for (int ch = 1; ch < kChannels; ++ch) check = check + col[ch];
      if (std::isnan(check)) continue;
      for (int ch = 0; ch < kChannels; ++ch) a[ch] = a[ch] + wq * col[ch];
      w = w + wq;
    }
    for (int ch = 0; ch < kChannels; ++ch) acc[static_cast<std::size_t>(ch) * n + i] = a[ch];
    sw[i] = w;
  }
}

void ScalarBlendRow(const TfBlendGeometry& g, const TfBlendSource& s, float x0, float dx, float y,
                    const float* v, int n, float* acc, float* sw) {
  if (s.channels == 3)
    ScalarBlendRowT<3>(g, s, x0, dx, y, v, n, acc, sw);
  else
    ScalarBlendRowT<1>(g, s, x0, dx, y, v, n, acc, sw);
}

template <int kChannels>
void ScalarBytesT(const float* acc, const float* sw, int n, float gain, std::uint8_t* out) {
  for (int i = 0; i < n; ++i) {
    const float scale = sw[i] > 0 ? gain / sw[i] : 0.0f;
    for (int ch = 0; ch < kChannels; ++ch) {
      const float x = acc[static_cast<std::size_t>(ch) * n + i] * scale + 0.5f;
      out[static_cast<std::size_t>(i) * kChannels + ch] =
          static_cast<std::uint8_t>(static_cast<int>(std::min(std::max(x, 0.0f), 255.0f)));
    }
  }
}

void ScalarBytes(const float* acc, const float* sw, int n, int channels, float gain,
                 std::uint8_t* out) {
  if (channels == 3)
    ScalarBytesT<3>(acc, sw, n, gain, out);
  else
    ScalarBytesT<1>(acc, sw, n, gain, out);
}

void DispatchedBytes(const float* acc, const float* sw, int n, int channels, float gain,
                     std::uint8_t* out) {
  HWY_DYNAMIC_DISPATCH(Bytes)(acc, sw, n, channels, gain, out);
}

void DispatchedBlendRow(const TfBlendGeometry& g, const TfBlendSource& s, float x0, float dx,
                        float y, const float* v, int n, float* acc, float* sw) {
  HWY_DYNAMIC_DISPATCH(BlendRow)(g, s, x0, dx, y, v, n, acc, sw);
}

}  // namespace

const TfBlendKernels& ScalarTfBlendKernels() {
  static const TfBlendKernels kernels{ScalarBlendRow, "scalar", ScalarBytes};
  return kernels;
}

const TfBlendKernels& SimdTfBlendKernels() {
  // The target this CPU runs (hwy/targets.h): the best one compiled in.
  static const TfBlendKernels kernels{DispatchedBlendRow,
                                      hwy::TargetName(hwy::SupportedAndGeneratedTargets()[0]),
                                      DispatchedBytes};
  return kernels;
}

}  // namespace lifmcr::processing::detail
#endif  // HWY_ONCE
