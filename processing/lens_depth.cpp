// Per-lens virtual depth (lens_depth.h).

#include "processing/lens_depth.h"

#include "processing/epipolar_search.h"
#include "processing/grey_plane_simd.h"
#include "processing/lens_search_simd.h"
#include "processing/tf_blend_simd.h"
#include "processing/tf_kernel.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <utility>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <type_traits>

namespace lifmcr::processing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr int kMaxSamples = 16;
// Pixels the temporal seed searches at most before the full search.
constexpr int kSeedPixels = 2;
// Lenses ahead whose window's leading edge is asked of the cache (Estimate).
constexpr int kPrefetchAhead = 2;

// The devignetted grey of the raw frame at an integer pixel and bilinear:
// the channel mean times the gain (plenoptic_frame.h), NaN where the gain is.
template <int kChannels>
struct RawGrey {
  const ConstImageView& raw;
  const detail::Gain16& gain;
  int width;
  // The strips of discs well inside the frame (epipolar_search.h); null:
  // through operator() below.
  const detail::StripKernels* kernels = nullptr;
  detail::StripSource source{};
  // The raw grey level (channel sum) at an integer pixel, without the gain.
  int RawSum(int x, int y) const {
    const std::uint8_t* p = raw.Row(y) + x * kChannels;
    if constexpr (kChannels == 3) return p[0] + p[1] + p[2];
    return p[0];
  }
  float Gain(int x, int y) const { return gain.At(static_cast<std::size_t>(y) * width + x); }
  float operator()(int x0, int y0, float fx, float fy) const {
    const std::uint8_t* q0 = raw.Row(y0) + x0 * kChannels;
    const std::uint8_t* q1 = raw.Row(y0 + 1) + x0 * kChannels;
    const std::uint16_t* g0 = gain.q.data() + static_cast<std::size_t>(y0) * width + x0;
    return detail::RawGainBilinear<kChannels>(q0, q1, g0, g0 + width, gain.scale, fx, fy);
  }
};

// The candidate offsets as the gate kernel reads them: dx, dy padded with
// kStripPad zeros (the centre); reach the largest |dx|, |dy|.
struct CandidateGate {
  const std::int32_t* dx = nullptr;
  const std::int32_t* dy = nullptr;
  int n = 0;
  int reach = 0;
};

// Storage of N T whose default member initialisers do not run: every
// element is written before it is read, and zeroing the estimates and the
// neighbours of every micro image was 2 % of the estimator's instructions.
template <typename T, int N>
struct Uninitialised {
  static_assert(std::is_trivially_destructible_v<T>);
  Uninitialised() {}
  union {
    T v[N];
  };
};

// The median of z over e[0..n) (n <= 4 kMaxSamples): the value nth_element
// puts at n / 2, by an insertion sort (a micro image has 1-8 estimates:
// nth_element's set-up cost more than the sort).
double MedianZ(const detail::Estimate* e, int n) {
  std::array<double, 4 * kMaxSamples> zs;
  for (int i = 0; i < n; ++i) {
    const double z = e[i].z;
    int q = i;
    for (; q > 0 && zs[q - 1] > z; --q) zs[q] = zs[q - 1];
    zs[q] = z;
  }
  return zs[n / 2];
}

// detail::Fuse of epipolar_search.h (the same numbers) for the few
// estimates of a micro image: its median through MedianZ.
int FuseFew(const detail::Estimate* e, int n, double rel_gate, double* z, double* sigma) {
  if (n == 0) return 0;
  return detail::FuseAround(e, n, MedianZ(e, n), rel_gate, z, sigma);
}

// Asks the cache for the line at p. An asm statement where there is one:
// GCC 12 drops a __builtin_prefetch in a loop that does nothing else (its
// dead-code elimination; the prefetches below compiled to nothing).
inline void PrefetchLine(const void* p) {
#if defined(__x86_64__) || defined(__i386__)
  asm volatile("prefetcht0 %0" ::"m"(*static_cast<const char*>(p)));
#elif defined(__aarch64__)
  asm volatile("prfm pldl1keep, %0" ::"Q"(*static_cast<const char*>(p)));
#else
  __builtin_prefetch(p);
#endif
}

// What a range of micro images did (LensDepthStats).
struct LensCounts {
  long long searched = 0, textured = 0, estimated = 0, seeded = 0, held = 0, predicted = 0,
            predicted_held = 0;
};

// A thread's buffers of the candidate gate (scores and axes of a micro
// image's candidates, kStripPad beyond them for the kernel): grown on a
// thread's first micro image, then reused.
struct GateScratch {
  std::vector<float> score;
  std::vector<std::int32_t> axis;
  void Reserve(int n) {
    if (score.size() < static_cast<std::size_t>(n + detail::kStripPad)) {
      score.resize(n + detail::kStripPad);
      axis.resize(n + detail::kStripPad);
    }
  }
};

struct Candidate {
  float score = 0;
  int x = 0, y = 0;
  int axis = 0;  // best ring-1 axis (0..2)
};

}  // namespace

Status LensDepthOptions::Check() const {
  if (samples < 1 || samples > kMaxSamples)
    return Error{"lens depth options: samples: expected 1..16"};
  if (!(candidate_step_px == 0 || (candidate_step_px >= 1 && candidate_step_px <= 8)))
    return Error{"lens depth options: candidate_step_px: expected 0 (auto) or 1..8"};
  if (!(candidate_fraction > 0 && candidate_fraction <= 1))
    return Error{"lens depth options: candidate_fraction: expected in (0, 1]"};
  if (!(min_gradient_dn >= 0)) return Error{"lens depth options: min_gradient_dn: expected >= 0"};
  if (!(noise_dn > 0)) return Error{"lens depth options: noise_dn: expected > 0"};
  for (const double step : {ring1_step_px, ring2_step_px})
    if (step != 1.0 && step != 0.5 && step != 0.25)
      return Error{std::string("lens depth options: ") +
                   (step == ring1_step_px ? "ring1_step_px" : "ring2_step_px") +
                   ": expected 1, 0.5 or 0.25"};
  if (rings < 1 || rings > 2) return Error{"lens depth options: rings: expected 1 or 2"};
  if (ring1_lines != 1 && ring1_lines != 3)
    return Error{"lens depth options: ring1_lines: expected 1 or 3"};
  if (!(geometric_px >= 0)) return Error{"lens depth options: geometric_px: expected >= 0"};
  if (!(cross_type_px >= 0)) return Error{"lens depth options: cross_type_px: expected >= 0"};
  if (!(max_cost_ratio > 0 && max_cost_ratio <= 1))
    return Error{"lens depth options: max_cost_ratio: expected in (0, 1]"};
  if (!(fuse_gate > 0 && fuse_gate <= 1))
    return Error{"lens depth options: fuse_gate: expected in (0, 1]"};
  if (min_estimates < 1) return Error{"lens depth options: min_estimates: expected >= 1"};
  if (enough_estimates < min_estimates)
    return Error{"lens depth options: enough_estimates: expected >= min_estimates"};
  // A divisor of the confidence.
  if (!(max_rel_sigma > 0 && max_rel_sigma <= 10))
    return Error{"lens depth options: max_rel_sigma: expected in (0, 10]"};
  if (!(seed_window > 0 && seed_window <= 1))
    return Error{"lens depth options: seed_window: expected in (0, 1]"};
  return Status::Ok();
}

std::string LensDepthStats::BriefReport() const {
  char buf[320];
  const int n = std::snprintf(
      buf, sizeof buf,
      "lens depth: %lld of %lld textured lenses (%.1f %%; %lld lenses), %lld pixels searched, "
      "%.4f s, kernels %s",
      estimated, textured, textured ? 100.0 * estimated / textured : 0.0, lenses, searched_pixels,
      seconds, kernels[0] ? kernels : "none");
  int at = n;
  if (seeded > 0 && at > 0 && at < static_cast<int>(sizeof buf))
    at += std::snprintf(buf + at, sizeof buf - at, ", previous depth held in %lld of %lld lenses",
                        seed_held, seeded);
  if (predicted > 0 && at > 0 && at < static_cast<int>(sizeof buf))
    std::snprintf(buf + at, sizeof buf - at, ", neighbours' depth held in %lld of %lld lenses",
                  predicted_held, predicted);
  return buf;
}

LensGrid LensGrid::Of(const PlenopticFrame& f) {
  LensGrid g;
  g.origin_px = f.grid.reference_px;
  g.lattice = f.grid.lattice;
  g.type_sign = f.grid.type_sign;
  g.lambda = f.lambda;
  g.principal_point_px = f.principal_point_px;
  if (f.lenses.empty()) return g;
  int j_lo = f.lenses[0].j, j_hi = j_lo;
  int c_lo = f.lenses[0].i + FloorHalf(j_lo), c_hi = c_lo;
  for (const MicroImage& m : f.lenses) {
    j_lo = std::min(j_lo, m.j);
    j_hi = std::max(j_hi, m.j);
    const int c = m.i + FloorHalf(m.j);
    c_lo = std::min(c_lo, c);
    c_hi = std::max(c_hi, c);
  }
  g.j_top = j_hi;
  g.rows = j_hi - j_lo + 1;
  g.col_base = c_lo;
  g.cols = c_hi - c_lo + 1;
  return g;
}

