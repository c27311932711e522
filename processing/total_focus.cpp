#include "processing/total_focus.h"

#include "processing/tf_kernel.h"

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
  return Status::Ok();
}

namespace {

// Weighted box sums over a (2 radius + 1)^2 window, separable running sums
// (O(1) per pixel whatever the radius): box_w = sum w, box_wz = sum w z, with
// w = 0 where a pixel has no value, and box_n = how many had one (exact,
// unlike a running double sum, whose subtractions leave residues).
void BoxSums(int width, int height, int radius, const std::vector<double>& w,
             const std::vector<double>& wz, TfDepthMap::Scratch* s) {
  s->row_w.resize(w.size());
  s->row_wz.resize(w.size());
  s->row_n.resize(w.size());
  tbb::parallel_for(0, height, [&](int y) {
    const std::size_t base = static_cast<std::size_t>(y) * width;
    double a = 0, b = 0;
    int c = 0;
    auto add = [&](int x, int sign) {
      a += sign * w[base + x];
      b += sign * wz[base + x];
      c += sign * (w[base + x] > 0);
    };
    for (int x = 0; x <= std::min(radius, width - 1); ++x) add(x, 1);
    for (int x = 0; x < width; ++x) {
      s->row_w[base + x] = a;
      s->row_wz[base + x] = b;
      s->row_n[base + x] = c;
      if (x + radius + 1 < width) add(x + radius + 1, 1);
      if (x - radius >= 0) add(x - radius, -1);
    }
  });
  s->box_w.resize(w.size());
  s->box_wz.resize(w.size());
  s->box_n.resize(w.size());
  constexpr int kStrip = 64;
  tbb::parallel_for(0, (width + kStrip - 1) / kStrip, [&](int strip) {
    const int x0 = strip * kStrip, x1 = std::min(width, x0 + kStrip);
    double a[kStrip] = {}, b[kStrip] = {};
    int c[kStrip] = {};
    auto add = [&](int y, int sign) {
      for (int x = x0; x < x1; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * width + x;
        a[x - x0] += sign * s->row_w[i];
        b[x - x0] += sign * s->row_wz[i];
        c[x - x0] += sign * s->row_n[i];
      }
    };
    for (int y = 0; y <= std::min(radius, height - 1); ++y) add(y, 1);
    for (int y = 0; y < height; ++y) {
      for (int x = x0; x < x1; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * width + x;
        s->box_w[i] = a[x - x0];
        s->box_wz[i] = b[x - x0];
        s->box_n[i] = c[x - x0];
      }
      if (y + radius + 1 < height) add(y + radius + 1, 1);
      if (y - radius >= 0) add(y - radius, -1);
    }
  });
}

}  // namespace

