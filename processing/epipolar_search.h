#pragma once
// The epipolar search between two micro images, written once for the dense
// estimator (processing/virtual_depth.h, on the smoothed devignetted grey)
// and the per-lens estimator (processing/lens_depth.h, on the raw pixels
// times the devignetting gain): what differs is only how a grey level is
// read at a sub-pixel position (the `Bilinear` callable below).
//
// A pixel p of micro image k appears in neighbour n at
//   q(z) = p + lambda (c_n - c_k) (1 - z),   z = 1 / v
// (virtual_depth.h). MatchAlong searches z in [z_lo, z_hi] (clipped to the z
// for which q lies in the neighbour's disc) in steps of step_px of
// disparity, minimising the SSD of a 5 x 3 patch along the baseline; the
// minimum must lie strictly inside the run and be distinct (<=
// max_cost_ratio of the run's mean cost, plus noise); a parabola through the
// three costs around it gives the sub-step position. Its uncertainty
//   sigma_px^2 = 2 sigma_I^2 / sum (g_e)^2 + sigma_model^2,
//   sigma_z = sigma_px / (lambda |Delta|).
// The patch positions of all steps lie on three lines along the baseline at
// step_px spacing, so the neighbour is sampled once per line (a strip) and
// step k reads the strip at shift k: 3 (K + 4 / step) samples instead of 15 K.
//
// `Bilinear(x0, y0, fx, fy)` is the grey level at (x0 + fx, y0 + fy) for
// 0 <= x0 < width - 1, 0 <= y0 < height - 1, fx, fy in [0, 1); NaN next to
// an invalid pixel (NaN propagates through the costs). A Bilinear that
// also has members `kernels` (const StripKernels*, may be null) and
// `source` (StripSource) reads the strips of a disc well inside the frame
// and their costs through those kernels (processing/lens_search_simd.h:
// the scalar reference or Highway's, the same numbers).
// Internal to processing/.

#include "config/mla.h"
#include "processing/lens_search_simd.h"
#include "processing/plenoptic_frame.h"
#include "processing/virtual_depth.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace lifmcr::processing::detail {

constexpr int kAlong = 5, kAcross = 3, kSamples = kAlong * kAcross;
// Neighbour steps (di, dj): ring 1 (|Delta| = D), ring 2 (|Delta| = sqrt(3) D).
constexpr std::array<std::array<int, 2>, 6> kRing1{
    {{1, 0}, {0, 1}, {-1, 1}, {-1, 0}, {0, -1}, {1, -1}}};
constexpr std::array<std::array<int, 2>, 6> kRing2{
    {{1, 1}, {-1, 2}, {-2, 1}, {-1, -1}, {1, -2}, {2, -1}}};

struct Estimate {
  double z = 0, sigma = 0;
};

struct Neighbour {
  const MicroImage* lens = nullptr;
  float cx = 0, cy = 0;            // c_n (the search reads no more of the neighbour)
  float delta_x = 0, delta_y = 0;  // c_n - c_k
  float e_x = 0, e_y = 0;          // unit baseline direction
  double length = 0;
  bool same_type = false;
  // Opposite neighbours (direction d and d + 3 of a ring) share their
  // reference patch, reversed: axis = 3 (ring - 1) + d mod 3.
  int axis = 0;
  bool flipped = false;
};

// The neighbours of `lens` in rings 1..rings that exist (ring 1 first, in
// kRing1's order); returns their count, *ring1_count those of ring 1.
inline int FindNeighbours(const PlenopticFrame& f, const MicroImage& lens, int rings,
                          std::array<Neighbour, 12>* nbs, int* ring1_count) {
  int count = 0;
  *ring1_count = 0;
  for (int ring = 1; ring <= rings; ++ring)
    for (int dir = 0; dir < 6; ++dir) {
      const auto& d = (ring == 1 ? kRing1 : kRing2)[dir];
      const int idx = f.LensAt(lens.i + d[0], lens.j + d[1]);
      if (idx < 0) continue;
      Neighbour& nb = (*nbs)[count++];
      nb.axis = 3 * (ring - 1) + dir % 3;
      nb.flipped = dir >= 3;
      nb.lens = &f.lenses[idx];
      nb.cx = static_cast<float>(nb.lens->centre_px.x());
      nb.cy = static_cast<float>(nb.lens->centre_px.y());
      const Eigen::Vector2d delta = nb.lens->centre_px - lens.centre_px;
      nb.length = delta.norm();
      nb.delta_x = static_cast<float>(delta.x());
      nb.delta_y = static_cast<float>(delta.y());
      nb.e_x = static_cast<float>(delta.x() / nb.length);
      nb.e_y = static_cast<float>(delta.y() / nb.length);
      nb.same_type = nb.lens->type == lens.type;
      if (ring == 1) *ring1_count = count;
    }
  return count;
}

