#include "processing/virtual_depth.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>

namespace lifmcr::processing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
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
  float delta_x = 0, delta_y = 0;  // c_n - c_k
  float e_x = 0, e_y = 0;          // unit baseline direction
  double length = 0;
  bool same_type = false;
  // Opposite neighbours (direction d and d + 3 of a ring) share their
  // reference patch, reversed: axis = 3 (ring - 1) + d mod 3.
  int axis = 0;
  bool flipped = false;
};

// Bilinear grey at (x, y) if within r2 of (cx, cy) and inside the image;
// NaN otherwise (and next to an invalid pixel: NaN propagates).
inline float SampleInDisc(const PlenopticFrame& f, float x, float y, float cx, float cy, float r2) {
  const float dx = x - cx, dy = y - cy;
  if (dx * dx + dy * dy > r2 || x < 0 || y < 0) return kNaN;
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  if (x0 >= f.width - 1 || y0 >= f.height - 1) return kNaN;
  const float fx = x - x0, fy = y - y0;
  const float* r0 = f.grey.data() + static_cast<std::size_t>(y0) * f.width + x0;
  const float* r1 = r0 + f.width;
  return (r0[0] + (r0[1] - r0[0]) * fx) * (1 - fy) + (r1[0] + (r1[1] - r1[0]) * fx) * fy;
}

// The reference patch around p: samples p + a e + b e_perp, a = -2..2
// (kAlong), b = -1..1 (kAcross), row-major by b; false if one is invalid.
bool SampleReference(const PlenopticFrame& f, float px, float py, const Neighbour& nb, float cx,
                     float cy, float r2, float* out) {
  for (int b = -1, m = 0; b <= 1; ++b)
    for (int a = -2; a <= 2; ++a, ++m) {
      out[m] =
          SampleInDisc(f, px + a * nb.e_x - b * nb.e_y, py + a * nb.e_y + b * nb.e_x, cx, cy, r2);
      if (std::isnan(out[m])) return false;
    }
  return true;
}

struct Search {
  const PlenopticFrame& f;
  const DepthOptions& o;
  double lambda;
  int samples_per_px;  // 1 / step_px
};

constexpr int kMaxSteps = 256;