void LensMedianOf(const PlenopticFrame& f, const LensGrid& grid, const std::vector<float>& raw_grid,
                  double min_share, std::vector<float>* out) {
  out->assign(static_cast<std::size_t>(grid.cols) * grid.rows, kNaN);
  if (raw_grid.size() != static_cast<std::size_t>(f.width) * f.height) return;
  tbb::parallel_for(0, static_cast<int>(f.lenses.size()), [&](int k) {
    const MicroImage& m = f.lenses[k];
    const double r = f.radius_px;
    std::vector<float> values;
    int pixels = 0;
    for (int y = std::max(0, static_cast<int>(m.centre_px.y() - r));
         y <= std::min(f.height - 1, static_cast<int>(m.centre_px.y() + r) + 1); ++y)
      for (int x = std::max(0, static_cast<int>(m.centre_px.x() - r));
           x <= std::min(f.width - 1, static_cast<int>(m.centre_px.x() + r) + 1); ++x) {
        const std::size_t idx = static_cast<std::size_t>(y) * f.width + x;
        if (f.lens_of_pixel[idx] != k) continue;
        ++pixels;
        if (std::isfinite(raw_grid[idx])) values.push_back(raw_grid[idx]);
      }
    if (values.empty() || values.size() < min_share * pixels) return;
    std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
    (*out)[static_cast<std::size_t>(grid.Row(m.j)) * grid.cols + grid.Col(m.i, m.j)] =
        values[values.size() / 2];
  });
}

Status SeedFromLensDepth(const PlenopticFrame& f, const LensDepthMap& lens, LensSeed* out) {
  out->z.assign(f.lenses.size(), kNaN);
  out->sigma_z.assign(f.lenses.size(), kNaN);
  out->skip.clear();  // every micro image estimated unless the caller says otherwise
  const LensGrid& g = lens.grid;
  if (lens.virtual_depth.size() != static_cast<std::size_t>(g.cols) * g.rows ||
      lens.sigma_z.size() != lens.virtual_depth.size())
    return Error{"dense seed: per-lens map of " + std::to_string(lens.virtual_depth.size()) +
                 " cells, expected cols x rows = " + std::to_string(g.cols * g.rows)};
  for (std::size_t k = 0; k < f.lenses.size(); ++k) {
    const MicroImage& m = f.lenses[k];
    const int col = g.Col(m.i, m.j), row = g.Row(m.j);
    if (col < 0 || row < 0 || col >= g.cols || row >= g.rows) continue;
    if ((g.Centre(col, row) - m.centre_px).norm() > 0.5)
      return Error{"dense seed: the per-lens map's cell (" + std::to_string(col) + ", " +
                   std::to_string(row) + ") lies off micro image (" + std::to_string(m.i) + ", " +
                   std::to_string(m.j) + "): expected the frame's lattice"};
    const std::size_t c = lens.Cell(col, row);
    const float v = lens.virtual_depth[c];
    if (!(v > 0)) continue;
    out->z[k] = 1.0f / v;
    out->sigma_z[k] = lens.sigma_z[c];
  }
  return Status::Ok();
}

struct LensDepthEstimator::LatticeTables {
  // Per direction m (ring 1: 0..5, ring 2: 6..11, the order of kRing1 and
  // kRing2) the neighbour without its lens; per axis its unit direction.
  std::array<detail::Neighbour, 12> neighbour;
  std::array<std::array<double, 2>, 12> delta{};  // c_n - c_k
  std::array<std::array<float, 2>, 6> axis_e{};
  explicit LatticeTables(const Eigen::Matrix2d& lattice) {
    for (int m = 0; m < 12; ++m) {
      const int ring = m < 6 ? 1 : 2, dir = m % 6;
      const auto& d = (ring == 1 ? detail::kRing1 : detail::kRing2)[dir];
      const Eigen::Vector2d delta = lattice * Eigen::Vector2d(d[0], d[1]);
      detail::Neighbour& nb = neighbour[m];
      this->delta[m] = {delta.x(), delta.y()};
      nb.length = delta.norm();
      nb.delta_x = static_cast<float>(delta.x());
      nb.delta_y = static_cast<float>(delta.y());
      nb.e_x = static_cast<float>(delta.x() / nb.length);
      nb.e_y = static_cast<float>(delta.y() / nb.length);
      nb.axis = 3 * (ring - 1) + dir % 3;
      nb.flipped = dir >= 3;
      if (!nb.flipped) axis_e[nb.axis] = {nb.e_x, nb.e_y};
    }
  }
};

LensDepthEstimator::~LensDepthEstimator() = default;

Expected<std::unique_ptr<LensDepthEstimator>> LensDepthEstimator::Create(
    PlenopticFrame geometry, const MlaCalibration& mla, const LensDepthOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  if (!geometry.geometry_ready) return Error{"lens depth: PrepareGeometry has not run"};
  if (geometry.lenses.empty()) return Error{"lens depth: no micro image in the frame"};
  std::unique_ptr<LensDepthEstimator> e(new LensDepthEstimator());
  e->geometry_ = std::move(geometry);
  // The smoothed grey is not used here (pixels are read from the raw frame).
  e->geometry_.grey = {};
  e->geometry_.work = {};
  e->mla_ = mla;
  e->options_ = options;
  e->grid_ = LensGrid::Of(e->geometry_);
  e->kernel_ = std::make_unique<detail::TfKernel>(e->geometry_, mla, 1.0);
  e->tables_ = std::make_unique<LatticeTables>(e->geometry_.grid.lattice);
  e->gain_ =
      std::make_unique<detail::Gain16>(detail::Gain16::From(e->geometry_.gain, e->geometry_.width));
  // Searches and preview read the 16-bit gain: the float one (4 bytes per
  // pixel, 130 MB on an R32) is not kept.
  e->kernel_->UseGain16(e->gain_.get());
  std::vector<float>().swap(e->geometry_.gain);
  // Candidate offsets from the rounded micro-image centre: a square grid of
  // candidate_step_px within candidate_fraction r_valid.
  const double reach = options.candidate_fraction * e->geometry_.radius_px;
  const double step = options.candidate_step_px > 0
                          ? options.candidate_step_px
                          : std::max(1.0, std::round(e->geometry_.grid.NominalPitchPx() / 11));
  const int n_half = static_cast<int>(std::floor(reach / step));
  for (int b = -n_half; b <= n_half; ++b)
    for (int a = -n_half; a <= n_half; ++a) {
      const double ox = a * step, oy = b * step;
      if (ox * ox + oy * oy > reach * reach) continue;
      e->candidates_.push_back(
          {static_cast<std::int16_t>(std::lround(ox)), static_cast<std::int16_t>(std::lround(oy))});
    }
  for (const std::array<std::int16_t, 2>& c : e->candidates_) {
    e->candidate_dx_.push_back(c[0]);
    e->candidate_dy_.push_back(c[1]);
    e->candidate_reach_ = std::max(
        {e->candidate_reach_, std::abs(static_cast<int>(c[0])), std::abs(static_cast<int>(c[1]))});
  }
  e->candidate_dx_.resize(e->candidates_.size() + detail::kStripPad, 0);
  e->candidate_dy_.resize(e->candidates_.size() + detail::kStripPad, 0);
  // Micro images by (grid row, type), each group in the order of the lenses.
  {
    const LensGrid& g = e->grid_;
    const auto& lenses = e->geometry_.lenses;
    std::vector<std::int32_t> count(3 * static_cast<std::size_t>(g.rows) + 1, 0);
    auto group = [&](const MicroImage& m) {
      return 3 * static_cast<std::size_t>(g.Row(m.j)) + static_cast<std::size_t>(m.type);
    };
    for (const MicroImage& m : lenses) ++count[group(m) + 1];
    for (std::size_t q = 1; q < count.size(); ++q) count[q] += count[q - 1];
    e->row_type_start_ = count;
    e->by_row_type_.resize(lenses.size());
    for (std::size_t k = 0; k < lenses.size(); ++k)
      e->by_row_type_[count[group(lenses[k])]++] = static_cast<std::int32_t>(k);
  }
  return e;
}