// The search range in z = 1 / v per lens type (the MLA file's depth ranges
// as SearchedVirtualDepths reads them) and their union.
struct SearchRange {
  std::array<double, 3> z_lo{}, z_hi{};
  double union_lo = 1, union_hi = 0;
  explicit SearchRange(const MlaCalibration& mla) {
    for (int t = 0; t < 3; ++t) {
      const VirtualDepthRange range = SearchedVirtualDepths(mla.lens_types[t]);
      z_lo[t] = 1.0 / range.max;
      z_hi[t] = 1.0 / range.min;
      union_lo = std::min(union_lo, z_lo[t]);
      union_hi = std::max(union_hi, z_hi[t]);
    }
  }
};

// What one search needs besides the patch: the frame's geometry and the
// estimator's parameters.
struct MatchParams {
  double lambda = 1;
  double step_px = 0.5;    // 1, 0.5 or 0.25
  int samples_per_px = 2;  // 1 / step_px
  double noise_dn = 2.5;   // sigma_I
  double max_cost_ratio = 0.5;
  double geometric_px = 0.05;  // sigma_model of a pair of one lens type
  double cross_type_px = 0.3;  // sigma_model of a pair of two types
  // Defocus equalisation of pairs of two lens types (DefocusModel below);
  // blur_px_per_z 0: off.
  double blur_px_per_z = 0;
  std::array<double, 3> z_sharp{};
  // With it, the reference micro image k: its lens type and centre (its
  // patch sampled beyond the 5 x 3 samples); set per micro image.
  int ref_type = 0;
  float ref_cx = 0, ref_cy = 0;
};

// The defocus of a lens type at virtual depth v, from the MLA description:
// a micro lens of type t images v_t sharply and spreads a point at v to a
// disc of diameter rho_t(v) = d |1 / v_t - 1 / v| (d the micro-lens pitch
// in px, lambda D: the lens equation of the micro lens at the sensor
// distance B), whose Gaussian equivalent has sigma = rho / 4 (a uniform
// disc's). The MLA file's sharp depth range of a type is where rho stays
// below one blur limit, symmetric about 1 / v_t in 1 / v, so
// z_t = 1 / v_t is the middle of the range in z.
inline void DefocusModel(const MlaCalibration& mla, double lambda, double pitch_px,
                         MatchParams* p) {
  for (int t = 0; t < 3; ++t) {
    const MlaLensType& type = mla.lens_types[t];
    const double z_near = type.depth_min > 0 ? 1.0 / type.depth_min : 1.0;
    const double z_far = type.depth_max > 0 ? 1.0 / type.depth_max : 0.0;
    p->z_sharp[t] = 0.5 * (z_near + z_far);
  }
  p->blur_px_per_z = lambda * pitch_px;
}

constexpr int kMaxSteps = 256;

// ceil(x) and floor(x) as int for |x| < 2^31, without a call (x86-64's
// baseline has no rounding instruction: std::ceil / std::floor of a float
// are calls into libm, 4 % of the dense search's time in MatchAlong).
inline int CeilToInt(float x) {
  const int t = static_cast<int>(x);  // truncation towards 0
  return t + (static_cast<float>(t) < x);
}
inline int FloorToInt(float x) {
  const int t = static_cast<int>(x);
  return t - (static_cast<float>(t) > x);
}

// Bilinear grey at (x, y) if within r2 of (cx, cy) and inside the image;
// NaN otherwise.
template <typename Bilinear>
inline float SampleInDisc(const Bilinear& grey, int width, int height, float x, float y, float cx,
                          float cy, float r2) {
  const float dx = x - cx, dy = y - cy;
  if (dx * dx + dy * dy > r2 || x < 0 || y < 0) return std::numeric_limits<float>::quiet_NaN();
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  if (x0 >= width - 1 || y0 >= height - 1) return std::numeric_limits<float>::quiet_NaN();
  return grey(x0, y0, x - x0, y - y0);
}

