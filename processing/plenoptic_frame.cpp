#include "processing/plenoptic_frame.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace lifmcr::processing {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

float GreyAt(ConstImageView image, int x, int y) {
  const std::uint8_t* row = image.Row(y);
  if (image.format == PixelFormat::kMono8) return row[x];
  return (row[3 * x] + row[3 * x + 1] + row[3 * x + 2]) / 3.0f;
}

}  // namespace

Status FrameOptions::Check() const {
  if (!(lambda > 0 && lambda <= 1.5))
    return Error{"frame options: lambda: expected in (0, 1.5] (b_L0 / (b_L0 + B))"};
  if (principal_point_px && !principal_point_px->allFinite())
    return Error{"frame options: principal_point_px: expected finite numbers"};
  if (!(margin_px >= 0 && margin_px < 1000)) return Error{"frame options: margin_px: expected 0..1000"};
  if (smooth_passes < 0 || smooth_passes > 16)
    return Error{"frame options: smooth_passes: expected 0..16"};
  if (!(min_white_fraction >= 0 && min_white_fraction < 1))
    return Error{"frame options: min_white_fraction: expected in [0, 1)"};
  return Status::Ok();
}

Status PrepareGeometry(ConstImageView white, int width, int height, const MlaGrid& grid,
                       const MlaCalibration& mla, const FrameOptions& options,
                       PlenopticFrame* frame) {
  if (Status s = options.Check(); !s) return s;
  const int w = width, h = height;
  if (w <= 0 || h <= 0) return Error{"raw frame: empty image"};
  const bool devignette = white.data != nullptr;
  if (devignette && (white.width != w || white.height != h))
    return Error{"white image: " + std::to_string(white.width) + "x" +
                 std::to_string(white.height) + ", expected the raw frame's size " +
                 std::to_string(w) + "x" + std::to_string(h)};
  PlenopticFrame& f = *frame;
  f.width = w;
  f.height = h;
  f.grid = grid;
  f.lambda = options.lambda;
  f.smooth_passes = options.smooth_passes;
  f.geometry_ready = false;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  f.lens_of_pixel.assign(n, -1);

  // White level W_ref: the white image's mean over the cores (within D / 6
  // of the centre) of the micro images near the image centre, where the
  // vignetting is least: a white surface reads W_ref after devignetting.
  double white_level = 255.0;
  if (devignette) {
    const int half = std::max(8, static_cast<int>(0.1 * std::min(w, h)));
    const double core = grid.PitchPx() / 6;
    double sum = 0;
    long long count = 0;
    for (int y = h / 2 - half; y <= h / 2 + half; ++y)
      for (int x = w / 2 - half; x <= w / 2 + half; ++x) {
        if (x < 0 || y < 0 || x >= w || y >= h) continue;
        int i = 0, j = 0;
        grid.Nearest(Eigen::Vector2d(x, y), &i, &j);
        if ((grid.Center(i, j) - Eigen::Vector2d(x, y)).norm() > core) continue;
        sum += GreyAt(white, x, y);
        ++count;
      }
    if (count == 0 || !(sum / count > 1.0))
      return Error{"white image: the micro images near the image centre are dark"};
    white_level = sum / count;
  }
  f.white_level = white_level;
  // Gain per pixel: W_ref / W(p), NaN where the white image is too dark.
  f.gain.resize(n);
  const float min_white = static_cast<float>(options.min_white_fraction * white_level);
  tbb::parallel_for(0, h, [&](int y) {
    const std::uint8_t* wrow = devignette ? white.Row(y) : nullptr;
    float* gain = f.gain.data() + static_cast<std::size_t>(y) * w;
    for (int x = 0; x < w; ++x) {
      if (!devignette) {
        gain[x] = 1.0f;
        continue;
      }
      const float wv = white.format == PixelFormat::kMono8
                           ? wrow[x]
                           : (wrow[3 * x] + wrow[3 * x + 1] + wrow[3 * x + 2]) / 3.0f;
      gain[x] = wv >= min_white ? static_cast<float>(white_level) / wv : kNaN;
    }
  });

  // Micro images and the pixel -> lens map.
  int i_max = 0, j_max = 0;
  grid.IndexBounds(w, h, &f.i_min, &i_max, &f.j_min, &j_max);
  f.ni = i_max - f.i_min + 1;
  f.nj = j_max - f.j_min + 1;
  f.lens_index.assign(static_cast<std::size_t>(f.ni) * f.nj, -1);
  f.lenses.clear();
  f.radius_px = grid.PitchPx() / 2 - mla.lens_border_px - options.margin_px;
  if (!(f.radius_px > 1.0)) return Error{"MLA: lens border leaves no usable micro-image radius"};
  const Eigen::Vector2d c =
      options.principal_point_px.value_or(Eigen::Vector2d((w - 1) / 2.0, (h - 1) / 2.0));
  f.principal_point_px = c;
  for (int j = f.j_min; j <= j_max; ++j)
    for (int i = f.i_min; i <= i_max; ++i) {
      const Eigen::Vector2d ck = grid.Center(i, j);
      if (ck.x() < -f.radius_px || ck.y() < -f.radius_px || ck.x() > w - 1 + f.radius_px ||
          ck.y() > h - 1 + f.radius_px)
        continue;
      MicroImage m;
      m.i = i;
      m.j = j;
      m.type = grid.Type(i, j);
      m.centre_px = ck;
      m.lens_px = c + (ck - c) * options.lambda;
      f.lens_index[static_cast<std::size_t>(j - f.j_min) * f.ni + (i - f.i_min)] =
          static_cast<std::int32_t>(f.lenses.size());
      f.lenses.push_back(m);
    }
  const double r2 = f.radius_px * f.radius_px;
  tbb::parallel_for(0, static_cast<int>(f.lenses.size()), [&](int k) {
    const Eigen::Vector2d ck = f.lenses[k].centre_px;
    const int x0 = std::max(0, static_cast<int>(std::ceil(ck.x() - f.radius_px)));
    const int x1 = std::min(w - 1, static_cast<int>(std::floor(ck.x() + f.radius_px)));
    const int y0 = std::max(0, static_cast<int>(std::ceil(ck.y() - f.radius_px)));
    const int y1 = std::min(h - 1, static_cast<int>(std::floor(ck.y() + f.radius_px)));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        if ((Eigen::Vector2d(x, y) - ck).squaredNorm() <= r2)
          f.lens_of_pixel[static_cast<std::size_t>(y) * w + x] = k;
  });
  f.smooth_mask.assign(n, 0);
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t idx = static_cast<std::size_t>(y) * w + x;
      const std::int32_t lens = f.lens_of_pixel[idx];
      if (lens < 0) continue;
      auto takes = [&](std::size_t q) {
        return f.lens_of_pixel[q] == lens && !std::isnan(f.gain[q]);
      };
      f.smooth_mask[idx] = static_cast<std::uint8_t>(
          (x > 0 && takes(idx - 1) ? 1 : 0) | (x < w - 1 && takes(idx + 1) ? 2 : 0) |
          (y > 0 && takes(idx - w) ? 4 : 0) | (y < h - 1 && takes(idx + w) ? 8 : 0));
    }
  });
  f.geometry_ready = true;
  return Status::Ok();
}

