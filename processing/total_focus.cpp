#include "processing/total_focus.h"

#include "processing/lens_depth.h"
#include "processing/lens_search_simd.h"
#include "processing/tf_kernel.h"
#include "processing/tf_splat_simd.h"

#include <Eigen/LU>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>

namespace lifmcr::processing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

}  // namespace

Status TfOptions::Check() const {
  if (fill_iterations < 0) return Error{"TF options: fill_iterations: expected >= 0"};
  if (smooth_radius < 0) return Error{"TF options: smooth_radius: expected >= 0"};
  if (!(inner_fraction > 0 && inner_fraction <= 1))
    return Error{"TF options: inner_fraction: expected in (0, 1]"};
  if (!(gain > 0)) return Error{"TF options: gain: expected > 0"};
  if (!(sharpen >= 0 && sharpen <= 10)) return Error{"TF options: sharpen: expected 0..10"};
  if (!(bary_floor >= 0 && bary_floor <= 0.3))
    return Error{"TF options: bary_floor: expected 0..0.3"};
  return Status::Ok();
}

namespace {

// The inverse-variance window mean over (2 radius + 1)^2 cells: mean =
// sum w z / sum w over the window (w = 0 where a cell has no value), NaN
// where no cell of it has a weight. Separable and direct, 2 (2 radius + 1)
// adds per cell (radius 2 by default) in loops along x that the compiler
// vectorises: a row pass into `row_w`, `row_wz`, then per row the column
// sums over 2 radius + 1 of those rows, divided at once. Sums of
// non-negative terms without subtractions: a window without weight sums to
// 0 exactly (running sums leave residues, and needed a count of the cells
// with a value to tell; those two passes cost about three times these on
// an R32, as the window passes of a separable O(1) sum do not vectorise).
void WindowMeans(int width, int height, int radius, const std::vector<double>& w,
                 const std::vector<double>& wz, TfDepthMap::Scratch* s, std::vector<float>* mean) {
  s->row_w.resize(w.size());
  s->row_wz.resize(w.size());
  mean->resize(w.size());
  // Both passes sum a row in blocks of kBlock cells kept on the stack (in
  // L1; the row pass summed in place read and wrote the row 2 radius + 1
  // times from memory): `add(x0, n, sa, sb)` adds the block's terms,
  // `take(x0, n, sa, sb)` its sums.
  constexpr int kBlock = 256;
  auto in_blocks = [&](auto&& add, auto&& take) {
    double sa[kBlock], sb[kBlock];
    for (int x0 = 0; x0 < width; x0 += kBlock) {
      const int n = std::min(kBlock, width - x0);
      std::fill(sa, sa + n, 0.0);
      std::fill(sb, sb + n, 0.0);
      add(x0, n, sa, sb);
      take(x0, n, sa, sb);
    }
  };
  tbb::parallel_for(0, height, [&](int y) {
    const std::size_t base = static_cast<std::size_t>(y) * width;
    const double* const a = w.data() + base;
    const double* const b = wz.data() + base;
    double* const ra = s->row_w.data() + base;
    double* const rb = s->row_wz.data() + base;
    in_blocks(
        [&](int b0, int n, double* sa, double* sb) {
          for (int d = -radius; d <= radius; ++d) {
            // Cells x of the block with 0 <= x + d < width.
            const int x0 = std::max(b0, -d), x1 = std::min(b0 + n, width - d);
            for (int x = x0; x < x1; ++x) {
              sa[x - b0] += a[x + d];
              sb[x - b0] += b[x + d];
            }
          }
        },
        [&](int b0, int n, const double* sa, const double* sb) {
          std::copy(sa, sa + n, ra + b0);
          std::copy(sb, sb + n, rb + b0);
        });
  });
  tbb::parallel_for(0, height, [&](int y) {
    float* const out = mean->data() + static_cast<std::size_t>(y) * width;
    const int y0 = std::max(0, y - radius), y1 = std::min(height - 1, y + radius);
    in_blocks(
        [&](int x0, int n, double* sa, double* sb) {
          for (int yy = y0; yy <= y1; ++yy) {
            const double* const ra = s->row_w.data() + static_cast<std::size_t>(yy) * width + x0;
            const double* const rb = s->row_wz.data() + static_cast<std::size_t>(yy) * width + x0;
            for (int i = 0; i < n; ++i) {
              sa[i] += ra[i];
              sb[i] += rb[i];
            }
          }
        },
        [&](int x0, int n, const double* sa, const double* sb) {
          for (int i = 0; i < n; ++i)
            out[x0 + i] = sa[i] > 0 ? static_cast<float>(sb[i] / sa[i]) : kNaN;
        });
  });
}

// Agreement of a lens's ring-1 neighbours with its z for its depth to hold
// (total_focus.h), the share of z (the regularisation's 5 %).
constexpr float kLensHoldGate = 0.05f;
// With the per-lens depth, the dense pixels of the micro images that do not
// hold are splatted on every n-th raw row, weighted by n, n = max(4, pitch /
// 4 px) (total_focus.h): about four rows of each micro image (pitch 34 px
// on an R32: every 8th row; 16 px on `small`: every 4th). On bench_depth's
// r32 frame every 8th row instead of every 4th took 0.013 CPU-s less, PSNR
// 0.01 dB lower; every 16th 0.04 dB lower for no more time.
constexpr int kDenseRowStepMin = 4;
int DenseRowStep(const PlenopticFrame& f) {
  return std::max(kDenseRowStepMin, static_cast<int>(f.grid.PitchPx() / 4));
}

}  // namespace