// The reference patch around p: samples p + a e + b e_perp, a = -2..2
// (kAlong), b over kLines lines (-1..1 for 3, 0 for 1), row-major by b;
// false if one is invalid.
// The patch is a rectangle of half-sizes 2 and kHalf around p, so every
// sample lies within sqrt(4 + kHalf^2) of p: when p is that much (plus a
// pixel for rounding) inside the disc and the image, no sample needs the
// tests of SampleInDisc (the same samples, without a branch each).
template <int kLines = kAcross, typename Bilinear>
bool SampleReference(const Bilinear& grey, int width, int height, float px, float py, float e_x,
                     float e_y, float cx, float cy, float r2, float* out) {
  static_assert(kLines == 1 || kLines == 3);
  constexpr int kHalf = kLines / 2;
  constexpr float kReach = kHalf == 0 ? 2.0f + 1.0f : 2.2361f + 1.0f;  // sqrt(4 + kHalf^2) + 1
  {
    const float dx = px - cx, dy = py - cy;
    const float inner = std::sqrt(r2) - kReach;
    if (inner > 0 && dx * dx + dy * dy <= inner * inner && px >= kReach && py >= kReach &&
        px + kReach < width - 1 && py + kReach < height - 1) {
      bool valid = true;
      for (int b = -kHalf, m = 0; b <= kHalf; ++b)
        for (int a = -2; a <= 2; ++a, ++m) {
          const float x = px + a * e_x - b * e_y, y = py + a * e_y + b * e_x;
          const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
          out[m] = grey(x0, y0, x - x0, y - y0);
          valid &= !std::isnan(out[m]);
        }
      return valid;
    }
  }
  for (int b = -kHalf, m = 0; b <= kHalf; ++b)
    for (int a = -2; a <= 2; ++a, ++m) {
      out[m] = SampleInDisc(grey, width, height, px + a * e_x - b * e_y, py + a * e_y + b * e_x, cx,
                            cy, r2);
      if (std::isnan(out[m])) return false;
    }
  return true;
}

// Sum of squared central differences of the patch along the baseline (the
// sum (g_e)^2 of the uncertainty).
template <int kLines = kAcross>
inline double PatchGradient2(const float* patch) {
  double g2 = 0;
  for (int b = 0; b < kLines; ++b)
    for (int a = 0; a + 2 < kAlong; ++a) {
      const double g = 0.5 * (patch[b * kAlong + a + 2] - patch[b * kAlong + a]);
      g2 += g * g;
    }
  return g2;
}

// The z of [*z_lo, *z_hi] for which q(z) = p + lambda Delta (1 - z) lies in
// nb's disc of radius_px + 0.5 (|d - z u| <= R with u = lambda Delta,
// d = p + u - c_n), written back, and the number of steps of step_px that
// MatchAlong searches there; 0 when it would search nothing (fewer than 3
// steps, or more than kMaxSteps). Cheap: a caller tests it before it samples
// a reference patch that no neighbour could match.
inline int SearchSteps(const MatchParams& s, double radius_px, float px, float py,
                       const Neighbour& nb, double* z_lo, double* z_hi) {
  const double r_lim = radius_px + 0.5;
  const double ux = s.lambda * nb.delta_x, uy = s.lambda * nb.delta_y;
  const double dx = px + ux - nb.cx, dy = py + uy - nb.cy;
  const double uu = ux * ux + uy * uy, du = dx * ux + dy * uy;
  const double disc = du * du - uu * (dx * dx + dy * dy - r_lim * r_lim);
  if (disc <= 0) return 0;
  const double root = std::sqrt(disc);
  *z_lo = std::max(*z_lo, (du - root) / uu);
  *z_hi = std::min(*z_hi, (du + root) / uu);
  // ceil((z_hi - z_lo) / dz) + 1 without a call to ceil (x86-64's baseline
  // has no rounding instruction: the call was 4 % of the per-lens
  // estimator's instructions); the quotient is far below 2^31 in magnitude
  // whenever the steps matter, and a larger one is clamped first.
  const double dz = s.step_px / (s.lambda * nb.length);
  const double t = std::clamp((*z_hi - *z_lo) / dz, -1.0, static_cast<double>(kMaxSteps));
  int steps = static_cast<int>(t);
  steps += (static_cast<double>(steps) < t) + 1;
  return steps < 3 || steps > kMaxSteps ? 0 : steps;
}

