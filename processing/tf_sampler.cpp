#include "processing/tf_sampler.h"

#include "processing/tf_kernel.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace lifmcr::processing {
namespace {

// Grey at raw position (x, y), virtual depth v; NaN when no micro image sees it.
template <int kChannels>
float GreyAt(const detail::TfKernel& kernel, const ConstImageView& raw, float x, float y,
             float v) {
  const int type = kernel.SharpType(v);
  float acc[kChannels];
  const float sw = kernel.Blend<kChannels>(raw, x, y, v, type, acc);
  if (!(sw > 0)) return std::numeric_limits<float>::quiet_NaN();
  float sum = 0;
  for (int ch = 0; ch < kChannels; ++ch) sum += acc[ch];
  return sum / (sw * kChannels);
}

template <int kChannels>
bool PatchOf(const detail::TfKernel& kernel, const ConstImageView& raw,
             const Eigen::Vector2d& centre_tf, const Eigen::Matrix2d& warp, double v, int size,
             double step, int box, float* out) {
  const double half = 0.5 * (size - 1);
  const double sub = step / box, sub_half = 0.5 * (box - 1);
  const float vf = static_cast<float>(v);
  for (int j = 0; j < size; ++j)
    for (int i = 0; i < size; ++i) {
      double sum = 0;
      for (int b = 0; b < box; ++b)
        for (int a = 0; a < box; ++a) {
          const Eigen::Vector2d at =
              centre_tf + warp * Eigen::Vector2d(step * (i - half) + sub * (a - sub_half),
                                                 step * (j - half) + sub * (b - sub_half));
          const double u = at.x(), w = at.y();
          // TF pixel (u, w) is raw position (2u + 1/2, 2w + 1/2) (total_focus.h).
          const float g = GreyAt<kChannels>(kernel, raw, static_cast<float>(2 * u + 0.5),
                                            static_cast<float>(2 * w + 0.5), vf);
          if (std::isnan(g)) return false;
          sum += g;
        }
      out[j * size + i] = static_cast<float>(sum / (box * box));
    }
  return true;
}

}  // namespace

TfSampler::TfSampler(PlenopticFrame geometry, const MlaCalibration& mla)
    : geometry_(std::move(geometry)),
      // Refocused at the caller's depth: lenses around the position itself
      // (tf_kernel.h, LensSelection).
      kernel_(std::make_unique<detail::TfKernel>(geometry_, mla, 1.0,
                                                 detail::TfKernel::LensSelection::kAroundPosition)) {}

TfSampler::~TfSampler() = default;

bool TfSampler::Patch(const ConstImageView& raw, const Eigen::Vector2d& centre_tf, double v,
                      int size, double step, int box, float* out) const {
  return PatchWarped(raw, centre_tf, Eigen::Matrix2d::Identity(), v, size, step, box, out);
}

bool TfSampler::PatchWarped(const ConstImageView& raw, const Eigen::Vector2d& centre_tf,
                            const Eigen::Matrix2d& warp, double v, int size, double step, int box,
                            float* out) const {
  if (raw.width != geometry_.width || raw.height != geometry_.height || !(v > 1) || size < 1 ||
      box < 1 || !warp.allFinite())
    return false;
  if (raw.format == PixelFormat::kBgr8)
    return PatchOf<3>(*kernel_, raw, centre_tf, warp, v, size, step, box, out);
  return PatchOf<1>(*kernel_, raw, centre_tf, warp, v, size, step, box, out);
}

float RefocusDepths::At(double u, double w) const {
  // Cell centres at ((i + 1/2) tf_width / cells_x, ...).
  const double a = std::clamp(u / tf_width * cells_x - 0.5, 0.0, cells_x - 1.0);
  const double b = std::clamp(w / tf_height * cells_y - 0.5, 0.0, cells_y - 1.0);
  const int i = std::min(static_cast<int>(a), cells_x - 1), j = std::min(static_cast<int>(b), cells_y - 1);
  const int i1 = std::min(i + 1, cells_x - 1), j1 = std::min(j + 1, cells_y - 1);
  const double fa = a - i, fb = b - j;
  const auto cell = [&](int x, int y) { return v[static_cast<std::size_t>(y) * cells_x + x]; };
  return static_cast<float>((1 - fa) * (1 - fb) * cell(i, j) + fa * (1 - fb) * cell(i1, j) +
                            (1 - fa) * fb * cell(i, j1) + fa * fb * cell(i1, j1));
}

RefocusDepths RefocusDepths::FromPoints(int tf_width, int tf_height, int cells_x, int cells_y,
                                        const std::vector<Eigen::Vector2d>& tf_px,
                                        const std::vector<double>& v, double fallback,
                                        int min_points) {
  RefocusDepths out;
  out.cells_x = std::max(1, cells_x);
  out.cells_y = std::max(1, cells_y);
  out.tf_width = tf_width;
  out.tf_height = tf_height;
  std::vector<std::vector<double>> in_cell(static_cast<std::size_t>(out.cells_x) * out.cells_y);
  for (std::size_t k = 0; k < tf_px.size() && k < v.size(); ++k) {
    const Eigen::Vector2d& p = tf_px[k];
    if (!(p.x() >= 0 && p.y() >= 0 && p.x() < tf_width && p.y() < tf_height && v[k] > 1)) continue;
    const int i = std::min(out.cells_x - 1, static_cast<int>(p.x() / tf_width * out.cells_x));
    const int j = std::min(out.cells_y - 1, static_cast<int>(p.y() / tf_height * out.cells_y));
    in_cell[static_cast<std::size_t>(j) * out.cells_x + i].push_back(v[k]);
  }
  out.v.assign(in_cell.size(), static_cast<float>(fallback));
  for (std::size_t c = 0; c < in_cell.size(); ++c) {
    std::vector<double>& d = in_cell[c];
    if (static_cast<int>(d.size()) < std::max(1, min_points)) continue;
    std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
    out.v[c] = static_cast<float>(d[d.size() / 2]);
  }
  return out;
}