namespace {

// Whether nb sees the whole patch of p (kAlong x lines, reaching
// sqrt(4 + (lines / 2)^2) px from p) at z and one search step either side,
// within the disc of radius_px + 0.5: else a search around z finds its
// minimum at the end of its run (the costs there are NaN) and fails.
double PatchReach(int lines) { return lines == 1 ? 2.0 : std::sqrt(5.0); }

bool SeesPatchAround(const detail::MatchParams& params, double radius_px, int lines, float px,
                     float py, const detail::Neighbour& nb, double z) {
  const double reach = PatchReach(lines);
  const double dz = params.step_px / (params.lambda * nb.length);
  double lo = z - dz, hi = z + dz;
  if (detail::SearchSteps(params, radius_px - reach, px, py, nb, &lo, &hi) == 0) return false;
  return lo <= z - dz && z + dz <= hi;
}

// The reference patch of epipolar_search.h's SampleReference (the same
// samples, to the last bit), read by the patch kernel (lens_search_simd.h,
// SamplePatchFn: all lines in one call) where the patch lies inside the
// disc and well inside the frame (the scalar bilinear reads cost about 130
// instructions a sample; the ring-2 patch was an eighth of the estimator's
// instructions on a `medium` frame, and with one strip-kernel call per
// line the patches made half of that kernel's calls).
template <int kLines, int kChannels>
bool SampleReferencePatch(const RawGrey<kChannels>& grey, int width, int height, float px,
                          float py, float e_x, float e_y, float cx, float cy, float r2,
                          float* out) {
  constexpr int kHalf = kLines / 2;
  constexpr float kReach = kHalf == 0 ? 2.0f + 1.0f : 2.2361f + 1.0f;  // as SampleReference
  const float dx = px - cx, dy = py - cy;
  const float inner = std::sqrt(r2) - kReach;
  if (grey.kernels == nullptr || !(inner > 0 && dx * dx + dy * dy <= inner * inner) ||
      px < 3 || py < 3 || px + 3 > width - 3 || py + 3 > height - 3)
    return detail::SampleReference<kLines>(grey, width, height, px, py, e_x, e_y, cx, cy, r2,
                                           out);
  // All its lines in one kernel call (lens_search_simd.h, SamplePatchFn).
  constexpr int kN = detail::kAlong * kLines;
  float samples[kN + detail::kStripPad];
  grey.kernels->patch(grey.source, px, py, e_x, e_y, kLines, samples);
  for (int m = 0; m < kN; ++m) {
    out[m] = samples[m];
    if (std::isnan(out[m])) return false;
  }
  return true;
}

// One micro image: candidates, searches, fusion (lens_depth.h, steps 1-3).
template <int kChannels>
void EstimateLens(const PlenopticFrame& f, const LensDepthOptions& o,
                  const LensDepthEstimator::LatticeTables& tables,
                  const std::vector<std::array<std::int16_t, 2>>& candidates,
                  const CandidateGate& gate, const detail::SearchRange& range,
                  const detail::MatchParams& ring1, const detail::MatchParams& ring2,
                  const RawGrey<kChannels>& grey, GateScratch& scratch, int k, double prior_z,
                  double prior_sigma_z, double neighbour_z, double neighbour_sigma_z,
                  float* v_out, float* sigma_out, float* conf_out, std::uint8_t* textured_out,
                  LensCounts* counts) {
  long long* const searched = &counts->searched;
  long long* const seeded = &counts->seeded;
  long long* const held = &counts->held;
  long long* const predicted = &counts->predicted;
  long long* const predicted_held = &counts->predicted_held;
  const MicroImage& lens = f.lenses[k];
  // 1. Candidates on a square grid around c_k (offsets made once per camera).
  const double cx = lens.centre_px.x(), cy = lens.centre_px.y();
  const int ix = static_cast<int>(std::floor(cx + 0.5));
  const int iy = static_cast<int>(std::floor(cy + 0.5));
  const float thr = static_cast<float>(o.min_gradient_dn);
  // The gradient gate reads the raw pixels only, scaled by the gain at the
  // micro image's centre: the gain varies little over the candidates (they
  // lie within candidate_fraction r_valid) and a gate needs no precision;
  // one gain read per micro image instead of four per candidate.
  if (ix < 1 || iy < 1 || ix >= f.width - 1 || iy >= f.height - 1) return;
  const float centre_gain = grey.Gain(ix, iy);
  if (!std::isfinite(centre_gain)) return;
  const float to_grey = 0.5f * centre_gain / kChannels;
  // The neighbours that exist, from the lattice's templates (c_n - c_k =
  // A (di, dj) for every lens, and the type rule (i - j) mod 3 makes ring 1
  // of the other types, ring 2 of the same): the neighbours' MicroImage
  // records are not read (a cache miss each, rows of lenses apart). Their
  // indices first (the gate needs the ring-1 axes that have one); the
  // records the searches read only for a textured micro image, after the
  // gate (its first candidate's rows are asked of the cache meanwhile).
  std::array<int, 12> nb_index;
  const int n_dirs = 6 * o.rings;
  unsigned mask = 0;
  for (int m = 0; m < n_dirs; ++m) {
    const auto& d = m < 6 ? detail::kRing1[m] : detail::kRing2[m - 6];
    nb_index[m] = f.LensAt(lens.i + d[0], lens.j + d[1]);
    if (m < 6 && nb_index[m] >= 0) mask |= 1u << (m % 3);
  }
  const std::array<std::array<float, 2>, 6>& axis_e = tables.axis_e;
  // Every candidate's score (its largest gradient along a ring-1 axis with
  // a neighbour) and that axis; -1: outside the frame. The candidates are
  // then taken lazily, the best remaining first (ties: the earlier in the
  // candidate list), as many as are searched: about 2 of the 29-37 of a
  // micro image, where keeping the `samples` best sorted as the scores came
  // (an insertion, a prefetch of its rows and a bubble for each of about 16
  // entrants) was 9 % of the estimator's instructions.
  float* const score = scratch.score.data();
  std::int32_t* const axis = scratch.axis.data();
  const int reach = gate.reach;
  if (grey.kernels != nullptr && ix - reach >= 2 && iy - reach >= 2 && ix + reach <= f.width - 3 &&
      iy + reach <= f.height - 3) {
    const float ax[3] = {axis_e[0][0], axis_e[1][0], axis_e[2][0]};
    const float ay[3] = {axis_e[0][1], axis_e[1][1], axis_e[2][1]};
    grey.kernels->scores(grey.source, ix, iy, gate.dx, gate.dy, gate.n, to_grey, ax, ay, mask,
                         score, axis);
  } else {
    for (int q = 0; q < gate.n; ++q) {
      const int x = ix + candidates[q][0], y = iy + candidates[q][1];
      score[q] = -1;
      axis[q] = 0;
      if (x < 1 || y < 1 || x >= f.width - 1 || y >= f.height - 1) continue;
      const float gx = to_grey * static_cast<float>(grey.RawSum(x + 1, y) - grey.RawSum(x - 1, y));
      const float gy = to_grey * static_cast<float>(grey.RawSum(x, y + 1) - grey.RawSum(x, y - 1));
      float best_score = 0;
      for (int d = 0; d < 3; ++d) {
        if (!((mask >> d) & 1u)) continue;
        const float g = std::abs(gx * axis_e[d][0] + gy * axis_e[d][1]);
        if (g > best_score) {
          best_score = g;
          axis[q] = d;
        }
      }
      score[q] = best_score;
    }
  }
  // The s-th most textured candidate (s = 0, 1, ... in turn), taken from
  // the scores when first asked for; null past the last textured one or
  // past `samples`. A taken candidate's score becomes -infinity.
  std::array<Candidate, kMaxSamples> best;
  int n_best = 0;
  bool exhausted = false;
  auto candidate = [&](int s) -> const Candidate* {
    while (n_best <= s && !exhausted) {
      int b = -1;
      float bs = -std::numeric_limits<float>::infinity();
      for (int q = 0; q < gate.n; ++q)
        if (score[q] > bs) {
          bs = score[q];
          b = q;
        }
      if (b < 0 || !(bs >= thr) || n_best == o.samples) {
        exhausted = true;
        break;
      }
      score[b] = -std::numeric_limits<float>::infinity();
      Candidate& c = best[n_best++];
      c.x = ix + candidates[b][0];
      c.y = iy + candidates[b][1];
      c.score = bs;
      c.axis = axis[b];
    }
    return s < n_best ? &best[s] : nullptr;
  };
  const Candidate* first = candidate(0);
  *textured_out = first != nullptr;
  if (first == nullptr) return;
  // Its ring-1 reference patch's rows (gain and raw, y - 2 .. y + 3 from
  // x - 2) asked of the cache while the neighbours are set up: their first
  // touch in this micro image, where `perf` put the estimator's largest
  // stall.
  if (first->x >= 2 && first->y >= 2 && first->y + 3 < f.height)
    for (int dy = -2; dy <= 3; ++dy) {
      __builtin_prefetch(grey.gain.q.data() +
                         static_cast<std::size_t>(first->y + dy) * f.width + first->x - 2);
      __builtin_prefetch(grey.raw.Row(first->y + dy) + (first->x - 2) * kChannels);
    }
  Uninitialised<detail::Neighbour, 12> nbs_store;
  detail::Neighbour* const nbs = nbs_store.v;
  int count = 0;
  std::array<std::array<int, 2>, 6> axis_nb;
  std::array<int, 6> axis_n{};
  for (int m = 0; m < n_dirs; ++m) {
    const int idx = nb_index[m];
    if (idx < 0) continue;
    detail::Neighbour& nb = nbs[count];
    nb = tables.neighbour[m];
    nb.lens = &f.lenses[idx];
    nb.cx = static_cast<float>(lens.centre_px.x() + tables.delta[m][0]);
    nb.cy = static_cast<float>(lens.centre_px.y() + tables.delta[m][1]);
    nb.same_type = m >= 6;
    axis_nb[nb.axis][axis_n[nb.axis]++] = count;
    ++count;
  }
  auto gradient = [&](int x, int y, float* gx, float* gy) {
    *gx = to_grey * static_cast<float>(grey.RawSum(x + 1, y) - grey.RawSum(x - 1, y));
    *gy = to_grey * static_cast<float>(grey.RawSum(x, y + 1) - grey.RawSum(x, y - 1));
  };

  // 2. Searches.
  const float ref_r2 = static_cast<float>((f.radius_px + 0.5) * (f.radius_px + 0.5));
  const float fcx = static_cast<float>(cx), fcy = static_cast<float>(cy);
  Uninitialised<detail::Estimate, 4 * kMaxSamples> all_store;
  detail::Estimate* const all = all_store.v;
  int n_all = 0;
  float patch[detail::kSamples], ref[detail::kSamples];
  const double lo = range.union_lo, hi = range.union_hi;
  float px = 0, py = 0;  // the pixel searched
  // The patch along the axis's unflipped direction and the searches of
  // the axis's neighbours that `wanted(nb)` keeps with it (a flipped
  // neighbour reads it reversed); the patch is sampled only when one is
  // searched.
  auto search_axis = [&](auto lines, int axis, const detail::MatchParams& params, double z0,
                         double z1, auto&& wanted, detail::Estimate* out, int* n_out) {
    constexpr int kLines = decltype(lines)::value;
    constexpr int kN = detail::kAlong * kLines;
    bool sampled = false;
    double g2 = 0;
    // The neighbour that sees the whole patch over more of [z0, z1]
    // first: the likelier to see it at its depth.
    std::array<int, 2> order{0, 1};
    if (axis_n[axis] == 2) {
      std::array<double, 2> seen{};
      for (int q = 0; q < 2; ++q) {
        double vis_lo = z0, vis_hi = z1;
        if (detail::SearchSteps(params, f.radius_px - PatchReach(kLines), px, py,
                                nbs[axis_nb[axis][q]], &vis_lo, &vis_hi) > 0)
          seen[q] = vis_hi - vis_lo;
      }
      if (seen[1] > seen[0]) order = {1, 0};
    }
    for (int qq = 0; qq < axis_n[axis]; ++qq) {
      const detail::Neighbour& nb = nbs[axis_nb[axis][order[qq]]];
      if (!wanted(nb)) continue;
      if (!sampled) {
        if (!SampleReferencePatch<kLines>(grey, f.width, f.height, px, py, axis_e[axis][0],
                                          axis_e[axis][1], fcx, fcy, ref_r2, patch))
          return;
        g2 = detail::PatchGradient2<kLines>(patch);
        sampled = true;
      }
      for (int m = 0; m < kN; ++m) ref[m] = nb.flipped ? patch[kN - 1 - m] : patch[m];
      detail::Estimate e;
      if (detail::MatchAlong<kLines>(params, grey, f.width, f.height, f.radius_px, px, py, ref,
                                     g2, nb, z0, z1, &e))
        out[(*n_out)++] = e;
    }
  };

  // 2a. The temporal seed (lens_depth.h): up to kSeedPixels of the most
  // textured pixels, each searched around the previous depth only; it
  // holds at the first with two agreeing estimates that agree with the
  // previous depth. Else the full search below, from nothing.
  if (prior_z > 0 && std::isfinite(prior_z)) ++*seeded;
  std::array<detail::Estimate, 4> found;
  int n_found = 0;
  for (int s = 0; s < kSeedPixels && prior_z > 0 && std::isfinite(prior_z) &&
                  candidate(s) != nullptr;
       ++s) {
    ++*searched;
    const Candidate& c = *candidate(s);
    px = static_cast<float>(c.x);
    py = static_cast<float>(c.y);
    float gx = 0, gy = 0;
    gradient(c.x, c.y, &gx, &gy);
    std::array<std::pair<float, int>, 6> axes;  // (gradient along it, axis)
    int n_axes = 0;
    for (int ring = 2; ring >= 1; --ring) {
      const int first = n_axes;
      const detail::MatchParams& params = ring == 1 ? ring1 : ring2;
      const int lines = ring == 1 ? o.ring1_lines : 3;
      for (int d = 0; d < 3; ++d) {
        const int a = 3 * (ring - 1) + d;
        // An axis along which the pixel has too little gradient matches
        // anything (the aperture problem).
        const float g = std::abs(gx * axis_e[a][0] + gy * axis_e[a][1]);
        if (g < thr) continue;
        bool sees = false;
        for (int q = 0; q < axis_n[a] && !sees; ++q)
          sees = SeesPatchAround(params, f.radius_px, lines, px, py, nbs[axis_nb[a][q]], prior_z);
        if (sees) axes[n_axes++] = {g, a};
      }
      std::sort(axes.begin() + first, axes.begin() + n_axes,
                [](const auto& x, const auto& y) { return x.first > y.first; });
    }
    // The best ring-2 axis (the longer baseline, the same type: the
    // precise estimate), then the ring-1 axes (5 x 1 patches: cheap), then
    // the other ring-2 axes, until two estimates.
    {
      int n2 = 0;
      while (n2 < n_axes && axes[n2].second >= 3) ++n2;
      if (n2 > 1) std::rotate(axes.begin() + 1, axes.begin() + n2, axes.begin() + n_axes);
    }
    n_found = 0;
    for (int i = 0; i < n_axes && n_found < 2; ++i) {
      const int a = axes[i].second;
      const bool ring1_axis = a < 3;
      const detail::MatchParams& params = ring1_axis ? ring1 : ring2;
      const double length = f.grid.PitchPx() * (ring1_axis ? 1.0 : std::sqrt(3.0));
      const double dz = params.step_px / (f.lambda * length);
      double span = std::max(o.seed_window * prior_z, 2 * dz);
      if (prior_sigma_z > 0 && std::isfinite(prior_sigma_z)) span = std::max(span, 3 * prior_sigma_z);
      const double z0 = std::max(lo, prior_z - span), z1 = std::min(hi, prior_z + span);
      const int lines = ring1_axis ? o.ring1_lines : 3;
      auto wanted = [&](const detail::Neighbour& nb) {
        return SeesPatchAround(params, f.radius_px, lines, px, py, nb, prior_z);
      };
      if (lines == 1)
        search_axis(std::integral_constant<int, 1>{}, a, params, z0, z1, wanted, found.data(),
                    &n_found);
      else
        search_axis(std::integral_constant<int, 3>{}, a, params, z0, z1, wanted, found.data(),
                    &n_found);
    }
    // Two estimates of this frame that agree, and with the previous depth
    // within the fusion's relative gate (its 3 sigma term let weakly
    // textured pixels' poor estimates confirm). One estimate with the
    // previous depth as the second let a spurious minimum inside the window
    // hold where the depth had moved out of it (a knocked camera: outliers
    // 4.2 -> 6.6 %).
    if (n_found < o.enough_estimates) continue;
    double zf = 0, sf = 0;
    const int used = FuseFew(found.data(), n_found, o.fuse_gate, &zf, &sf);
    // Step 3's spread, the previous depth one more estimate of it; the
    // value is this frame's alone.
    double spread2 = 0.5 * (zf - prior_z) * (zf - prior_z);
    {
      double sw = 0, swd = 0;
      for (int q = 0; q < n_found; ++q) {
        const double w = 1.0 / (found[q].sigma * found[q].sigma);
        sw += w;
        swd += w * (found[q].z - zf) * (found[q].z - zf);
      }
      spread2 = std::max(spread2, swd / (sw * (n_found - 1)));
    }
    const double sigma = std::sqrt(std::max(sf * sf, spread2));
    if (used >= o.enough_estimates && zf > 0 && sigma / zf <= o.max_rel_sigma &&
        std::abs(zf - prior_z) <= o.fuse_gate * prior_z) {
      ++*held;
      *v_out = static_cast<float>(1.0 / zf);
      *sigma_out = static_cast<float>(sigma);
      *conf_out = static_cast<float>(std::clamp(1.0 - (sigma / zf) / o.max_rel_sigma, 0.0, 1.0));
      return;
    }
  }

  // Of candidate c, the ring-2 axis with the largest gradient along it among
  // those with a neighbour that sees c's 5 x 3 patch at z with a step to
  // spare (SeesPatchAround), in the order of the gradient: the first that
  // sees is the one; -1: none.
  auto ring2_axis = [&](const Candidate& c, double z) {
    float gx = 0, gy = 0;
    gradient(c.x, c.y, &gx, &gy);
    std::array<std::pair<float, int>, 3> order;
    for (int d = 0; d < 3; ++d)
      order[d] = {std::abs(gx * axis_e[3 + d][0] + gy * axis_e[3 + d][1]), d};
    // Descending, the lower axis first among equal gradients (a bubble sort
    // of three: std::stable_sort allocates its buffer, 9 % of the
    // estimator's instructions).
    auto descend = [&](int q) {
      if (order[q + 1].first > order[q].first) std::swap(order[q], order[q + 1]);
    };
    descend(0);
    descend(1);
    descend(0);
    for (const auto& [g, d] : order)
      for (int q = 0; q < axis_n[3 + d]; ++q)
        if (SeesPatchAround(ring2, f.radius_px, 3, static_cast<float>(c.x),
                            static_cast<float>(c.y), nbs[axis_nb[3 + d][q]], z))
          return d;
    return -1;
  };
  // 2b. The neighbours' depth (lens_depth.h): one search around it per
  // pixel, on up to kSeedPixels of the most textured pixels (the best
  // ring-2 axis that sees the patch there, else the pixel's ring-1 axis);
  // it holds at the first whose estimates agree with it within fuse_gate.
  // Else the full search below, from nothing.
  if (neighbour_z > 0 && std::isfinite(neighbour_z) && o.rings >= 2) {
    ++*predicted;
    auto window = [&](const detail::MatchParams& params, double length_pitches, double* z0,
                      double* z1) {
      const double dz = params.step_px / (f.lambda * length_pitches * f.grid.PitchPx());
      double span = std::max(o.seed_window * neighbour_z, 2 * dz);
      if (neighbour_sigma_z > 0 && std::isfinite(neighbour_sigma_z))
        span = std::max(span, 3 * neighbour_sigma_z);
      *z0 = std::max(lo, neighbour_z - span);
      *z1 = std::min(hi, neighbour_z + span);
    };
    for (int s = 0; s < kSeedPixels && candidate(s) != nullptr; ++s) {
      const Candidate& c = *candidate(s);
      px = static_cast<float>(c.x);
      py = static_cast<float>(c.y);
      std::array<detail::Estimate, 4> found;
      int n_found = 0;
      double z0 = 0, z1 = 0;
      // The best ring-2 axis that sees the patch at the neighbours' depth
      // (the precise baseline); else the pixel's ring-1 axis (5 x 1).
      const int axis2 = ring2_axis(c, neighbour_z);
      if (axis2 >= 0) {
        window(ring2, std::sqrt(3.0), &z0, &z1);
        auto wanted = [&](const detail::Neighbour& nb) {
          return SeesPatchAround(ring2, f.radius_px, 3, px, py, nb, neighbour_z);
        };
        search_axis(std::integral_constant<int, 3>{}, 3 + axis2, ring2, z0, z1, wanted,
                    found.data(), &n_found);
      } else if (o.ring1_lines == 1) {
        window(ring1, 1.0, &z0, &z1);
        auto wanted = [&](const detail::Neighbour& nb) {
          return SeesPatchAround(ring1, f.radius_px, 1, px, py, nb, neighbour_z);
        };
        search_axis(std::integral_constant<int, 1>{}, c.axis, ring1, z0, z1, wanted, found.data(),
                    &n_found);
      }
      ++*searched;
      double zf = 0, sf = 0;
      if (FuseFew(found.data(), n_found, o.fuse_gate, &zf, &sf) != n_found || n_found == 0 ||
          !(zf > 0) || std::abs(zf - neighbour_z) > o.fuse_gate * neighbour_z)
        continue;
      // The spread to the neighbours' depth counts as step 3's spread of
      // two estimates; the value is this lens's own estimate.
      const double sigma = std::sqrt(std::max(sf * sf, 0.5 * (zf - neighbour_z) * (zf - neighbour_z)));
      if (sigma / zf > o.max_rel_sigma) continue;
      ++*predicted_held;
      *v_out = static_cast<float>(1.0 / zf);
      *sigma_out = static_cast<float>(sigma);
      *conf_out = static_cast<float>(std::clamp(1.0 - (sigma / zf) / o.max_rel_sigma, 0.0, 1.0));
      return;
    }
  }

  // 2c. The full search (no prior, or it did not hold).
  for (int s = 0; candidate(s) != nullptr; ++s) {
    const Candidate& c = *candidate(s);
    px = static_cast<float>(c.x);
    py = static_cast<float>(c.y);
    ++*searched;
    std::array<detail::Estimate, 4> mine;
    int n_mine = 0;
    // Ring 1 over the whole range. Its two neighbours see p at different
    // depths (the one on p's side of the micro image at the nearer ones);
    // once one has found z, the other is searched only where it sees p at
    // z with a step to spare (else its minimum lies at the end of its run
    // and it fails: half of the ring-1 searches of a `medium` frame did).
    auto ring1_wanted = [&](const detail::Neighbour& nb) {
      if (n_mine > 0)
        return SeesPatchAround(ring1, f.radius_px, o.ring1_lines, px, py, nb, mine[0].z);
      // One that sees the whole patch at fewer than 3 depths of the range
      // finds nothing.
      double vis_lo = lo, vis_hi = hi;
      return detail::SearchSteps(ring1, f.radius_px - PatchReach(o.ring1_lines), px, py, nb,
                                 &vis_lo, &vis_hi) > 0;
    };
    if (o.ring1_lines == 1)
      search_axis(std::integral_constant<int, 1>{}, c.axis, ring1, lo, hi, ring1_wanted,
                  mine.data(), &n_mine);
    else
      search_axis(std::integral_constant<int, 3>{}, c.axis, ring1, lo, hi, ring1_wanted,
                  mine.data(), &n_mine);
    if (n_mine == 0) continue;
    double z = 0, sigma = 0;
    // The pixel's ring-1 estimates fused with the dense estimator's gate (3 %).
    if (FuseFew(mine.data(), n_mine, 0.03, &z, &sigma) == 0) continue;
    if (o.rings >= 2) {
      // |Delta| of ring 2 is sqrt(3) D: lambda sqrt(3) D px of disparity per unit z.
      const double dz2 = o.ring2_step_px / (f.lambda * std::sqrt(3.0) * f.grid.PitchPx());
      const double span = std::max(3 * sigma, 2 * dz2);
      const double z0 = std::max(lo, z - span), z1 = std::min(hi, z + span);
      // A ring-2 neighbour that sees p at z with a step to spare either
      // side (at a micro image's small virtual depths most see p at no
      // depth near z: 8 of 10 ring-2 searches of a `medium` frame found
      // nothing); of the axes with one, the one with the largest gradient
      // of the grey along it.
      auto ring2_wanted = [&](const detail::Neighbour& nb) {
        return SeesPatchAround(ring2, f.radius_px, 3, px, py, nb, z);
      };
      const int axis2 = ring2_axis(c, z);
      if (axis2 >= 0)
        search_axis(std::integral_constant<int, 3>{}, 3 + axis2, ring2, z0, z1, ring2_wanted,
                    mine.data(), &n_mine);
    }
    for (int q = 0; q < n_mine; ++q) all[n_all++] = mine[q];
    // Enough agreeing estimates: the remaining (less textured) pixels are not searched.
    if (n_all >= o.enough_estimates) {
      double zz = 0, ss = 0;
      if (FuseFew(all, n_all, o.fuse_gate, &zz, &ss) >= o.enough_estimates) break;
    }
  }

  // 3. Fusion of the micro image's estimates.
  double z = 0, sigma = 0;
  const int used = FuseFew(all, n_all, o.fuse_gate, &z, &sigma);
  if (used < o.min_estimates || !(z > 0)) return;
  // The agreeing estimates' weighted spread (they are not independent).
  {
    const double med = MedianZ(all, n_all);
    double sw = 0, swd = 0;
    int n = 0;
    for (int q = 0; q < n_all; ++q) {
      if (std::abs(all[q].z - med) > std::max(3 * all[q].sigma, o.fuse_gate * med)) continue;
      const double w = 1.0 / (all[q].sigma * all[q].sigma);
      sw += w;
      swd += w * (all[q].z - z) * (all[q].z - z);
      ++n;
    }
    if (n > 1) sigma = std::sqrt(std::max(sigma * sigma, swd / (sw * (n - 1))));
  }
  if (sigma / z > o.max_rel_sigma) return;
  *v_out = static_cast<float>(1.0 / z);
  *sigma_out = static_cast<float>(sigma);
  *conf_out = static_cast<float>(std::clamp(1.0 - (sigma / z) / o.max_rel_sigma, 0.0, 1.0));
}

}  // namespace