// An estimate, and every ring-1 neighbour that exists with one within
// kLensHoldGate of its z.
void LensesHeldForTf(const PlenopticFrame& f, const LensSeed& lens_z,
                     std::vector<std::uint8_t>* held) {
  held->assign(f.lenses.size(), 0);
  static constexpr int kRing1[6][2] = {{1, 0}, {0, 1}, {-1, 1}, {-1, 0}, {0, -1}, {1, -1}};
  tbb::parallel_for(std::size_t{0}, f.lenses.size(), [&](std::size_t k) {
    const float z = lens_z.z[k];
    if (!(z > 0)) return;
    const MicroImage& m = f.lenses[k];
    for (const auto& d : kRing1) {
      const int n = f.LensAt(m.i + d[0], m.j + d[1]);
      if (n < 0) continue;
      if (!(std::abs(lens_z.z[n] - z) <= kLensHoldGate * z)) return;  // NaN too
    }
    (*held)[k] = 1;
  });
}

namespace {

// VirtualDepthToTf; with `lens_z` (per micro image z and sigma_z of the
// per-lens depth) the lenses that hold splat their lens depth and the rest
// their dense pixels (total_focus.h).
Status TfDepthOf(const PlenopticFrame& f, const VirtualDepthMap& raw, const LensSeed* lens_z,
                 const TfOptions& options, TfDepthMap* out) {
  if (Status s = options.Check(); !s) return s;
  if (raw.width != f.width || raw.height != f.height)
    return Error{"virtual depth map: size differs from the frame"};
  const int tw = f.width / 2, th = f.height / 2;
  const std::size_t tn = static_cast<std::size_t>(tw) * th;
  out->width = tw;
  out->height = th;
  TfDepthMap::Scratch& scratch = out->scratch;
  // The sums are left zero by the last pass below (it reads them for the
  // last time), so a reused map does not clear 8 bytes per TF pixel again.
  // With the per-lens depth the splats go to the cells' sums directly
  // (lens_cell_w, lens_cell_wz below): the per-TF-pixel sums are not used.
  std::vector<float>& sum_vec = scratch.sums;
  if (lens_z == nullptr) {
    if (sum_vec.size() != 2 * tn || !scratch.zeroed) sum_vec.assign(2 * tn, 0.0f);
    scratch.zeroed = false;
  }
  float* const sums = sum_vec.data();
  // Regularisation on a grid of kCell x kCell TF pixels (below).
  constexpr int kCell = detail::TfSplatRow::kCellPx;
  const int cw = (tw + kCell - 1) / kCell, ch = (th + kCell - 1) / kCell;
  const std::size_t cn = static_cast<std::size_t>(cw) * ch;
  std::vector<double>& cell_w = scratch.cell_w;
  std::vector<double>& cell_wz = scratch.cell_wz;
  cell_w.resize(cn);
  cell_wz.resize(cn);
  std::vector<float>& lens_xy = scratch.lens_xy;
  lens_xy.resize(2 * f.lenses.size());
  for (std::size_t k = 0; k < f.lenses.size(); ++k) {
    lens_xy[2 * k] = static_cast<float>(f.lenses[k].lens_px.x());
    lens_xy[2 * k + 1] = static_cast<float>(f.lenses[k].lens_px.y());
  }
  // Splat, in bands of kBand raw rows, row by row (the map, sigma and
  // micro-image index are read in order; the row's splats computed a vector
  // at a time by tf_splat_simd.h, then added here): even bands in parallel,
  // then odd ones. A band writes only TF rows within kBand / 4 of its own (a
  // splat moves (v - 1) |p - l| raw pixels, 70 TF rows at v 8 on an R32), so
  // two bands of one phase (a band apart) never write the same TF pixel:
  // plain adds, no atomics. A splat beyond that reach is kept and added
  // after both phases. Sums in float: a TF pixel gets a few splats, each
  // weight to 6e-8 of itself.
  constexpr int kBand = 256;
  const int bands = (f.height + kBand - 1) / kBand;
  scratch.deferred.resize(bands);
  const std::size_t row_room = static_cast<std::size_t>(f.width) + detail::kTfSplatPad;
  scratch.splat_t.resize(bands * row_room);
  scratch.splat_w.resize(bands * row_room);
  scratch.splat_wz.resize(bands * row_room);
  const int row_step = DenseRowStep(f);
  const float row_scale = static_cast<float>(row_step);
  const detail::TfSplatKernels& splat =
      options.simd ? detail::SimdTfSplatKernels() : detail::ScalarTfSplatKernels();
  // With the per-lens depth: which micro images hold, their centres and
  // rows, and per band the lists of the splat below.
  const std::size_t lenses = f.lenses.size();
  std::vector<float>& centre_x = scratch.centre_x;
  std::vector<float>& centre_y = scratch.centre_y;
  std::vector<std::int32_t>& lens_top = scratch.lens_top;
  std::vector<std::int32_t>& lens_bottom = scratch.lens_bottom;
  const float reach = static_cast<float>(f.radius_px) + 1.0f;
  const float lambda = static_cast<float>(f.lambda);
  // pitch / (2 sqrt 3) TF px: the circumradius of a lens's Voronoi cell at s = 1.
  const float share_radius = static_cast<float>(f.grid.PitchPx() / (2.0 * std::sqrt(3.0)));
  out->lenses_held = out->lenses = 0;
  if (lens_z != nullptr) {
    LensesHeldForTf(f, *lens_z, &scratch.held);
    centre_x.resize(lenses);
    centre_y.resize(lenses);
    lens_top.resize(lenses);
    lens_bottom.resize(lenses);
    scratch.band_dense.resize(bands);
    scratch.band_held.resize(bands);
    scratch.band_active.resize(bands);
    scratch.band_spans.resize(bands);
    for (int b = 0; b < bands; ++b) {
      scratch.band_dense[b].clear();
      scratch.band_held[b].clear();
    }
    for (std::size_t k = 0; k < lenses; ++k) {
      const float cx = static_cast<float>(f.lenses[k].centre_px.x());
      const float cy = static_cast<float>(f.lenses[k].centre_px.y());
      centre_x[k] = cx;
      centre_y[k] = cy;
      lens_top[k] = std::max(0, static_cast<int>(std::floor(cy - reach)));
      lens_bottom[k] = std::min(f.height - 1, static_cast<int>(std::ceil(cy + reach)));
      if (scratch.held[k]) {
        const int band = std::clamp(static_cast<int>(cy), 0, f.height - 1) / kBand;
        scratch.band_held[band].push_back(static_cast<std::int32_t>(k));
        ++out->lenses_held;
        continue;
      }
      if (lens_bottom[k] < lens_top[k]) continue;
      for (int b = lens_top[k] / kBand; b <= lens_bottom[k] / kBand; ++b)
        scratch.band_dense[b].push_back(static_cast<std::int32_t>(k));
    }
    for (int b = 0; b < bands; ++b)
      std::sort(scratch.band_dense[b].begin(), scratch.band_dense[b].end(),
                [&](std::int32_t a, std::int32_t c) { return lens_top[a] < lens_top[c]; });
    out->lenses = static_cast<long long>(lenses);
    // Cleared in parallel (8 bytes per cell each, 4 MB on an R32: a serial
    // fill kept the other core waiting).
    scratch.lens_cell_w.resize(cn);
    scratch.lens_cell_wz.resize(cn);
    tbb::parallel_for(0, ch, [&](int cy) {
      const std::size_t row = static_cast<std::size_t>(cy) * cw;
      std::fill_n(scratch.lens_cell_w.data() + row, cw, 0.0);
      std::fill_n(scratch.lens_cell_wz.data() + row, cw, 0.0);
    });
  }
  double* const lens_cell_w = scratch.lens_cell_w.data();
  double* const lens_cell_wz = scratch.lens_cell_wz.data();
  for (int phase = 0; phase < 2; ++phase)
    tbb::parallel_for(0, (bands - phase + 1) / 2, [&](int half) {
      const int band = 2 * half + phase;
      std::vector<TfDepthMap::Scratch::Deferred>& deferred = scratch.deferred[band];
      deferred.clear();
      const int y0 = band * kBand, y1 = std::min(f.height, y0 + kBand);
      // TF rows this band may write: its own (raw rows / 2) and kBand / 4
      // beyond; with the per-lens depth the rows of cells of those (the
      // bounds are multiples of kCell, or the last band's beyond the grid).
      const int w_lo = std::max(0, y0 / 2 - kBand / 4), w_hi = y1 / 2 + kBand / 4;
      const std::uint32_t t_lo =
          lens_z == nullptr ? static_cast<std::uint32_t>(w_lo) * tw
                            : static_cast<std::uint32_t>(w_lo / kCell) * cw;
      const std::uint32_t t_hi =
          lens_z == nullptr ? static_cast<std::uint32_t>(w_hi) * tw
                            : static_cast<std::uint32_t>((w_hi + kCell - 1) / kCell) * cw;
      std::uint32_t* const ts = scratch.splat_t.data() + band * row_room;
      float* const ws = scratch.splat_w.data() + band * row_room;
      float* const wzs = scratch.splat_wz.data() + band * row_room;
      detail::TfSplatRow r;
      r.lens_xy = lens_xy.data();
      r.tf_width = tw;
      r.tf_height = th;
      // With the per-lens depth the splats' cells (no per-TF-pixel sums).
      r.cell_width = lens_z == nullptr ? 0 : cw;
      // t: the TF pixel, or with the per-lens depth the cell.
      auto add = [&](std::uint32_t t, float w, float wz) {
        if (t >= t_lo && t < t_hi) {
          if (lens_z == nullptr) {
            sums[2 * t] += w;
            sums[2 * t + 1] += wz;
          } else {
            lens_cell_w[t] += w;
            lens_cell_wz[t] += wz;
          }
        } else {
          deferred.push_back({t, w, wz});
        }
      };
      // The pixels x0 .. x0 + n - 1 of raw row y.
      auto splat_span = [&](int y, int x0, int n) {
        const std::size_t at = static_cast<std::size_t>(y) * f.width + x0;
        r.v = raw.virtual_depth.data() + at;
        r.sigma_z = raw.sigma_z.data() + at;
        r.lens = f.lens_of_pixel.data() + at;
        r.x0 = x0;
        r.width = n;
        r.y = y;
        const int count = splat.row(r, ts, ws, wzs);
        if (lens_z == nullptr) {
          for (int i = 0; i < count; ++i) add(ts[i], ws[i], wzs[i]);
        } else {
          for (int i = 0; i < count; ++i) add(ts[i], row_scale * ws[i], row_scale * wzs[i]);
        }
      };
      if (lens_z == nullptr) {
        for (int y = y0; y < y1; ++y) splat_span(y, 0, f.width);
        return;
      }
      // The dense pixels of the micro images that do not hold, on every
      // row_step-th row (the map's rows read in order): the chord of
      // each disc of radius r_valid + 1 around c_k that crosses the row
      // (`band_dense` in order of first row; `active` those crossing it).
      const std::vector<std::int32_t>& list = scratch.band_dense[band];
      std::vector<std::int32_t>& active = scratch.band_active[band];
      active.clear();
      std::vector<std::int32_t>& spans = scratch.band_spans[band];  // x0, n of each
      std::size_t next = 0;
      for (int y = y0; y < y1; ++y) {
        while (next < list.size() && lens_top[list[next]] <= y) active.push_back(list[next++]);
        if (y % row_step != 0) continue;
        active.erase(std::remove_if(active.begin(), active.end(),
                                    [&](std::int32_t k) { return lens_bottom[k] < y; }),
                     active.end());
        spans.clear();
        for (const std::int32_t k : active) {
          const float dy = static_cast<float>(y) - centre_y[k];
          const float h2 = reach * reach - dy * dy;
          if (h2 < 0) continue;
          const float h = std::sqrt(h2);
          const int xa = std::max(0, static_cast<int>(std::floor(centre_x[k] - h)));
          const int xb = std::min(f.width, static_cast<int>(std::ceil(centre_x[k] + h)) + 1);
          if (xb > xa) spans.insert(spans.end(), {xa, xb - xa});
        }
        // The spans, each with the map's lines of the one kPrefetchAhead
        // further asked for: a span starts where the prefetcher cannot
        // guess, and the splat kernel waited on its first loads (about 40 %
        // of its perf samples).
        constexpr std::size_t kPrefetchAhead = 2;
        const std::size_t row = static_cast<std::size_t>(y) * f.width;
        for (std::size_t i = 0; i < spans.size(); i += 2) {
          if (i + 2 * kPrefetchAhead < spans.size()) {
            const std::size_t at = row + spans[i + 2 * kPrefetchAhead];
            const int n = spans[i + 2 * kPrefetchAhead + 1];
            for (int dx = 0; dx < n; dx += 16) {
              __builtin_prefetch(raw.virtual_depth.data() + at + dx);
              __builtin_prefetch(raw.sigma_z.data() + at + dx);
              __builtin_prefetch(f.lens_of_pixel.data() + at + dx);
            }
          }
          splat_span(y, spans[i], spans[i + 1]);
        }
      }
      // The micro images that hold, centred in this band: their lens depth
      // at TF points one cell apart over their share of the virtual image.
      for (const std::int32_t k : scratch.band_held[band]) {
        const float z = lens_z->z[k], sz = lens_z->sigma_z[k];
        const float v = 1.0f / z;
        const float lx = lens_xy[2 * k], ly = lens_xy[2 * k + 1];
        const float u_c = (lx + v * (centre_x[k] - lx) - 0.5f) * 0.5f;
        const float w_c = (ly + v * (centre_y[k] - ly) - 0.5f) * 0.5f;
        const float s = lambda + v * (1.0f - lambda);
        const float radius = share_radius * s, r2 = radius * radius;
        const int steps = static_cast<int>(radius / kCell);
        int points = 0;
        for (int b = -steps; b <= steps; ++b)
          for (int a = -steps; a <= steps; ++a)
            points += static_cast<float>(a * a + b * b) * (kCell * kCell) <= r2;
        const float weight = 1.0f / (std::max(1e-12f, sz * sz) * static_cast<float>(points));
        const float weight_z = weight * z;
        for (int b = -steps; b <= steps; ++b)
          for (int a = -steps; a <= steps; ++a) {
            if (static_cast<float>(a * a + b * b) * (kCell * kCell) > r2) continue;
            const float ur = u_c + static_cast<float>(kCell * a) + 0.5f;
            const float wr = w_c + static_cast<float>(kCell * b) + 0.5f;
            if (!(ur >= 0 && wr >= 0 && ur < static_cast<float>(tw) &&
                  wr < static_cast<float>(th)))
              continue;
            add(static_cast<std::uint32_t>((static_cast<int>(wr) / kCell) * cw +
                                           static_cast<int>(ur) / kCell),
                weight, weight_z);
          }
      }
    });
  for (const auto& band : scratch.deferred)
    for (const TfDepthMap::Scratch::Deferred& d : band) {
      if (lens_z == nullptr) {
        sums[2 * d.t] += d.w;
        sums[2 * d.t + 1] += d.wz;
      } else {
        lens_cell_w[d.t] += d.w;
        lens_cell_wz[d.t] += d.wz;
      }
    }
  out->virtual_depth.resize(tn);
  out->sigma_z.resize(tn);
  // Regularisation on a grid of kCell x kCell TF pixels (the depth map is
  // smooth at that scale after the window mean anyway; the window passes
  // then touch 16x less memory): per cell the sums of the splats, the
  // inverse-variance mean of z over a window of about smooth_radius, again
  // over the measured pixels that agree with their cell's mean within 5 %
  // (a step in depth splits the window; the side holding the majority
  // stays), holes filled from the cells within fill_iterations TF pixels, then
  // bilinear interpolation back to every TF pixel.
  std::vector<float>& cell_z = scratch.cell_z;
  // Cell sums again over the measured pixels within 5 % of their cell's
  // mean z, |swz / sw - mean| <= 0.05 mean with sw > 0.
  // Per cell the sums of a TF row's kCell pixels, in float (a few values
  // each), added to the cell's double sums; `kept`: only the measured
  // pixels within 5 % of the cell's mean. Branch-free over the whole cells
  // (loops the compiler vectorises), the row's last partial cell apart.
  auto sum_cells = [&](bool kept) {
    tbb::parallel_for(0, ch, [&](int cy) {
      double* cwr = cell_w.data() + static_cast<std::size_t>(cy) * cw;
      double* cwzr = cell_wz.data() + static_cast<std::size_t>(cy) * cw;
      const float* mean = cell_z.data() + static_cast<std::size_t>(cy) * cw;
      std::fill(cwr, cwr + cw, 0.0);
      std::fill(cwzr, cwzr + cw, 0.0);
      const int whole = tw / kCell;
      for (int w = cy * kCell; w < std::min(th, (cy + 1) * kCell); ++w) {
        const float* p = sums + 2 * static_cast<std::size_t>(w) * tw;
        auto keep = [&](float a, float b, float m) {
          return !kept || (a > 0 && std::abs(b - m * a) <= 0.05f * m * a);
        };
        if (kept) {
          for (int c = 0; c < whole; ++c) {
            const float* q = p + 2 * kCell * c;
            const float m = mean[c];
            float sa = 0, sb = 0;
            for (int i = 0; i < kCell; ++i) {
              const bool k = keep(q[2 * i], q[2 * i + 1], m);
              sa += k ? q[2 * i] : 0.0f;
              sb += k ? q[2 * i + 1] : 0.0f;
            }
            cwr[c] += sa;
            cwzr[c] += sb;
          }
        } else {
          for (int c = 0; c < whole; ++c) {
            const float* q = p + 2 * kCell * c;
            float sa = 0, sb = 0;
            for (int i = 0; i < kCell; ++i) {
              sa += q[2 * i];
              sb += q[2 * i + 1];
            }
            cwr[c] += sa;
            cwzr[c] += sb;
          }
        }
        for (int u = whole * kCell; u < tw; ++u)
          if (keep(p[2 * u], p[2 * u + 1], kept ? mean[whole] : 0.0f)) {
            cwr[whole] += p[2 * u];
            cwzr[whole] += p[2 * u + 1];
          }
      }
    });
  };
  // The per-cell passes below, over rows of cells in parallel (serial, they
  // were a tenth of the TF depth map's wall time on 2 cores).
  auto for_cells = [&](auto&& body) {
    tbb::parallel_for(0, ch, [&](int cy) {
      const std::size_t c0 = static_cast<std::size_t>(cy) * cw;
      for (std::size_t c = c0; c < c0 + cw; ++c) body(c);
    });
  };
  // The cells' sums of every splat (with the per-lens depth: made by the
  // splat, read where they are).
  if (lens_z == nullptr) sum_cells(false);
  const std::vector<double>& all_w = lens_z == nullptr ? cell_w : scratch.lens_cell_w;
  const std::vector<double>& all_wz = lens_z == nullptr ? cell_wz : scratch.lens_cell_wz;
  const int cell_radius = std::max(0, (options.smooth_radius + kCell / 2) / kCell);
  WindowMeans(cw, ch, cell_radius, all_w, all_wz, &scratch, &cell_z);
  if (lens_z == nullptr) {
    sum_cells(true);
  } else {
    // Again over the cells within 5 % of their window's mean (the rule of
    // the measured pixels above, on the cells: a splat has no pixel here).
    for_cells([&](std::size_t c) {
      const double w = scratch.lens_cell_w[c], wz = scratch.lens_cell_wz[c];
      const bool keep = w > 0 && !std::isnan(cell_z[c]) &&
                        std::abs(wz / w - cell_z[c]) <= 0.05 * cell_z[c];
      cell_w[c] = keep ? w : 0.0;
      cell_wz[c] = keep ? wz : 0.0;
    });
  }
  WindowMeans(cw, ch, cell_radius, cell_w, cell_wz, &scratch, &cell_z);
  // Holes: the mean z of the valid cells within fill_iterations TF pixels
  // (a window of 2 fill_cells + 1 cells), summed directly for the cells
  // without a value only (few; a third window-sum pass over every cell
  // cost more), into a second array so that a filled cell is no source.
  const int fill_cells = (options.fill_iterations + kCell - 1) / kCell;
  if (fill_cells > 0) {
    std::vector<float>& filled = scratch.cell_filled;
    filled.resize(cn);
    tbb::parallel_for(0, ch, [&](int cy) {
      const int y0 = std::max(0, cy - fill_cells), y1 = std::min(ch - 1, cy + fill_cells);
      for (int cx = 0; cx < cw; ++cx) {
        const std::size_t c = static_cast<std::size_t>(cy) * cw + cx;
        filled[c] = cell_z[c];
        if (!std::isnan(cell_z[c])) continue;
        const int x0 = std::max(0, cx - fill_cells), x1 = std::min(cw - 1, cx + fill_cells);
        double n = 0, sum_z = 0;
        for (int y = y0; y <= y1; ++y)
          for (int x = x0; x <= x1; ++x) {
            const float z = cell_z[static_cast<std::size_t>(y) * cw + x];
            if (std::isnan(z)) continue;
            n += 1;
            sum_z += z;
          }
        if (n > 0) filled[c] = static_cast<float>(sum_z / n);
      }
    });
    cell_z.swap(filled);
  }
  // Back to TF pixels: bilinear between cell centres over the valid cells,
  // v = sum w_q / sum w_q z_q over the valid corners q, separable: per cell
  // row the blend along x of the cells' validity and z (0 where invalid),
  // once, then per TF row the blend of two of those rows (contiguous loops
  // the compiler vectorises). With it the valid pixels counted, a histogram
  // of the measured ones' v on every kHistogramStep-th row (the median, to 1
  // / kBinsPerUnit: a sample of 600 k values on an R32) and the sums cleared
  // for the next frame.
  std::vector<float>& along_a = scratch.along_a;
  std::vector<float>& along_b = scratch.along_b;
  along_a.resize(static_cast<std::size_t>(ch) * tw);
  along_b.resize(static_cast<std::size_t>(ch) * tw);
  // The cells and weights of each TF column, the same for every cell row:
  // made once, so that a row is four table reads and two blends per column.
  std::vector<std::int32_t>& along_x = scratch.along_x;
  std::vector<float>& along_f = scratch.along_f;
  along_x.resize(2 * static_cast<std::size_t>(tw));
  along_f.resize(2 * static_cast<std::size_t>(tw));
  for (int u = 0; u < tw; ++u) {
    const float gx = std::clamp((u + 0.5f) / kCell - 0.5f, 0.0f, static_cast<float>(cw - 1));
    const int x0 = std::min(static_cast<int>(gx), cw - 1), x1 = std::min(x0 + 1, cw - 1);
    const float fx = gx - x0;
    along_x[2 * u] = x0;
    along_x[2 * u + 1] = x1;
    along_f[2 * u] = 1 - fx;
    along_f[2 * u + 1] = fx;
  }
  scratch.cell_ok.resize(cn);
  scratch.cell_z0.resize(cn);
  tbb::parallel_for(0, ch, [&](int cy) {
    const float* z = cell_z.data() + static_cast<std::size_t>(cy) * cw;
    float* a = along_a.data() + static_cast<std::size_t>(cy) * tw;
    float* b = along_b.data() + static_cast<std::size_t>(cy) * tw;
    // Per cell its validity (1, 0) and z (0 where invalid).
    float* const ok = scratch.cell_ok.data() + static_cast<std::size_t>(cy) * cw;
    float* const zv = scratch.cell_z0.data() + static_cast<std::size_t>(cy) * cw;
    for (int c = 0; c < cw; ++c) {
      const bool valid = !std::isnan(z[c]);
      ok[c] = valid ? 1.0f : 0.0f;
      zv[c] = valid ? z[c] : 0.0f;
    }
    const std::int32_t* const xs = along_x.data();
    const float* const fs = along_f.data();
    for (int u = 0; u < tw; ++u) {
      const int x0 = xs[2 * u], x1 = xs[2 * u + 1];
      const float f0 = fs[2 * u], f1 = fs[2 * u + 1];
      a[u] = f0 * ok[x0] + f1 * ok[x1];
      b[u] = f0 * zv[x0] + f1 * zv[x1];
    }
  });
  constexpr int kBinsPerUnit = 1024, kBins = 64 * kBinsPerUnit, kChunks = 8, kHistogramStep = 4;
  std::vector<std::uint32_t>& histogram = scratch.histogram;
  histogram.resize(static_cast<std::size_t>(kChunks) * kBins);  // each chunk clears its own
  std::atomic<long long> valid{0}, measured{0};
  // With the per-lens depth sigma_z is the cell's, once per cell.
  std::vector<float>& cell_sigma_rows = scratch.cell_sigma;
  if (lens_z != nullptr) {
    cell_sigma_rows.resize(cn);
    tbb::parallel_for(0, ch, [&](int cy) {
      const std::size_t row = static_cast<std::size_t>(cy) * cw;
      for (int c = 0; c < cw; ++c) {
        const double sw = scratch.lens_cell_w[row + c];
        cell_sigma_rows[row + c] = sw > 0 ? static_cast<float>(std::sqrt(1.0 / sw)) : kNaN;
      }
    });
  }
  tbb::parallel_for(0, kChunks, [&](int chunk) {
    std::uint32_t* hist = histogram.data() + static_cast<std::size_t>(chunk) * kBins;
    std::fill_n(hist, kBins, 0u);
    long long chunk_valid = 0, chunk_measured = 0;
    for (int w = chunk * th / kChunks; w < (chunk + 1) * th / kChunks; ++w) {
      const float gy = std::clamp((w + 0.5f) / kCell - 0.5f, 0.0f, static_cast<float>(ch - 1));
      const int y0 = std::min(static_cast<int>(gy), ch - 1), y1 = std::min(y0 + 1, ch - 1);
      const float fy = gy - y0;
      const float* a0 = along_a.data() + static_cast<std::size_t>(y0) * tw;
      const float* a1 = along_a.data() + static_cast<std::size_t>(y1) * tw;
      const float* b0 = along_b.data() + static_cast<std::size_t>(y0) * tw;
      const float* b1 = along_b.data() + static_cast<std::size_t>(y1) * tw;
      const std::size_t row = static_cast<std::size_t>(w) * tw;
      float* vd = out->virtual_depth.data() + row;
      float* sigma = out->sigma_z.data() + row;
      float* p = sums + 2 * row;
      const double* lw = lens_z == nullptr
                             ? nullptr
                             : scratch.lens_cell_w.data() + static_cast<std::size_t>(w / kCell) * cw;
      int row_valid = 0, row_measured = 0;
      for (int u = 0; u < tw; ++u) {
        const float a = (1 - fy) * a0[u] + fy * a1[u];
        const float b = (1 - fy) * b0[u] + fy * b1[u];
        const bool ok = a > 1e-6f;
        vd[u] = ok ? a / b : kNaN;
        row_valid += ok;
      }
      if (lw != nullptr) {
        // With the per-lens depth: sigma_z of the cell's splats (above).
        const float* const cell_sigma =
            cell_sigma_rows.data() + static_cast<std::size_t>(w / kCell) * cw;
        // Whole cells kCell pixels at a time (unrolled), the row's last
        // partial cell apart.
        const int whole = tw / kCell;
        for (int c = 0; c < whole; ++c) {
          const float sc = cell_sigma[c];
          for (int i = 0; i < kCell; ++i) sigma[c * kCell + i] = sc;
          row_measured += lw[c] > 0 ? kCell : 0;
        }
        for (int u = whole * kCell; u < tw; ++u) {
          sigma[u] = cell_sigma[whole];
          row_measured += lw[whole] > 0;
        }
        if (w % kHistogramStep == 0)
          for (int c = 0; c < cw; ++c) {
            if (!(lw[c] > 0)) continue;
            for (int u = c * kCell; u < std::min(tw, (c + 1) * kCell); ++u)
              if (!std::isnan(vd[u]))
                ++hist[std::clamp(static_cast<int>(vd[u] * kBinsPerUnit), 0, kBins - 1)];
          }
      } else {
        for (int u = 0; u < tw; ++u) {
          const float sw = p[2 * u];
          const bool measured_here = sw > 0;
          sigma[u] = measured_here ? std::sqrt(1.0f / sw) : kNaN;
          row_measured += measured_here;
        }
        if (w % kHistogramStep == 0)
          for (int u = 0; u < tw; ++u)
            if (p[2 * u] > 0 && !std::isnan(vd[u]))
              ++hist[std::clamp(static_cast<int>(vd[u] * kBinsPerUnit), 0, kBins - 1)];
        std::fill(p, p + 2 * tw, 0.0f);
      }
      chunk_valid += row_valid;
      chunk_measured += row_measured;
    }
    valid += chunk_valid;
    measured += chunk_measured;
  });
  out->measured = measured;
  if (lens_z == nullptr) scratch.zeroed = true;
  out->fallback_v = 0;
  long long n = 0;
  for (int chunk = 1; chunk < kChunks; ++chunk)
    for (int bin = 0; bin < kBins; ++bin)
      histogram[bin] += histogram[static_cast<std::size_t>(chunk) * kBins + bin];
  for (int bin = 0; bin < kBins; ++bin) n += histogram[bin];
  // The element of rank n / 2 (0-based) of the sorted values: its bin's centre.
  long long below = 0;
  for (int bin = 0; bin < kBins && n > 0; ++bin) {
    below += histogram[bin];
    if (below > n / 2) {
      out->fallback_v = (bin + 0.5) / kBinsPerUnit;
      break;
    }
  }
  out->filled = valid - out->measured;
  return Status::Ok();
}

}  // namespace

