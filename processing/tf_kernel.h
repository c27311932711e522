#pragma once
// The totally focused image at one point, the rendering rule of
// processing/total_focus.h written once for the whole-image renderer
// (RenderTotalFocus) and for the sampler of single points and patches
// (processing/tf_sampler.h): for raw position x at virtual depth v, the lens
// type sharp at v; the three lenses of its triangular sublattice around x
// (steps A(1, 1), A(2, -1)), each sampled bilinearly at p_k = l_k + (x -
// l_k) / v on the raw pixels times the devignetting gain and weighted by its
// barycentric coordinate times 1 - |p_k - c_k|^2 / r^2; where none of them
// holds x, the nearest micro image of any type and its six neighbours.
// "Around x" is in the lattice of micro-image centres at the point that
// looks at x: the centre c_k of micro image k shows the virtual point
// l_k + v (c_k - l_k) = c + (c_k - c) (lambda + v (1 - lambda)) (p_k = c_k),
// so the micro images that see x are those around
//   q = c + (x - c) / (lambda + v (1 - lambda)),
// not around x: with the micro-lens centre adjustment (1 - lambda = 1.4 % on
// `medium`) q lies (v - 1)(1 - lambda) |x - c| nearer the centre, 4 lens
// pitches at the corner at v 4.7, where the lenses around x see nothing of x
// (the TF image was black there, in a pattern fixed to the lattice).
// Internal to processing/ (no OpenCV, no allocation per point).

#include "config/image.h"
#include "config/mla.h"
#include "processing/lens_search_simd.h"
#include "processing/plenoptic_frame.h"
#include "processing/tf_blend_simd.h"

#include <Eigen/Core>
#include <Eigen/LU>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace lifmcr::processing::detail {

// A micro image in float: micro-lens centre l, micro-image centre c.
struct LensF {
  float lx, ly, cx, cy;
};

// The lens type whose sharp range (MLA file) holds v most centrally (in
// log v); the nearest range when none holds it. A table over v (a log per
// TF pixel would cost more than its sampling).
class SharpTypeTable {
 public:
  explicit SharpTypeTable(const MlaCalibration& mla) {
    for (int q = 0; q < kSize; ++q) {
      const double v = std::max(1.0, (q + 0.5) / kPerUnit);
      double best_score = -1e300;
      for (int t = 0; t < 3; ++t) {
        const MlaLensType& type = mla.lens_types[t];
        const double score = std::min(std::log(v / type.depth_min), std::log(type.depth_max / v));
        if (score > best_score) {
          best_score = score;
          table_[q] = static_cast<std::uint8_t>(t);
        }
      }
    }
  }
  int operator()(double v) const {
    return table_[std::clamp(static_cast<int>(v * kPerUnit), 0, kSize - 1)];
  }
  static constexpr int kPerUnit = 256, kSize = 64 * kPerUnit;
  int At(int index) const { return table_[index]; }

 private:
  std::array<std::uint8_t, kSize> table_{};
};

