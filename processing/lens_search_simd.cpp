// The per-lens search's kernels (lens_search_simd.h): the scalar reference
// and Highway's, compiled once per target by foreach_target.h.

// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "processing/lens_search_simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
// foreach_target.h first (it includes this file again once per target),
// then highway.h.
#include <hwy/highway.h>
// clang-format on

#include "processing/lens_search_simd.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

HWY_BEFORE_NAMESPACE();
namespace lifmcr::processing::detail {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// The raw pixels' channel sums at (x0, y0 + row) and (x0 + 1, y0 + row) of
// each lane, from 32-bit loads at byte offsets (unaligned). BGR: the word
// at 3 x0 holds B G R of x0 in its low three bytes, the word at 3 x0 + 2
// those of x0 + 1 in its high three; neither reads past pixel x0 + 1. Mono8:
// the word at x0 holds x0 and x0 + 1 in its low two bytes and reads up to
// x0 + 3, which may be the next row's first bytes: lens_search_simd.h's
// precondition (x0 <= width - 3, a row below y0 + 1) keeps every load in
// the frame.
template <int kChannels, class DU, class VI>
HWY_INLINE void ChannelSums(DU du, const std::uint32_t* base, VI offset, hn::Vec<DU>* s0,
                            hn::Vec<DU>* s1) {
  const auto mask = hn::Set(du, 0xFFu);
  const auto w0 = hn::GatherOffset(du, base, offset);
  if constexpr (kChannels == 3) {
    const auto w1 =
        hn::GatherOffset(du, base, hn::Add(offset, hn::Set(hn::RebindToSigned<DU>(), 2)));
    *s0 = hn::Add(hn::Add(hn::And(w0, mask), hn::And(hn::ShiftRight<8>(w0), mask)),
                  hn::And(hn::ShiftRight<16>(w0), mask));
    *s1 = hn::Add(
        hn::Add(hn::And(hn::ShiftRight<8>(w1), mask), hn::And(hn::ShiftRight<16>(w1), mask)),
        hn::ShiftRight<24>(w1));
  } else {
    *s0 = hn::And(w0, mask);
    *s1 = hn::And(hn::ShiftRight<8>(w0), mask);
  }
}

// The grey level of the raw pixels times the gain at (x, y) of each lane
// (x, y >= 0: truncation is floor), NaN where a corner's gain is invalid:
// RawGainBilinear's expression (lens_search_simd.h).
template <int kChannels, class VF>
HWY_INLINE VF RawBilinear(const StripSource& src, VF x, VF y) {
  const hn::DFromV<VF> df;
  const hn::RebindToSigned<decltype(df)> di;
  const hn::RebindToUnsigned<decltype(df)> du;
  const auto nan = hn::Set(df, std::numeric_limits<float>::quiet_NaN());
  const auto one = hn::Set(df, 1.0f), inv = hn::Set(df, 1.0f / kChannels);
  const auto stride = hn::Set(di, static_cast<std::int32_t>(src.stride_bytes));
  // Byte offsets into the 16-bit gain: 2 (y0 width + x0); a row 2 width on.
  const auto gain_row = hn::Set(di, 2 * src.width);
  const auto scale = hn::Set(df, src.gain_scale);
  const auto low16 = hn::Set(du, 0xFFFFu);
  const auto zero = hn::Zero(di);
  const auto* base = reinterpret_cast<const std::uint32_t*>(src.raw);
  const auto* gain_base = reinterpret_cast<const std::uint32_t*>(src.gain);
  const auto x0 = hn::ConvertTo(di, x);  // truncation: x, y >= 0
  const auto y0 = hn::ConvertTo(di, y);
  const auto fx = hn::Sub(x, hn::ConvertTo(df, x0));
  const auto fy = hn::Sub(y, hn::ConvertTo(df, y0));
  const auto row0 = hn::Mul(y0, stride);
  const auto col = kChannels == 3 ? hn::Add(hn::Add(x0, x0), x0) : x0;
  hn::Vec<decltype(du)> s00, s01, s10, s11;
  ChannelSums<kChannels>(du, base, hn::Add(row0, col), &s00, &s01);
  ChannelSums<kChannels>(du, base, hn::Add(hn::Add(row0, stride), col), &s10, &s11);
  // One 32-bit word per row holds the gains of x0 (low half) and x0 + 1.
  const auto g = hn::Mul(hn::Add(hn::Mul(y0, hn::Set(di, src.width)), x0), hn::Set(di, 2));
  const auto w0 = hn::BitCast(di, hn::GatherOffset(du, gain_base, g));
  const auto w1 = hn::BitCast(di, hn::GatherOffset(du, gain_base, hn::Add(g, gain_row)));
  const auto q00 = hn::BitCast(di, hn::And(hn::BitCast(du, w0), low16));
  const auto q01 = hn::BitCast(di, hn::ShiftRight<16>(hn::BitCast(du, w0)));
  const auto q10 = hn::BitCast(di, hn::And(hn::BitCast(du, w1), low16));
  const auto q11 = hn::BitCast(di, hn::ShiftRight<16>(hn::BitCast(du, w1)));
  const auto invalid = hn::Eq(hn::Min(hn::Min(q00, q01), hn::Min(q10, q11)), zero);
  const auto a = hn::Mul(hn::ConvertTo(df, hn::BitCast(di, s00)),
                         hn::Mul(hn::ConvertTo(df, q00), scale));
  const auto b = hn::Mul(hn::ConvertTo(df, hn::BitCast(di, s01)),
                         hn::Mul(hn::ConvertTo(df, q01), scale));
  const auto c = hn::Mul(hn::ConvertTo(df, hn::BitCast(di, s10)),
                         hn::Mul(hn::ConvertTo(df, q10), scale));
  const auto d = hn::Mul(hn::ConvertTo(df, hn::BitCast(di, s11)),
                         hn::Mul(hn::ConvertTo(df, q11), scale));
  const auto top = hn::Add(a, hn::Mul(hn::Sub(b, a), fx));
  const auto bottom = hn::Add(c, hn::Mul(hn::Sub(d, c), fx));
  const auto v = hn::Mul(hn::Add(hn::Mul(top, hn::Sub(one, fy)), hn::Mul(bottom, fy)), inv);
  return hn::IfThenElse(hn::RebindMask(df, invalid), nan, v);
}

template <int kChannels>
void SampleLine(const StripSource& src, const StripLine& l, float* out) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const int lanes = static_cast<int>(hn::Lanes(df));
  const auto nan = hn::Set(df, std::numeric_limits<float>::quiet_NaN());
  const auto px = hn::Set(df, l.px), py = hn::Set(df, l.py);
  const auto ex = hn::Set(df, l.e_x), ey = hn::Set(df, l.e_y);
  const auto bey = hn::Set(df, l.b_ey), bex = hn::Set(df, l.b_ex);
  const auto along0 = hn::Set(df, l.along0), step = hn::Set(df, l.step);
  const auto j_lo = hn::Set(di, l.j_lo), j_hi = hn::Set(di, l.j_hi);
  // Highway 1.0.3 compares signed integers with Lt / Gt only.
  const auto below_lo = hn::Set(di, l.j_lo - 1), above_hi = hn::Set(di, l.j_hi + 1);
  for (int i = 0; i < l.n; i += lanes) {
    const auto j = hn::Sub(hn::Set(di, l.n - 1 - i), hn::Iota(di, 0));
    const auto valid = hn::And(hn::Gt(j, below_lo), hn::Lt(j, above_hi));
    if (hn::AllFalse(di, valid)) {
      hn::StoreU(nan, df, out + i);
      continue;
    }
    // Lanes outside [j_lo, j_hi] read at a valid position and are discarded.
    const auto jc = hn::Min(hn::Max(j, j_lo), j_hi);
    const auto t = hn::Add(along0, hn::Mul(hn::ConvertTo(df, jc), step));
    const auto x = hn::Sub(hn::Add(px, hn::Mul(t, ex)), bey);
    const auto y = hn::Add(hn::Add(py, hn::Mul(t, ey)), bex);
    const auto v = RawBilinear<kChannels>(src, x, y);
    hn::StoreU(hn::IfThenElse(hn::RebindMask(df, valid), v, nan), df, out + i);
  }
}