namespace {

// RenderAtDepth(s)'s loop; depth(u, w) the virtual depth at output pixel (u, w).
// `where`: nullptr, or the output pixels to render (non-zero; the others
// are `fill`).
template <typename DepthOf>
Status RenderRefocused(const detail::TfKernel& kernel, const ConstImageView& raw, int tw, int th, int step,
              const DepthOf& depth, TfImage* out, const ConstImageView* where = nullptr,
              std::uint8_t fill = 0) {
  out->width = tw;
  out->height = th;
  out->format = PixelFormat::kMono8;
  out->pixels.resize(static_cast<std::size_t>(tw) * th);
  out->linear.clear();
  const bool colour = raw.format == PixelFormat::kBgr8;
  // TF position u is raw position 2u + 1/2 (total_focus.h); output pixel i
  // is TF position step i + (step - 1) / 2.
  const float offset = static_cast<float>(step - 1) + 0.5f;
  const float raw_step = 2.0f * static_cast<float>(step);
  tbb::parallel_for(0, th, [&](int w) {
    const float y = raw_step * static_cast<float>(w) + offset;
    std::uint8_t* row = out->pixels.data() + static_cast<std::size_t>(w) * tw;
    const std::uint8_t* wanted =
        where != nullptr ? where->data + static_cast<std::size_t>(w) * where->stride_bytes : nullptr;
    for (int u = 0; u < tw; ++u) {
      if (wanted != nullptr && wanted[u] == 0) {
        row[u] = fill;
        continue;
      }
      const float x = raw_step * static_cast<float>(u) + offset;
      const float vf = depth(u, w);
      const int type = kernel.SharpType(vf);
      float acc[3], sw;
      float grey = 0;
      if (colour) {
        sw = kernel.Blend<3>(raw, x, y, vf, type, acc);
        grey = (acc[0] + acc[1] + acc[2]) / 3;
      } else {
        sw = kernel.Blend<1>(raw, x, y, vf, type, acc);
        grey = acc[0];
      }
      row[u] = sw > 0 ? static_cast<std::uint8_t>(std::clamp(grey / sw + 0.5f, 0.0f, 255.0f)) : 0;
    }
  });
  return Status::Ok();
}

}  // namespace

Status TfSampler::RenderAtDepth(const ConstImageView& raw, double v, int step,
                                TfImage* out) const {
  if (raw.width != geometry_.width || raw.height != geometry_.height)
    return Error{"TF sampler: frame " + std::to_string(raw.width) + "x" +
                 std::to_string(raw.height) + ", the camera's geometry is " +
                 std::to_string(geometry_.width) + "x" + std::to_string(geometry_.height)};
  if (!(v > 1)) return Error{"TF sampler: virtual depth: expected > 1"};
  if (step < 1) return Error{"TF sampler: step: expected >= 1"};
  const float vf = static_cast<float>(v);
  return RenderRefocused(*kernel_, raw, tf_width() / step, tf_height() / step, step,
                [vf](int, int) { return vf; }, out);
}

Status TfSampler::RenderAtDepths(const ConstImageView& raw, const RefocusDepths& depths, int step,
                                 TfImage* out, const ConstImageView* where,
                                 std::uint8_t fill) const {
  if (raw.width != geometry_.width || raw.height != geometry_.height)
    return Error{"TF sampler: frame " + std::to_string(raw.width) + "x" +
                 std::to_string(raw.height) + ", the camera's geometry is " +
                 std::to_string(geometry_.width) + "x" + std::to_string(geometry_.height)};
  if (step < 1) return Error{"TF sampler: step: expected >= 1"};
  if (depths.cells_x < 1 || depths.cells_y < 1 ||
      depths.v.size() != static_cast<std::size_t>(depths.cells_x) * depths.cells_y)
    return Error{"TF sampler: refocus depths: expected cells_x * cells_y values"};
  for (const float v : depths.v)
    if (!(v > 1)) return Error{"TF sampler: refocus depths: expected every virtual depth > 1"};
  if (where != nullptr &&
      (where->data == nullptr || where->format != PixelFormat::kMono8 ||
       where->width != tf_width() / step || where->height != tf_height() / step))
    return Error{"TF sampler: render mask: expected Mono8 of the render's size " +
                 std::to_string(tf_width() / step) + " x " + std::to_string(tf_height() / step)};
  // Interpolated per output pixel (a few multiplications beside the blend's
  // three lens samples).
  const float half = 0.5f * static_cast<float>(step - 1), fstep = static_cast<float>(step);
  return RenderRefocused(*kernel_, raw, tf_width() / step, tf_height() / step, step,
                [&](int u, int w) {
                  return depths.At(fstep * static_cast<float>(u) + half,
                                   fstep * static_cast<float>(w) + half);
                },
                out, where, fill);
}

}  // namespace lifmcr::processing