Status VirtualDepthToTf(const PlenopticFrame& f, const VirtualDepthMap& raw,
                        const TfOptions& options, TfDepthMap* out) {
  return TfDepthOf(f, raw, nullptr, options, out);
}

Status VirtualDepthToTf(const PlenopticFrame& f, const VirtualDepthMap& raw,
                        const LensDepthMap& lens_depth, const TfOptions& options,
                        TfDepthMap* out) {
  if (Status s = SeedFromLensDepth(f, lens_depth, &out->scratch.lens_z); !s) return s;
  return TfDepthOf(f, raw, &out->scratch.lens_z, options, out);
}

// The per-camera tables of the renderer and what they were made from: the
// frame (the kernel refers to it), its geometry (gain buffer, lattice, lens
// centres, a sample of the gain, lambda, c, r_valid), the MLA file's depth
// ranges (the sharp type per v) and inner_fraction.
struct TfImage::Tables {
  struct Key {
    const PlenopticFrame* frame = nullptr;
    const float* gain = nullptr;
    std::vector<double> values;
    bool operator==(const Key& o) const {
      return frame == o.frame && gain == o.gain && values == o.values;
    }
  } key;
  detail::Gain16 gain16;
  std::unique_ptr<detail::TfKernel> kernel;

  static Key KeyOf(const PlenopticFrame& f, const MlaCalibration& mla, double inner_fraction) {
    Key k;
    k.frame = &f;
    k.gain = f.gain.data();
    std::vector<double>& v = k.values;
    v = {static_cast<double>(f.width),
         static_cast<double>(f.height),
         static_cast<double>(f.gain.size()),
         static_cast<double>(f.lenses.size()),
         f.lambda,
         f.radius_px,
         f.principal_point_px.x(),
         f.principal_point_px.y(),
         inner_fraction};
    for (int i = 0; i < 4; ++i) v.push_back(f.grid.lattice(i / 2, i % 2));
    if (!f.lenses.empty())
      for (const MicroImage* m : {&f.lenses.front(), &f.lenses.back()})
        v.insert(v.end(), {m->centre_px.x(), m->centre_px.y(), m->lens_px.x(), m->lens_px.y()});
    for (const MlaLensType& t : mla.lens_types) v.insert(v.end(), {t.depth_min, t.depth_max});
    constexpr int kSamples = 64;
    for (int i = 0; i < kSamples && !f.gain.empty(); ++i)
      v.push_back(std::isnan(f.gain[f.gain.size() / kSamples * i])
                      ? -1.0  // NaN would never compare equal
                      : f.gain[f.gain.size() / kSamples * i]);
    return k;
  }
};