// The grey pixels at index g and g + 1 of each lane (left, right): the two
// floats of a pair are adjacent, so each is one 64-bit gather lane (two
// gathers of half as many lanes instead of two of a float each: the gathers
// were four fifths of this kernel's time, and their cost grows with the
// lanes gathered). The same values as two float gathers.
template <class DF, class VI>
HWY_INLINE void GreyPairs(DF df, const float* grey, VI g, hn::Vec<DF>* left,
                          hn::Vec<DF>* right) {
#if HWY_TARGET == HWY_SCALAR
  // One lane: no pairs to split.
  *left = hn::GatherIndex(df, grey, g);
  *right = hn::GatherIndex(df, grey, hn::Add(g, hn::Set(hn::DFromV<VI>(), 1)));
#else
  const hn::Repartition<double, DF> dd;  // half the lanes, 64 bits each
  const hn::Rebind<std::int64_t, decltype(dd)> d64;
  const hn::Half<hn::DFromV<VI>> dh;
  const double* const base = reinterpret_cast<const double*>(grey);
  const auto lo = hn::BitCast(
      df, hn::GatherOffset(dd, base, hn::ShiftLeft<2>(hn::PromoteTo(d64, hn::LowerHalf(dh, g)))));
  const auto hi = hn::BitCast(
      df, hn::GatherOffset(dd, base, hn::ShiftLeft<2>(hn::PromoteTo(d64, hn::UpperHalf(dh, g)))));
  *left = hn::ConcatEven(df, hi, lo);
  *right = hn::ConcatOdd(df, hi, lo);
#endif
}

