#include "processing/vignetting.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>

namespace lifmcr::processing {

Status VignettingOptions::Check() const {
  if (!(bin_px > 0 && bin_px <= 1)) return Error{"vignetting: bin_px: expected 0 < bin <= 1 px"};
  if (!(flat_fraction > 0 && flat_fraction < 1))
    return Error{"vignetting: flat_fraction: expected 0 < fraction < 1"};
  if (row_step < 1) return Error{"vignetting: row_step: expected >= 1"};
  return Status::Ok();
}

ConstImageView VignettingEstimate::White() const {
  if (white.empty()) return {};
  return {white.data(), width, height, static_cast<std::size_t>(width), PixelFormat::kMono8};
}

std::string VignettingEstimate::BriefReport() const {
  char buf[240];
  if (already_corrected)
    std::snprintf(buf, sizeof buf,
                  "no white image: taken as already devignetted (the frame's mean micro image "
                  "keeps %.0f %% of its centre out to r_valid %.2f px)",
                  100 * min_ratio, radius_valid_px);
  else
    std::snprintf(buf, sizeof buf,
                  "no white image: vignetting estimated from the frame (the mean micro image "
                  "falls to %.0f %% of its centre within r_valid %.2f px)",
                  100 * min_ratio, radius_valid_px);
  return buf;
}

Expected<VignettingEstimate> EstimateVignetting(ConstImageView raw, const MlaGrid& grid,
                                                const MlaCalibration& mla,
                                                const VignettingOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  const int w = raw.width, h = raw.height;
  if (raw.data == nullptr) return Error{"raw frame: empty image"};
  if (w < 8 || h < 8)
    return Error{"raw frame: " + std::to_string(w) + "x" + std::to_string(h) +
                 " px, expected at least 8x8 px to estimate its vignetting"};
  const double half_pitch = grid.PitchPx() / 2;
  const int bins = static_cast<int>(std::ceil(half_pitch / options.bin_px)) + 1;
  std::vector<double> sum(bins, 0.0);
  std::vector<long long> count(bins, 0);
  std::mutex merge;
  const bool mono = raw.format == PixelFormat::kMono8;
  const int rows = (h + options.row_step - 1) / options.row_step;
  tbb::parallel_for(0, rows, [&](int r) {
    const int y = r * options.row_step;
    std::vector<double> s(bins, 0.0);
    std::vector<long long> c(bins, 0);
    const std::uint8_t* row = raw.Row(y);
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector2d p(x, y);
      int i = 0, j = 0;
      grid.Nearest(p, &i, &j);
      const int b = static_cast<int>((p - grid.Center(i, j)).norm() / options.bin_px);
      if (b >= bins) continue;
      s[b] += mono ? row[x] : (row[3 * x] + row[3 * x + 1] + row[3 * x + 2]) / 3.0;
      ++c[b];
    }
    std::lock_guard<std::mutex> lock(merge);
    for (int b = 0; b < bins; ++b) {
      sum[b] += s[b];
      count[b] += c[b];
    }
  });
  VignettingEstimate e;
  e.bin_px = options.bin_px;
  e.width = w;
  e.height = h;
  e.radius_valid_px = half_pitch - mla.lens_border_px;
  // m(0): the core within D/6, where the micro lens's vignetting is least.
  double core_sum = 0;
  long long core_n = 0;
  for (int b = 0; b < bins && (b + 0.5) * options.bin_px <= grid.PitchPx() / 6; ++b) {
    core_sum += sum[b];
    core_n += count[b];
  }
  if (core_n == 0 || !(core_sum / core_n > 1.0))
    return Error{"raw frame: the micro-image centres are dark; cannot estimate vignetting"};
  const double m0 = core_sum / core_n;
  e.profile.resize(bins);
  double peak = 0;
  for (int b = 0; b < bins; ++b) {
    e.profile[b] = count[b] > 0 ? sum[b] / count[b] / m0 : 0.0;
    peak = std::max(peak, e.profile[b]);
  }
  e.min_ratio = 1.0;
  for (int b = 0; b < bins && (b + 1) * options.bin_px <= e.radius_valid_px; ++b)
    if (count[b] > 0) e.min_ratio = std::min(e.min_ratio, e.profile[b]);
  e.already_corrected = e.min_ratio >= options.flat_fraction;
  if (e.already_corrected) return e;

  // W(p) = 255 m(r(p)) / max m, linear between bin centres.
  e.white.resize(static_cast<std::size_t>(w) * h);
  tbb::parallel_for(0, h, [&](int y) {
    std::uint8_t* out = e.white.data() + static_cast<std::size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      const Eigen::Vector2d p(x, y);
      int i = 0, j = 0;
      grid.Nearest(p, &i, &j);
      const double t = (p - grid.Center(i, j)).norm() / options.bin_px - 0.5;
      const int b0 = std::clamp(static_cast<int>(std::floor(t)), 0, bins - 1);
      const int b1 = std::min(b0 + 1, bins - 1);
      const double f = std::clamp(t - b0, 0.0, 1.0);
      const double m = e.profile[b0] * (1 - f) + e.profile[b1] * f;
      out[x] = static_cast<std::uint8_t>(std::lround(std::clamp(255.0 * m / peak, 0.0, 255.0)));
    }
  });
  return e;
}

}  // namespace lifmcr::processing