// Colour of micro image m seen from virtual point (x, y) at 1 / v = inv_v:
// bilinear at p = l + (x - l) / v of the raw pixels times the devignetting
// gain (f.gain, or `gain16` where set: lens_search_simd.h's 16-bit copy);
// false outside its usable disc (radius^2 r2) or next to an invalid pixel
// (the gain is NaN there and propagates through the sum).
// `centrality` = 1 - |p - c|^2 / r^2.
template <int kChannels>
inline bool SampleLens(const LensF& m, float x, float y, float inv_v, float r2,
                       const PlenopticFrame& f, const Gain16* gain16, const ConstImageView& raw,
                       float* c, float* centrality) {
  const float px = m.lx + (x - m.lx) * inv_v, py = m.ly + (y - m.ly) * inv_v;
  const float dx = px - m.cx, dy = py - m.cy;
  const float d2 = dx * dx + dy * dy;
  if (d2 > r2 || px < 0 || py < 0) return false;
  const int x0 = static_cast<int>(px), y0 = static_cast<int>(py);
  if (x0 >= f.width - 1 || y0 >= f.height - 1) return false;
  const float fx = px - x0, fy = py - y0;
  const std::size_t at = static_cast<std::size_t>(y0) * f.width + x0;
  float g00, g01, g10, g11;
  if (gain16 != nullptr) {
    g00 = gain16->At(at), g01 = gain16->At(at + 1);
    g10 = gain16->At(at + f.width), g11 = gain16->At(at + f.width + 1);
  } else {
    const float* g0 = f.gain.data() + at;
    g00 = g0[0], g01 = g0[1], g10 = g0[f.width], g11 = g0[f.width + 1];
  }
  const float w00 = (1 - fx) * (1 - fy) * g00, w01 = fx * (1 - fy) * g01,
              w10 = (1 - fx) * fy * g10, w11 = fx * fy * g11;
  const std::uint8_t* q0 = raw.Row(y0) + x0 * kChannels;
  const std::uint8_t* q1 = raw.Row(y0 + 1) + x0 * kChannels;
  float check = 0;
  for (int ch = 0; ch < kChannels; ++ch) {
    c[ch] = w00 * q0[ch] + w01 * q0[kChannels + ch] + w10 * q1[ch] + w11 * q1[kChannels + ch];
    check += c[ch];
  }
  *centrality = 1 - d2 / r2;
  return !std::isnan(check);
}

// The per-frame-geometry tables of the rule: lenses in float, the three
// sublattices (origin lens, inverse steps), the sharp type per v.
class TfKernel {
 public:
  // Where the blended lenses are chosen: around LookingAt(x, y, v), right
  // where v is the point's own virtual depth (the TF image: RenderTotalFocus);
  // or around (x, y) itself, for images refocused at one depth v_r
  // (TfSampler). There lens k puts a point X of virtual depth v_t at
  // l_k + (v_r / v_t)(X - l_k), so the blend moves it by (1 - v_r / v_t)(X - l),
  // l the mean l_k blended: the lenses around LookingAt see X from up to
  // v (1 - lambda) |X - c| away (4 lens pitches at medium's corners), those
  // around X from (1 - lambda) |X - c|; with the first the live localizer's
  // c0_from_cx was 1.98 mm median on bench_live medium, with the second
  // 1.28 mm (bench/README.md). The price: a refocused
  // image is darker at high v near the border, where few lenses around X
  // see X.
  enum class LensSelection { kLookingAt, kAroundPosition };

  TfKernel(const PlenopticFrame& f, const MlaCalibration& mla, double inner_fraction,
           LensSelection selection = LensSelection::kLookingAt)
      : f_(f), sharp_type_(mla), selection_(selection) {
    const float r = static_cast<float>(f.radius_px * inner_fraction);
    r2_ = r * r;
    cx_ = static_cast<float>(f.principal_point_px.x());
    cy_ = static_cast<float>(f.principal_point_px.y());
    lambda_ = static_cast<float>(f.lambda);
    lenses_.resize(f.lenses.size());
    for (std::size_t k = 0; k < f.lenses.size(); ++k) {
      const MicroImage& m = f.lenses[k];
      lenses_[k] = {static_cast<float>(m.lens_px.x()), static_cast<float>(m.lens_px.y()),
                    static_cast<float>(m.centre_px.x()), static_cast<float>(m.centre_px.y())};
    }
    // The lenses of one type form a triangular sublattice with steps
    // A (1, 1) and A (2, -1) (type = sigma (i - j) mod 3 is constant along
    // both); per type its origin lens and the inverse of those steps.
    for (int t = 0; t < 3; ++t) {
      SublatticeOf& s = sub_[t];
      while (f.grid.Type(s.i0, 0) != t) ++s.i0;
      s.origin = f.grid.Center(s.i0, 0);
      Eigen::Matrix2d steps;
      steps.col(0) = f.grid.lattice * Eigen::Vector2d(1, 1);
      steps.col(1) = f.grid.lattice * Eigen::Vector2d(2, -1);
      s.from_px = steps.inverse();
    }
    type_of_v_.resize(SharpTypeTable::kSize);
    for (int q = 0; q < SharpTypeTable::kSize; ++q) type_of_v_[q] = sharp_type_.At(q);
  }