// A strip line of the float grey image: the pairs of its two rows
// (GreyPairs), the expression of GreyImageBilinear.
void SampleGreyLine(const StripSource& src, const StripLine& l, float* out) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const int lanes = static_cast<int>(hn::Lanes(df));
  const auto nan = hn::Set(df, std::numeric_limits<float>::quiet_NaN());
  const auto px = hn::Set(df, l.px), py = hn::Set(df, l.py);
  const auto ex = hn::Set(df, l.e_x), ey = hn::Set(df, l.e_y);
  const auto bey = hn::Set(df, l.b_ey), bex = hn::Set(df, l.b_ex);
  const auto along0 = hn::Set(df, l.along0), step = hn::Set(df, l.step);
  const auto one = hn::Set(df, 1.0f);
  const auto j_lo = hn::Set(di, l.j_lo), j_hi = hn::Set(di, l.j_hi);
  const auto below_lo = hn::Set(di, l.j_lo - 1), above_hi = hn::Set(di, l.j_hi + 1);
  const auto width = hn::Set(di, src.width);
  for (int i = 0; i < l.n; i += lanes) {
    const auto j = hn::Sub(hn::Set(di, l.n - 1 - i), hn::Iota(di, 0));
    const auto valid = hn::And(hn::Gt(j, below_lo), hn::Lt(j, above_hi));
    if (hn::AllFalse(di, valid)) {
      hn::StoreU(nan, df, out + i);
      continue;
    }
    const auto jc = hn::Min(hn::Max(j, j_lo), j_hi);
    const auto t = hn::Add(along0, hn::Mul(hn::ConvertTo(df, jc), step));
    const auto x = hn::Sub(hn::Add(px, hn::Mul(t, ex)), bey);
    const auto y = hn::Add(hn::Add(py, hn::Mul(t, ey)), bex);
    const auto x0 = hn::ConvertTo(di, x);  // truncation: x, y >= 0
    const auto y0 = hn::ConvertTo(di, y);
    const auto fx = hn::Sub(x, hn::ConvertTo(df, x0));
    const auto fy = hn::Sub(y, hn::ConvertTo(df, y0));
    const auto g = hn::Add(hn::Mul(y0, width), x0);
    hn::Vec<decltype(df)> a, b, c, d;
    GreyPairs(df, src.grey, g, &a, &b);
    GreyPairs(df, src.grey, hn::Add(g, width), &c, &d);
    const auto top = hn::Add(a, hn::Mul(hn::Sub(b, a), fx));
    const auto bottom = hn::Add(c, hn::Mul(hn::Sub(d, c), fx));
    const auto v = hn::Add(hn::Mul(top, hn::Sub(one, fy)), hn::Mul(bottom, fy));
    hn::StoreU(hn::IfThenElse(hn::RebindMask(df, valid), v, nan), df, out + i);
  }
}