Status VirtualDepthToTf(const PlenopticFrame& f, const VirtualDepthMap& raw,
                        const TfOptions& options, TfDepthMap* out) {
  if (Status s = options.Check(); !s) return s;
  if (raw.width != f.width || raw.height != f.height)
    return Error{"virtual depth map: size differs from the frame"};
  const int tw = f.width / 2, th = f.height / 2;
  const std::size_t tn = static_cast<std::size_t>(tw) * th;
  out->width = tw;
  out->height = th;
  TfDepthMap::Scratch& scratch = out->scratch;
  std::vector<double>& sw = scratch.sw;
  std::vector<double>& swz = scratch.swz;
  sw.assign(tn, 0.0);
  swz.assign(tn, 0.0);
  // Splat, parallel over micro images; a TF pixel may get splats from several
  // micro images at once, hence the atomic adds (rarely contended).
  tbb::parallel_for(0, static_cast<int>(f.lenses.size()), [&](int k) {
    const MicroImage& m = f.lenses[k];
    const double r = f.radius_px;
    const int x0 = std::max(0, static_cast<int>(std::ceil(m.centre_px.x() - r)));
    const int x1 = std::min(f.width - 1, static_cast<int>(std::floor(m.centre_px.x() + r)));
    const int y0 = std::max(0, static_cast<int>(std::ceil(m.centre_px.y() - r)));
    const int y1 = std::min(f.height - 1, static_cast<int>(std::floor(m.centre_px.y() + r)));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const std::size_t idx = static_cast<std::size_t>(y) * f.width + x;
        const float v = raw.virtual_depth[idx];
        if (std::isnan(v) || f.lens_of_pixel[idx] != k) continue;
        const double xv = m.lens_px.x() + v * (x - m.lens_px.x());
        const double yv = m.lens_px.y() + v * (y - m.lens_px.y());
        // Nearest TF pixel: lround without its libm call (a call per
        // splat): for a > -0.5, lround(a) = trunc(a + 0.5); a <= -0.5
        // rounds below 0, off the grid.
        const double ua = (xv - 0.5) / 2.0, wa = (yv - 0.5) / 2.0;
        if (!(ua > -0.5) || !(wa > -0.5)) continue;
        const int u = static_cast<int>(ua + 0.5), w = static_cast<int>(wa + 0.5);
        if (u >= tw || w >= th) continue;
        const double s = raw.sigma_z[idx];
        const double weight = 1.0 / std::max(1e-12, s * s);
        const std::size_t t = static_cast<std::size_t>(w) * tw + u;
        std::atomic_ref<double>(sw[t]).fetch_add(weight, std::memory_order_relaxed);
        std::atomic_ref<double>(swz[t]).fetch_add(weight / v, std::memory_order_relaxed);
      }
  });
  out->virtual_depth.resize(tn);
  out->sigma_z.resize(tn);
  std::atomic<long long> measured{0};
  tbb::parallel_for(0, th, [&](int w) {
    long long row_measured = 0;
    for (std::size_t t = static_cast<std::size_t>(w) * tw; t < static_cast<std::size_t>(w + 1) * tw;
         ++t) {
      out->sigma_z[t] = sw[t] > 0 ? static_cast<float>(std::sqrt(1.0 / sw[t])) : kNaN;
      row_measured += sw[t] > 0;
    }
    measured += row_measured;
  });
  out->measured = measured;
  // Regularisation on a grid of kCell x kCell TF pixels (the depth map is
  // smooth at that scale after the window mean anyway; the window passes
  // then touch 16x less memory): per cell the sums of the splats, the
  // inverse-variance mean of z over a window of about smooth_radius, again
  // over the measured pixels that agree with their cell's mean within 5 %
  // (a step in depth splits the window; the side holding the majority
  // stays), holes filled from the cells within fill_iterations, then
  // bilinear interpolation back to every TF pixel.
  constexpr int kCell = 4;
  const int cw = (tw + kCell - 1) / kCell, ch = (th + kCell - 1) / kCell;
  const std::size_t cn = static_cast<std::size_t>(cw) * ch;
  std::vector<double>& cell_w = scratch.cell_w;
  std::vector<double>& cell_wz = scratch.cell_wz;
  auto sum_cells = [&](auto keep) {
    cell_w.assign(cn, 0.0);
    cell_wz.assign(cn, 0.0);
    tbb::parallel_for(0, ch, [&](int cy) {
      for (int w = cy * kCell; w < std::min(th, (cy + 1) * kCell); ++w)
        for (int u = 0; u < tw; ++u) {
          const std::size_t t = static_cast<std::size_t>(w) * tw + u;
          if (sw[t] <= 0 || !keep(t)) continue;
          const std::size_t c = static_cast<std::size_t>(cy) * cw + u / kCell;
          cell_w[c] += sw[t];
          cell_wz[c] += swz[t];
        }
    });
  };
  const int cell_radius = std::max(0, (options.smooth_radius + kCell / 2) / kCell);
  sum_cells([](std::size_t) { return true; });
  BoxSums(cw, ch, cell_radius, cell_w, cell_wz, &scratch);
  std::vector<float>& cell_z = scratch.cell_z;
  cell_z.assign(cn, kNaN);
  for (std::size_t c = 0; c < cn; ++c)
    if (scratch.box_n[c] > 0) cell_z[c] = static_cast<float>(scratch.box_wz[c] / scratch.box_w[c]);
  sum_cells([&](std::size_t t) {
    const int u = static_cast<int>(t % tw), w = static_cast<int>(t / tw);
    const double mean = cell_z[static_cast<std::size_t>(w / kCell) * cw + u / kCell];
    return std::abs(swz[t] / sw[t] - mean) <= 0.05 * mean;
  });
  BoxSums(cw, ch, cell_radius, cell_w, cell_wz, &scratch);
  for (std::size_t c = 0; c < cn; ++c)
    cell_z[c] =
        scratch.box_n[c] > 0 ? static_cast<float>(scratch.box_wz[c] / scratch.box_w[c]) : kNaN;
  // Holes: the mean z of the valid cells within fill_iterations TF pixels.
  const int fill_cells = (options.fill_iterations + kCell - 1) / kCell;
  if (fill_cells > 0) {
    for (std::size_t c = 0; c < cn; ++c) {
      cell_w[c] = std::isnan(cell_z[c]) ? 0.0 : 1.0;
      cell_wz[c] = std::isnan(cell_z[c]) ? 0.0 : cell_z[c];
    }
    BoxSums(cw, ch, fill_cells, cell_w, cell_wz, &scratch);
    for (std::size_t c = 0; c < cn; ++c)
      if (std::isnan(cell_z[c]) && scratch.box_n[c] > 0)
        cell_z[c] = static_cast<float>(scratch.box_wz[c] / scratch.box_w[c]);
  }
  // Back to TF pixels: bilinear between cell centres over the valid cells.
  tbb::parallel_for(0, th, [&](int w) {
    const float gy = std::clamp((w + 0.5f) / kCell - 0.5f, 0.0f, static_cast<float>(ch - 1));
    const int y0 = std::min(static_cast<int>(gy), ch - 1), y1 = std::min(y0 + 1, ch - 1);
    const float fy = gy - y0;
    for (int u = 0; u < tw; ++u) {
      const float gx = std::clamp((u + 0.5f) / kCell - 0.5f, 0.0f, static_cast<float>(cw - 1));
      const int x0 = std::min(static_cast<int>(gx), cw - 1), x1 = std::min(x0 + 1, cw - 1);
      const float fx = gx - x0;
      const float zs[4] = {cell_z[static_cast<std::size_t>(y0) * cw + x0],
                           cell_z[static_cast<std::size_t>(y0) * cw + x1],
                           cell_z[static_cast<std::size_t>(y1) * cw + x0],
                           cell_z[static_cast<std::size_t>(y1) * cw + x1]};
      const float ws[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
      float a = 0, b = 0;
      for (int q = 0; q < 4; ++q)
        if (!std::isnan(zs[q])) {
          a += ws[q];
          b += ws[q] * zs[q];
        }
      out->virtual_depth[static_cast<std::size_t>(w) * tw + u] = a > 1e-6f ? a / b : kNaN;
    }
  });
  out->fallback_v = 0;
  std::vector<float>& values = scratch.measured_v;
  values.clear();
  for (std::size_t t = 0; t < tn; ++t)
    if (sw[t] > 0 && !std::isnan(out->virtual_depth[t])) values.push_back(out->virtual_depth[t]);
  if (!values.empty()) {
    std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
    out->fallback_v = values[values.size() / 2];
  }
  std::atomic<long long> valid{0};
  tbb::parallel_for(0, th, [&](int w) {
    long long row_valid = 0;
    for (std::size_t t = static_cast<std::size_t>(w) * tw; t < static_cast<std::size_t>(w + 1) * tw;
         ++t)
      row_valid += !std::isnan(out->virtual_depth[t]);
    valid += row_valid;
  });
  out->filled = valid - out->measured;
  return Status::Ok();
}