// Costs of a pair of two lens types with their defocus equalised: at step k
// (z_k = z_lo + k dz) the two types' blur (DefocusModel) differs by
// sigma_eq^2 = |sigma_n^2 - sigma_k^2|; the sharper side is blurred by a
// Gaussian of sigma_eq along the baseline before the SSD (the neighbour's
// strip samples, or the reference patch sampled kPad px further along), so
// both sides compare the scene through the same blur. An option of the
// dense search (DepthOptions::equalise_defocus, off): measured against the
// renderer's truth it does not remove the lens types' bias
// (docs/processing.md, "Systematic error of the virtual depth").
// sigma_eq is rounded to kLevelPx (few kernels); below half a level nothing
// is blurred. Invalid (NaN) samples are left out of a kernel's sum. The
// steps of one level and side form runs, each costed by `costs` (the strip
// kernels of lens_search_simd.h) on the blurred strip or with the blurred
// reference.
template <int kLines, typename Bilinear>
void EqualisedCosts(const MatchParams& s, const Bilinear& grey, int width, int height,
                    double radius_px, float px, float py, const Neighbour& nb, const float* ref,
                    const float* const* lines, int strip_len, int steps, double z_lo, double dz,
                    StripCostsFn costs, float* cost) {
  constexpr int kHalf = kLines / 2;
  constexpr int kPad = 6;  // reference samples beyond the patch: kernels up to sigma 2.4 px
  constexpr int kWide = kAlong + 2 * kPad;
  constexpr double kLevelPx = 0.25;
  constexpr int kMaxLevel = 9;  // sigma_eq <= 2.25 px: rad = ceil(2.5 sigma) <= kPad
  const float r2 = static_cast<float>((radius_px + 0.5) * (radius_px + 0.5));
  const double zt_ref = s.z_sharp[s.ref_type], zt_nb = s.z_sharp[nb.lens->type];
  const int spp = s.samples_per_px;
  // Gaussian taps 1 px apart per level (made once); returns the radius in taps.
  struct Kernels {
    float taps[kMaxLevel + 1][2 * kPad + 1];
    int rad[kMaxLevel + 1];
    Kernels() {
      for (int level = 1; level <= kMaxLevel; ++level) {
        const double sg = level * kLevelPx;
        rad[level] = static_cast<int>(std::ceil(2.5 * sg));
        for (int d = -rad[level]; d <= rad[level]; ++d)
          taps[level][d + rad[level]] = static_cast<float>(std::exp(-0.5 * d * d / (sg * sg)));
      }
    }
  };
  static const Kernels kKernels;
  auto kernel = [](int level, const float** out) {
    *out = kKernels.taps[level];
    return kKernels.rad[level];
  };
  // Signed level per step: > 0 blur the reference, < 0 the strip. With
  // sigma_t = c |z - z_t| / 4 the difference of variances is linear in z:
  //   sigma_n^2 - sigma_k^2 = (c / 4)^2 (z_k - z_n) (2 z - z_k - z_n).
  std::int8_t levels[kMaxSteps];
  {
    const double c4 = 0.25 * s.blur_px_per_z;
    const double slope = c4 * c4 * (zt_ref - zt_nb);
    const double inv_level = 1.0 / kLevelPx;
    for (int k = 0; k < steps; ++k) {
      const double var = slope * (2 * (z_lo + k * dz) - zt_ref - zt_nb);
      const int level =
          std::min(kMaxLevel, static_cast<int>(std::sqrt(std::abs(var)) * inv_level + 0.5));
      levels[k] = static_cast<std::int8_t>(var > 0 ? level : -level);
    }
  }
  float wide[kLines][kWide];
  bool wide_ready = false;
  const float* kern = nullptr;
  // Blurred strip lines (valid 0/1 and NaN-free values for the sums).
  float blurred[kLines][kMaxSteps + 16 + kStripPad];
  float value0[kMaxSteps + 16 + 2 * 4 * kPad], valid[kMaxSteps + 16 + 2 * 4 * kPad];
  float sum[kMaxSteps + 16], wsum[kMaxSteps + 16];
  float blurred_ref[kSamples];
  int k = 0;
  while (k < steps) {
    const int level = levels[k];
    int end = k + 1;
    while (end < steps && levels[end] == level) ++end;
    const int run = end - k;
    if (level == 0) {
      std::array<const float*, kLines> l;
      for (int b = 0; b < kLines; ++b) l[b] = lines[b] + k;
      costs(l.data(), kLines, ref, spp, run, cost + k);
    } else if (level > 0) {
      // The neighbour is the blurrier: the reference blurred along the baseline.
      if (!wide_ready) {
        for (int b = -kHalf; b <= kHalf; ++b)
          for (int a = -2 - kPad; a <= 2 + kPad; ++a)
            wide[b + kHalf][a + 2 + kPad] =
                SampleInDisc(grey, width, height, px + a * nb.e_x - b * nb.e_y,
                             py + a * nb.e_y + b * nb.e_x, s.ref_cx, s.ref_cy, r2);
        wide_ready = true;
      }
      const int rad = kernel(level, &kern);
      for (int b = 0; b < kLines; ++b)
        for (int a = 0; a < kAlong; ++a) {
          float sum = 0, wsum = 0;
          for (int d = -rad; d <= rad; ++d) {
            const float x = wide[b][a + kPad + d];
            if (std::isnan(x)) continue;
            sum += kern[d + rad] * x;
            wsum += kern[d + rad];
          }
          // The patch's own sample valid (SampleReference), so wsum > 0.
          blurred_ref[b * kAlong + a] = sum / wsum;
        }
      std::array<const float*, kLines> l;
      for (int b = 0; b < kLines; ++b) l[b] = lines[b] + k;
      costs(l.data(), kLines, blurred_ref, spp, run, cost + k);
    } else {
      // The neighbour is the sharper: its strip blurred over the samples
      // this run reads (k .. end - 1 + 4 spp), taps spp samples (1 px) apart.
      const int rad = kernel(-level, &kern);
      const int lo = k - rad * spp;  // the taps' first strip index (may be < 0)
      const int n = end - k + 4 * spp;
      const int span = n + 2 * rad * spp;
      for (int b = 0; b < kLines; ++b) {
        // Invalid samples (NaN, or beyond the strip) weigh 0 in the sums.
        for (int i = 0; i < span; ++i) {
          const int j = lo + i;
          const float x = j >= 0 && j < strip_len ? lines[b][j] : std::numeric_limits<float>::quiet_NaN();
          const bool ok = !std::isnan(x);
          value0[i] = ok ? x : 0.0f;
          valid[i] = ok ? 1.0f : 0.0f;
        }
        for (int i = 0; i < n; ++i) sum[i] = wsum[i] = 0.0f;
        for (int d = 0; d <= 2 * rad; ++d) {
          const float g = kern[d];
          const float* v = value0 + d * spp;
          const float* m = valid + d * spp;
          for (int i = 0; i < n; ++i) {
            sum[i] += g * v[i];
            wsum[i] += g * m[i];
          }
        }
        float* out = blurred[b];
        const float* centre = valid + rad * spp;
        for (int i = 0; i < n; ++i)
          out[i] = centre[i] > 0 ? sum[i] / wsum[i] : std::numeric_limits<float>::quiet_NaN();
        std::fill(out + n, out + n + kStripPad, 0.0f);
      }
      std::array<const float*, kLines> l;
      for (int b = 0; b < kLines; ++b) l[b] = blurred[b];
      costs(l.data(), kLines, ref, spp, run, cost + k);
    }
    k = end;
  }
}