Status LensDepthEstimator::Estimate(ConstImageView frame, LensDepthMap* out,
                                    const LensDepthMap* previous) const {
  ConstImageView raw = frame;  // what the searches read: the frame or its grey plane
  const auto start = std::chrono::steady_clock::now();
  const PlenopticFrame& f = geometry_;
  if (raw.data == nullptr || raw.width != f.width || raw.height != f.height)
    return Error{"lens depth: frame " + std::to_string(raw.width) + "x" +
                 std::to_string(raw.height) + ", expected " + std::to_string(f.width) + "x" +
                 std::to_string(f.height) + " (the camera's geometry)"};
  if (raw.format != PixelFormat::kMono8 && raw.format != PixelFormat::kBgr8)
    return Error{"lens depth: expected a Mono8 or BGR8 frame"};
  if (previous != nullptr &&
      (previous == out || previous->grid.cols != grid_.cols || previous->grid.rows != grid_.rows ||
       previous->virtual_depth.size() != static_cast<std::size_t>(grid_.cols) * grid_.rows ||
       previous->sigma_z.size() != previous->virtual_depth.size()))
    return Error{"lens depth: the previous map is not of this camera's lens grid (" +
                 std::to_string(grid_.cols) + "x" + std::to_string(grid_.rows) +
                 " cells) or is the output map itself"};
  // A BGR8 frame's grey plane (LensDepthOptions::grey_plane): one pass over
  // the frame, in rows, then every later read a byte a pixel instead of
  // three. On the `r32` frame the estimate with the plane's making cost
  // about a quarter less CPU than reading the channels (docs/processing.md,
  // "The grey plane").
  if (raw.format == PixelFormat::kBgr8 && options_.grey_plane) {
    out->grey.resize(static_cast<std::size_t>(raw.width) * raw.height);
    const detail::GreyPlaneKernels& grey_kernels =
        options_.simd ? detail::SimdGreyPlaneKernels() : detail::ScalarGreyPlaneKernels();
    std::uint8_t* const plane = out->grey.data();
    tbb::parallel_for(tbb::blocked_range<int>(0, raw.height, 16),
                      [&](const tbb::blocked_range<int>& r) {
                        for (int y = r.begin(); y < r.end(); ++y)
                          grey_kernels.row(frame.Row(y), frame.width,
                                           plane + static_cast<std::size_t>(y) * frame.width);
                      });
    raw = ConstImageView(plane, frame.width, frame.height, static_cast<std::size_t>(frame.width),
                         PixelFormat::kMono8);
  }
  out->grid = grid_;
  const std::size_t cells = static_cast<std::size_t>(grid_.cols) * grid_.rows;
  out->virtual_depth.assign(cells, kNaN);
  out->sigma_z.assign(cells, kNaN);
  out->confidence.assign(cells, 0.0f);
  out->type.assign(cells, -1);
  out->textured.assign(cells, 0);
  out->lens.assign(cells, -1);
  const detail::SearchRange range(mla_);
  auto params = [&](double step) {
    detail::MatchParams p;
    p.lambda = f.lambda;
    p.step_px = step;
    p.samples_per_px = static_cast<int>(std::lround(1.0 / step));
    p.noise_dn = options_.noise_dn;
    p.max_cost_ratio = options_.max_cost_ratio;
    p.geometric_px = options_.geometric_px;
    p.cross_type_px = options_.cross_type_px;
    return p;
  };
  const detail::MatchParams ring1 = params(options_.ring1_step_px);
  const detail::MatchParams ring2 = params(options_.ring2_step_px);
  std::atomic<long long> searched{0}, textured{0}, estimated{0}, seeded{0}, held{0},
      predicted{0}, predicted_held{0};
  const CandidateGate gate{candidate_dx_.data(), candidate_dy_.data(),
                           static_cast<int>(candidates_.size()), candidate_reach_};
  // With the neighbours' depth (lens_depth.h, step 2b): the lenses by type,
  // type 0 first from nothing, then type 1 seeded by its type-0 ring-1
  // neighbours, then type 2 by all six (types 0 and 1): a pass reads only
  // the cells of passes finished before it.
  const bool by_neighbours = previous == nullptr && options_.neighbour_seed && options_.rings >= 2;
  // The depth of lens m's ring-1 neighbours of types below its own: the
  // mean z of those within fuse_gate of their median and the spread of
  // those; 0 where fewer than two have a depth or more than one disagrees.
  auto neighbours_z = [&](const MicroImage& m, double* z_spread) {
    std::array<double, 6> zs;
    int n = 0;
    for (const auto& d : detail::kRing1) {
      const int idx = f.LensAt(m.i + d[0], m.j + d[1]);
      if (idx < 0 || f.lenses[idx].type >= m.type) continue;
      const float v = out->virtual_depth[static_cast<std::size_t>(grid_.Row(m.j + d[1])) *
                                             grid_.cols +
                                         grid_.Col(m.i + d[0], m.j + d[1])];
      if (v > 0) {
        // Sorted as they come (at most six).
        const double z = 1.0 / v;
        int q = n++;
        for (; q > 0 && zs[q - 1] > z; --q) zs[q] = zs[q - 1];
        zs[q] = z;
      }
    }
    if (n < 2) return 0.0;
    const double median = zs[n / 2];
    double sum = 0, sum2 = 0;
    int inliers = 0;
    for (int q = 0; q < n; ++q)
      if (std::abs(zs[q] - median) <= options_.fuse_gate * median) {
        sum += zs[q];
        sum2 += zs[q] * zs[q];
        ++inliers;
      }
    if (inliers < 2 || inliers < n - 1) return 0.0;
    const double mean = sum / inliers;
    *z_spread = std::sqrt(std::max(0.0, sum2 / inliers - mean * mean));
    return mean;
  };
  // One lens (its cell written once).
  auto one = [&](const auto& grey, GateScratch& scratch, int k, bool seeded_by_neighbours,
                 LensCounts* my) {
    const MicroImage& m = f.lenses[k];
    const std::size_t cell =
        static_cast<std::size_t>(grid_.Row(m.j)) * grid_.cols + grid_.Col(m.i, m.j);
    out->type[cell] = static_cast<std::int8_t>(m.type);
    out->lens[cell] = k;
    double prior_z = 0, prior_sigma_z = 0;
    if (previous != nullptr && previous->virtual_depth[cell] > 0) {
      prior_z = 1.0 / previous->virtual_depth[cell];
      prior_sigma_z = previous->sigma_z[cell];
    }
    double neighbour_z = 0, neighbour_sigma_z = 0;
    if (seeded_by_neighbours) neighbour_z = neighbours_z(m, &neighbour_sigma_z);
    EstimateLens(f, options_, *tables_, candidates_, gate, range, ring1, ring2, grey, scratch, k,
                 prior_z, prior_sigma_z, neighbour_z, neighbour_sigma_z, &out->virtual_depth[cell],
                 &out->sigma_z[cell], &out->confidence[cell], &out->textured[cell], my);
    my->textured += out->textured[cell];
    my->estimated += !std::isnan(out->virtual_depth[cell]);
  };
  auto add = [&](const LensCounts& my) {
    searched += my.searched;
    textured += my.textured;
    estimated += my.estimated;
    seeded += my.seeded;
    held += my.held;
    predicted += my.predicted;
    predicted_held += my.predicted_held;
  };
  // The leading edge of lens k's window asked of the cache a few lenses
  // before it is estimated (kPrefetchAhead): the lenses go along a lens row
  // (i, then j, ascending), so each lens's window lies one pitch along the
  // row from the one before, and what it reads first is the column of lines
  // at that end, over every row of its own disc, of its ring-1 neighbour
  // (0, 1) in the next lens row and of its ring-2 neighbour (-1, 2) two rows
  // on, which its searches reach (its other neighbour in the next row,
  // (-1, 1), is the previous lens's (0, 1); the lens rows before were read
  // by their own searches). Per row, the raw and the 16-bit gain, the lines
  // of one pitch back from the edge. The hardware prefetcher does not
  // anticipate these: some 70 rows at once, each advancing by a line or
  // two per lens. The same map; a fifth less CPU at `medium`, an eighth at
  // `r32` (docs/processing.md, "The leading edge of the window").
  const int channels = raw.format == PixelFormat::kBgr8 ? 3 : 1;
  const int n_lenses = static_cast<int>(f.lenses.size());
  const double along_x = tables_->delta[0][0];  // lens (i + 1, j) - lens (i, j)
  const double edge_px = along_x >= 0 ? f.radius_px + 1 : -f.radius_px - 1;
  const int sign = along_x >= 0 ? 1 : -1;
  const int raw_bytes = static_cast<int>(std::ceil(std::abs(along_x) * channels));
  const int gain_bytes = static_cast<int>(std::ceil(std::abs(along_x) * 2));
  const std::uint8_t* const gain_base = reinterpret_cast<const std::uint8_t*>(gain_->q.data());
  const std::size_t gain_row_bytes = 2 * static_cast<std::size_t>(f.width);
  auto prefetch_window = [&](int k) {
    const MicroImage& m = f.lenses[k];
    auto disc = [&](double cx, double cy) {
      const int x = std::clamp(static_cast<int>(cx + edge_px), 0, f.width - 1);
      const int y0 = std::max(0, static_cast<int>(cy - f.radius_px) - 1);
      const int y1 = std::min(f.height - 1, static_cast<int>(cy + f.radius_px) + 1);
      // The byte offsets in a row (at most kMaxLines of each), then the rows.
      constexpr int kMaxLines = 4;
      std::array<int, kMaxLines> raw_at, gain_at;
      int n_raw = 0, n_gain = 0;
      for (int o = 0; o < raw_bytes && n_raw < kMaxLines; o += 64)
        raw_at[n_raw++] = std::clamp(x * channels - sign * o, 0, (f.width - 1) * channels);
      for (int o = 0; o < gain_bytes && n_gain < kMaxLines; o += 64)
        gain_at[n_gain++] = std::clamp(2 * x - sign * o, 0, 2 * (f.width - 1));
      const std::uint8_t* raw_row = raw.Row(y0);
      const std::uint8_t* gain_row = gain_base + y0 * gain_row_bytes;
      for (int y = y0; y <= y1; ++y, raw_row += raw.stride_bytes, gain_row += gain_row_bytes) {
        for (int q = 0; q < n_raw; ++q) PrefetchLine(raw_row + raw_at[q]);
        for (int q = 0; q < n_gain; ++q) PrefetchLine(gain_row + gain_at[q]);
      }
    };
    disc(m.centre_px.x(), m.centre_px.y());
    for (const int nb : {1, 7})  // tables_: ring 1 (0, 1); ring 2 (-1, 2)
      disc(m.centre_px.x() + tables_->delta[nb][0], m.centre_px.y() + tables_->delta[nb][1]);
  };
  auto run = [&](const auto& grey) {
    if (!by_neighbours) {
      tbb::parallel_for(tbb::blocked_range<int>(0, n_lenses, 64),
                        [&](const tbb::blocked_range<int>& r) {
                          LensCounts my;
                          thread_local GateScratch scratch;
                          scratch.Reserve(gate.n);
                          for (int k = r.begin(); k < r.end(); ++k) {
                            if (k + kPrefetchAhead < n_lenses) prefetch_window(k + kPrefetchAhead);
                            one(grey, scratch, k, false, &my);
                          }
                          add(my);
                        });
      return;
    }
    // The passes of step 2b in bands of kBand grid rows, type t a band
    // behind type t - 1 (a lens's ring-1 neighbours lie in the rows next
    // to its own, so those of the types before its own are done): the
    // frame's lines a band's searches read are still in the cache for the
    // next type's. Measured on `medium` (docs/processing.md): bands of 8
    // rows cost 15 % more CPU than the search from nothing, of 2 rows 3 %
    // more, of 1 row none (the lines of four lens rows fit the L2 cache);
    // three passes over the whole frame cost more still.
    constexpr int kBand = 1;
    for (int top = 0; top < grid_.rows + 2 * kBand; top += kBand)
      for (int type = 0; type < 3; ++type) {
        const int r0 = std::max(0, top - type * kBand);
        const int r1 = std::min(grid_.rows, top - type * kBand + kBand);
        if (r0 >= r1) continue;
        const int q0 = row_type_start_[3 * r0], q1 = row_type_start_[3 * r1];
        tbb::parallel_for(tbb::blocked_range<int>(q0, q1, 32), [&](const tbb::blocked_range<int>& r) {
          LensCounts my;
          thread_local GateScratch scratch;
          scratch.Reserve(gate.n);
          for (int q = r.begin(); q < r.end(); ++q) {
            const int k = by_row_type_[q];
            if (f.lenses[k].type == type) one(grey, scratch, k, type > 0, &my);
          }
          add(my);
        });
      }
  };
  // The kernels address the frame with 32-bit byte offsets.
  const bool addressable = static_cast<double>(raw.stride_bytes) * raw.height < 2147483648.0 &&
                           raw.stride_bytes > 0 &&
                           2.0 * raw.width * raw.height < 2147483648.0;
  const detail::StripKernels* kernels = !addressable    ? nullptr
                                        : options_.simd ? &detail::SimdStripKernels()
                                                        : &detail::ScalarStripKernels();
  const detail::StripSource source{raw.data,      raw.stride_bytes,
                                   raw.format == PixelFormat::kBgr8 ? 3 : 1,
                                   gain_->q.data(), f.width, nullptr, gain_->scale};
  if (raw.format == PixelFormat::kBgr8)
    run(RawGrey<3>{raw, *gain_, f.width, kernels, source});
  else
    run(RawGrey<1>{raw, *gain_, f.width, kernels, source});
  LensDepthStats& st = out->stats;
  st = LensDepthStats{};
  st.lenses = static_cast<long long>(f.lenses.size());
  st.textured = textured.load();
  st.estimated = estimated.load();
  st.searched_pixels = searched.load();
  st.seeded = seeded.load();
  st.seed_held = held.load();
  st.predicted = predicted.load();
  st.predicted_held = predicted_held.load();
  st.kernels = kernels != nullptr ? kernels->name : "";
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return Status::Ok();
}