namespace {

// The tables of `f` in `out`, made when it has none for this geometry.
const TfImage::Tables& TablesFor(const PlenopticFrame& f, const MlaCalibration& mla,
                                 const TfOptions& options, TfImage* out) {
  TfImage::Tables::Key key = TfImage::Tables::KeyOf(f, mla, options.inner_fraction);
  if (out->tables == nullptr || !(out->tables->key == key)) {
    auto tables = std::make_shared<TfImage::Tables>();
    tables->key = std::move(key);
    tables->gain16 = detail::Gain16::From(f.gain, f.width);
    tables->kernel = std::make_unique<detail::TfKernel>(f, mla, options.inner_fraction);
    tables->kernel->UseGain16(&tables->gain16);
    out->tables = std::move(tables);
  }
  return *out->tables;
}

template <int kChannels>
void RenderRows(const PlenopticFrame& f, const MlaCalibration& mla, const TfDepthMap& depth,
                const TfOptions& options, TfImage* out) {
  const int tw = f.width / 2, th = f.height / 2;
  const float fallback = static_cast<float>(depth.fallback_v > 1 ? depth.fallback_v : 3.0);
  const TfImage::Tables& tables = TablesFor(f, mla, options, out);
  const detail::TfKernel& kernel = *tables.kernel;
  const float gain = static_cast<float>(options.gain);
  const bool sharpen = options.sharpen > 0;
  // Runs of a row through the row kernel (tf_blend_simd.h); its
  // preconditions (a frame of 8 x 2 pixels at least, offsets in 32 bits)
  // hold for every camera; a frame outside them goes point by point.
  detail::TfBlendGeometry geometry = kernel.BlendGeometry();
  geometry.bary_floor = static_cast<float>(options.bary_floor);
  detail::TfBlendSource source{f.raw.data, f.raw.stride_bytes, kChannels, nullptr};
  source.gain16 = tables.gain16.q.data();
  source.gain16_scale = tables.gain16.scale;
  const bool rows = f.width >= 8 && f.height >= 2 &&
                    static_cast<double>(f.width) * f.height < 2147483648.0 &&
                    (f.height - 1.0) * f.raw.stride_bytes + 3.0 * f.width < 2147483648.0;
  const detail::TfBlendKernels& kernels =
      options.simd ? detail::SimdTfBlendKernels() : detail::ScalarTfBlendKernels();
  tbb::parallel_for(0, th, [&](int w) {
    const float y = 2.0f * w + 0.5f;
    constexpr int kRun = 256;
    float run_v[kRun], run_acc[kChannels * kRun], run_sw[kRun];
    for (int u0 = 0; u0 < tw; u0 += kRun) {
      const int n = std::min(kRun, tw - u0);
      const std::size_t t0 = static_cast<std::size_t>(w) * tw + u0;
      // Locals, not the captures: the loops below then vectorise (a store
      // through a float pointer could otherwise change a captured value).
      const float fallback_v = fallback, gain_v = gain;
      const float* const v_row = depth.virtual_depth.data() + t0;
      // The next run's depths (at a row's end the next row's first), asked
      // of the cache while this run is blended: the TF depth map comes from
      // memory, and half of this function's perf samples were on the first
      // load of a run's depths.
      const float* const v_next =
          u0 + kRun < tw ? v_row + kRun
                         : (w + 1 < th ? depth.virtual_depth.data() + t0 - u0 + tw : nullptr);
      if (v_next != nullptr)
        for (int i = 0; i < kRun; i += 16) __builtin_prefetch(v_next + i);
      for (int i = 0; i < n; ++i) {
        const float v = v_row[i];
        run_v[i] = v > 1.0f ? v : fallback_v;  // NaN too
      }
      if (rows)
        kernels.row(geometry, source, 2.0f * u0 + 0.5f, 2.0f, y, run_v, n, run_acc, run_sw);
      else
        std::fill(run_sw, run_sw + n, 0.0f);
      // Points none of the three lenses sees: counted by a loop the compiler
      // vectorises (they are few: the image border, the vignetted periphery;
      // an or of the tests per point stayed a scalar loop, 2 % of the TF
      // stage's perf samples).
      int seen = 0;
      for (int i = 0; i < n; ++i) seen += run_sw[i] > 0 ? 1 : 0;
      const bool unseen = !rows || seen < n;
      for (int i = 0; unseen && i < n; ++i) {
        if (run_sw[i] > 0) continue;
        // The border fallback (tf_kernel.h), point by point.
        float acc[kChannels];
        const float x = 2.0f * (u0 + i) + 0.5f;
        run_sw[i] = kernel.Blend<kChannels>(f.raw, x, y, run_v[i], kernel.SharpType(run_v[i]), acc);
        for (int ch = 0; ch < kChannels; ++ch) run_acc[ch * n + i] = acc[ch];
      }
      const std::size_t t0c = t0 * kChannels;
      if (!sharpen) {
        // The 8-bit pixels (tf_blend_simd.h), interleaved.
        kernels.bytes(run_acc, run_sw, n, kChannels, gain_v, out->pixels.data() + t0c);
        continue;
      }
      for (int i = 0; i < n; ++i) {
        const float scale = run_sw[i] > 0 ? gain_v / run_sw[i] : 0.0f;
        for (int ch = 0; ch < kChannels; ++ch)
          out->linear[t0c + i * kChannels + ch] = run_acc[ch * n + i] * scale;
      }
    }
  });
}

}  // namespace