// One baseline: best z in [z_lo, z_hi]; false when unconfirmed. `ref` is the
// patch of p sampled along nb's direction (kAlong x kLines); gradient_sum its
// PatchGradient2; radius_px the usable disc radius r_valid. kLines 1: a
// patch of one line along the baseline (a third of the samples, for a
// coarse search whose result a longer baseline refines). kEqualise: pairs
// of two lens types through EqualisedCosts when s.blur_px_per_z > 0 (a
// template parameter, so the searches without it compile as before).
template <int kLines = kAcross, bool kEqualise = false, typename Bilinear>
bool MatchAlong(const MatchParams& s, const Bilinear& grey, int width, int height, double radius_px,
                float px, float py, const float* ref, double gradient_sum, const Neighbour& nb,
                double z_lo, double z_hi, Estimate* est) {
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  const double scale = s.lambda * nb.length;  // px of disparity per unit z
  const float cx = nb.cx, cy = nb.cy;
  const double r_lim = radius_px + 0.5;
  // A disc well inside the image needs no bounds test per sample.
  const bool interior =
      cx - r_lim > 1 && cy - r_lim > 1 && cx + r_lim < width - 2 && cy + r_lim < height - 2;
  const int steps = SearchSteps(s, radius_px, px, py, nb, &z_lo, &z_hi);
  if (steps == 0) return false;
  const double dz = s.step_px / scale;
  // Strip sample j (0 .. steps - 1 + 4 spp) sits at along-offset
  // o_j = -2 - (steps - 1) step + j step from q(z_lo); step k, patch column
  // a reads j = (steps - 1 - k) + (a + 2) spp. Reversed (index
  // i = steps - 1 + 4 spp - j) step k reads i = k + (2 - a) spp, so the
  // cost loop runs forwards over k.
  const int spp = s.samples_per_px;
  const int strip_len = steps + 4 * spp;
  const float step = static_cast<float>(s.step_px);
  const double q0 = s.lambda * nb.length * (1.0 - z_lo);  // q(z_lo) = p + q0 e
  static_assert(kLines == 1 || kLines == 3);
  constexpr int kHalf = kLines / 2;
  float strip[kLines][kMaxSteps + 16 + kStripPad];
  const float r2 = static_cast<float>(r_lim * r_lim);
  const StripKernels* kernels = nullptr;
  if constexpr (requires {
                  grey.kernels;
                  grey.source;
                })
    if (interior) kernels = grey.kernels;
  const float along0 = static_cast<float>(q0) - 2.0f - (steps - 1) * step;
  for (int b = -kHalf; b <= kHalf; ++b) {
    float* line = strip[b + kHalf];
    // Line b: s(t) = p + b e_perp + t e; inside the disc for t in
    // [t_c - h, t_c + h] (t_c = (c - p - b e_perp) . e), so only those
    // strip samples are taken, without a test per sample.
    const float ox = px - b * nb.e_y - cx, oy = py + b * nb.e_x - cy;
    const float t_c = -(ox * nb.e_x + oy * nb.e_y);
    const float d2 = ox * ox + oy * oy - t_c * t_c;  // squared distance of c from the line
    int j_lo = strip_len, j_hi = -1;
    if (d2 < r2) {
      const float half = std::sqrt(r2 - d2);
      j_lo = std::max(0, CeilToInt((t_c - half - along0) / step));
      j_hi = std::min(strip_len - 1, FloorToInt((t_c + half - along0) / step));
    }
    if constexpr (requires {
                    grey.kernels;
                    grey.source;
                  }) {
      if (kernels != nullptr) {
        StripLine l;
        l.px = px;
        l.py = py;
        l.e_x = nb.e_x;
        l.e_y = nb.e_y;
        l.b_ey = static_cast<float>(b) * nb.e_y;
        l.b_ex = static_cast<float>(b) * nb.e_x;
        l.along0 = along0;
        l.step = step;
        l.n = strip_len;
        l.j_lo = j_lo;
        l.j_hi = j_hi;
        kernels->sample(grey.source, l, line);
        continue;
      }
    }
    for (int i = 0; i < strip_len; ++i) {
      const int j = strip_len - 1 - i;
      if (j < j_lo || j > j_hi) {
        line[i] = kNaN;
        continue;
      }
      const float along = along0 + j * step;
      const float x = px + along * nb.e_x - b * nb.e_y, y = py + along * nb.e_y + b * nb.e_x;
      if (!interior && (x < 0 || y < 0 || x >= width - 1 || y >= height - 1)) {
        line[i] = kNaN;
        continue;
      }
      const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
      line[i] = grey(x0, y0, x - x0, y - y0);
    }
  }
  float cost[kMaxSteps + kStripPad];
  if (kEqualise && s.blur_px_per_z > 0 && !nb.same_type) {
    std::array<const float*, kLines> lines;
    for (int b = 0; b < kLines; ++b) lines[b] = strip[b];
    EqualisedCosts<kLines>(s, grey, width, height, radius_px, px, py, nb, ref, lines.data(),
                           strip_len, steps, z_lo, dz,
                           kernels != nullptr ? kernels->costs : ScalarStripKernels().costs, cost);
  } else if (kernels != nullptr) {
    std::array<const float*, kLines> lines;
    for (int b = 0; b < kLines; ++b) lines[b] = strip[b];
    kernels->costs(lines.data(), kLines, ref, spp, steps, cost);
  } else {
    for (int k = 0; k < steps; ++k) cost[k] = 0;
    for (int b = 0; b < kLines; ++b)
      for (int a = -2; a <= 2; ++a) {
        const float r = ref[b * kAlong + a + 2];
        const float* line = strip[b] + (2 - a) * spp;
        for (int k = 0; k < steps; ++k) {
          const float d = line[k] - r;
          cost[k] += d * d;
        }
      }
  }
  int best = -1, first_valid = -1, last_valid = -1, run_n = 0;
  float best_cost = std::numeric_limits<float>::max();
  double run_sum = 0;
  for (int k = 0; k < steps; ++k) {
    const float c = cost[k];
    if (std::isnan(c)) continue;
    if (first_valid < 0) first_valid = k;
    last_valid = k;
    run_sum += c;
    ++run_n;
    if (c < best_cost) {
      best_cost = c;
      best = k;
    }
  }
  if (best < 0 || best <= first_valid || best >= last_valid) return false;
  if (std::isnan(cost[best - 1]) || std::isnan(cost[best + 1])) return false;
  // Distinctiveness: the minimum well below the mean cost over the run.
  const double noise2 = 2.0 * s.noise_dn * s.noise_dn;
  if (best_cost > s.max_cost_ratio * run_sum / run_n + kAlong * kLines * noise2) return false;
  const double cm = cost[best - 1], c0 = cost[best], cp = cost[best + 1];
  const double denom = cm - 2 * c0 + cp;
  const double delta = denom > 0 ? std::clamp(0.5 * (cm - cp) / denom, -0.5, 0.5) : 0.0;
  est->z = z_lo + (best + delta) * dz;
  const double model_px = nb.same_type ? s.geometric_px : s.cross_type_px;
  const double sigma_px2 = noise2 / std::max(gradient_sum, 1e-6) + model_px * model_px;
  est->sigma = std::sqrt(sigma_px2) / scale;
  return true;
}

