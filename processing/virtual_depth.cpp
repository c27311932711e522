#include "processing/virtual_depth.h"

#include "processing/epipolar_search.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>

namespace lifmcr::processing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
using detail::Estimate;
using detail::Estimates;
using detail::Fuse;
using detail::kAcross;
using detail::kAlong;
using detail::kRing1;
using detail::kSamples;
using detail::Neighbour;

// The smoothed devignetted grey of the frame, bilinear (epipolar_search.h);
// the strips of discs well inside the frame through `kernels`.
struct GreyBilinear {
  const float* grey;
  int width;
  const detail::StripKernels* kernels;
  detail::StripSource source;
  float operator()(int x0, int y0, float fx, float fy) const {
    const float* r0 = grey + static_cast<std::size_t>(y0) * width + x0;
    return detail::GreyImageBilinear(r0, r0 + width, fx, fy);
  }
};

// Step 4's value of an unsearched pixel's window, made when first asked
// for.
struct WindowCell {
  enum State : std::uint8_t { kUnknown, kHolds, kTooLittle };
  float v = 0, sigma = 0, confidence = 0;
  State state = kUnknown;
};

// The cells of step 4's windows of radius `rad` along one axis of a box of
// n local columns (or rows): local column c's window spans the tables'
// columns table[clamp(c - rad)] to table[clamp(c + rad + 1)] (clamped to
// the estimates' [lo, hi + 1]); consecutive columns with the same pair form
// one cell (both edges are non-decreasing in c). Writes cell_of[c] and the
// pairs (edges[2 i], edges[2 i + 1]); returns the number of cells.
int MakeWindowCells(const std::int32_t* table, int n, int lo, int hi, int rad,
                    std::vector<std::int32_t>& cell_of, std::vector<std::int32_t>& edges) {
  if (cell_of.size() < static_cast<std::size_t>(n)) cell_of.resize(n);
  if (edges.size() < 2 * static_cast<std::size_t>(n)) edges.resize(2 * static_cast<std::size_t>(n));
  int cells = 0, last_a = -1, last_b = -1;
  for (int c = 0; c < n; ++c) {
    const int a = table[std::clamp(c - rad, lo, hi + 1)];
    const int b = table[std::clamp(c + rad + 1, lo, hi + 1)];
    if (a != last_a || b != last_b) {
      edges[2 * cells] = a;
      edges[2 * cells + 1] = b;
      ++cells;
      last_a = a, last_b = b;
    }
    cell_of[c] = cells - 1;
  }
  return cells;
}

// One micro image's buffers (the estimates on its bounding box, its pixel
// lists, the summed-area tables of the regularisation), kept per thread.
struct LensWorkspace {
  std::vector<float> patch_z, patch_sigma;
  std::vector<std::uint8_t> search_failed, inlier;
  // Textured pixels and those with an estimate: local (x, y) on the bounding
  // box, x + (y << 16).
  std::vector<std::uint32_t> textured_pixels, estimate_pixels;
  std::vector<std::uint32_t> between_pixels;  // seeded: lattice points off the coarse lattice
  std::vector<std::size_t> untextured_pixels;  // frame indices
  std::vector<std::int32_t> row_class;         // the gate's class of a row's pixels
  std::vector<double> sat_w, sat_wz, sat_wzz;
  std::vector<std::int32_t> sat_n;
  std::vector<std::int32_t> sat_col, sat_row;  // local x, y -> the tables' column, row
  // Seeded: whether a local column, row lies on the searched lattice.
  std::vector<std::uint8_t> lattice_col, lattice_row;
  // Step 4's window cells (MakeWindowCells): per local column (row) its
  // cell, per cell the tables' columns (rows) of its edges, and per cell
  // its value once made.
  std::vector<std::int32_t> cell_of_col, cell_of_row, cell_col_edges, cell_row_edges;
  std::vector<WindowCell> cells;
};

// The texture gate's class of n pixels of a row (g the grey at the first,
// lens its pixel -> lens map, w the row stride): 0 not micro image k's or
// invalid, 1 valid with an invalid neighbour (no gradient), 2 untextured,
// 3 textured (the largest |gx e_x[m] + gy e_y[m]| >= threshold over the
// three ring-1 axes: opposite neighbours' directions differ only in sign,
// which the absolute value drops; an axis without a neighbour (0, 0) adds
// 0). Without a branch, so the compiler vectorises it (`out` restrict: a
// byte store may otherwise alias every input), and with AVX2 where the CPU
// has it (x86-64: GCC's function clones; the same float operations, no
// FMA: the same classes). Not in a sanitizer build: the clones dispatch
// through an ifunc resolver, which runs while the binary is relocated,
// before the sanitizer's runtime is up (under ThreadSanitizer every binary
// with it crashed at start).
// The classes are 32-bit (not bytes): with every operand 32 bits wide the
// vectorised loop takes 8 pixels a vector on AVX2 instead of 32 (four
// vectors packed into a byte store), and the caller rounds n up to a
// multiple of kGateLanes where the row allows, so no pixel of a chord runs
// through the scalar remainder (a 24 px chord never reached the 32-pixel
// loop, a 34 px one ran 2 of them scalar).
#if defined(__SANITIZE_THREAD__) || defined(__SANITIZE_ADDRESS__)
#define LIFMCR_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer) || __has_feature(address_sanitizer)
#define LIFMCR_SANITIZED 1
#endif
#endif
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(LIFMCR_SANITIZED)
#define LIFMCR_GATE_ROW_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define LIFMCR_GATE_ROW_CLONES
#endif
constexpr int kGateLanes = 8;
// The seeded lattice's flags of a column or row: on the searched lattice,
// and on its coarse lattice (every second line, seed_interp_spread).
constexpr std::uint8_t kOnLattice = 1, kOnCoarse = 2;
LIFMCR_GATE_ROW_CLONES void GateRow(
    const float* g, const std::int32_t* lens, int w, int n, int k, const std::array<float, 3>& e_x,
    const std::array<float, 3>& e_y, float threshold, std::int32_t* __restrict out) {
  const float ex0 = e_x[0], ex1 = e_x[1], ex2 = e_x[2];
  const float ey0 = e_y[0], ey1 = e_y[1], ey2 = e_y[2];
  for (int i = 0; i < n; ++i) {
    const float gx = 0.5f * (g[i + 1] - g[i - 1]);
    const float gy = 0.5f * (g[i + w] - g[i - w]);
    float g_max = 0;
    g_max = std::max(g_max, std::abs(gx * ex0 + gy * ey0));
    g_max = std::max(g_max, std::abs(gx * ex1 + gy * ey1));
    g_max = std::max(g_max, std::abs(gx * ex2 + gy * ey2));
    const int own = (lens[i] == k) & (g[i] == g[i]);
    const int grad_ok = (gx == gx) & (gy == gy);
    const int textured = grad_ok & (g_max >= threshold);
    out[i] = own * (1 + grad_ok + textured);
  }
}

// The map's initial values (no estimate, not textured) for pixels
// [a, b) of the frame.
struct MapInit {
  float* v;
  float* sigma;
  float* confidence;
  std::uint8_t* textured;
  void Run(std::size_t a, std::size_t b) const {
    std::fill(v + a, v + b, kNaN);
    std::fill(sigma + a, sigma + b, kNaN);
    std::fill(confidence + a, confidence + b, 0.0f);
    std::fill(textured + a, textured + b, std::uint8_t{0});
  }
};