Status LensDepthEstimator::RenderPreview(ConstImageView raw, int max_side, LensDepthMap* depth,
                                         TfImage* out) const {
  const PlenopticFrame& f = geometry_;
  if (raw.data == nullptr || raw.width != f.width || raw.height != f.height)
    return Error{"lens preview: frame " + std::to_string(raw.width) + "x" +
                 std::to_string(raw.height) + ", expected " + std::to_string(f.width) + "x" +
                 std::to_string(f.height)};
  if (max_side < 1) return Error{"lens preview: max_side: expected >= 1"};
  const LensGrid& g = depth->grid;
  const std::size_t cells = static_cast<std::size_t>(g.cols) * g.rows;
  if (depth->virtual_depth.size() != cells || g.cols != grid_.cols || g.rows != grid_.rows)
    return Error{"lens preview: the depth map is not of this camera's lens grid"};
  // Holes: the mean of the ring-1 neighbours' depths (two rounds), then the median.
  std::vector<float>& v = depth->filled_v;
  v.assign(depth->virtual_depth.begin(), depth->virtual_depth.end());
  double median = 3.0;
  {
    // The median of the estimates, without a copy: nth_element on the
    // scratch's tail would reorder it, so over a histogram of v in 1/64 steps.
    std::array<int, 64 * 32> hist{};
    long long n = 0;
    for (const float x : depth->virtual_depth)
      if (std::isfinite(x)) {
        ++hist[std::clamp(static_cast<int>(x * 64), 0, static_cast<int>(hist.size()) - 1)];
        ++n;
      }
    long long acc = 0;
    for (std::size_t b = 0; b < hist.size() && n > 0; ++b) {
      acc += hist[b];
      if (2 * acc >= n) {
        median = (b + 0.5) / 64.0;
        break;
      }
    }
  }
  for (int round = 0; round < 2; ++round) {
    std::vector<float>& before = depth->fill_scratch;
    before.assign(v.begin(), v.end());
    for (int row = 0; row < g.rows; ++row)
      for (int col = 0; col < g.cols; ++col) {
        const std::size_t cell = depth->Cell(col, row);
        if (depth->type[cell] < 0 || std::isfinite(before[cell])) continue;
        int i = 0, j = 0;
        g.Lens(col, row, &i, &j);
        double sum = 0;
        int n = 0;
        for (const auto& d : detail::kRing1) {
          const int jj = j + d[1], ii = i + d[0];
          const int r = g.Row(jj), c = g.Col(ii, jj);
          if (r < 0 || r >= g.rows || c < 0 || c >= g.cols) continue;
          const float x = before[depth->Cell(c, r)];
          if (std::isfinite(x)) {
            sum += x;
            ++n;
          }
        }
        if (n > 0) v[cell] = static_cast<float>(sum / n);
      }
  }
  for (std::size_t c = 0; c < cells; ++c)
    if (!std::isfinite(v[c])) v[c] = static_cast<float>(median);

  const int tw = f.width / 2, th = f.height / 2;
  const float s = std::max(1.0f, static_cast<float>(std::max(tw, th)) / max_side);
  const int ow = std::max(1, static_cast<int>(std::lround(tw / s)));
  const int oh = std::max(1, static_cast<int>(std::lround(th / s)));
  const bool colour = raw.format == PixelFormat::kBgr8;
  out->width = ow;
  out->height = oh;
  out->format = colour ? PixelFormat::kBgr8 : PixelFormat::kMono8;
  out->pixels.resize(static_cast<std::size_t>(ow) * oh * (colour ? 3 : 1));
  out->linear.clear();
  const detail::TfKernel& kernel = *kernel_;
  // Each output row in runs of points: every point's depth, then the run
  // through the TF blend's row kernel (tf_blend_simd.h, the rule of
  // tf_kernel.h; SIMD with options_.simd), reading the 16-bit gain; points
  // that none of their triangle's lenses sees (sw = 0) take the border
  // fallback point by point (TfKernel::Blend). The kernel's gathers ask for
  // the lines of a whole vector of points at once: the points lie 2 s raw
  // pixels apart (s = 12.8 on an R32), every sample a new cache line.
  const detail::TfBlendGeometry geometry = kernel.BlendGeometry();
  const int channels = colour ? 3 : 1;
  const detail::TfBlendSource source{raw.data,        raw.stride_bytes,     channels, nullptr,
                                     gain_->q.data(), gain_->scale};
  const bool rows = f.width >= 8 && f.height >= 2 &&
                    static_cast<double>(f.width) * f.height < 2147483648.0 &&
                    (f.height - 1.0) * raw.stride_bytes + 3.0 * f.width < 2147483648.0;
  const detail::TfBlendKernels& kernels =
      options_.simd ? detail::SimdTfBlendKernels() : detail::ScalarTfBlendKernels();
  // The lens that looks at a point (MlaGrid::Nearest of TfKernel::LookingAt)
  // in float, affine in the point: with k(v) = 1 / (lambda + v (1 - lambda)),
  // LookingAt(x, v) = c + k(v) (x - c), so in the lattice's axial
  // coordinates a(q) = A^-1 (q - o) it is a_c + k(v) A^-1 (x - c), and along
  // an output row A^-1 (x - c) steps by dx A^-1 (1, 0)^T. Per point and
  // round: two multiply-adds, the cube rounding of the hex lattice and the
  // cell's v; k(v) per cell made once per frame (one per lens: the lens's
  // refocus scale).
  const Eigen::Matrix2d to_lattice = f.grid.lattice.inverse();
  const Eigen::Vector2d centre(f.principal_point_px.x(), f.principal_point_px.y());
  const Eigen::Vector2d a_c = to_lattice * (centre - f.grid.reference_px);
  const float lambda = static_cast<float>(f.lambda);
  auto scale_of = [lambda](float vv) { return 1.0f / (lambda + vv * (1.0f - lambda)); };
  // Per cell v (at least 1.05) and k(v), side by side (one cache line for both).
  std::vector<float>& vk = depth->fill_scratch;
  vk.resize(2 * cells);
  for (std::size_t c = 0; c < cells; ++c) {
    vk[2 * c] = std::max(v[c], 1.05f);
    vk[2 * c + 1] = scale_of(vk[2 * c]);
  }
  const float* v_of_cell = vk.data();
  const float* k_of_cell = vk.data() + 1;
  const float v_median = std::max(static_cast<float>(median), 1.05f);
  const float k_median = scale_of(v_median);
  const float acx = static_cast<float>(a_c.x()), acy = static_cast<float>(a_c.y());
  // For points r of a run (axial a_c + k_r (d0 + r d_step)): 2 x the cell
  // of the lens nearest (hex cube rounding, halves away from zero), the
  // index of its pair in vk; -1 outside the grid. Branch-free over the run
  // (floor(j / 2) as j >> 1): the compiler vectorises it.
  const int j_top = g.j_top, col_base = g.col_base, grid_rows = g.rows, grid_cols = g.cols;
  auto cells_of = [=](const float* k, float d0x, float d0y, float dax, float day, int n,
                      std::int32_t* cell) {
    for (int r = 0; r < n; ++r) {
      const float t = static_cast<float>(r);
      const float qa = acx + k[r] * (d0x + t * dax), ra = acy + k[r] * (d0y + t * day);
      const float sa = -qa - ra;
      const float rq = static_cast<float>(static_cast<std::int32_t>(qa + std::copysign(0.5f, qa)));
      const float rr = static_cast<float>(static_cast<std::int32_t>(ra + std::copysign(0.5f, ra)));
      const float rs = static_cast<float>(static_cast<std::int32_t>(sa + std::copysign(0.5f, sa)));
      const float dq = std::abs(rq - qa), dr = std::abs(rr - ra), ds = std::abs(rs - sa);
      // The selects as arithmetic on 0/1 (exact: one term is 0): a
      // conditional on floats keeps GCC from vectorising (-ftrapping-math).
      const int fix_q = (dq > dr) & (dq > ds);
      const int fix_r = (1 - fix_q) & (dr > ds);
      const float alt_q = -rr - rs, alt_r = -rq - rs;
      const std::int32_t i = static_cast<std::int32_t>(fix_q * alt_q + (1 - fix_q) * rq);
      const std::int32_t j = static_cast<std::int32_t>(fix_r * alt_r + (1 - fix_r) * rr);
      const std::int32_t row = j_top - j, col = i + (j >> 1) - col_base;
      const int inside = (row >= 0) & (row < grid_rows) & (col >= 0) & (col < grid_cols);
      cell[r] = inside * (2 * (row * grid_cols + col) + 1) - 1;
    }
  };
  // TF position u = (a + 1/2) s - 1/2 is raw position 2u + 1/2 = x0 + dx a.
  const float dx = 2.0f * s, x0 = s - 0.5f;
  tbb::parallel_for(0, oh, [&](int b) {
    const float y = 2.0f * ((b + 0.5f) * s - 0.5f) + 0.5f;
    // A^-1 (x - c) at the row's first point and its step per point.
    const Eigen::Vector2d d0 = to_lattice * (Eigen::Vector2d(x0, y) - centre);
    const Eigen::Vector2d d_step = to_lattice * Eigen::Vector2d(dx, 0);
    const float d0x = static_cast<float>(d0.x()), d0y = static_cast<float>(d0.y());
    const float dax = static_cast<float>(d_step.x()), day = static_cast<float>(d_step.y());
    std::uint8_t* row = out->pixels.data() + static_cast<std::size_t>(b) * ow * channels;
    constexpr int kRun = 128;
    float run_v[kRun], run_acc[3 * kRun], run_sw[kRun];
    for (int a0 = 0; a0 < ow; a0 += kRun) {
      const int n = std::min(kRun, ow - a0);
      // The micro images that see x at depth v lie around LookingAt(x, v)
      // (tf_kernel.h), up to lenses away from x at the border: the lens
      // there gives v, twice from the frame's median. Each round over the
      // whole run first (independent points: their cell loads overlap).
      std::int32_t run_cell[kRun];
      float run_k[kRun];
      const float run_d0x = d0x + static_cast<float>(a0) * dax;
      const float run_d0y = d0y + static_cast<float>(a0) * day;
      std::fill(run_k, run_k + n, k_median);
      cells_of(run_k, run_d0x, run_d0y, dax, day, n, run_cell);
      for (int r = 0; r < n; ++r) {
        const std::int32_t cell = run_cell[r];
        run_v[r] = cell >= 0 ? v_of_cell[cell] : v_median;
        run_k[r] = cell >= 0 ? k_of_cell[cell] : k_median;
      }
      cells_of(run_k, run_d0x, run_d0y, dax, day, n, run_cell);
      for (int r = 0; r < n; ++r)
        if (run_cell[r] >= 0) run_v[r] = v_of_cell[run_cell[r]];
      if (rows)
        kernels.row(geometry, source, x0 + dx * static_cast<float>(a0), dx, y, run_v, n, run_acc,
                    run_sw);
      for (int r = 0; r < n; ++r) {
        float acc[3] = {0, 0, 0};
        float sw = 0;
        if (rows) {
          for (int ch = 0; ch < channels; ++ch) acc[ch] = run_acc[ch * n + r];
          sw = run_sw[r];
        }
        if (!(sw > 0)) {
          const float x = x0 + dx * static_cast<float>(a0 + r);
          const int type = kernel.SharpType(run_v[r]);
          sw = colour ? kernel.Blend<3>(raw, x, y, run_v[r], type, acc)
                      : kernel.Blend<1>(raw, x, y, run_v[r], type, acc);
        }
        std::uint8_t* pix = row + static_cast<std::size_t>(a0 + r) * channels;
        for (int ch = 0; ch < channels; ++ch)
          pix[ch] = sw > 0 ? static_cast<std::uint8_t>(std::clamp(acc[ch] / sw + 0.5f, 0.0f, 255.0f))
                           : 0;
      }
    }
  });
  return Status::Ok();
}

}  // namespace lifmcr::processing