  // The geometry of the whole-row blend (tf_blend_simd.h) of this frame;
  // it points into this kernel (the type table).
  TfBlendGeometry BlendGeometry() const {
    TfBlendGeometry g;
    g.width = f_.width;
    g.height = f_.height;
    g.cx = cx_;
    g.cy = cy_;
    g.lambda = lambda_;
    g.r2 = r2_;
    for (int t = 0; t < 3; ++t) {
      g.ox[t] = static_cast<float>(sub_[t].origin.x());
      g.oy[t] = static_cast<float>(sub_[t].origin.y());
      g.fxx[t] = static_cast<float>(sub_[t].from_px(0, 0));
      g.fxy[t] = static_cast<float>(sub_[t].from_px(0, 1));
      g.fyx[t] = static_cast<float>(sub_[t].from_px(1, 0));
      g.fyy[t] = static_cast<float>(sub_[t].from_px(1, 1));
    }
    const Eigen::Vector2d a = f_.grid.lattice * Eigen::Vector2d(1, 1);
    const Eigen::Vector2d b = f_.grid.lattice * Eigen::Vector2d(2, -1);
    g.sxa = static_cast<float>(a.x());
    g.sya = static_cast<float>(a.y());
    g.sxb = static_cast<float>(b.x());
    g.syb = static_cast<float>(b.y());
    g.type_of_v = type_of_v_.data();
    g.type_per_unit = SharpTypeTable::kPerUnit;
    g.type_size = SharpTypeTable::kSize;
    SetTypeRuns(&g);
    return g;
  }

  // The gain is read from `gain` (the frame's geometry may then drop its
  // float gain): half the bytes; the gain to 3e-5 of itself (Gain16).
  void UseGain16(const Gain16* gain) { gain16_ = gain; }

  int SharpType(float v) const { return sharp_type_(v); }
  // Sublattice coordinates of raw position (x, y) in type t's sublattice.
  Eigen::Vector2f Sublattice(int t, double x, double y) const {
    const Eigen::Vector2d a = sub_[t].from_px * (Eigen::Vector2d(x, y) - sub_[t].origin);
    return {static_cast<float>(a.x()), static_cast<float>(a.y())};
  }
  // The micro-image-centre position q of the lenses that look at raw
  // position (x, y) at virtual depth v (header comment).
  Eigen::Vector2f LookingAt(float x, float y, float v) const {
    const float k = 1.0f / (lambda_ + v * (1.0f - lambda_));
    return {cx_ + (x - cx_) * k, cy_ + (y - cy_) * k};
  }

  // The three lenses of type `type`'s sublattice triangle around
  // LookingAt(x, y, v) (or (x, y): LensSelection) with their barycentric
  // weights (a lens index of -1 where the lattice has none); q the point
  // they are chosen around.
  void Triangle(float x, float y, float v, int type, int* lens, float* bary,
                Eigen::Vector2f* q_out) const {
    const Eigen::Vector2f q =
        selection_ == LensSelection::kLookingAt ? LookingAt(x, y, v) : Eigen::Vector2f(x, y);
    *q_out = q;
    const Eigen::Vector2f a = Sublattice(type, q.x(), q.y());
    const float ax = a.x(), ay = a.y();
    const int m = static_cast<int>(std::floor(ax)), n = static_cast<int>(std::floor(ay));
    const float fa = ax - m, fb = ay - n;
    int ci[3], cj[3];
    if (fa + fb < 1) {
      ci[0] = m, cj[0] = n, bary[0] = 1 - fa - fb;
      ci[1] = m + 1, cj[1] = n, bary[1] = fa;
      ci[2] = m, cj[2] = n + 1, bary[2] = fb;
    } else {
      ci[0] = m + 1, cj[0] = n + 1, bary[0] = fa + fb - 1;
      ci[1] = m, cj[1] = n + 1, bary[1] = 1 - fa;
      ci[2] = m + 1, cj[2] = n, bary[2] = 1 - fb;
    }
    const int i0 = sub_[type].i0;
    for (int k = 0; k < 3; ++k) lens[k] = f_.LensAt(i0 + ci[k] + 2 * cj[k], ci[k] - cj[k]);
  }