// Initialises the map where micro image k owns it: its own pixels (lens ==
// k; the disc's rows of its box as PrepareGeometry labels them, one run per
// row) and, on each such row, the pixels outside every disc (-1) between
// its run and the next labelled pixel to the left, and those to the right
// up to the frame's edge when no labelled pixel follows. Every pixel of a
// row that holds some micro image's pixel is so written by exactly one
// micro image (a -1 run by the one right of it, else the one left of it).
// Returns the first and last row with a pixel of k's (-1: none).
std::pair<int, int> InitOwnedRuns(const std::int32_t* lens, int w, int h, int k, double cx,
                                  double cy, double r, const MapInit& init) {
  const int x0 = std::max(0, static_cast<int>(std::ceil(cx - r)));
  const int x1 = std::min(w - 1, static_cast<int>(std::floor(cx + r)));
  const int y0 = std::max(0, static_cast<int>(std::ceil(cy - r)));
  const int y1 = std::min(h - 1, static_cast<int>(std::floor(cy + r)));
  int first_row = -1, last_row = -1;
  for (int y = y0; y <= y1; ++y) {
    const std::int32_t* const row = lens + static_cast<std::size_t>(y) * w;
    int s = x0, e = x1;
    while (s <= x1 && row[s] != k) ++s;
    if (s > x1) continue;
    while (row[e] != k) --e;
    if (first_row < 0) first_row = y;
    last_row = y;
    int a = s;
    while (a > 0 && row[a - 1] == -1) --a;
    int b = e + 1;
    while (b < w && row[b] == -1) ++b;
    if (b < w) b = e + 1;  // a labelled pixel follows: its micro image's run
    const std::size_t at = static_cast<std::size_t>(y) * w;
    init.Run(at + a, at + b);
  }
  return {first_row, last_row};
}

// Step 5's support of a seeded micro image searched on a lattice of
// `lattice`: fill_min_support (the full search's, on its stride's lattice)
// scaled by the lattices' densities, at least 3 (the fill counts estimates).
int FillSupport(int fill_min_support, int full_stride, int lattice) {
  return std::max(std::min(3, fill_min_support),
                  static_cast<int>(std::lround(fill_min_support * static_cast<double>(full_stride) /
                                               (lattice * lattice))));
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
  if (seed_search_stride < 0 || seed_search_stride > 8)
    return Error{"depth options: seed_search_stride: expected 0 (auto)..8"};
  if (seed_max_ring1 < 1 || seed_max_ring1 > 6)
    return Error{"depth options: seed_max_ring1: expected 1..6"};
  if (seed_max_ring2 < 0 || seed_max_ring2 > 6)
    return Error{"depth options: seed_max_ring2: expected 0..6"};
  if (seed_flat_stride < 0 || seed_flat_stride > 8)
    return Error{"depth options: seed_flat_stride: expected 0 (auto)..8"};
  if (!(seed_flat_px >= 0 && seed_flat_px <= 100))
    return Error{"depth options: seed_flat_px: expected 0 (off)..100"};
  if (!(seed_cost_ratio > 0 && seed_cost_ratio <= 1))
    return Error{"depth options: seed_cost_ratio: expected in (0, 1]"};
  if (!(seed_sigmas >= 0 && seed_sigmas <= 100))
    return Error{"depth options: seed_sigmas: expected 0..100"};
  if (!(seed_margin_px >= 0 && seed_margin_px <= 100))
    return Error{"depth options: seed_margin_px: expected 0..100"};
  if (seed_ring1_lines != 0 && seed_ring1_lines != 1 && seed_ring1_lines != 3)
    return Error{"depth options: seed_ring1_lines: expected 0 (auto), 1 or 3"};
  if (seed_ring2_lines != 0 && seed_ring2_lines != 1 && seed_ring2_lines != 3)
    return Error{"depth options: seed_ring2_lines: expected 0 (auto), 1 or 3"};
  if (!(seed_interp_spread >= 0 && seed_interp_spread <= 1))
    return Error{"depth options: seed_interp_spread: expected 0 (off)..1"};
  if (seed_interp_min < 1 || seed_interp_min > 25)
    return Error{"depth options: seed_interp_min: expected 1..25"};
  // type_ranges, simd: any value.
  return Status::Ok();
}

std::string DepthStats::BriefReport() const {
  const std::string skipped =
      skipped_lenses > 0 ? "; " + std::to_string(skipped_lenses) + " micro images skipped" : "";
  char buf[448];
  std::snprintf(
      buf, sizeof buf,
      "virtual depth: %lld of %lld textured pixels (%.1f %%; %lld valid), %lld rejected, "
      "%lld untextured filled, %lld searched (%lld seeded, %lld of them again in full; "
      "%lld flat micro images on the sparse lattice; %lld lattice points from the coarse "
      "lattice's)%s, %.3f s, kernels %s",
      estimated, textured_pixels, textured_pixels ? 100.0 * estimated / textured_pixels : 0.0,
      valid_pixels, rejected, filled, searched, seeded, fallback, flat_lenses, interpolated,
      skipped.c_str(), seconds, kernels);
  return buf;
}

VirtualDepthRange SearchedVirtualDepths(const MlaLensType& type) {
  const double v_min = std::max(1.05, type.depth_min);
  return {v_min, std::max(v_min + 0.1, type.depth_max)};
}

Status EstimateVirtualDepth(const PlenopticFrame& f, const MlaCalibration& mla,
                            const DepthOptions& options, VirtualDepthMap* out) {
  return EstimateVirtualDepth(f, mla, options, nullptr, out);
}

