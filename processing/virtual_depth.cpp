#include "processing/virtual_depth.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

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
  Eigen::Vector2d delta;  // c_n - c_k
  Eigen::Vector2d e, e_perp;
  double length = 0;
  bool same_type = false;
  std::array<double, kSamples> offset_x{}, offset_y{};
};

// Patch samples around p: offsets a e + b e_perp, a = -2..2, b = -1..1.
// Samples must lie within r_limit of the micro image's centre `c`. The
// offsets a e + b e_perp (a = -2..2, b = -1..1) are the neighbour's `offset`.
bool SamplePatch(const PlenopticFrame& f, const Eigen::Vector2d& p, const Neighbour& nb,
                 const Eigen::Vector2d& c, double r_limit, float* out) {
  const double r2 = r_limit * r_limit;
  const double px = p.x(), py = p.y(), cx = c.x(), cy = c.y();
  const int w = f.width, h = f.height;
  const float* grey = f.grey.data();
  for (int k = 0; k < kSamples; ++k) {
    const double sx = px + nb.offset_x[k], sy = py + nb.offset_y[k];
    if ((sx - cx) * (sx - cx) + (sy - cy) * (sy - cy) > r2) return false;
    const int x0 = static_cast<int>(sx), y0 = static_cast<int>(sy);
    if (sx < 0 || sy < 0 || x0 >= w - 1 || y0 >= h - 1) return false;
    const float fx = static_cast<float>(sx - x0), fy = static_cast<float>(sy - y0);
    const float* r0 = grey + static_cast<std::size_t>(y0) * w + x0;
    const float* r1 = r0 + w;
    const float v = (r0[0] + (r0[1] - r0[0]) * fx) * (1 - fy) + (r1[0] + (r1[1] - r1[0]) * fx) * fy;
    if (std::isnan(v)) return false;
    out[k] = v;
  }
  return true;
}

struct Search {
  const PlenopticFrame& f;
  const DepthOptions& o;
  double lambda;
};