namespace {

template <int kChannels>
void RenderRows(const PlenopticFrame& f, const MlaCalibration& mla, const TfDepthMap& depth,
                const TfOptions& options, TfImage* out) {
  const int tw = f.width / 2, th = f.height / 2;
  const double fallback = depth.fallback_v > 1 ? depth.fallback_v : 3.0;
  const detail::TfKernel kernel(f, mla, options.inner_fraction);
  const float gain = static_cast<float>(options.gain);
  const bool sharpen = options.sharpen > 0;
  tbb::parallel_for(0, th, [&](int w) {
    const float y = 2.0f * w + 0.5f;
    for (int u = 0; u < tw; ++u) {
      const std::size_t t = static_cast<std::size_t>(w) * tw + u;
      float v = depth.virtual_depth[t];
      if (!(v > 1.0f)) v = static_cast<float>(fallback);  // NaN too
      const float x = 2.0f * u + 0.5f;
      const int type = kernel.SharpType(v);
      float acc[kChannels];
      const float sw = kernel.Blend<kChannels>(f.raw, x, y, v, type, acc);
      const float scale = sw > 0 ? gain / sw : 0.0f;
      if (sharpen) {
        float* dst = out->linear.data() + t * kChannels;
        for (int ch = 0; ch < kChannels; ++ch) dst[ch] = acc[ch] * scale;
      } else {
        std::uint8_t* pix = out->pixels.data() + t * kChannels;
        for (int ch = 0; ch < kChannels; ++ch)
          pix[ch] = static_cast<std::uint8_t>(std::clamp(acc[ch] * scale + 0.5f, 0.0f, 255.0f));
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