// Estimates of one point (at most 12 baselines).
struct Estimates {
  std::array<Estimate, 12> e;
  int n = 0;
  void Add(const Estimate& x) { e[n++] = x; }
};

// Inverse-variance fusion in z of the estimates within max(3 sigma,
// rel_gate med) of `med` (their median): the others are outliers; returns
// the number used.
inline int FuseAround(const Estimate* e, int n, double med, double rel_gate, double* z,
                      double* sigma) {
  double sw = 0, swz = 0;
  int used = 0;
  for (int i = 0; i < n; ++i) {
    const Estimate& x = e[i];
    if (std::abs(x.z - med) > std::max(3 * x.sigma, rel_gate * med)) continue;
    const double w = 1.0 / (x.sigma * x.sigma);
    sw += w;
    swz += w * x.z;
    ++used;
  }
  if (used == 0) return 0;
  *z = swz / sw;
  *sigma = std::sqrt(1.0 / sw);
  return used;
}

// Median-consistent inverse-variance fusion in z: estimates farther than
// max(3 sigma, rel_gate z) from the median are outliers; returns the number used.
inline int Fuse(const Estimate* e, int n, double rel_gate, double* z, double* sigma) {
  if (n == 0) return 0;
  std::array<double, 64> zs;
  n = std::min(n, static_cast<int>(zs.size()));
  for (int i = 0; i < n; ++i) zs[i] = e[i].z;
  std::nth_element(zs.begin(), zs.begin() + n / 2, zs.begin() + n);
  return FuseAround(e, n, zs[n / 2], rel_gate, z, sigma);
}

inline int Fuse(const Estimates& es, double* z, double* sigma) {
  return Fuse(es.e.data(), es.n, 0.03, z, sigma);
}

}  // namespace lifmcr::processing::detail