Status EstimateVirtualDepth(const PlenopticFrame& f, const MlaCalibration& mla,
                            const DepthOptions& options, const LensSeed* seed,
                            VirtualDepthMap* out) {
  if (Status s = options.Check(); !s) return s;
  if (seed != nullptr &&
      (seed->z.size() != f.lenses.size() || seed->sigma_z.size() != f.lenses.size()))
    return Error{"virtual depth: the seed has " + std::to_string(seed->z.size()) +
                 " micro images, the frame " + std::to_string(f.lenses.size())};
  if (seed != nullptr && !seed->skip.empty() && seed->skip.size() != f.lenses.size())
    return Error{"virtual depth: the seed's skip has " + std::to_string(seed->skip.size()) +
                 " micro images, the frame " + std::to_string(f.lenses.size())};
  const std::uint8_t* const skip =
      seed != nullptr && !seed->skip.empty() ? seed->skip.data() : nullptr;
  const auto start = std::chrono::steady_clock::now();
  const int w = f.width, h = f.height;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  out->width = w;
  out->height = h;
  // The map is written once per pixel, by the micro image whose rows hold
  // it (InitOwnedRuns, while its rows are in cache), and the rows without a
  // micro image's pixel afterwards; resize keeps the buffers of a map of
  // this size.
  out->virtual_depth.resize(n);
  out->sigma_z.resize(n);
  out->confidence.resize(n);
  out->textured.resize(n);
  const MapInit init{out->virtual_depth.data(), out->sigma_z.data(), out->confidence.data(),
                     out->textured.data()};
  // Per micro image, the first and last row holding a pixel of its own (-1:
  // none): the rows no micro image covers are initialised after the search.
  std::vector<std::int32_t> own_row_first(f.lenses.size(), -1), own_row_last(f.lenses.size(), -1);
  // Search range per type: z = 1 / v.
  const detail::SearchRange range(mla);
  const std::array<double, 3>& z_lo = range.z_lo;
  const std::array<double, 3>& z_hi = range.z_hi;
  const double union_lo = range.union_lo, union_hi = range.union_hi;
  const double lambda = f.lambda;
  // The lattices step at a pitch: the nominal one (processing/mla_grid.h), so
  // a pitch read from a file chooses as the same pitch made in memory.
  const double nominal_pitch_px = f.grid.NominalPitchPx();
  const int stride =
      options.search_stride != 0 ? options.search_stride : (nominal_pitch_px >= 24 ? 2 : 1);
  detail::MatchParams search;
  search.lambda = lambda;
  search.step_px = options.step_px;
  search.samples_per_px = static_cast<int>(std::lround(1.0 / options.step_px));
  search.noise_dn = options.noise_dn;
  search.max_cost_ratio = options.max_cost_ratio;
  search.geometric_px = options.geometric_px;
  search.cross_type_px = options.cross_type_px;
  if (options.equalise_defocus) detail::DefocusModel(mla, lambda, f.grid.PitchPx(), &search);
  detail::MatchParams narrow = search;  // the seeded window's search
  narrow.max_cost_ratio = options.seed_cost_ratio;
  const detail::StripKernels& kernels =
      options.simd ? detail::SimdStripKernels() : detail::ScalarStripKernels();
  detail::StripSource source;
  source.grey = f.grey.data();
  source.width = w;
  const GreyBilinear grey{f.grey.data(), w, &kernels, source};
  std::vector<long long> textured_count(f.lenses.size(), 0), valid_count(f.lenses.size(), 0),
      estimated_count(f.lenses.size(), 0), rejected_count(f.lenses.size(), 0),
      filled_count(f.lenses.size(), 0), searched_count(f.lenses.size(), 0),
      seeded_count(f.lenses.size(), 0), fallback_count(f.lenses.size(), 0),
      interpolated_count(f.lenses.size(), 0);
  // Seeded: the lattice of searched pixels, and step 5's support scaled by
  // its density against the full search's (the fill counts estimates).
  const int seed_stride =
      options.seed_search_stride != 0
          ? options.seed_search_stride
          : (nominal_pitch_px >= 32 ? 3 : (nominal_pitch_px >= 24 ? 2 : 1));
  const int seed_ring1_lines = options.seed_ring1_lines != 0 ? options.seed_ring1_lines
                                                             : (nominal_pitch_px >= 24 ? 1 : 3);
  const int seed_ring2_lines = options.seed_ring2_lines != 0 ? options.seed_ring2_lines
                                                             : (nominal_pitch_px >= 24 ? 1 : 3);
  // Seeded: the sparser lattice of a flat micro image (header comment).
  const int flat_stride =
      options.seed_flat_stride != 0
          ? options.seed_flat_stride
          : (nominal_pitch_px >= 32 ? 4 : (nominal_pitch_px >= 24 ? 3 : seed_stride));
  // Seeded: ring-1 disparity per unit z (the window's margin in z).
  const double ring1_scale = lambda * f.grid.PitchPx();
  // Per micro image, its agreeing estimates' inverse-variance sums (step 5's
  // second part fills micro images without estimates from their ring 1).
  struct SurfaceSums {
    double w = 0, wz = 0, wzz = 0;
    int n = 0;
  };
  std::vector<SurfaceSums> lens_sums(f.lenses.size());
  std::vector<std::uint8_t> lens_has_depth(f.lenses.size(), 0);
  // Per micro image, step 5's support (its searched lattice's) and whether
  // it searched the flat lattice.
  std::vector<std::int32_t> lens_fill_support(f.lenses.size(), options.fill_min_support);
  std::vector<std::uint8_t> lens_flat(f.lenses.size(), 0);

  tbb::parallel_for(0, static_cast<int>(f.lenses.size()), [&](int k) {
    const MicroImage& lens = f.lenses[k];
    const double lo = options.type_ranges ? z_lo[lens.type] : union_lo;
    const double hi = options.type_ranges ? z_hi[lens.type] : union_hi;
    std::array<Neighbour, 12> nbs;
    int ring1_count = 0;
    const int count = detail::FindNeighbours(f, lens, options.rings, &nbs, &ring1_count);
    const double r = f.radius_px;
    const float cx = static_cast<float>(lens.centre_px.x());
    const float cy = static_cast<float>(lens.centre_px.y());
    const float ref_r2 = static_cast<float>((r + 0.5) * (r + 0.5));
    const int x0 = std::max(1, static_cast<int>(std::ceil(lens.centre_px.x() - r)));
    const int x1 = std::min(w - 2, static_cast<int>(std::floor(lens.centre_px.x() + r)));
    const int y0 = std::max(1, static_cast<int>(std::ceil(lens.centre_px.y() - r)));
    const int y1 = std::min(h - 2, static_cast<int>(std::floor(lens.centre_px.y() + r)));
    const int bw = x1 - x0 + 1, bh = y1 - y0 + 1;
    std::tie(own_row_first[k], own_row_last[k]) = InitOwnedRuns(
        f.lens_of_pixel.data(), w, h, k, lens.centre_px.x(), lens.centre_px.y(), r, init);
    if (bw <= 0 || bh <= 0) return;
    // Nothing reads this micro image's dense pixels (LensSeed::skip): the
    // initial values just written are its map.
    if (skip != nullptr && skip[k]) return;
    // Seeded: the ring-1 window (header comment); none without a seed of
    // the micro image's own.
    double seed_lo = lo, seed_hi = hi;
    bool seeded = false, flat = false;
    int lens_stride = seed_stride;  // the searched lattice of a seeded micro image
    if (seed != nullptr && seed->z[k] > 0) {
      int seeded_neighbours = 0;
      double a = seed->z[k] - options.seed_sigmas * seed->sigma_z[k];
      double b = seed->z[k] + options.seed_sigmas * seed->sigma_z[k];
      for (const auto& d : kRing1) {
        const int n_idx = f.LensAt(lens.i + d[0], lens.j + d[1]);
        if (n_idx < 0 || !(seed->z[n_idx] > 0)) continue;
        ++seeded_neighbours;
        a = std::min(a, seed->z[n_idx] - options.seed_sigmas * seed->sigma_z[n_idx]);
        b = std::max(b, seed->z[n_idx] + options.seed_sigmas * seed->sigma_z[n_idx]);
      }
      const double margin = options.seed_margin_px / ring1_scale;
      seed_lo = std::max(lo, a - margin);
      seed_hi = std::min(hi, b + margin);
      // NaN sigma or a window wider than the range: the full search.
      seeded = seed_lo < seed_hi && (seed_lo > lo || seed_hi < hi);
      if (!seeded) seed_lo = lo, seed_hi = hi;
      // Flat: all six ring-1 neighbours seeded and the window (the seeds'
      // spread and 3 sigma) narrow: one confident surface over the micro
      // image and the neighbours it is matched against.
      flat = seeded && flat_stride > lens_stride && seeded_neighbours == 6 &&
             (b - a) * ring1_scale <= options.seed_flat_px;
      if (flat) lens_stride = flat_stride;
      lens_flat[k] = flat;
      if (seeded) lens_fill_support[k] = FillSupport(options.fill_min_support, stride, lens_stride);
    }
    // The micro image's estimates on a local grid (z and sigma, NaN = none)
    // and its textured pixels, for the regularisation below.
    // Its buffers are the thread's (LensWorkspace): no allocation per micro
    // image, none per frame after the first.
    thread_local LensWorkspace ws_;
    LensWorkspace& wk = ws_;
    const std::size_t box = static_cast<std::size_t>(bw) * bh;
    // The per-pixel buffers rest at "none" (NaN, 0) between micro images:
    // each micro image restores the few entries it wrote (RestoreBuffers
    // below) instead of filling its whole box (four fills of a box per
    // micro image were 4 % of the estimate's CPU).
    if (wk.patch_z.size() < box) wk.patch_z.resize(box, kNaN);
    if (wk.patch_sigma.size() < box) wk.patch_sigma.resize(box, kNaN);
    if (wk.search_failed.size() < box) wk.search_failed.resize(box, 0);
    if (wk.inlier.size() < box) wk.inlier.resize(box, 0);
    // The pixel lists hold at most the box's pixels: sized once, written
    // through pointers (a push_back's bookkeeping per pixel reloaded after
    // every byte store of the map).
    if (wk.textured_pixels.size() < box) wk.textured_pixels.resize(box);
    if (wk.untextured_pixels.size() < box) wk.untextured_pixels.resize(box);
    wk.estimate_pixels.clear();
    // Per local pixel: searched (a checkerboard pixel was not) and failed.
    float* const patch_z = wk.patch_z.data();
    float* const patch_sigma = wk.patch_sigma.data();
    std::uint8_t* const search_failed = wk.search_failed.data();
    std::uint32_t* const textured_list = wk.textured_pixels.data();
    int n_textured = 0;
    std::vector<std::uint32_t>& estimate_pixels = wk.estimate_pixels;
    std::size_t* const untextured_list = wk.untextured_pixels.data();
    int n_untextured = 0;
    float ref[kSamples];
    int narrow_found = 0, narrow_missed = 0;  // the seeded windows' outcomes so far
    const float* const grey_px = f.grey.data();
    const std::int32_t* const lens_of = f.lens_of_pixel.data();
    std::uint8_t* const textured_map = out->textured.data();
    const double min_gradient = options.min_gradient_dn;
    // The ring-1 axes' directions (an axis with either of its two
    // neighbours; (0, 0) without).
    std::array<float, 3> e_x1{}, e_y1{};
    for (int m = 0; m < ring1_count; ++m) e_x1[nbs[m].axis] = nbs[m].e_x, e_y1[nbs[m].axis] = nbs[m].e_y;
    // The gate (textured: some ring-1 baseline with enough gradient along
    // it), row by row over the chord of the disc (plus a pixel either side
    // for rounding; the pixel -> lens map decides) in two loops: the class
    // of each pixel without a branch (0 not this micro image's or invalid,
    // 1 valid with an invalid neighbour, 2 untextured, 3 textured; the
    // compiler vectorises it), then the pixel lists written without a
    // branch per pixel. Over the three axes (GateRow), an absent one (0, 0)
    // adding |0| to the maximum: the same gate as over the present
    // baselines. The float threshold is the least float >= min_gradient_dn, so
    // g >= it exactly where g >= min_gradient_dn.
    float min_gradient_f = static_cast<float>(min_gradient);
    if (static_cast<double>(min_gradient_f) < min_gradient)
      min_gradient_f = std::nextafter(min_gradient_f, std::numeric_limits<float>::infinity());
    if (wk.row_class.size() < static_cast<std::size_t>(bw) + 2 + kGateLanes)
      wk.row_class.resize(bw + 2 + kGateLanes);
    std::int32_t* const row_class = wk.row_class.data();
    long long n_valid = 0;
    for (int y = y0; y <= y1; ++y) {
      const double dy = y - lens.centre_px.y(), chord2 = r * r - dy * dy;
      if (chord2 < 0) continue;
      const double half = std::sqrt(chord2);
      const int xa = std::max(x0, static_cast<int>(std::floor(lens.centre_px.x() - half)));
      const int xb = std::min(x1, static_cast<int>(std::ceil(lens.centre_px.x() + half)));
      const std::size_t row = static_cast<std::size_t>(y) * w;
      const float* const g_row = grey_px + row;
      const std::int32_t* const lens_row = lens_of + row;
      const int n_row = xb - xa + 1;
      // The gate over whole vectors: up to kGateLanes - 1 pixels past the
      // chord (still in the frame's row, whose last pixel GateRow's x + 1
      // may read), whose classes nobody reads.
      const int n_gate =
          std::min((n_row + kGateLanes - 1) / kGateLanes * kGateLanes, w - 1 - xa);
      GateRow(g_row + xa, lens_row + xa, w, n_gate, k, e_x1, e_y1, min_gradient_f, row_class);
      const std::uint32_t packed_row = static_cast<std::uint32_t>((y - y0) << 16);
      for (int i = 0; i < n_row; ++i) {
        const int c = row_class[i];
        const int x = xa + i;
        n_valid += c != 0;
        untextured_list[n_untextured] = row + x;
        n_untextured += c == 2;
        textured_list[n_textured] = packed_row | static_cast<std::uint32_t>(x - x0);
        n_textured += c == 3;
      }
    }
    for (int t = 0; t < n_textured; ++t) {
      const std::uint32_t packed = textured_list[t];
      textured_map[static_cast<std::size_t>(y0 + (packed >> 16)) * w + x0 + (packed & 0xFFFF)] = 1;
    }
    // The next micro image (its right neighbour: lenses are in row order)
    // reads its box rows of the grey and the pixel -> lens map next and
    // writes those of the map; each row is a stream of its own (a pitch of
    // rows apart) that the hardware prefetchers do not follow, so the gate
    // waited on them: fetched after this gate (not during it, where they
    // compete with its loads), while this micro image is searched.
    if (k + 1 < static_cast<int>(f.lenses.size())) {
      const Eigen::Vector2d next = f.lenses[k + 1].centre_px;
      const int nx0 = std::max(1, static_cast<int>(next.x() - r) - 1);
      const int nx1 = std::min(w - 2, static_cast<int>(next.x() + r) + 1);
      const int ny0 = std::max(1, static_cast<int>(next.y() - r) - 1);
      const int ny1 = std::min(h - 2, static_cast<int>(next.y() + r) + 1);
      for (int y = ny0; y <= ny1 && nx0 <= nx1; ++y) {
        const std::size_t row = static_cast<std::size_t>(y) * w;
        for (int x = nx0; x <= nx1 + 15; x += 16) {
          const std::size_t at = row + std::min(x, nx1);
          __builtin_prefetch(f.grey.data() + at);
          __builtin_prefetch(f.lens_of_pixel.data() + at);
          __builtin_prefetch(out->virtual_depth.data() + at, 1);
          __builtin_prefetch(out->sigma_z.data() + at, 1);
          __builtin_prefetch(out->confidence.data() + at, 1);
        }
        __builtin_prefetch(out->textured.data() + row + nx0, 1);
        __builtin_prefetch(out->textured.data() + row + nx1, 1);
      }
    }
    // Seeded: the lattice's columns and rows of the box, looked up per
    // textured pixel (two integer divisions per pixel were 3 % of the perf
    // samples of this function's own code on `r32`).
    if (wk.lattice_col.size() < static_cast<std::size_t>(bw)) wk.lattice_col.resize(bw);
    if (wk.lattice_row.size() < static_cast<std::size_t>(bh)) wk.lattice_row.resize(bh);
    std::uint8_t* const lattice_col = wk.lattice_col.data();
    std::uint8_t* const lattice_row = wk.lattice_row.data();
    // Seeded with seed_interp_spread: the coarse lattice (every second line
    // of the lattice) is searched first and decides the points between.
    const bool interpolate = seeded && options.seed_interp_spread > 0;
    if (seeded) {
      const int coarse = 2 * lens_stride;
      for (int c = 0; c < bw; ++c)
        lattice_col[c] = ((x0 + c) % lens_stride == 0 ? kOnLattice : 0) |
                         ((x0 + c) % coarse == 0 ? kOnCoarse : 0);
      for (int c = 0; c < bh; ++c)
        lattice_row[c] = ((y0 + c) % lens_stride == 0 ? kOnLattice : 0) |
                         ((y0 + c) % coarse == 0 ? kOnCoarse : 0);
    }
    // A searched pixel's estimates: made once per micro image and emptied
    // per pixel (made per pixel, its 12 zeroed estimates were a 192-byte
    // `rep stos` per searched pixel).
    Estimates estimates;
    // One searched pixel (x + (y << 16) local): steps 1-3, its estimate
    // on the local grid where one passes.
    auto search_pixel = [&](const std::uint32_t packed) {
      const int x = x0 + static_cast<int>(packed & 0xFFFF), y = y0 + static_cast<int>(packed >> 16);
      const int local = (y - y0) * bw + (x - x0);
      const float* const g_row = grey_px + static_cast<std::size_t>(y) * w;
      const float gx = 0.5f * (g_row[x + 1] - g_row[x - 1]);
      const float gy = 0.5f * (g_row[x + w] - g_row[x - w]);
      // Ring-1 baselines ordered by the gradient along them (the most
      // informative first); at most max_ring1 of them are searched.
      std::array<std::pair<float, int>, 6> order;
      int gated = 0;
      for (int m = 0; m < ring1_count; ++m) {
        const float g = std::abs(gx * nbs[m].e_x + gy * nbs[m].e_y);
        if (g >= options.min_gradient_dn) order[gated++] = {g, m};
      }
      for (int i = 1; i < gated; ++i)  // insertion sort, descending (at most 6)
        for (int j = i; j > 0 && order[j - 1].first < order[j].first; --j)
          std::swap(order[j - 1], order[j]);
      gated = std::min(gated, seeded ? options.seed_max_ring1 : options.max_ring1);
      search_failed[local] = 1;  // until an estimate passes
      estimates.n = 0;
      // Reference patches per axis, sampled along the unflipped direction;
      // a flipped neighbour reads it reversed ((a, b) -> (-a, -b)). A
      // one-line search reads only the patch's middle line, so that line is
      // sampled alone until a 5 x 3 search asks for the rest (most seeded
      // pixels search one line only: two thirds of their reference samples
      // were never read), and its validity is its own five samples'.
      // States: 0 not yet, 1 valid, 2 invalid; line_state for the middle
      // line, patch_state for the whole patch.
      std::array<std::int8_t, 6> patch_state{}, line_state{};
      std::array<std::array<float, kSamples>, 6> patch_cache;
      std::array<double, 6> g2_cache;
      // one_line: a 5 x 1 patch (the seeded window's ring-1 search, ring 2
      // around its estimate).
      auto match = [&](const detail::MatchParams& params, const Neighbour& nb, double z0,
                       double z1, bool one_line = false) {
        std::array<float, kSamples>& cached = patch_cache[nb.axis];
        const float e_x = nb.flipped ? -nb.e_x : nb.e_x;
        const float e_y = nb.flipped ? -nb.e_y : nb.e_y;
        if (one_line) {
          if (line_state[nb.axis] == 0) {
            // The middle line's samples (b = 0) are those of the whole
            // patch's middle line, value for value.
            const bool ok = detail::SampleReference<1>(
                grey, w, h, static_cast<float>(x), static_cast<float>(y), e_x, e_y, cx, cy,
                ref_r2, cached.data() + kAlong);
            line_state[nb.axis] = ok ? 1 : 2;
          }
          if (line_state[nb.axis] != 1) return;
          // The patch's middle line (b = 0: the same samples as a 5 x 1
          // patch), reversed for a flipped neighbour.
          float ref1[kAlong];
          for (int m = 0; m < kAlong; ++m)
            ref1[m] = nb.flipped ? cached[kAlong + kAlong - 1 - m] : cached[kAlong + m];
          Estimate e;
          if (detail::MatchAlong<1>(params, grey, w, h, f.radius_px, static_cast<float>(x),
                                    static_cast<float>(y), ref1,
                                    detail::PatchGradient2<1>(cached.data() + kAlong), nb, z0,
                                    z1, &e))
            estimates.Add(e);
          return;
        }
        if (patch_state[nb.axis] == 0) {
          const bool ok =
              detail::SampleReference(grey, w, h, static_cast<float>(x), static_cast<float>(y),
                                      e_x, e_y, cx, cy, ref_r2, cached.data());
          patch_state[nb.axis] = ok ? 1 : 2;
          g2_cache[nb.axis] = ok ? detail::PatchGradient2(cached.data()) : 0.0;
          if (ok) line_state[nb.axis] = 1;
        }
        if (patch_state[nb.axis] != 1) return;
        for (int m = 0; m < kSamples; ++m)
          ref[m] = nb.flipped ? cached[kSamples - 1 - m] : cached[m];
        const double g2 = g2_cache[nb.axis];
        Estimate e;
        bool found = false;
        if (options.equalise_defocus) {
          // The equalised search also reads the reference micro image.
          detail::MatchParams with_ref = params;
          with_ref.ref_type = lens.type;
          with_ref.ref_cx = cx;
          with_ref.ref_cy = cy;
          found = detail::MatchAlong<detail::kAcross, true>(
              with_ref, grey, w, h, f.radius_px, static_cast<float>(x), static_cast<float>(y),
              ref, g2, nb, z0, z1, &e);
        } else {
          found = detail::MatchAlong(params, grey, w, h, f.radius_px, static_cast<float>(x),
                                     static_cast<float>(y), ref, g2, nb, z0, z1, &e);
        }
        if (found) estimates.Add(e);
      };
      ++searched_count[k];
      bool fell_back = false;
      for (int q = 0; q < gated; ++q)
        match(seeded ? narrow : search, nbs[order[q].second], seed_lo, seed_hi,
              seeded && seed_ring1_lines == 1);
      if (seeded) {
        ++seeded_count[k];
        // No clear minimum in the window (its least cost on the edge, or
        // not distinct): the same baselines over the whole range, while
        // the micro image's windows have missed at least twice as often
        // as they found one (header comment).
        if (estimates.n == 0) {
          ++narrow_missed;
          if (narrow_missed >= 2 * narrow_found) {
            fell_back = true;
            ++fallback_count[k];
            for (int q = 0; q < gated; ++q) match(search, nbs[order[q].second], lo, hi);
          }
        } else {
          ++narrow_found;
        }
      }
      double z = 0, sigma = 0;
      int used = Fuse(estimates, &z, &sigma);
      const bool have_prior = used > 0;
      // Longer baselines, searched around the current estimate; when the
      // short ones gave none, in the seed's window (its micro image's
      // windows find minima: the seed stands) or the whole range (no seed,
      // or the fallback searched it).
      std::array<std::pair<float, int>, 6> order2;
      int gated2 = 0;
      for (int m = ring1_count; m < count; ++m) {
        const float g = std::abs(gx * nbs[m].e_x + gy * nbs[m].e_y);
        if (g >= options.min_gradient_dn) order2[gated2++] = {g, m};
      }
      for (int i = 1; i < gated2; ++i)  // insertion sort, descending (at most 6)
        for (int j = i; j > 0 && order2[j - 1].first < order2[j].first; --j)
          std::swap(order2[j - 1], order2[j]);
      gated2 = std::min(gated2, seeded ? options.seed_max_ring2 : options.max_ring2);
      for (int q = 0; q < gated2; ++q) {
        const Neighbour& nb = nbs[order2[q].second];
        const double span = std::max(3 * sigma, 2 * options.step_px / (lambda * nb.length));
        if (have_prior)
          match(search, nb, std::max(lo, z - span), std::min(hi, z + span),
                seeded && seed_ring2_lines == 1);
        else if (seeded && !fell_back)
          match(narrow, nb, seed_lo, seed_hi);
        else
          match(search, nb, lo, hi);
      }
      used = Fuse(estimates, &z, &sigma);
      if (used < options.min_estimates || z <= 0) return;
      if (sigma / z > options.max_rel_sigma) return;
      patch_z[local] = static_cast<float>(z);
      patch_sigma[local] = static_cast<float>(sigma);
      search_failed[local] = 0;
      estimate_pixels.push_back(packed);
    };
    if (!interpolate) {
      // The searched pixels, in row order (the seeded windows' outcomes so
      // far decide a fallback): all, a checkerboard or the seeded lattice
      // (the others are filled by the regularisation from their searched
      // neighbours).
      for (int t = 0; t < n_textured; ++t) {
        const std::uint32_t packed = textured_list[t];
        if (seeded) {
          if (!(lattice_col[packed & 0xFFFF] & lattice_row[packed >> 16] & kOnLattice)) continue;
        } else if (stride == 2 &&
                   ((x0 + static_cast<int>(packed & 0xFFFF) + y0 + static_cast<int>(packed >> 16)) & 1)) {
          continue;
        }
        search_pixel(packed);
      }
    } else {
      // The coarse lattice first (every second lattice line in x and y),
      // in row order; then each other lattice point takes the mean of the
      // coarse estimates within two lattice steps where there are at least
      // seed_interp_min of them and they agree within seed_interp_spread of
      // their mean (a smooth surface over them), else it is searched.
      // The other lattice points, in row order, to a list of their own.
      if (wk.between_pixels.size() < static_cast<std::size_t>(n_textured))
        wk.between_pixels.resize(n_textured);
      std::uint32_t* const between = wk.between_pixels.data();
      int n_between = 0;
      for (int t = 0; t < n_textured; ++t) {
        const std::uint32_t packed = textured_list[t];
        const int on = lattice_col[packed & 0xFFFF] & lattice_row[packed >> 16];
        if (on & kOnCoarse)
          search_pixel(packed);
        else if (on & kOnLattice)
          between[n_between++] = packed;
      }
      const int s = lens_stride;
      const float spread = static_cast<float>(options.seed_interp_spread);
      const int interp_min = options.seed_interp_min;
      for (int t = 0; t < n_between; ++t) {
        const std::uint32_t packed = between[t];
        const int lx = static_cast<int>(packed & 0xFFFF), ly = static_cast<int>(packed >> 16);
        // The coarse points within 2 s of it (Chebyshev) with an estimate:
        // on a coarse column (row) itself and 2 s either side, else s
        // either side (3 s is farther).
        const bool coarse_x = lattice_col[lx] & kOnCoarse, coarse_y = lattice_row[ly] & kOnCoarse;
        const int dx0 = coarse_x ? -2 * s : -s, dy0 = coarse_y ? -2 * s : -s;
        const int dx_end = coarse_x ? 2 * s : s, dy_end = coarse_y ? 2 * s : s;
        int n_near = 0;
        float z_min = std::numeric_limits<float>::infinity(), z_max = -z_min, z_sum = 0,
              sigma_sum = 0;
        for (int dy = dy0; dy <= dy_end; dy += 2 * s) {
          const int yy = ly + dy;
          if (yy < 0 || yy >= bh) continue;
          for (int dx = dx0; dx <= dx_end; dx += 2 * s) {
            const int xx = lx + dx;
            if (xx < 0 || xx >= bw) continue;
            const float zz = patch_z[yy * bw + xx];
            if (!(zz == zz)) continue;
            ++n_near;
            z_min = std::min(z_min, zz);
            z_max = std::max(z_max, zz);
            z_sum += zz;
            sigma_sum += patch_sigma[yy * bw + xx];
          }
        }
        const float z_mean = z_sum / static_cast<float>(std::max(n_near, 1));
        if (n_near >= interp_min && z_max - z_min <= spread * z_mean) {
          const int local = ly * bw + lx;
          patch_z[local] = z_mean;
          patch_sigma[local] = sigma_sum / static_cast<float>(n_near);
          estimate_pixels.push_back(packed);
          ++interpolated_count[k];
        } else {
          search_pixel(packed);
        }
      }
    }
    valid_count[k] = n_valid;
    textured_count[k] = n_textured;
    // Regularisation within the micro image: neighbouring pixels see nearby
    // virtual points. Over the (2 smooth_radius_px + 1)^2 window of each
    // textured pixel: the mean of the estimates, then the inverse-variance
    // mean over the estimates that agree with the mean of their own window
    // (within max(3 sigma, 5 %)); fewer than min_support agreeing, or a searched pixel itself
    // disagreeing: rejected (outlier). Window sums from summed-area tables,
    // O(1) per pixel.
    const int rad = options.smooth_radius_px;
    // The buffers back at rest: search_failed was set only at searched
    // (textured) pixels, the estimates and inlier flags only at estimates.
    std::uint8_t* const inlier = wk.inlier.data();
    auto restore_buffers = [&] {
      for (int t = 0; t < n_textured; ++t) {
        const std::uint32_t packed = textured_list[t];
        search_failed[static_cast<int>(packed >> 16) * bw + static_cast<int>(packed & 0xFFFF)] = 0;
      }
      for (const std::uint32_t e : estimate_pixels) {
        const int local = static_cast<int>(e >> 16) * bw + static_cast<int>(e & 0xFFFF);
        patch_z[local] = kNaN;
        patch_sigma[local] = kNaN;
        inlier[local] = 0;
      }
    };
    // Without an estimate the micro image gets nothing from steps 4 and 5
    // (no window holds support; its sums stay 0).
    if (estimate_pixels.empty()) {
      restore_buffers();
      return;
    }
    // The tables span only the estimates' bounding rectangle [ex0, ex1] x
    // [ey0, ey1]: every weight outside it is 0, so a window's sums are
    // those of its part inside it, and the tables' entries are the same
    // sums in the same order as over the whole box (adding 0 changes none).
    int ex0 = bw, ex1 = -1, ey0 = bh, ey1 = -1;
    for (const std::uint32_t e : estimate_pixels) {
      const int lx = static_cast<int>(e & 0xFFFF), ly = static_cast<int>(e >> 16);
      ex0 = std::min(ex0, lx);
      ex1 = std::max(ex1, lx);
      ey0 = std::min(ey0, ly);
      ey1 = std::max(ey1, ly);
    }
    // Seeded, the estimates lie on the searched lattice (every seed_stride-th
    // pixel of the frame in x and y): the tables hold only its points, every
    // other weight being 0 (the same sums in the same order: a row's sums
    // change only at its points, and a row without one adds 0). sat_col[c]
    // (sat_row) is the number of the rectangle's points left of (above)
    // local x (y) c, the tables' column (row) of a window's edge at c.
    const int lattice = seeded ? lens_stride : 1;
    const int tw = (ex1 - ex0) / lattice + 1, th = (ey1 - ey0) / lattice + 1;
    if (wk.sat_col.size() < static_cast<std::size_t>(bw) + 1) wk.sat_col.resize(bw + 1);
    if (wk.sat_row.size() < static_cast<std::size_t>(bh) + 1) wk.sat_row.resize(bh + 1);
    std::int32_t* const sat_col = wk.sat_col.data();
    std::int32_t* const sat_row = wk.sat_row.data();
    for (int c = ex0; c <= ex1 + 1; ++c) sat_col[c] = (c - ex0 + lattice - 1) / lattice;
    for (int c = ey0; c <= ey1 + 1; ++c) sat_row[c] = (c - ey0 + lattice - 1) / lattice;
    const int sw_ = tw + 1;  // summed-area tables are (tw + 1) x (th + 1)
    const std::size_t sat_size = static_cast<std::size_t>(sw_) * (th + 1);
    if (wk.sat_w.size() < sat_size) {
      wk.sat_w.resize(sat_size);
      wk.sat_wz.resize(sat_size);
      wk.sat_wzz.resize(sat_size);
      wk.sat_n.resize(sat_size);
    }
    double* const sat_w = wk.sat_w.data();
    double* const sat_wz = wk.sat_wz.data();
    double* const sat_wzz = wk.sat_wzz.data();
    std::int32_t* const sat_n = wk.sat_n.data();
    // Row 0 and column 0 are 0; the rest is written by every build.
    for (std::size_t o = 0; o < sat_size; o += (o < static_cast<std::size_t>(sw_) ? 1 : sw_)) {
      sat_w[o] = sat_wz[o] = sat_wzz[o] = 0.0;
      sat_n[o] = 0;
    }
    // kWeighted false: weight 1 per estimate (w = n; wzz not summed).
    auto build = [&](auto weight_of, auto weighted) {
      constexpr bool kWeighted = decltype(weighted)::value;
      for (int ty = 0; ty < th; ++ty) {
        double row_w = 0, row_wz = 0, row_wzz = 0;
        std::int32_t row_n = 0;
        const std::size_t row = static_cast<std::size_t>(ey0 + ty * lattice) * bw + ex0;
        const std::size_t o_row = static_cast<std::size_t>(ty + 1) * sw_ + 1;
        for (int tx = 0; tx < tw; ++tx) {
          const std::size_t i = row + static_cast<std::size_t>(tx) * lattice;
          const double wgt = weight_of(i);
          if (wgt > 0) {
            row_wz += wgt * patch_z[i];
            if constexpr (kWeighted) {
              row_w += wgt;
              row_wzz += wgt * patch_z[i] * patch_z[i];
            }
            ++row_n;
          }
          const std::size_t o = o_row + tx;
          sat_wz[o] = sat_wz[o - sw_] + row_wz;
          if constexpr (kWeighted) {
            sat_w[o] = sat_w[o - sw_] + row_w;
            sat_wzz[o] = sat_wzz[o - sw_] + row_wzz;
          }
          sat_n[o] = sat_n[o - sw_] + row_n;
        }
      }
    };
    struct WindowSum {
      double w, wz, wzz;
      int n;
    };
    // The summed-area tables' four corners of the window of `radius` about
    // (lx, ly), clipped to the estimates' bounding rectangle.
    struct Corners {
      std::size_t i11, i01, i10, i00;
    };
    auto corners = [&](int lx, int ly, int radius) {
      const std::size_t xa = sat_col[std::clamp(lx - radius, ex0, ex1 + 1)];
      const std::size_t xb = sat_col[std::clamp(lx + radius + 1, ex0, ex1 + 1)];
      const std::size_t ya = sat_row[std::clamp(ly - radius, ey0, ey1 + 1)];
      const std::size_t yb = sat_row[std::clamp(ly + radius + 1, ey0, ey1 + 1)];
      return Corners{yb * sw_ + xb, ya * sw_ + xb, yb * sw_ + xa, ya * sw_ + xa};
    };
    auto window_at = [&](const Corners& c) {
      return WindowSum{sat_w[c.i11] - sat_w[c.i01] - sat_w[c.i10] + sat_w[c.i00],
                       sat_wz[c.i11] - sat_wz[c.i01] - sat_wz[c.i10] + sat_wz[c.i00],
                       sat_wzz[c.i11] - sat_wzz[c.i01] - sat_wzz[c.i10] + sat_wzz[c.i00],
                       sat_n[c.i11] - sat_n[c.i01] - sat_n[c.i10] + sat_n[c.i00]};
    };
    auto window = [&](int lx, int ly, int radius) { return window_at(corners(lx, ly, radius)); };
    // Pass 1's window: the count and the sum of z (its w is the count).
    auto window_count = [&](int lx, int ly, int radius) {
      const Corners c = corners(lx, ly, radius);
      return std::pair<double, int>{sat_wz[c.i11] - sat_wz[c.i01] - sat_wz[c.i10] + sat_wz[c.i00],
                                    sat_n[c.i11] - sat_n[c.i01] - sat_n[c.i10] + sat_n[c.i00]};
    };
    auto agrees = [](double z, double sigma, double mean) {
      return std::abs(z - mean) <= std::max(3 * sigma, 0.05 * mean);
    };
    // Pass 1: the plain window means at the estimates (unweighted: a few
    // estimates with tiny sigma, at strong edges, must not set the
    // reference alone), which then vote.
    // (The sum of n weights 1.0 is n exactly: pass 1 sums only z and n.)
    build([&](std::size_t i) { return std::isnan(patch_z[i]) ? 0.0 : 1.0; }, std::false_type{});
    for (const std::uint32_t e : estimate_pixels) {
      const int lx = static_cast<int>(e & 0xFFFF), ly = static_cast<int>(e >> 16);
      const std::size_t i = static_cast<std::size_t>(ly) * bw + lx;
      const auto [wz, count] = window_count(lx, ly, rad);
      inlier[i] = agrees(patch_z[i], patch_sigma[i], wz / static_cast<double>(count));
    }
    // Pass 2: the means over the agreeing estimates.
    build(
        [&](std::size_t i) {
          const float sg = patch_sigma[i];
          return inlier[i] ? 1.0 / (static_cast<double>(sg) * sg) : 0.0;
        },
        std::true_type{});
    // Textured pixels this step leaves without a value and step 5 fills
    // (its list after the untextured ones): those whose own search failed
    // (no distinct minimum) and those not searched without enough support;
    // a searched pixel that disagrees keeps none.
    const bool fill_on = options.fill_min_support > 0;
    // A flat micro image's sparser lattice holds fewer estimates per
    // window: the support scaled by its density against the seeded lattice's.
    const int min_support =
        flat ? std::max(std::min(2, options.min_support), static_cast<int>(std::lround(options.min_support *
                                                        static_cast<double>(seed_stride * seed_stride) /
                                                        (lens_stride * lens_stride))))
             : options.min_support;
    // An unsearched pixel's value depends only on its window's sums, whose
    // corners on the tables are a function of its column (the tables'
    // columns at the window's left and right edges) and of its row, and
    // change only every lattice-th pixel: the columns with the same pair of
    // edges form a cell column (likewise rows), and each cell's value is
    // made once, when a pixel first asks for it (the same numbers, without
    // a division or square root per pixel; before, the corners per pixel
    // and a value per run of a row were 10 % of the estimate's perf
    // samples on `r32`).
    const int n_cell_x = MakeWindowCells(sat_col, bw, ex0, ex1, rad, wk.cell_of_col, wk.cell_col_edges);
    const int n_cell_y = MakeWindowCells(sat_row, bh, ey0, ey1, rad, wk.cell_of_row, wk.cell_row_edges);
    const std::size_t n_cells = static_cast<std::size_t>(n_cell_x) * n_cell_y;
    if (wk.cells.size() < n_cells) wk.cells.resize(n_cells);
    WindowCell* const cells = wk.cells.data();
    for (std::size_t c = 0; c < n_cells; ++c) cells[c].state = WindowCell::kUnknown;
    const std::int32_t* const cell_of_col = wk.cell_of_col.data();
    const std::int32_t* const cell_of_row = wk.cell_of_row.data();
    const std::int32_t* const cell_col_edges = wk.cell_col_edges.data();
    const std::int32_t* const cell_row_edges = wk.cell_row_edges.data();
    for (int t = 0; t < n_textured; ++t) {
      const std::uint32_t packed = textured_list[t];
      const int lx = static_cast<int>(packed & 0xFFFF), ly = static_cast<int>(packed >> 16);
      const int local = ly * bw + lx;
      const std::size_t at = static_cast<std::size_t>(y0 + ly) * w + (x0 + lx);
      if (search_failed[local]) {  // step 4 gives it nothing; step 5 may
        if (fill_on) untextured_list[n_untextured++] = at;
        continue;
      }
      const float own_z = patch_z[local], own_sigma = patch_sigma[local];
      const bool searched = !std::isnan(own_z);
      if (!searched) {
        const int cx = cell_of_col[lx], cy = cell_of_row[ly];
        WindowCell& cell = cells[static_cast<std::size_t>(cy) * n_cell_x + cx];
        if (cell.state == WindowCell::kUnknown) {
          // The window's sums from its edges' table columns and rows, as
          // window() makes them.
          const std::size_t xa = cell_col_edges[2 * cx], xb = cell_col_edges[2 * cx + 1];
          const std::size_t ya = cell_row_edges[2 * cy], yb = cell_row_edges[2 * cy + 1];
          const Corners c{yb * sw_ + xb, ya * sw_ + xb, yb * sw_ + xa, ya * sw_ + xa};
          const WindowSum ws = window_at(c);
          cell.state = ws.n >= min_support ? WindowCell::kHolds : WindowCell::kTooLittle;
          if (cell.state == WindowCell::kHolds) {
            const double z = ws.wz / ws.w, sigma = std::sqrt(1.0 / ws.w);
            cell.v = static_cast<float>(1.0 / z);
            cell.sigma = static_cast<float>(sigma);
            cell.confidence =
                static_cast<float>(std::clamp(1.0 - (sigma / z) / options.max_rel_sigma, 0.0, 1.0));
          }
        }
        if (cell.state != WindowCell::kHolds) {
          if (fill_on) untextured_list[n_untextured++] = at;
          continue;
        }
        out->virtual_depth[at] = cell.v;
        out->sigma_z[at] = cell.sigma;
        out->confidence[at] = cell.confidence;
        ++estimated_count[k];
        continue;
      }
      const WindowSum ws = window(lx, ly, rad);
      if (ws.n < min_support || !inlier[local]) {
        ++rejected_count[k];
        continue;
      }
      const double z = ws.wz / ws.w;
      if (!agrees(own_z, own_sigma, z)) {
        ++rejected_count[k];
        continue;
      }
      // The neighbours are not independent views of one point: a searched
      // pixel keeps its own sigma shrunk by at most sqrt(support); an
      // unsearched one (above) takes the fused sigma of its window.
      const double sigma = own_sigma / std::sqrt(static_cast<double>(ws.n));
      out->virtual_depth[at] = static_cast<float>(1.0 / z);
      out->sigma_z[at] = static_cast<float>(sigma);
      out->confidence[at] =
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
    // The list holds only pixels without a value (the gate's untextured
    // ones, and step 4's textured ones it left without): none is read back.
    if (fill_on) {
      const int fill_radius = options.fill_radius_px > 0 ? options.fill_radius_px : bw + bh;
      // A window of the whole micro image (the default) has the same sums
      // for every pixel: taken once; and without enough support none fills.
      const int fill_support = lens_fill_support[k];
      const bool whole = fill_radius >= bw + bh;
      const WindowSum whole_sums = window(0, 0, bw + bh);
      // The fill of a window's sums: false where they hold too little
      // support or two surfaces.
      struct Fill {
        float v, sigma, confidence;
      };
      auto fill_of = [&](const WindowSum& ws, Fill* fill) {
        if (ws.n < fill_support) return false;
        const double z = ws.wz / ws.w;
        const double spread2 = std::max(0.0, ws.wzz / ws.w - z * z);
        if (spread2 > options.fill_max_spread * options.fill_max_spread * z * z) return false;
        // As uncertain as one supporting estimate (their harmonic mean
        // sigma), or as their spread where that is larger: the supports are
        // not independent views of this pixel's point.
        const double sigma = std::sqrt(std::max(ws.n / ws.w, spread2));
        *fill = Fill{static_cast<float>(1.0 / z), static_cast<float>(sigma),
                     static_cast<float>(
                         std::clamp(1.0 - (sigma / z) / options.max_rel_sigma, 0.0, 1.0))};
        return true;
      };
      Fill whole_fill{};
      const bool whole_fills = whole && fill_of(whole_sums, &whole_fill);
      if (whole && !whole_fills) n_untextured = 0;
      // The map's arrays through locals: a float store may alias the
      // vectors' own pointers, which were otherwise reloaded per pixel.
      float* const vd = out->virtual_depth.data();
      float* const sd = out->sigma_z.data();
      float* const cd = out->confidence.data();
      for (int u = 0; u < n_untextured; ++u) {
        const std::size_t at = untextured_list[u];
        Fill fill = whole_fill;
        if (!whole) {
          const int lx = static_cast<int>(at % w) - x0, ly = static_cast<int>(at / w) - y0;
          if (!fill_of(window(lx, ly, fill_radius), &fill)) continue;
        }
        vd[at] = fill.v;
        sd[at] = fill.sigma;
        cd[at] = fill.confidence;
        ++filled_count[k];
      }
      if (filled_count[k] > 0) lens_has_depth[k] = 1;
    }
    restore_buffers();
  });
  // The rows without a pixel of any micro image.
  {
    std::vector<int> cover(static_cast<std::size_t>(h) + 1, 0);
    for (std::size_t k = 0; k < f.lenses.size(); ++k)
      if (own_row_first[k] >= 0) ++cover[own_row_first[k]], --cover[own_row_last[k] + 1];
    for (int y = 0, c = 0; y < h; ++y) {
      c += cover[y];
      if (c == 0) init.Run(static_cast<std::size_t>(y) * w, static_cast<std::size_t>(y + 1) * w);
    }
  }
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
        if (idx < 0 ||
            lens_sums[idx].n < lens_fill_support[idx])
          continue;
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
    st.searched += searched_count[k];
    st.seeded += seeded_count[k];
    st.fallback += fallback_count[k];
    st.interpolated += interpolated_count[k];
    st.flat_lenses += lens_flat[k];
    if (skip != nullptr) st.skipped_lenses += skip[k];
  }
  st.kernels = kernels.name;
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return Status::Ok();
}

}  // namespace lifmcr::processing