Status RenderTotalFocus(const PlenopticFrame& f, const MlaCalibration& mla, const TfDepthMap& depth,
                        const TfOptions& options, TfImage* out) {
  if (Status s = options.Check(); !s) return s;
  const int tw = f.width / 2, th = f.height / 2;
  if (depth.width != tw || depth.height != th)
    return Error{"TF depth map: size differs from the frame's TF grid"};
  out->width = tw;
  out->height = th;
  out->format = f.has_colour ? PixelFormat::kBgr8 : PixelFormat::kMono8;
  const int channels = f.has_colour ? 3 : 1;
  out->pixels.resize(static_cast<std::size_t>(tw) * th * channels);
  // The float image is only the sharpening's input: 12 bytes per TF pixel
  // of an R32 frame not written when it is off.
  out->linear.resize(options.sharpen > 0 ? out->pixels.size() : 0);
  if (f.has_colour)
    RenderRows<3>(f, mla, depth, options, out);
  else
    RenderRows<1>(f, mla, depth, options, out);
  if (options.sharpen <= 0) return Status::Ok();
  // Optional deblurring: I - k laplacian(I) (a first-order inverse of a
  // Gaussian blur of variance 2k), then 8-bit.
  const double k = options.sharpen;
  tbb::parallel_for(0, th, [&](int w) {
    for (int u = 0; u < tw; ++u) {
      const std::size_t t = static_cast<std::size_t>(w) * tw + u;
      for (int c = 0; c < channels; ++c) {
        double value = out->linear[t * channels + c];
        if (u > 0 && w > 0 && u < tw - 1 && w < th - 1) {
          const float* q = out->linear.data() + c;
          const double lap = q[(t - 1) * channels] + q[(t + 1) * channels] +
                             q[(t - tw) * channels] + q[(t + tw) * channels] - 4 * value;
          value -= k * lap;
        }
        out->pixels[t * channels + c] =
            static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
      }
    }
  });
  return Status::Ok();
}

}  // namespace lifmcr::processing