void SampleStripLine(const StripSource& source, const StripLine& line, float* out) {
  if (source.grey != nullptr)
    SampleGreyLine(source, line, out);
  else if (source.channels == 3)
    SampleLine<3>(source, line, out);
  else
    SampleLine<1>(source, line, out);
}

// Lane l of a patch: column a = l mod 5 - 2 and line b = l / 5 - lines / 2
// (lens_search_simd.h, SamplePatchFn); lanes past the patch repeat its last
// sample (read in the frame, stored in the padding).
struct PatchLanes {
  float a[16 + kStripPad], b[2][16 + kStripPad];
  PatchLanes() {
    for (int l = 0; l < 16 + kStripPad; ++l) {
      a[l] = static_cast<float>(std::min(l, 14) % 5 - 2);
      b[0][l] = 0;
      b[1][l] = static_cast<float>(std::min(l, 14) / 5 - 1);
    }
  }
};

template <int kChannels>
void Patch(const StripSource& src, float px, float py, float e_x, float e_y, int lines,
           float* out) {
  static const PatchLanes kLanes;
  const hn::ScalableTag<float> df;
  const int lanes = static_cast<int>(hn::Lanes(df));
  const float* b_of = kLanes.b[lines == 3 ? 1 : 0];
  const auto vpx = hn::Set(df, px), vpy = hn::Set(df, py);
  const auto ex = hn::Set(df, e_x), ey = hn::Set(df, e_y);
  for (int i = 0; i < 5 * lines; i += lanes) {
    const auto t = hn::LoadU(df, kLanes.a + i);
    const auto b = hn::LoadU(df, b_of + i);
    const auto x = hn::Sub(hn::Add(vpx, hn::Mul(t, ex)), hn::Mul(b, ey));
    const auto y = hn::Add(hn::Add(vpy, hn::Mul(t, ey)), hn::Mul(b, ex));
    hn::StoreU(RawBilinear<kChannels>(src, x, y), df, out + i);
  }
}

void SamplePatch(const StripSource& source, float px, float py, float e_x, float e_y, int lines,
                 float* out) {
  if (source.channels == 3)
    Patch<3>(source, px, py, e_x, e_y, lines, out);
  else
    Patch<1>(source, px, py, e_x, e_y, lines, out);
}

void StripCosts(const float* const* lines, int n_lines, const float* ref, int spp, int steps,
                float* cost) {
  const hn::ScalableTag<float> df;
  const int lanes = static_cast<int>(hn::Lanes(df));
  for (int k = 0; k < steps; k += lanes) {
    auto acc = hn::Zero(df);
    for (int b = 0; b < n_lines; ++b)
      for (int a = -2; a <= 2; ++a) {
        const auto d =
            hn::Sub(hn::LoadU(df, lines[b] + (2 - a) * spp + k), hn::Set(df, ref[b * 5 + a + 2]));
        acc = hn::Add(acc, hn::Mul(d, d));
      }
    hn::StoreU(acc, df, cost + k);
  }
}

// The channel sum of the pixel at each lane's byte offset: the low byte
// (Mono8) or the low three bytes (BGR8) of the 32-bit word there.
template <int kChannels, class DU, class VI>
HWY_INLINE hn::Vec<DU> PixelSum(DU du, const std::uint32_t* base, VI offset) {
  const auto mask = hn::Set(du, 0xFFu);
  const auto w = hn::GatherOffset(du, base, offset);
  if constexpr (kChannels == 3)
    return hn::Add(hn::Add(hn::And(w, mask), hn::And(hn::ShiftRight<8>(w), mask)),
                   hn::And(hn::ShiftRight<16>(w), mask));
  return hn::And(w, mask);
}

