#include "processing/total_focus.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

namespace lifmcr::processing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

}  // namespace

Status TfOptions::Check() const {
  if (fill_iterations < 0) return Error{"TF options: fill_iterations: expected >= 0"};
  if (!(unsharp_weight >= 0 && unsharp_weight <= 1))
    return Error{"TF options: unsharp_weight: expected 0..1"};
  if (!(gain > 0)) return Error{"TF options: gain: expected > 0"};
  return Status::Ok();
}

Status VirtualDepthToTf(const PlenopticFrame& f, const VirtualDepthMap& raw,
                        const TfOptions& options, TfDepthMap* out) {
  if (Status s = options.Check(); !s) return s;
  if (raw.width != f.width || raw.height != f.height)
    return Error{"virtual depth map: size differs from the frame"};
  const int tw = f.width / 2, th = f.height / 2;
  const std::size_t tn = static_cast<std::size_t>(tw) * th;
  out->width = tw;
  out->height = th;
  std::vector<double> sw(tn, 0.0), swz(tn, 0.0);
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
        if (f.lens_of_pixel[idx] != k) continue;
        const float v = raw.virtual_depth[idx];
        if (std::isnan(v)) continue;
        const Eigen::Vector2d xv = m.lens_px + v * (Eigen::Vector2d(x, y) - m.lens_px);
        const int u = static_cast<int>(std::lround((xv.x() - 0.5) / 2.0));
        const int w = static_cast<int>(std::lround((xv.y() - 0.5) / 2.0));
        if (u < 0 || w < 0 || u >= tw || w >= th) continue;
        const double s = raw.sigma_z[idx];
        const double weight = 1.0 / std::max(1e-12, s * s);
        const std::size_t t = static_cast<std::size_t>(w) * tw + u;
        std::atomic_ref<double>(sw[t]).fetch_add(weight, std::memory_order_relaxed);
        std::atomic_ref<double>(swz[t]).fetch_add(weight / v, std::memory_order_relaxed);
      }
  });
  out->virtual_depth.assign(tn, kNaN);
  out->sigma_z.assign(tn, kNaN);
  out->measured = 0;
  for (std::size_t t = 0; t < tn; ++t)
    if (sw[t] > 0) {
      out->virtual_depth[t] = static_cast<float>(sw[t] / swz[t]);
      out->sigma_z[t] = static_cast<float>(std::sqrt(1.0 / sw[t]));
      ++out->measured;
    }
  // Regularisation of the measured map: each measured pixel becomes the
  // inverse-variance mean of the measured pixels within smooth_radius that
  // agree with their median within 5 % of z.
  if (options.smooth_radius > 0) {
    const int rad = options.smooth_radius;
    std::vector<float> smoothed = out->virtual_depth;
    tbb::parallel_for(0, th, [&](int w) {
      std::vector<float> zs;
      for (int u = 0; u < tw; ++u) {
        const std::size_t t = static_cast<std::size_t>(w) * tw + u;
        if (std::isnan(out->virtual_depth[t])) continue;
        zs.clear();
        for (int dw = -rad; dw <= rad; ++dw)
          for (int du = -rad; du <= rad; ++du) {
            const int uu = u + du, ww = w + dw;
            if (uu < 0 || ww < 0 || uu >= tw || ww >= th) continue;
            const float v = out->virtual_depth[static_cast<std::size_t>(ww) * tw + uu];
            if (!std::isnan(v)) zs.push_back(1.0f / v);
          }
        std::nth_element(zs.begin(), zs.begin() + zs.size() / 2, zs.end());
        const double med = zs[zs.size() / 2];
        double a = 0, b = 0;
        for (int dw = -rad; dw <= rad; ++dw)
          for (int du = -rad; du <= rad; ++du) {
            const int uu = u + du, ww = w + dw;
            if (uu < 0 || ww < 0 || uu >= tw || ww >= th) continue;
            const std::size_t q = static_cast<std::size_t>(ww) * tw + uu;
            const float v = out->virtual_depth[q];
            if (std::isnan(v) || std::abs(1.0 / v - med) > 0.05 * med) continue;
            const double wq = 1.0 / (static_cast<double>(out->sigma_z[q]) * out->sigma_z[q]);
            a += wq;
            b += wq / v;
          }
        if (a > 0) smoothed[t] = static_cast<float>(a / b);
      }
    });
    out->virtual_depth.swap(smoothed);
  }
  out->fallback_v = 0;
  std::vector<float> all_v;
  for (std::size_t t = 0; t < tn; ++t)
    if (!std::isnan(out->virtual_depth[t])) all_v.push_back(out->virtual_depth[t]);
  if (!all_v.empty()) {
    std::nth_element(all_v.begin(), all_v.begin() + all_v.size() / 2, all_v.end());
    out->fallback_v = all_v[all_v.size() / 2];
  }
  // Hole filling: mean z of the valid 8-neighbours, one ring per round.
  std::vector<float> next;
  for (int it = 0; it < options.fill_iterations; ++it) {
    next = out->virtual_depth;
    tbb::parallel_for(0, th, [&](int w) {
      for (int u = 0; u < tw; ++u) {
        const std::size_t t = static_cast<std::size_t>(w) * tw + u;
        if (!std::isnan(out->virtual_depth[t])) continue;
        double sum = 0;
        int n = 0;
        for (int dw = -1; dw <= 1; ++dw)
          for (int du = -1; du <= 1; ++du) {
            const int uu = u + du, ww = w + dw;
            if (uu < 0 || ww < 0 || uu >= tw || ww >= th) continue;
            const float v = out->virtual_depth[static_cast<std::size_t>(ww) * tw + uu];
            if (std::isnan(v)) continue;
            sum += 1.0 / v;
            ++n;
          }
        if (n > 0) next[t] = static_cast<float>(n / sum);
      }
    });
    out->virtual_depth.swap(next);
  }
  out->filled = 0;
  for (std::size_t t = 0; t < tn; ++t)
    if (!std::isnan(out->virtual_depth[t])) ++out->filled;
  out->filled -= out->measured;
  return Status::Ok();
}

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
  out->linear.resize(out->pixels.size());
  const double r = f.radius_px * options.inner_fraction, r2 = r * r;
  const double pitch = f.grid.PitchPx();
  const double fallback = depth.fallback_v > 1 ? depth.fallback_v : 3.0;
  tbb::parallel_for(0, th, [&](int w) {
    for (int u = 0; u < tw; ++u) {
      const std::size_t t = static_cast<std::size_t>(w) * tw + u;
      double v = depth.virtual_depth[t];
      if (std::isnan(v) || v <= 1.0) v = fallback;
      const Eigen::Vector2d x(2.0 * u + 0.5, 2.0 * w + 0.5);
      int i0 = 0, j0 = 0;
      f.grid.Nearest(x, &i0, &j0);
      const int reach = static_cast<int>(std::ceil(v * r / pitch)) + 1;
      double acc[3] = {0, 0, 0}, sw = 0;
      for (int dj = -reach; dj <= reach; ++dj)
        for (int di = -reach; di <= reach; ++di) {
          if (std::abs(di + dj) > reach) continue;  // hex distance
          const int k = f.LensAt(i0 + di, j0 + dj);
          if (k < 0) continue;
          const MicroImage& m = f.lenses[k];
          const Eigen::Vector2d p = m.lens_px + (x - m.lens_px) / v;
          const double d2 = (p - m.centre_px).squaredNorm();
          if (d2 > r2) continue;
          const int px = static_cast<int>(p.x()), py = static_cast<int>(p.y());
          if (p.x() < 0 || p.y() < 0 || px >= f.width - 1 || py >= f.height - 1) continue;
          const MlaLensType& type = mla.lens_types[m.type];
          const double sharp =
              (v >= type.depth_min && v <= type.depth_max) ? 1.0 : options.unsharp_weight;
          const double weight = sharp * (1.0 - d2 / r2);
          const double fx = p.x() - px, fy = p.y() - py;
          const std::size_t i00 = static_cast<std::size_t>(py) * f.width + px;
          const std::size_t idx[4] = {i00, i00 + 1, i00 + f.width, i00 + f.width + 1};
          const double bw[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
          double sample[3] = {0, 0, 0};
          bool ok = true;
          for (int c = 0; c < channels && ok; ++c)
            for (int q = 0; q < 4; ++q) {
              const float val = channels == 3 ? f.colour[3 * idx[q] + c] : f.grey[idx[q]];
              if (std::isnan(val)) {
                ok = false;
                break;
              }
              sample[c] += bw[q] * val;
            }
          if (!ok) continue;
          for (int c = 0; c < channels; ++c) acc[c] += weight * sample[c];
          sw += weight;
        }
      float* dst = out->linear.data() + t * channels;
      for (int c = 0; c < channels; ++c)
        dst[c] = static_cast<float>(sw > 0 ? options.gain * acc[c] / sw : 0.0);
    }
  });
  // Optional deblurring: I - k laplacian(I) (a first-order inverse of a
  // Gaussian blur of variance 2k), then 8-bit.
  const double k = options.sharpen;
  tbb::parallel_for(0, th, [&](int w) {
    for (int u = 0; u < tw; ++u) {
      const std::size_t t = static_cast<std::size_t>(w) * tw + u;
      for (int c = 0; c < channels; ++c) {
        double value = out->linear[t * channels + c];
        if (k > 0 && u > 0 && w > 0 && u < tw - 1 && w < th - 1) {
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
