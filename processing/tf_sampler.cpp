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
             const Eigen::Vector2d& centre_tf, double v, int size, double step, int box,
             float* out) {
  const double half = 0.5 * (size - 1);
  const double sub = step / box, sub_half = 0.5 * (box - 1);
  const float vf = static_cast<float>(v);
  for (int j = 0; j < size; ++j)
    for (int i = 0; i < size; ++i) {
      double sum = 0;
      for (int b = 0; b < box; ++b)
        for (int a = 0; a < box; ++a) {
          const double u = centre_tf.x() + step * (i - half) + sub * (a - sub_half);
          const double w = centre_tf.y() + step * (j - half) + sub * (b - sub_half);
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
  if (raw.width != geometry_.width || raw.height != geometry_.height || !(v > 1) || size < 1 ||
      box < 1)
    return false;
  if (raw.format == PixelFormat::kBgr8)
    return PatchOf<3>(*kernel_, raw, centre_tf, v, size, step, box, out);
  return PatchOf<1>(*kernel_, raw, centre_tf, v, size, step, box, out);
}

Status TfSampler::RenderAtDepth(const ConstImageView& raw, double v, int step,
                                TfImage* out) const {
  if (raw.width != geometry_.width || raw.height != geometry_.height)
    return Error{"TF sampler: frame " + std::to_string(raw.width) + "x" +
                 std::to_string(raw.height) + ", the camera's geometry is " +
                 std::to_string(geometry_.width) + "x" + std::to_string(geometry_.height)};
  if (!(v > 1)) return Error{"TF sampler: virtual depth: expected > 1"};
  if (step < 1) return Error{"TF sampler: step: expected >= 1"};
  const int tw = tf_width() / step, th = tf_height() / step;
  out->width = tw;
  out->height = th;
  out->format = PixelFormat::kMono8;
  out->pixels.resize(static_cast<std::size_t>(tw) * th);
  out->linear.clear();
  const float vf = static_cast<float>(v);
  const int type = kernel_->SharpType(vf);
  const bool colour = raw.format == PixelFormat::kBgr8;
  // TF position u is raw position 2u + 1/2 (total_focus.h); output pixel i
  // is TF position step i + (step - 1) / 2.
  const float offset = static_cast<float>(step - 1) + 0.5f;
  const float raw_step = 2.0f * static_cast<float>(step);
  tbb::parallel_for(0, th, [&](int w) {
    const float y = raw_step * static_cast<float>(w) + offset;
    std::uint8_t* row = out->pixels.data() + static_cast<std::size_t>(w) * tw;
    for (int u = 0; u < tw; ++u) {
      const float x = raw_step * static_cast<float>(u) + offset;
      float acc[3], sw;
      float grey = 0;
      if (colour) {
        sw = kernel_->Blend<3>(raw, x, y, vf, type, acc);
        grey = (acc[0] + acc[1] + acc[2]) / 3;
      } else {
        sw = kernel_->Blend<1>(raw, x, y, vf, type, acc);
        grey = acc[0];
      }
      row[u] = sw > 0 ? static_cast<std::uint8_t>(std::clamp(grey / sw + 0.5f, 0.0f, 255.0f)) : 0;
    }
  });
  return Status::Ok();
}

}  // namespace lifmcr::processing