template <int kChannels>
void Scores(const StripSource& src, int cx, int cy, const std::int32_t* dx, const std::int32_t* dy,
            int n, float to_grey, const float* axis_x, const float* axis_y, unsigned axis_mask,
            float* score, std::int32_t* axis) {
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const hn::RebindToUnsigned<decltype(df)> du;
  const int lanes = static_cast<int>(hn::Lanes(df));
  const auto* base = reinterpret_cast<const std::uint32_t*>(src.raw);
  const auto stride = hn::Set(di, static_cast<std::int32_t>(src.stride_bytes));
  const auto centre =
      hn::Set(di, static_cast<std::int32_t>(cy * static_cast<std::int64_t>(src.stride_bytes) +
                                            static_cast<std::int64_t>(cx) * kChannels));
  const auto step = hn::Set(di, kChannels);
  const auto scale = hn::Set(df, to_grey);
  for (int q = 0; q < n; q += lanes) {
    const auto ox = hn::LoadU(di, dx + q), oy = hn::LoadU(di, dy + q);
    // Lanes past n read dx, dy's next entries (later candidates or the
    // padding's zeros, all within the same box) and land in the padding.
    const auto at = hn::Add(centre, hn::Add(hn::Mul(oy, stride), hn::Mul(ox, step)));
    const auto right = PixelSum<kChannels>(du, base, hn::Add(at, step));
    const auto left = PixelSum<kChannels>(du, base, hn::Sub(at, step));
    const auto down = PixelSum<kChannels>(du, base, hn::Add(at, stride));
    const auto up = PixelSum<kChannels>(du, base, hn::Sub(at, stride));
    const auto gx =
        hn::Mul(scale, hn::ConvertTo(df, hn::Sub(hn::BitCast(di, right), hn::BitCast(di, left))));
    const auto gy =
        hn::Mul(scale, hn::ConvertTo(df, hn::Sub(hn::BitCast(di, down), hn::BitCast(di, up))));
    auto best = hn::Zero(df);
    auto best_axis = hn::Zero(di);
    for (int d = 0; d < 3; ++d) {
      if (!((axis_mask >> d) & 1u)) continue;
      const auto g = hn::Abs(
          hn::Add(hn::Mul(gx, hn::Set(df, axis_x[d])), hn::Mul(gy, hn::Set(df, axis_y[d]))));
      const auto larger = hn::Gt(g, best);
      best = hn::IfThenElse(larger, g, best);
      best_axis = hn::IfThenElse(hn::RebindMask(di, larger), hn::Set(di, d), best_axis);
    }
    hn::StoreU(best, df, score + q);
    hn::StoreU(best_axis, di, axis + q);
  }
}