Status LoadRaw(ConstImageView raw, PlenopticFrame* frame) {
  PlenopticFrame& f = *frame;
  if (!f.geometry_ready) return Error{"raw frame: PrepareGeometry has not run"};
  const int w = f.width, h = f.height;
  if (raw.data == nullptr || raw.width != w || raw.height != h)
    return Error{"raw frame: " + std::to_string(raw.width) + "x" + std::to_string(raw.height) +
                 ", expected " + std::to_string(w) + "x" + std::to_string(h) +
                 " (the white image's and MLA grid's size)"};
  f.has_colour = raw.format == PixelFormat::kBgr8;
  f.raw = raw;
  const std::size_t n = static_cast<std::size_t>(w) * h;
  f.grey.resize(n);
  tbb::parallel_for(0, h, [&](int y) {
    const std::uint8_t* row = raw.Row(y);
    const std::size_t base = static_cast<std::size_t>(y) * w;
    const float* gain = f.gain.data() + base;
    float* grey = f.grey.data() + base;
    if (f.has_colour) {
      for (int x = 0; x < w; ++x)
        grey[x] = (row[3 * x] + row[3 * x + 1] + row[3 * x + 2]) * (gain[x] * (1.0f / 3.0f));
    } else {
      for (int x = 0; x < w; ++x) grey[x] = row[x] * gain[x];
    }
  });
  // Smoothing of the grey image within each micro image (binomial [1 2 1] / 4
  // applied `smooth_passes` times per axis, normalised over the pixels of the
  // same micro image): noise and the blur difference between lens types.
  // The neighbours a pixel takes are the camera's (smooth_mask); one left
  // out adds 0 and no weight, so every pixel is (2 g + sum of the taken) /
  // (2 + their count) in that order (a pixel outside every micro image:
  // 2 g / 2 = g), a loop without branches on the pixels.
  f.work.resize(n);
  for (int pass = 0; pass < f.smooth_passes; ++pass) {
    for (int axis = 0; axis < 2; ++axis) {
      const float* src = f.grey.data();
      float* dst = f.work.data();
      const std::uint8_t lo_bit = axis == 0 ? 1 : 4, hi_bit = axis == 0 ? 2 : 8;
      tbb::parallel_for(0, h, [&](int y) {
        const std::size_t base = static_cast<std::size_t>(y) * w;
        const std::uint8_t* mask = f.smooth_mask.data() + base;
        const float* row = src + base;
        float* out = dst + base;
        // The neighbours along the axis; rows past the border are never
        // taken (their mask bit is 0), so any valid row stands in.
        const float* lo_row = axis == 0 ? row - 1 : (y > 0 ? row - w : row);
        const float* hi_row = axis == 0 ? row + 1 : (y < h - 1 ? row + w : row);
        auto one = [&](int x) {
          const unsigned m = mask[x];
          float sum = 2.0f * row[x];
          sum += (m & lo_bit) ? lo_row[x] : 0.0f;
          sum += (m & hi_bit) ? hi_row[x] : 0.0f;
          const float weight = 2.0f + static_cast<float>((m & lo_bit) != 0) +
                               static_cast<float>((m & hi_bit) != 0);
          out[x] = sum / weight;
        };
        if (axis == 0) {
          // x = 0 and x = w - 1 would read past the row: lo_row[0] and
          // hi_row[w - 1] only when taken, which they never are.
          if (w == 1) {
            out[0] = row[0];
            return;
          }
          out[0] = (2.0f * row[0] + ((mask[0] & hi_bit) ? row[1] : 0.0f)) /
                   (2.0f + static_cast<float>((mask[0] & hi_bit) != 0));
          for (int x = 1; x < w - 1; ++x) one(x);
          out[w - 1] = (2.0f * row[w - 1] + ((mask[w - 1] & lo_bit) ? row[w - 2] : 0.0f)) /
                       (2.0f + static_cast<float>((mask[w - 1] & lo_bit) != 0));
        } else {
          for (int x = 0; x < w; ++x) one(x);
        }
      });
      f.grey.swap(f.work);
    }
  }
  return Status::Ok();
}

Status PrepareFrame(ConstImageView raw, ConstImageView white, const MlaGrid& grid,
                    const MlaCalibration& mla, const FrameOptions& options, PlenopticFrame* frame) {
  if (raw.width <= 0 || raw.height <= 0 || raw.data == nullptr)
    return Error{"raw frame: empty image"};
  if (Status s = PrepareGeometry(white, raw.width, raw.height, grid, mla, options, frame); !s)
    return s;
  return LoadRaw(raw, frame);
}

}  // namespace lifmcr::processing