// One baseline: best z in [z_lo, z_hi]; false when unconfirmed.
bool MatchAlong(const Search& s, const Eigen::Vector2d& p, const float* ref, double gradient_sum,
                const Neighbour& nb, double z_lo, double z_hi, Estimate* est) {
  const double scale = s.lambda * nb.length;  // px of disparity per unit z
  // Only the z for which q(z) = p + lambda Delta (1 - z) lies in the
  // neighbour's disc: |d - z u| <= R with u = lambda Delta, d = p + u - c_n.
  {
    const Eigen::Vector2d u = s.lambda * nb.delta;
    const Eigen::Vector2d d = p + u - nb.lens->centre_px;
    const double uu = u.squaredNorm(), du = d.dot(u), r_lim = s.f.radius_px + 0.5;
    const double disc = du * du - uu * (d.squaredNorm() - r_lim * r_lim);
    if (disc <= 0) return false;
    const double root = std::sqrt(disc);
    z_lo = std::max(z_lo, (du - root) / uu);
    z_hi = std::min(z_hi, (du + root) / uu);
  }
  const double dz = s.o.step_px / scale;
  const int steps = static_cast<int>(std::ceil((z_hi - z_lo) / dz)) + 1;
  if (steps < 3) return false;
  constexpr int kMaxSteps = 256;
  if (steps > kMaxSteps) return false;
  std::array<double, kMaxSteps> cost;
  const double r_limit = s.f.radius_px + 0.5;
  int best = -1;
  double best_cost = std::numeric_limits<double>::max();
  int first_valid = -1, last_valid = -1;
  float patch[kSamples];
  for (int k = 0; k < steps; ++k) {
    const double z = z_lo + k * dz;
    const Eigen::Vector2d q = p + s.lambda * nb.delta * (1.0 - z);
    cost[k] = std::numeric_limits<double>::infinity();
    if (!SamplePatch(s.f, q, nb, nb.lens->centre_px, r_limit, patch)) continue;
    double c = 0;
    for (int m = 0; m < kSamples; ++m) {
      const double d = patch[m] - ref[m];
      c += d * d;
    }
    cost[k] = c;
    if (first_valid < 0) first_valid = k;
    last_valid = k;
    if (c < best_cost) {
      best_cost = c;
      best = k;
    }
  }
  if (best < 0) return false;
  if (best <= first_valid || best >= last_valid) return false;
  if (!std::isfinite(cost[best - 1]) || !std::isfinite(cost[best + 1])) return false;
  // Distinctiveness: the minimum well below the mean cost over the run.
  double run_sum = 0;
  int run_n = 0;
  for (int k = first_valid; k <= last_valid; ++k)
    if (std::isfinite(cost[k])) {
      run_sum += cost[k];
      ++run_n;
    }
  const double noise2 = 2.0 * s.o.noise_dn * s.o.noise_dn;
  if (best_cost > s.o.max_cost_ratio * run_sum / run_n + kSamples * noise2) {
    return false;
  }
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
int Fuse(std::vector<Estimate>& e, double* z, double* sigma) {
  if (e.empty()) return 0;
  std::vector<double> zs;
  for (const Estimate& x : e) zs.push_back(x.z);
  std::nth_element(zs.begin(), zs.begin() + zs.size() / 2, zs.end());
  const double med = zs[zs.size() / 2];
  double sw = 0, swz = 0;
  int used = 0;
  for (const Estimate& x : e) {
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
  if (!(step_px > 0.05 && step_px <= 2)) return Error{"depth options: step_px: expected 0.05..2"};
  if (rings < 1 || rings > 2) return Error{"depth options: rings: expected 1 or 2"};
  if (min_estimates < 1) return Error{"depth options: min_estimates: expected >= 1"};
  return Status::Ok();
}

std::string DepthStats::BriefReport() const {
  char buf[256];
  std::snprintf(
      buf, sizeof buf,
      "virtual depth: %lld of %lld textured pixels (%.1f %%; %lld valid), %lld rejected, %.3f s",
      estimated, textured_pixels, textured_pixels ? 100.0 * estimated / textured_pixels : 0.0,
      valid_pixels, rejected, seconds);
  return buf;
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
    const double v_min = std::max(1.05, mla.lens_types[t].depth_min);
    const double v_max = std::max(v_min + 0.1, mla.lens_types[t].depth_max);
    z_lo[t] = 1.0 / v_max;
    z_hi[t] = 1.0 / v_min;
    union_lo = std::min(union_lo, z_lo[t]);
    union_hi = std::max(union_hi, z_hi[t]);
  }
  const double lambda = f.lambda;
  const Search search{f, options, lambda};
  std::vector<long long> textured_count(f.lenses.size(), 0), valid_count(f.lenses.size(), 0),
      estimated_count(f.lenses.size(), 0), rejected_count(f.lenses.size(), 0);

  tbb::parallel_for(0, static_cast<int>(f.lenses.size()), [&](int k) {
    const MicroImage& lens = f.lenses[k];
    const double lo = options.type_ranges ? z_lo[lens.type] : union_lo;
    const double hi = options.type_ranges ? z_hi[lens.type] : union_hi;
    std::array<Neighbour, 12> nbs;
    int count = 0, ring1_count = 0;
    for (int ring = 1; ring <= options.rings; ++ring)
      for (const auto& d : ring == 1 ? kRing1 : kRing2) {
        const int idx = f.LensAt(lens.i + d[0], lens.j + d[1]);
        if (idx < 0) continue;
        Neighbour& nb = nbs[count++];
        nb.lens = &f.lenses[idx];
        nb.delta = nb.lens->centre_px - lens.centre_px;
        nb.length = nb.delta.norm();
        nb.e = nb.delta / nb.length;
        nb.e_perp = {-nb.e.y(), nb.e.x()};
        nb.same_type = nb.lens->type == lens.type;
        for (int b = -1, m = 0; b <= 1; ++b)
          for (int a = -2; a <= 2; ++a, ++m) {
            nb.offset_x[m] = a * nb.e.x() + b * nb.e_perp.x();
            nb.offset_y[m] = a * nb.e.y() + b * nb.e_perp.y();
          }
        if (ring == 1) ring1_count = count;
      }
    const double r = f.radius_px;
    const int x0 = std::max(1, static_cast<int>(std::ceil(lens.centre_px.x() - r)));
    const int x1 = std::min(w - 2, static_cast<int>(std::floor(lens.centre_px.x() + r)));
    const int y0 = std::max(1, static_cast<int>(std::ceil(lens.centre_px.y() - r)));
    const int y1 = std::min(h - 2, static_cast<int>(std::floor(lens.centre_px.y() + r)));
    std::vector<Estimate> estimates;
    std::vector<std::size_t> pixels;
    std::vector<float> patch_z, patch_sigma;
    float ref[kSamples];
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const std::size_t idx = static_cast<std::size_t>(y) * w + x;
        if (f.lens_of_pixel[idx] != k || std::isnan(f.grey[idx])) continue;
        ++valid_count[k];
        const Eigen::Vector2d p(x, y);
        // Gradient gate along each ring-1 direction.
        bool textured = false;
        const float gx = 0.5f * (f.Grey(x + 1, y) - f.Grey(x - 1, y));
        const float gy = 0.5f * (f.Grey(x, y + 1) - f.Grey(x, y - 1));
        if (std::isnan(gx) || std::isnan(gy)) continue;
        for (int m = 0; m < ring1_count; ++m)
          if (std::abs(gx * nbs[m].e.x() + gy * nbs[m].e.y()) >= options.min_gradient_dn)
            textured = true;
        if (!textured) continue;
        out->textured[idx] = 1;
        ++textured_count[k];
        estimates.clear();
        for (int m = 0; m < ring1_count; ++m) {
          const Neighbour& nb = nbs[m];
          if (std::abs(gx * nb.e.x() + gy * nb.e.y()) < options.min_gradient_dn) continue;
          if (!SamplePatch(f, p, nb, lens.centre_px, r + 0.5, ref)) continue;
          double g2 = 0;
          for (int b = 0; b < kAcross; ++b)
            for (int a = 0; a + 2 < kAlong; ++a) {
              const double g = 0.5 * (ref[b * kAlong + a + 2] - ref[b * kAlong + a]);
              g2 += g * g;
            }
          Estimate e;
          if (MatchAlong(search, p, ref, g2, nb, lo, hi, &e)) estimates.push_back(e);
        }
        double z = 0, sigma = 0;
        int used = Fuse(estimates, &z, &sigma);
        const bool have_prior = used > 0;
        // Longer baselines, searched around the current estimate (the whole
        // range when the short ones gave none).
        for (int m = ring1_count; m < count; ++m) {
          const Neighbour& nb = nbs[m];
          if (std::abs(gx * nb.e.x() + gy * nb.e.y()) < options.min_gradient_dn) continue;
          if (!SamplePatch(f, p, nb, lens.centre_px, r + 0.5, ref)) continue;
          double g2 = 0;
          for (int b = 0; b < kAcross; ++b)
            for (int a = 0; a + 2 < kAlong; ++a) {
              const double g = 0.5 * (ref[b * kAlong + a + 2] - ref[b * kAlong + a]);
              g2 += g * g;
            }
          const double span = std::max(3 * sigma, 2 * options.step_px / (lambda * nb.length));
          Estimate e;
          const double z0 = have_prior ? std::max(lo, z - span) : lo;
          const double z1 = have_prior ? std::min(hi, z + span) : hi;
          if (MatchAlong(search, p, ref, g2, nb, z0, z1, &e)) estimates.push_back(e);
        }
        used = Fuse(estimates, &z, &sigma);
        if (used < options.min_estimates || z <= 0) continue;
        if (sigma / z > options.max_rel_sigma) continue;
        out->virtual_depth[idx] = static_cast<float>(1.0 / z);
        out->sigma_z[idx] = static_cast<float>(sigma);
        out->confidence[idx] =
            static_cast<float>(std::clamp(1.0 - (sigma / z) / options.max_rel_sigma, 0.0, 1.0));
        pixels.push_back(idx);
      }
    // Regularisation within the micro image: neighbouring pixels see nearby
    // virtual points. Each estimate becomes the inverse-variance mean of the
    // estimates within `smooth_radius_px` that agree with their median
    // (within max(3 sigma, 5 %)); fewer than min_support agreeing: rejected.
    // Local grid of the micro image's estimates (z and sigma, NaN = none).
    const int bw = x1 - x0 + 1, bh = y1 - y0 + 1;
    if (bw <= 0 || bh <= 0) return;
    patch_z.assign(static_cast<std::size_t>(bw) * bh, kNaN);
    patch_sigma.assign(patch_z.size(), kNaN);
    for (std::size_t idx : pixels) {
      const int lx = static_cast<int>(idx % w) - x0, ly = static_cast<int>(idx / w) - y0;
      patch_z[static_cast<std::size_t>(ly) * bw + lx] = 1.0f / out->virtual_depth[idx];
      patch_sigma[static_cast<std::size_t>(ly) * bw + lx] = out->sigma_z[idx];
    }
    const int rad = options.smooth_radius_px;
    std::vector<float> near_z, near_s, sorted;
    for (std::size_t idx : pixels) {
      const int lx = static_cast<int>(idx % w) - x0, ly = static_cast<int>(idx / w) - y0;
      near_z.clear();
      near_s.clear();
      for (int yy = std::max(0, ly - rad); yy <= std::min(bh - 1, ly + rad); ++yy)
        for (int xx = std::max(0, lx - rad); xx <= std::min(bw - 1, lx + rad); ++xx) {
          const float z = patch_z[static_cast<std::size_t>(yy) * bw + xx];
          if (std::isnan(z)) continue;
          near_z.push_back(z);
          near_s.push_back(patch_sigma[static_cast<std::size_t>(yy) * bw + xx]);
        }
      sorted = near_z;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      const double med = sorted[sorted.size() / 2];
      double sw = 0, swz = 0;
      int support = 0;
      for (std::size_t m = 0; m < near_z.size(); ++m) {
        const double sg = near_s[m];
        if (std::abs(near_z[m] - med) > std::max(3 * sg, 0.05 * med)) continue;
        sw += 1 / (sg * sg);
        swz += near_z[m] / (sg * sg);
        ++support;
      }
      const float own_z = patch_z[static_cast<std::size_t>(ly) * bw + lx];
      const float own_sigma = patch_sigma[static_cast<std::size_t>(ly) * bw + lx];
      if (support < options.min_support ||
          std::abs(own_z - med) > std::max(3.0 * own_sigma, 0.05 * med)) {
        out->virtual_depth[idx] = kNaN;
        out->sigma_z[idx] = kNaN;
        out->confidence[idx] = 0;
        ++rejected_count[k];
        continue;
      }
      const double z = swz / sw;
      // The neighbours are not independent views of one point: keep the
      // pixel's own sigma, shrunk by at most sqrt(support).
      const double sigma = own_sigma / std::sqrt(static_cast<double>(support));
      out->virtual_depth[idx] = static_cast<float>(1.0 / z);
      out->sigma_z[idx] = static_cast<float>(sigma);
      out->confidence[idx] =
          static_cast<float>(std::clamp(1.0 - (sigma / z) / options.max_rel_sigma, 0.0, 1.0));
      ++estimated_count[k];
    }
  });
  DepthStats& st = out->stats;
  st = DepthStats{};
  for (std::size_t k = 0; k < f.lenses.size(); ++k) {
    st.valid_pixels += valid_count[k];
    st.textured_pixels += textured_count[k];
    st.estimated += estimated_count[k];
    st.rejected += rejected_count[k];
  }
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return Status::Ok();
}

}  // namespace lifmcr::processing