void CandidateScores(const StripSource& source, int cx, int cy, const std::int32_t* dx,
                     const std::int32_t* dy, int n, float to_grey, const float* axis_x,
                     const float* axis_y, unsigned axis_mask, float* score, std::int32_t* axis) {
  if (source.channels == 3)
    Scores<3>(source, cx, cy, dx, dy, n, to_grey, axis_x, axis_y, axis_mask, score, axis);
  else
    Scores<1>(source, cx, cy, dx, dy, n, to_grey, axis_x, axis_y, axis_mask, score, axis);
}

}  // namespace HWY_NAMESPACE
}  // namespace lifmcr::processing::detail
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace lifmcr::processing::detail {

HWY_EXPORT(SampleStripLine);
HWY_EXPORT(StripCosts);
HWY_EXPORT(CandidateScores);
HWY_EXPORT(SamplePatch);

namespace {

template <int kChannels>
void ScalarLine(const StripSource& src, const StripLine& l, float* out) {
  for (int i = 0; i < l.n; ++i) {
    const int j = l.n - 1 - i;
    if (j < l.j_lo || j > l.j_hi) {
      out[i] = std::numeric_limits<float>::quiet_NaN();
      continue;
    }
    const float t = l.along0 + j * l.step;
    const float x = l.px + t * l.e_x - l.b_ey, y = l.py + t * l.e_y + l.b_ex;
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const float fx = x - x0, fy = y - y0;
    const std::uint8_t* q0 =
        src.raw + static_cast<std::size_t>(y0) * src.stride_bytes + x0 * kChannels;
    const std::uint8_t* q1 = q0 + src.stride_bytes;
    const std::uint16_t* g0 = src.gain + static_cast<std::size_t>(y0) * src.width + x0;
    out[i] = RawGainBilinear<kChannels>(q0, q1, g0, g0 + src.width, src.gain_scale, fx, fy);
  }
}

void ScalarGreyLine(const StripSource& src, const StripLine& l, float* out) {
  for (int i = 0; i < l.n; ++i) {
    const int j = l.n - 1 - i;
    if (j < l.j_lo || j > l.j_hi) {
      out[i] = std::numeric_limits<float>::quiet_NaN();
      continue;
    }
    const float t = l.along0 + j * l.step;
    const float x = l.px + t * l.e_x - l.b_ey, y = l.py + t * l.e_y + l.b_ex;
    const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
    const float* r0 = src.grey + static_cast<std::size_t>(y0) * src.width + x0;
    out[i] = GreyImageBilinear(r0, r0 + src.width, x - x0, y - y0);
  }
}

void ScalarSampleStripLine(const StripSource& source, const StripLine& line, float* out) {
  if (source.grey != nullptr)
    ScalarGreyLine(source, line, out);
  else if (source.channels == 3)
    ScalarLine<3>(source, line, out);
  else
    ScalarLine<1>(source, line, out);
}

template <int kChannels>
void ScalarPatchOf(const StripSource& src, float px, float py, float e_x, float e_y, int lines,
                   float* out) {
  const int half = lines / 2;
  for (int b = -half; b <= half; ++b) {
    const float b_ey = static_cast<float>(b) * e_y, b_ex = static_cast<float>(b) * e_x;
    for (int a = -2; a <= 2; ++a) {
      const float t = static_cast<float>(a);
      const float x = px + t * e_x - b_ey, y = py + t * e_y + b_ex;
      const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
      const std::uint8_t* q0 =
          src.raw + static_cast<std::size_t>(y0) * src.stride_bytes + x0 * kChannels;
      const std::uint16_t* g0 = src.gain + static_cast<std::size_t>(y0) * src.width + x0;
      out[5 * (b + half) + a + 2] = RawGainBilinear<kChannels>(
          q0, q0 + src.stride_bytes, g0, g0 + src.width, src.gain_scale, x - x0, y - y0);
    }
  }
}

void ScalarSamplePatch(const StripSource& source, float px, float py, float e_x, float e_y,
                       int lines, float* out) {
  if (source.channels == 3)
    ScalarPatchOf<3>(source, px, py, e_x, e_y, lines, out);
  else
    ScalarPatchOf<1>(source, px, py, e_x, e_y, lines, out);
}

void ScalarStripCosts(const float* const* lines, int n_lines, const float* ref, int spp, int steps,
                      float* cost) {
  for (int k = 0; k < steps; ++k) cost[k] = 0;
  for (int b = 0; b < n_lines; ++b)
    for (int a = -2; a <= 2; ++a) {
      const float r = ref[b * 5 + a + 2];
      const float* line = lines[b] + (2 - a) * spp;
      for (int k = 0; k < steps; ++k) {
        const float d = line[k] - r;
        cost[k] += d * d;
      }
    }
}

template <int kChannels>
void ScalarScoresOf(const StripSource& src, int cx, int cy, const std::int32_t* dx,
                    const std::int32_t* dy, int n, float to_grey, const float* axis_x,
                    const float* axis_y, unsigned axis_mask, float* score, std::int32_t* axis) {
  auto sum = [&](int x, int y) {
    const std::uint8_t* p =
        src.raw + static_cast<std::size_t>(y) * src.stride_bytes + x * kChannels;
    if constexpr (kChannels == 3) return p[0] + p[1] + p[2];
    return static_cast<int>(p[0]);
  };
  for (int q = 0; q < n; ++q) {
    const int x = cx + dx[q], y = cy + dy[q];
    const float gx = to_grey * static_cast<float>(sum(x + 1, y) - sum(x - 1, y));
    const float gy = to_grey * static_cast<float>(sum(x, y + 1) - sum(x, y - 1));
    float best = 0;
    int best_axis = 0;
    for (int d = 0; d < 3; ++d) {
      if (!((axis_mask >> d) & 1u)) continue;
      const float g = std::abs(gx * axis_x[d] + gy * axis_y[d]);
      if (g > best) {
        best = g;
        best_axis = d;
      }
    }
    score[q] = best;
    axis[q] = best_axis;
  }
}

void ScalarCandidateScores(const StripSource& source, int cx, int cy, const std::int32_t* dx,
                           const std::int32_t* dy, int n, float to_grey, const float* axis_x,
                           const float* axis_y, unsigned axis_mask, float* score,
                           std::int32_t* axis) {
  if (source.channels == 3)
    ScalarScoresOf<3>(source, cx, cy, dx, dy, n, to_grey, axis_x, axis_y, axis_mask, score, axis);
  else
    ScalarScoresOf<1>(source, cx, cy, dx, dy, n, to_grey, axis_x, axis_y, axis_mask, score, axis);
}

void DispatchedScores(const StripSource& source, int cx, int cy, const std::int32_t* dx,
                      const std::int32_t* dy, int n, float to_grey, const float* axis_x,
                      const float* axis_y, unsigned axis_mask, float* score, std::int32_t* axis) {
  HWY_DYNAMIC_DISPATCH(CandidateScores)
  (source, cx, cy, dx, dy, n, to_grey, axis_x, axis_y, axis_mask, score, axis);
}

void DispatchedPatch(const StripSource& source, float px, float py, float e_x, float e_y,
                     int lines, float* out) {
  HWY_DYNAMIC_DISPATCH(SamplePatch)(source, px, py, e_x, e_y, lines, out);
}

void DispatchedSample(const StripSource& source, const StripLine& line, float* out) {
  HWY_DYNAMIC_DISPATCH(SampleStripLine)(source, line, out);
}

void DispatchedCosts(const float* const* lines, int n_lines, const float* ref, int spp, int steps,
                     float* cost) {
  HWY_DYNAMIC_DISPATCH(StripCosts)(lines, n_lines, ref, spp, steps, cost);
}

}  // namespace

Gain16 Gain16::From(const std::vector<float>& gain, int width) {
  Gain16 out;
  out.width = width;
  float largest = 0;
  for (const float g : gain)
    if (std::isfinite(g)) largest = std::max(largest, g);
  int e = 16;
  while (e > -16 && static_cast<double>(largest) * std::ldexp(1.0, e) > 65535.0) --e;
  out.scale = static_cast<float>(std::ldexp(1.0, -e));
  const double to_q = std::ldexp(1.0, e);
  out.q.resize(gain.size());
  // Once per camera, but 32.5 M pixels on an R32: in parallel, rounding by
  // + 0.5 and truncation (g >= 0).
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, gain.size(), 1 << 16),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      for (std::size_t k = r.begin(); k < r.end(); ++k) {
                        const float g = gain[k];
                        out.q[k] = std::isfinite(g) && g > 0
                                       ? static_cast<std::uint16_t>(
                                             std::clamp(g * to_q + 0.5, 1.0, 65535.0))
                                       : 0;
                      }
                    });
  return out;
}

const StripKernels& ScalarStripKernels() {
  static const StripKernels kernels{ScalarSampleStripLine, ScalarStripCosts, ScalarCandidateScores,
                                    ScalarSamplePatch, "scalar"};
  return kernels;
}

const StripKernels& SimdStripKernels() {
  // The target this CPU runs (hwy/targets.h): the best one compiled in.
  static const StripKernels kernels{DispatchedSample, DispatchedCosts, DispatchedScores,
                                    DispatchedPatch, hwy::TargetName(hwy::SupportedAndGeneratedTargets()[0])};
  return kernels;
}

}  // namespace lifmcr::processing::detail
#endif  // HWY_ONCE