// One baseline: best z in [z_lo, z_hi]; false when unconfirmed.
// The patch positions q(z_k) + a e + b e_perp of all steps k lie on three
// lines along e at a spacing of step_px, so the neighbour is sampled once
// per line (a strip) and the cost of step k reads the strip at a shift of
// k: 3 (K + 4 / step) bilinear samples instead of 15 K.
bool MatchAlong(const Search& s, float px, float py, const float* ref, double gradient_sum,
                const Neighbour& nb, double z_lo, double z_hi, Estimate* est) {
  const double scale = s.lambda * nb.length;  // px of disparity per unit z
  const PlenopticFrame& f = s.f;
  const float cx = static_cast<float>(nb.lens->centre_px.x());
  const float cy = static_cast<float>(nb.lens->centre_px.y());
  const double r_lim = f.radius_px + 0.5;
  // A disc well inside the image needs no bounds test per sample.
  const bool interior =
      cx - r_lim > 1 && cy - r_lim > 1 && cx + r_lim < f.width - 2 && cy + r_lim < f.height - 2;
  // Only the z for which q(z) = p + lambda Delta (1 - z) lies in the
  // neighbour's disc: |d - z u| <= R with u = lambda Delta, d = p + u - c_n.
  {
    const double ux = s.lambda * nb.delta_x, uy = s.lambda * nb.delta_y;
    const double dx = px + ux - cx, dy = py + uy - cy;
    const double uu = ux * ux + uy * uy, du = dx * ux + dy * uy;
    const double disc = du * du - uu * (dx * dx + dy * dy - r_lim * r_lim);
    if (disc <= 0) return false;
    const double root = std::sqrt(disc);
    z_lo = std::max(z_lo, (du - root) / uu);
    z_hi = std::min(z_hi, (du + root) / uu);
  }
  const double dz = s.o.step_px / scale;
  const int steps = static_cast<int>(std::ceil((z_hi - z_lo) / dz)) + 1;
  if (steps < 3 || steps > kMaxSteps) return false;
  // Strip sample j (0 .. steps - 1 + 4 spp) sits at along-offset
  // o_j = -2 - (steps - 1) step + j step from q(z_lo); step k, patch column
  // a reads j = (steps - 1 - k) + (a + 2) spp. Reversed (index
  // i = steps - 1 + 4 spp - j) step k reads i = k + (2 - a) spp, so the
  // cost loop runs forwards over k.
  const int spp = s.samples_per_px;
  const int strip_len = steps + 4 * spp;
  const float step = static_cast<float>(s.o.step_px);
  const double q0 = s.lambda * nb.length * (1.0 - z_lo);  // q(z_lo) = p + q0 e
  float strip[3][kMaxSteps + 16];
  const float r2 = static_cast<float>(r_lim * r_lim);
  const float along0 = static_cast<float>(q0) - 2.0f - (steps - 1) * step;
  for (int b = -1; b <= 1; ++b) {
    float* line = strip[b + 1];
    // Line b: s(t) = p + b e_perp + t e; inside the disc for t in
    // [t_c - h, t_c + h] (t_c = (c - p - b e_perp) . e), so only those
    // strip samples are taken, without a test per sample.
    const float ox = px - b * nb.e_y - cx, oy = py + b * nb.e_x - cy;
    const float t_c = -(ox * nb.e_x + oy * nb.e_y);
    const float d2 = ox * ox + oy * oy - t_c * t_c;  // squared distance of c from the line
    int j_lo = strip_len, j_hi = -1;
    if (d2 < r2) {
      const float half = std::sqrt(r2 - d2);
      j_lo = std::max(0, static_cast<int>(std::ceil((t_c - half - along0) / step)));
      j_hi = std::min(strip_len - 1, static_cast<int>(std::floor((t_c + half - along0) / step)));
    }
    const float* grey = f.grey.data();
    for (int i = 0; i < strip_len; ++i) {
      const int j = strip_len - 1 - i;
      if (j < j_lo || j > j_hi) {
        line[i] = kNaN;
        continue;
      }
      const float along = along0 + j * step;
      const float x = px + along * nb.e_x - b * nb.e_y, y = py + along * nb.e_y + b * nb.e_x;
      if (!interior && (x < 0 || y < 0 || x >= f.width - 1 || y >= f.height - 1)) {
        line[i] = kNaN;
        continue;
      }
      const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
      const float fx = x - x0, fy = y - y0;
      const float* r0 = grey + static_cast<std::size_t>(y0) * f.width + x0;
      const float* r1 = r0 + f.width;
      line[i] = (r0[0] + (r0[1] - r0[0]) * fx) * (1 - fy) + (r1[0] + (r1[1] - r1[0]) * fx) * fy;
    }
  }
  float cost[kMaxSteps];
  for (int k = 0; k < steps; ++k) cost[k] = 0;
  for (int b = 0; b < kAcross; ++b)
    for (int a = -2; a <= 2; ++a) {
      const float r = ref[b * kAlong + a + 2];
      const float* line = strip[b] + (2 - a) * spp;
      for (int k = 0; k < steps; ++k) {
        const float d = line[k] - r;
        cost[k] += d * d;
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
  const double noise2 = 2.0 * s.o.noise_dn * s.o.noise_dn;
  if (best_cost > s.o.max_cost_ratio * run_sum / run_n + kSamples * noise2) return false;
  const double cm = cost[best - 1], c0 = cost[best], cp = cost[best + 1];
  const double denom = cm - 2 * c0 + cp;
  const double delta = denom > 0 ? std::clamp(0.5 * (cm - cp) / denom, -0.5, 0.5) : 0.0;
  est->z = z_lo + (best + delta) * dz;
  const double model_px = nb.same_type ? s.o.geometric_px : s.o.cross_type_px;
  const double sigma_px2 = noise2 / std::max(gradient_sum, 1e-6) + model_px * model_px;
  est->sigma = std::sqrt(sigma_px2) / scale;
  return true;
}

// Median-consistent inverse-variance fusion; returns the number used.
struct Estimates {
  std::array<Estimate, 12> e;
  int n = 0;
  void Add(const Estimate& x) { e[n++] = x; }
};

int Fuse(const Estimates& es, double* z, double* sigma) {
  if (es.n == 0) return 0;
  std::array<double, 12> zs;
  for (int i = 0; i < es.n; ++i) zs[i] = es.e[i].z;
  std::nth_element(zs.begin(), zs.begin() + es.n / 2, zs.begin() + es.n);
  const double med = zs[es.n / 2];
  double sw = 0, swz = 0;
  int used = 0;
  for (int i = 0; i < es.n; ++i) {
    const Estimate& x = es.e[i];
    if (std::abs(x.z - med) > std::max(3 * x.sigma, 0.03 * med)) continue;
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

}  // namespace

Status DepthOptions::Check() const {
  if (!(min_gradient_dn >= 0)) return Error{"depth options: min_gradient_dn: expected >= 0"};
  if (!(noise_dn > 0)) return Error{"depth options: noise_dn: expected > 0"};
  if (step_px != 1.0 && step_px != 0.5 && step_px != 0.25)
    return Error{"depth options: step_px: expected 1, 0.5 or 0.25"};
  if (search_stride < 0 || search_stride > 2)
    return Error{"depth options: search_stride: expected 0 (auto), 1 or 2"};
  if (max_ring1 < 1 || max_ring1 > 6) return Error{"depth options: max_ring1: expected 1..6"};
  if (max_ring2 < 0 || max_ring2 > 6) return Error{"depth options: max_ring2: expected 0..6"};
  if (rings < 1 || rings > 2) return Error{"depth options: rings: expected 1 or 2"};
  if (min_estimates < 1) return Error{"depth options: min_estimates: expected >= 1"};
  if (!(geometric_px >= 0)) return Error{"depth options: geometric_px: expected >= 0"};
  if (!(cross_type_px >= 0)) return Error{"depth options: cross_type_px: expected >= 0"};
  if (smooth_radius_px < 0 || smooth_radius_px > 64)
    return Error{"depth options: smooth_radius_px: expected 0..64"};
  if (min_support < 1) return Error{"depth options: min_support: expected >= 1"};
  if (!(max_cost_ratio > 0 && max_cost_ratio <= 1))
    return Error{"depth options: max_cost_ratio: expected in (0, 1]"};
  // A divisor of the confidence (virtual_depth.h, step 4).
  if (!(max_rel_sigma > 0 && max_rel_sigma <= 10))
    return Error{"depth options: max_rel_sigma: expected in (0, 10]"};
  if (fill_min_support < 0) return Error{"depth options: fill_min_support: expected >= 0"};
  if (fill_radius_px < 0 || fill_radius_px > 64)
    return Error{"depth options: fill_radius_px: expected 0 (whole micro image)..64"};
  if (!(fill_max_spread > 0 && fill_max_spread <= 1))
    return Error{"depth options: fill_max_spread: expected in (0, 1]"};
  // type_ranges: any value.
  return Status::Ok();
}

std::string DepthStats::BriefReport() const {
  char buf[256];
  std::snprintf(
      buf, sizeof buf,
      "virtual depth: %lld of %lld textured pixels (%.1f %%; %lld valid), %lld rejected, "
      "%lld untextured filled, %.3f s",
      estimated, textured_pixels, textured_pixels ? 100.0 * estimated / textured_pixels : 0.0,
      valid_pixels, rejected, filled, seconds);
  return buf;
}

VirtualDepthRange SearchedVirtualDepths(const MlaLensType& type) {
  const double v_min = std::max(1.05, type.depth_min);
  return {v_min, std::max(v_min + 0.1, type.depth_max)};
}

Status EstimateVirtualDepth(const PlenopticFrame& f, const MlaCalibration& mla,
                            const DepthOptions& options, VirtualDepthMap* out) {
  if (Status s = options.Check(); !s) return s;
  const auto start = std::chrono::steady_clock::now();
  const int w = f.width, h = f.height;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  out->width = w;
  out->height = h;
  out->virtual_depth.assign(n, kNaN);
  out->sigma_z.assign(n, kNaN);
  out->confidence.assign(n, 0.0f);
  out->textured.assign(n, 0);
  // Search range per type: z = 1 / v.
  std::array<double, 3> z_lo{}, z_hi{};
  double union_lo = 1, union_hi = 0;
  for (int t = 0; t < 3; ++t) {
    const VirtualDepthRange range = SearchedVirtualDepths(mla.lens_types[t]);
    z_lo[t] = 1.0 / range.max;
    z_hi[t] = 1.0 / range.min;
    union_lo = std::min(union_lo, z_lo[t]);
    union_hi = std::max(union_hi, z_hi[t]);
  }
  const double lambda = f.lambda;
  const int stride =
      options.search_stride != 0 ? options.search_stride : (f.grid.PitchPx() >= 24 ? 2 : 1);
  const Search search{f, options, lambda, static_cast<int>(std::lround(1.0 / options.step_px))};
  std::vector<long long> textured_count(f.lenses.size(), 0), valid_count(f.lenses.size(), 0),
      estimated_count(f.lenses.size(), 0), rejected_count(f.lenses.size(), 0),
      filled_count(f.lenses.size(), 0);
  // Per micro image, its agreeing estimates' inverse-variance sums (step 5's
  // second part fills micro images without estimates from their ring 1).
  struct SurfaceSums {
    double w = 0, wz = 0, wzz = 0;
    int n = 0;
  };
  std::vector<SurfaceSums> lens_sums(f.lenses.size());
  std::vector<std::uint8_t> lens_has_depth(f.lenses.size(), 0);

  tbb::parallel_for(0, static_cast<int>(f.lenses.size()), [&](int k) {
    const MicroImage& lens = f.lenses[k];
    const double lo = options.type_ranges ? z_lo[lens.type] : union_lo;
    const double hi = options.type_ranges ? z_hi[lens.type] : union_hi;
    std::array<Neighbour, 12> nbs;
    int count = 0, ring1_count = 0;
    for (int ring = 1; ring <= options.rings; ++ring)
      for (int dir = 0; dir < 6; ++dir) {
        const auto& d = (ring == 1 ? kRing1 : kRing2)[dir];
        const int idx = f.LensAt(lens.i + d[0], lens.j + d[1]);
        if (idx < 0) continue;
        Neighbour& nb = nbs[count++];
        nb.axis = 3 * (ring - 1) + dir % 3;
        nb.flipped = dir >= 3;
        nb.lens = &f.lenses[idx];
        const Eigen::Vector2d delta = nb.lens->centre_px - lens.centre_px;
        nb.length = delta.norm();
        nb.delta_x = static_cast<float>(delta.x());
        nb.delta_y = static_cast<float>(delta.y());
        nb.e_x = static_cast<float>(delta.x() / nb.length);
        nb.e_y = static_cast<float>(delta.y() / nb.length);
        nb.same_type = nb.lens->type == lens.type;
        if (ring == 1) ring1_count = count;
      }
    const double r = f.radius_px;
    const float cx = static_cast<float>(lens.centre_px.x());
    const float cy = static_cast<float>(lens.centre_px.y());
    const float ref_r2 = static_cast<float>((r + 0.5) * (r + 0.5));
    const int x0 = std::max(1, static_cast<int>(std::ceil(lens.centre_px.x() - r)));
    const int x1 = std::min(w - 2, static_cast<int>(std::floor(lens.centre_px.x() + r)));
    const int y0 = std::max(1, static_cast<int>(std::ceil(lens.centre_px.y() - r)));
    const int y1 = std::min(h - 2, static_cast<int>(std::floor(lens.centre_px.y() + r)));
    const int bw = x1 - x0 + 1, bh = y1 - y0 + 1;
    if (bw <= 0 || bh <= 0) return;
    // The micro image's estimates on a local grid (z and sigma, NaN = none)
    // and its textured pixels, for the regularisation below.
    std::vector<float> patch_z(static_cast<std::size_t>(bw) * bh, kNaN);
    std::vector<float> patch_sigma(patch_z.size(), kNaN);
    std::vector<int> textured_pixels, untextured_pixels;
    // Per local pixel: searched (a checkerboard pixel was not) and failed.
    std::vector<std::uint8_t> search_failed(patch_z.size(), 0);
    float ref[kSamples];
    for (int y = y0; y <= y1; ++y) {
      // Only the row's chord of the disc (plus a pixel either side for
      // rounding; the map decides).
      const double dy = y - lens.centre_px.y(), chord2 = r * r - dy * dy;
      if (chord2 < 0) continue;
      const double half = std::sqrt(chord2);
      const int xa = std::max(x0, static_cast<int>(std::floor(lens.centre_px.x() - half)));
      const int xb = std::min(x1, static_cast<int>(std::ceil(lens.centre_px.x() + half)));
      for (int x = xa; x <= xb; ++x) {
        const std::size_t idx = static_cast<std::size_t>(y) * w + x;
        if (f.lens_of_pixel[idx] != k || std::isnan(f.grey[idx])) continue;
        ++valid_count[k];
        // Gradient gate along each ring-1 direction.
        const float gx = 0.5f * (f.Grey(x + 1, y) - f.Grey(x - 1, y));
        const float gy = 0.5f * (f.Grey(x, y + 1) - f.Grey(x, y - 1));
        if (std::isnan(gx) || std::isnan(gy)) continue;
        // Ring-1 baselines ordered by the gradient along them (the most
        // informative first); at most max_ring1 of them are searched.
        std::array<std::pair<float, int>, 6> order;
        int gated = 0;
        for (int m = 0; m < ring1_count; ++m) {
          const float g = std::abs(gx * nbs[m].e_x + gy * nbs[m].e_y);
          if (g >= options.min_gradient_dn) order[gated++] = {g, m};
        }
        if (gated == 0) {
          untextured_pixels.push_back((y - y0) * bw + (x - x0));
          continue;
        }
        out->textured[idx] = 1;
        ++textured_count[k];
        const int local = (y - y0) * bw + (x - x0);
        textured_pixels.push_back(local);
        // Searched pixels: all, or a checkerboard (the others are filled by
        // the regularisation from their searched neighbours).
        if (stride == 2 && ((x + y) & 1)) continue;
        for (int i = 1; i < gated; ++i)  // insertion sort, descending (at most 6)
          for (int j = i; j > 0 && order[j - 1].first < order[j].first; --j)
            std::swap(order[j - 1], order[j]);
        gated = std::min(gated, options.max_ring1);
        search_failed[local] = 1;  // until an estimate passes
        Estimates estimates;
        // Reference patches per axis, sampled along the unflipped direction;
        // a flipped neighbour reads it reversed ((a, b) -> (-a, -b)).
        std::array<std::int8_t, 6> patch_state{};  // 0 not yet, 1 valid, 2 invalid
        std::array<std::array<float, kSamples>, 6> patch_cache;
        std::array<double, 6> g2_cache;
        auto match = [&](const Neighbour& nb, double z0, double z1) {
          std::array<float, kSamples>& cached = patch_cache[nb.axis];
          if (patch_state[nb.axis] == 0) {
            Neighbour unflipped = nb;
            if (nb.flipped) {
              unflipped.e_x = -nb.e_x;
              unflipped.e_y = -nb.e_y;
            }
            const bool ok = SampleReference(f, static_cast<float>(x), static_cast<float>(y),
                                            unflipped, cx, cy, ref_r2, cached.data());
            patch_state[nb.axis] = ok ? 1 : 2;
            double g2 = 0;
            for (int b = 0; ok && b < kAcross; ++b)
              for (int a = 0; a + 2 < kAlong; ++a) {
                const double g = 0.5 * (cached[b * kAlong + a + 2] - cached[b * kAlong + a]);
                g2 += g * g;
              }
            g2_cache[nb.axis] = g2;
          }
          if (patch_state[nb.axis] != 1) return;
          for (int m = 0; m < kSamples; ++m)
            ref[m] = nb.flipped ? cached[kSamples - 1 - m] : cached[m];
          const double g2 = g2_cache[nb.axis];
          Estimate e;
          if (MatchAlong(search, static_cast<float>(x), static_cast<float>(y), ref, g2, nb, z0, z1,
                         &e))
            estimates.Add(e);
        };
        for (int q = 0; q < gated; ++q) match(nbs[order[q].second], lo, hi);
        double z = 0, sigma = 0;
        int used = Fuse(estimates, &z, &sigma);
        const bool have_prior = used > 0;
        // Longer baselines, searched around the current estimate (the whole
        // range when the short ones gave none).
        std::array<std::pair<float, int>, 6> order2;
        int gated2 = 0;
        for (int m = ring1_count; m < count; ++m) {
          const float g = std::abs(gx * nbs[m].e_x + gy * nbs[m].e_y);
          if (g >= options.min_gradient_dn) order2[gated2++] = {g, m};
        }
        for (int i = 1; i < gated2; ++i)  // insertion sort, descending (at most 6)
          for (int j = i; j > 0 && order2[j - 1].first < order2[j].first; --j)
            std::swap(order2[j - 1], order2[j]);
        gated2 = std::min(gated2, options.max_ring2);
        for (int q = 0; q < gated2; ++q) {
          const Neighbour& nb = nbs[order2[q].second];
          const double span = std::max(3 * sigma, 2 * options.step_px / (lambda * nb.length));
          match(nb, have_prior ? std::max(lo, z - span) : lo,
                have_prior ? std::min(hi, z + span) : hi);
        }
        used = Fuse(estimates, &z, &sigma);
        if (used < options.min_estimates || z <= 0) continue;
        if (sigma / z > options.max_rel_sigma) continue;
        patch_z[local] = static_cast<float>(z);
        patch_sigma[local] = static_cast<float>(sigma);
        search_failed[local] = 0;
      }
    }
    // Regularisation within the micro image: neighbouring pixels see nearby
    // virtual points. Over the (2 smooth_radius_px + 1)^2 window of each
    // textured pixel: the mean of the estimates, then the inverse-variance
    // mean over the estimates that agree with the mean of their own window
    // (within max(3 sigma, 5 %)); fewer than min_support agreeing, or a searched pixel itself
    // disagreeing: rejected (outlier). Window sums from summed-area tables,
    // O(1) per pixel.
    const int rad = options.smooth_radius_px;
    const int sw_ = bw + 1;  // summed-area tables are (bw + 1) x (bh + 1)
    std::vector<double> sat_w(static_cast<std::size_t>(sw_) * (bh + 1)), sat_wz(sat_w.size()),
        sat_wzz(sat_w.size());
    std::vector<std::int32_t> sat_n(sat_w.size());
    auto build = [&](auto weight_of) {
      for (int ly = 0; ly < bh; ++ly) {
        double row_w = 0, row_wz = 0, row_wzz = 0;
        std::int32_t row_n = 0;
        for (int lx = 0; lx < bw; ++lx) {
          const std::size_t i = static_cast<std::size_t>(ly) * bw + lx;
          const double wgt = weight_of(i);
          if (wgt > 0) {
            row_w += wgt;
            row_wz += wgt * patch_z[i];
            row_wzz += wgt * patch_z[i] * patch_z[i];
            ++row_n;
          }
          const std::size_t o = static_cast<std::size_t>(ly + 1) * sw_ + lx + 1;
          sat_w[o] = sat_w[o - sw_] + row_w;
          sat_wz[o] = sat_wz[o - sw_] + row_wz;
          sat_wzz[o] = sat_wzz[o - sw_] + row_wzz;
          sat_n[o] = sat_n[o - sw_] + row_n;
        }
      }
    };
    struct WindowSum {
      double w, wz, wzz;
      int n;
    };
    auto window = [&](int lx, int ly, int radius) {
      const int xa = std::max(0, lx - radius), xb = std::min(bw, lx + radius + 1);
      const int ya = std::max(0, ly - radius), yb = std::min(bh, ly + radius + 1);
      const std::size_t i11 = static_cast<std::size_t>(yb) * sw_ + xb;
      const std::size_t i01 = static_cast<std::size_t>(ya) * sw_ + xb;
      const std::size_t i10 = static_cast<std::size_t>(yb) * sw_ + xa;
      const std::size_t i00 = static_cast<std::size_t>(ya) * sw_ + xa;
      return WindowSum{sat_w[i11] - sat_w[i01] - sat_w[i10] + sat_w[i00],
                       sat_wz[i11] - sat_wz[i01] - sat_wz[i10] + sat_wz[i00],
                       sat_wzz[i11] - sat_wzz[i01] - sat_wzz[i10] + sat_wzz[i00],
                       sat_n[i11] - sat_n[i01] - sat_n[i10] + sat_n[i00]};
    };
    auto agrees = [](double z, double sigma, double mean) {
      return std::abs(z - mean) <= std::max(3 * sigma, 0.05 * mean);
    };
    // Pass 1: the plain window means at the estimates (unweighted: a few
    // estimates with tiny sigma, at strong edges, must not set the
    // reference alone), which then vote.
    build([&](std::size_t i) { return std::isnan(patch_z[i]) ? 0.0 : 1.0; });
    std::vector<std::uint8_t> inlier(patch_z.size(), 0);
    for (int ly = 0; ly < bh; ++ly)
      for (int lx = 0; lx < bw; ++lx) {
        const std::size_t i = static_cast<std::size_t>(ly) * bw + lx;
        if (std::isnan(patch_z[i])) continue;
        const WindowSum ws = window(lx, ly, rad);
        inlier[i] = agrees(patch_z[i], patch_sigma[i], ws.wz / ws.w);
      }
    // Pass 2: the means over the agreeing estimates.
    build([&](std::size_t i) {
      const float sg = patch_sigma[i];
      return inlier[i] ? 1.0 / (static_cast<double>(sg) * sg) : 0.0;
    });
    for (const int local : textured_pixels) {
      if (search_failed[local]) continue;  // no fill where the search itself failed
      const int lx = local % bw, ly = local / bw;
      const float own_z = patch_z[local], own_sigma = patch_sigma[local];
      const bool searched = !std::isnan(own_z);
      const WindowSum ws = window(lx, ly, rad);
      if (ws.n < options.min_support || (searched && !inlier[local])) {
        rejected_count[k] += searched;
        continue;
      }
      const double z = ws.wz / ws.w;
      if (searched && !agrees(own_z, own_sigma, z)) {
        ++rejected_count[k];
        continue;
      }
      // The neighbours are not independent views of one point: a searched
      // pixel keeps its own sigma shrunk by at most sqrt(support); a filled
      // one takes the fused sigma of its window.
      const double sigma =
          searched ? own_sigma / std::sqrt(static_cast<double>(ws.n)) : std::sqrt(1.0 / ws.w);
      const std::size_t idx = static_cast<std::size_t>(y0 + ly) * w + (x0 + lx);
      out->virtual_depth[idx] = static_cast<float>(1.0 / z);
      out->sigma_z[idx] = static_cast<float>(sigma);
      out->confidence[idx] =
          static_cast<float>(std::clamp(1.0 - (sigma / z) / options.max_rel_sigma, 0.0, 1.0));
      ++estimated_count[k];
    }
    {
      const WindowSum all = window(0, 0, bw + bh);
      lens_sums[k] = SurfaceSums{all.w, all.wz, all.wzz, all.n};
      lens_has_depth[k] = estimated_count[k] > 0;
    }
    // Untextured pixels (step 5 in virtual_depth.h): the search has nothing
    // to match there, but a micro image images a small patch of the scene, so
    // where the agreeing estimates around a pixel (pass 2's inliers) are many
    // and lie on one depth, the pixel sees that surface too.
    if (options.fill_min_support > 0) {
      // A textured pixel whose own search failed (no distinct minimum) is
      // filled alike: its surface is the one around it.
      for (const int local : textured_pixels)
        if (search_failed[local] || (std::isnan(patch_z[local]) && !inlier[local]))
          untextured_pixels.push_back(local);
      const int fill_radius = options.fill_radius_px > 0 ? options.fill_radius_px : bw + bh;
      for (const int local : untextured_pixels) {
        const std::size_t at = static_cast<std::size_t>(y0 + local / bw) * w + (x0 + local % bw);
        if (!std::isnan(out->virtual_depth[at])) continue;
        const WindowSum ws = window(local % bw, local / bw, fill_radius);
        if (ws.n < options.fill_min_support) continue;
        const double z = ws.wz / ws.w;
        const double spread2 = std::max(0.0, ws.wzz / ws.w - z * z);
        if (spread2 > options.fill_max_spread * options.fill_max_spread * z * z) continue;
        // As uncertain as one supporting estimate (their harmonic mean
        // sigma), or as their spread where that is larger: the supports are
        // not independent views of this pixel's point.
        const double sigma = std::sqrt(std::max(ws.n / ws.w, spread2));
        out->virtual_depth[at] = static_cast<float>(1.0 / z);
        out->sigma_z[at] = static_cast<float>(sigma);
        out->confidence[at] =
            static_cast<float>(std::clamp(1.0 - (sigma / z) / options.max_rel_sigma, 0.0, 1.0));
        ++filled_count[k];
        lens_has_depth[k] = 1;
      }
    }
  });
  // Micro images without any depth whose ring-1 neighbours' agreeing
  // estimates lie on one surface: with v > 2 neighbouring micro images image
  // overlapping patches of the scene, so the surface they agree on covers
  // this one too. Reads only the first pass's sums, writes only its own
  // micro image's pixels.
  if (options.fill_min_support > 0 && options.fill_from_neighbours) {
    tbb::parallel_for(0, static_cast<int>(f.lenses.size()), [&](int k) {
      if (lens_has_depth[k] || valid_count[k] == 0) return;
      const MicroImage& lens = f.lenses[k];
      SurfaceSums sum;
      int contributing = 0;
      for (const auto& d : kRing1) {
        const int idx = f.LensAt(lens.i + d[0], lens.j + d[1]);
        if (idx < 0 || lens_sums[idx].n < options.fill_min_support) continue;
        ++contributing;
        sum.w += lens_sums[idx].w;
        sum.wz += lens_sums[idx].wz;
        sum.wzz += lens_sums[idx].wzz;
        sum.n += lens_sums[idx].n;
      }
      if (contributing < 3) return;  // a surface seen around it, not beside it
      const double z = sum.wz / sum.w;
      const double spread2 = std::max(0.0, sum.wzz / sum.w - z * z);
      if (spread2 > options.fill_max_spread * options.fill_max_spread * z * z) return;
      const double sigma = std::sqrt(std::max(sum.n / sum.w, spread2));
      const float conf =
          static_cast<float>(std::clamp(1.0 - (sigma / z) / options.max_rel_sigma, 0.0, 1.0));
      const double r = f.radius_px;
      const int x0 = std::max(0, static_cast<int>(std::floor(lens.centre_px.x() - r)));
      const int x1 = std::min(w - 1, static_cast<int>(std::ceil(lens.centre_px.x() + r)));
      const int y0 = std::max(0, static_cast<int>(std::floor(lens.centre_px.y() - r)));
      const int y1 = std::min(h - 1, static_cast<int>(std::ceil(lens.centre_px.y() + r)));
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) {
          const std::size_t at = static_cast<std::size_t>(y) * w + x;
          if (f.lens_of_pixel[at] != k || std::isnan(f.grey[at])) continue;
          out->virtual_depth[at] = static_cast<float>(1.0 / z);
          out->sigma_z[at] = static_cast<float>(sigma);
          out->confidence[at] = conf;
          ++filled_count[k];
        }
    });
  }
  DepthStats& st = out->stats;
  st = DepthStats{};
  for (std::size_t k = 0; k < f.lenses.size(); ++k) {
    st.valid_pixels += valid_count[k];
    st.textured_pixels += textured_count[k];
    st.estimated += estimated_count[k];
    st.rejected += rejected_count[k];
    st.filled += filled_count[k];
  }
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return Status::Ok();
}

}  // namespace lifmcr::processing