  // A point's triangle (Triangle above).
  struct PointLenses {
    int lens[3];
    float bary[3];
    Eigen::Vector2f q;
  };

  // The blend at raw position (x, y), virtual depth v (> 1), with the lenses
  // of type `type` around LookingAt(x, y, v) (or (x, y): LensSelection):
  // acc (kChannels) and the sum of weights (0: no micro image sees the point).
  template <int kChannels>
  float Blend(const ConstImageView& raw, float x, float y, float v, int type, float* acc) const {
    PointLenses t;
    Triangle(x, y, v, type, t.lens, t.bary, &t.q);
    return BlendTriangle<kChannels>(raw, x, y, v, t, acc);
  }

  // Blend with the point's triangle made already.
  template <int kChannels>
  float BlendTriangle(const ConstImageView& raw, float x, float y, float v, const PointLenses& t,
                      float* acc) const {
    const float inv_v = 1.0f / v;
    const int* lens = t.lens;
    const float* bary = t.bary;
    const Eigen::Vector2f& q = t.q;
    for (int ch = 0; ch < kChannels; ++ch) acc[ch] = 0;
    float c[kChannels], centrality = 0, sw = 0;
    for (int t = 0; t < 3; ++t) {
      if (bary[t] <= 0) continue;
      const int k = lens[t];
      if (k < 0 ||
          !SampleLens<kChannels>(lenses_[k], x, y, inv_v, r2_, f_, gain16_, raw, c, &centrality))
        continue;
      const float wq = bary[t] * centrality;
      for (int ch = 0; ch < kChannels; ++ch) acc[ch] += wq * c[ch];
      sw += wq;
    }
    if (sw > 0) return sw;
    // Near the border, in the vignetted periphery (micro images valid only
    // near their centres) or where v is below the sublattice's reach: the
    // nearest micro image of any type and its six neighbours.
    int i = 0, j = 0;
    f_.grid.Nearest(Eigen::Vector2d(q.x(), q.y()), &i, &j);
    static constexpr int kAround[7][2] = {{0, 0},  {1, 0},  {0, 1}, {-1, 1},
                                          {-1, 0}, {0, -1}, {1, -1}};
    for (const auto& d : kAround) {
      const int k = f_.LensAt(i + d[0], j + d[1]);
      if (k < 0 ||
          !SampleLens<kChannels>(lenses_[k], x, y, inv_v, r2_, f_, gain16_, raw, c, &centrality))
        continue;
      for (int ch = 0; ch < kChannels; ++ch) acc[ch] += centrality * c[ch];
      sw += centrality;
    }
    return sw;
  }

 private:
  struct SublatticeOf {
    int i0 = 0;
    Eigen::Vector2d origin;
    Eigen::Matrix2d from_px;
  };
  const PlenopticFrame& f_;
  const Gain16* gain16_ = nullptr;
  SharpTypeTable sharp_type_;
  LensSelection selection_;
  float r2_ = 0;
  float cx_ = 0, cy_ = 0, lambda_ = 1;  // the frame's c and lambda of l_k
  std::vector<LensF> lenses_;
  std::array<SublatticeOf, 3> sub_;
  std::vector<std::int32_t> type_of_v_;  // sharp_type_'s table in 32 bits (the SIMD gather's)
};

}  // namespace lifmcr::processing::detail
