#include "processing/plenoptic_frame.h"

#include "processing/frame_smooth_simd.h"

#include <tbb/blocked_range.h>
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

namespace {

// LoadRaw's streaming pass over one band of rows [y0, y1): the grey of each
// row and the smoothing's passes (x, y, x, y, ...) on rows in cache, three
// rows per stage, the last y pass writing the frame's grey. Stage p (p < P
// = smooth_passes) holds the rows after pass p's y (none for p = 0) and
// pass p + 1's x; the final y pass of a row needs rows r - 1 .. r + 1 of
// stage P - 1, which needs r - 2 .. r + 2 of stage P - 2, ...: a band
// recomputes P - p rows of stage p beyond each of its ends (a band of 64
// rows and P = 2: 6 % more rows in stage 0, 3 % in stage 1), so bands are
// independent and the values are the same as whole-frame passes'.
class BandSmoother {
 public:
  BandSmoother(const detail::FrameSmoothKernels& k, ConstImageView raw, PlenopticFrame& f,
               int y0, int y1, float* rows)
      : k_(k), raw_(raw), f_(f), w_(f.width), h_(f.height), passes_(f.smooth_passes), y0_(y0),
        y1_(y1), scratch_(rows) {
    for (int p = 0; p < passes_; ++p) {
      ring_[p] = rows + static_cast<std::size_t>(1 + 3 * p) * w_;
      next_[p] = std::max(0, y0 - (passes_ - p));
      end_[p] = std::min(h_, y1 + (passes_ - p));
    }
  }

  // Floats of the rows a band needs: a scratch row and three per stage.
  static std::size_t RowFloats(int width, int passes) {
    return static_cast<std::size_t>(1 + 3 * passes) * width;
  }

  void Run() {
    for (int y = y0_; y < y1_; ++y) {
      float* out = f_.grey.data() + static_cast<std::size_t>(y) * w_;
      if (passes_ == 0) {
        Grey(y, out);
        continue;
      }
      const int last = passes_ - 1;
      Ensure(last, std::min(y + 1, h_ - 1));
      SmoothY(last, y, out);
    }
  }

 private:
  float* Ring(int p, int r) { return ring_[p] + static_cast<std::size_t>(r % 3) * w_; }
  const std::uint8_t* Mask(int r) const {
    return f_.smooth_mask.data() + static_cast<std::size_t>(r) * w_;
  }

  // The devignetted grey of row r.
  void Grey(int r, float* out) const {
    const std::uint8_t* row = raw_.Row(r);
    const float* gain = f_.gain.data() + static_cast<std::size_t>(r) * w_;
    if (f_.has_colour) {
      for (int x = 0; x < w_; ++x)
        out[x] = (row[3 * x] + row[3 * x + 1] + row[3 * x + 2]) * (gain[x] * (1.0f / 3.0f));
    } else {
      k_.grey_row(row, gain, w_, out);
    }
  }

  // The y pass on stage p - 1's rows r - 1 .. r + 1 (computed); a row off
  // the frame is never taken (its mask bit is 0), row r stands in.
  void SmoothY(int p, int r, float* out) {
    const float* row = Ring(p, r);
    const float* lo = r > 0 ? Ring(p, r - 1) : row;
    const float* hi = r < h_ - 1 ? Ring(p, r + 1) : row;
    k_.smooth_y(lo, row, hi, Mask(r), w_, out);
  }

  // Stage p up to row r (within its range).
  void Ensure(int p, int r) {
    for (; next_[p] <= r && next_[p] < end_[p]; ++next_[p]) {
      const int row = next_[p];
      if (p == 0) {
        Grey(row, scratch_);
      } else {
        Ensure(p - 1, std::min(row + 1, end_[p - 1] - 1));
        SmoothY(p - 1, row, scratch_);
      }
      k_.smooth_x(scratch_, Mask(row), w_, Ring(p, row));
    }
  }

  static constexpr int kMaxPasses = 16;  // FrameOptions::Check
  const detail::FrameSmoothKernels& k_;
  ConstImageView raw_;
  PlenopticFrame& f_;
  const int w_, h_, passes_, y0_, y1_;
  float* scratch_;
  float* ring_[kMaxPasses] = {};
  int next_[kMaxPasses] = {}, end_[kMaxPasses] = {};
};

// A band's rows, per thread and kept across frames: fresh pages per frame
// would cost more than the arithmetic (about 10 us each on a loaded VM).
std::vector<float>& ThreadRows(std::size_t floats) {
  thread_local std::vector<float> rows;
  if (rows.size() < floats) rows.resize(floats);
  return rows;
}

}  // namespace

Status LoadRaw(ConstImageView raw, PlenopticFrame* frame) {
  return LoadRaw(raw, detail::SimdFrameSmoothKernels(), frame);
}

Status LoadRaw(ConstImageView raw, const detail::FrameSmoothKernels& kernels,
               PlenopticFrame* frame) {
  PlenopticFrame& f = *frame;
  if (!f.geometry_ready) return Error{"raw frame: PrepareGeometry has not run"};
  const int w = f.width, h = f.height;
  if (raw.data == nullptr || raw.width != w || raw.height != h)
    return Error{"raw frame: " + std::to_string(raw.width) + "x" + std::to_string(raw.height) +
                 ", expected " + std::to_string(w) + "x" + std::to_string(h) +
                 " (the white image's and MLA grid's size)"};
  if (f.smooth_passes < 0 || f.smooth_passes > 16)
    return Error{"frame: smooth_passes: expected 0..16"};
  f.has_colour = raw.format == PixelFormat::kBgr8;
  f.raw = raw;
  f.grey.resize(static_cast<std::size_t>(w) * h);
  // Smoothing of the grey image within each micro image (binomial [1 2 1] / 4
  // applied `smooth_passes` times per axis, x then y, normalised over the
  // pixels of the same micro image): noise and the blur difference between
  // lens types. The neighbours a pixel takes are the camera's (smooth_mask);
  // one left out adds 0 and no weight (frame_smooth_simd.h), a pixel outside
  // every micro image keeps its grey. One pass over the frame: the raw frame
  // read once, the grey written once (BandSmoother).
  const std::size_t floats = BandSmoother::RowFloats(w, f.smooth_passes);
  constexpr int kBandRows = 128;  // tbb splits down to 64-128 rows
  tbb::parallel_for(tbb::blocked_range<int>(0, h, kBandRows),
                    [&](const tbb::blocked_range<int>& band) {
                      std::vector<float>& rows = ThreadRows(floats);
                      BandSmoother(kernels, raw, f, band.begin(), band.end(), rows.data()).Run();
                    });
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
