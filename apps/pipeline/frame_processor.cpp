// Preview and depth stages of the pipeline. OpenCV is used here only, at the
// encoding boundary: cv::Mat headers wrap the pooled frame (no copy).

#include "apps/pipeline/frame_processor.h"

#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/total_focus.h"
#include "processing/virtual_depth.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/sequence.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <mutex>

namespace lifmcr::apps {
namespace {

cv::Mat Wrap(ConstImageView image) {
  const int type = image.format == PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1;
  return cv::Mat(image.height, image.width, type, const_cast<std::uint8_t*>(image.data),
                 image.stride_bytes);
}

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

Status PreviewOptions::Check() const {
  if (max_side < 16 || max_side > 8192) return Error{"preview: max_side: expected 16..8192"};
  if (jpeg_quality < 1 || jpeg_quality > 100)
    return Error{"preview: jpeg_quality: expected 1..100"};
  return Status::Ok();
}

Expected<EncodedImage> EncodePreview(ConstImageView image, const PreviewOptions& options) {
  if (image.data == nullptr || image.width <= 0 || image.height <= 0)
    return Error{"preview: empty image"};
  const cv::Mat source = Wrap(image);
  const double factor =
      std::min(1.0, static_cast<double>(options.max_side) / std::max(image.width, image.height));
  cv::Mat small;
  if (factor < 1.0) {
    const int w = std::max(1, static_cast<int>(std::lround(image.width * factor)));
    const int h = std::max(1, static_cast<int>(std::lround(image.height * factor)));
    cv::resize(source, small, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  } else {
    small = source;
  }
  EncodedImage out;
  out.source_width = image.width;
  out.source_height = image.height;
  out.width = small.cols;
  out.height = small.rows;
  out.channels = small.channels();
  out.encoding = EncodedImage::Encoding::kJpeg;
  if (!cv::imencode(".jpg", small, out.bytes, {cv::IMWRITE_JPEG_QUALITY, options.jpeg_quality}))
    return Error{"preview: JPEG encoding failed"};
  return out;
}

Expected<EncodedDepth> EncodeDepth(const std::vector<float>& values, int width, int height,
                                   int bits) {
  if (width <= 0 || height <= 0 || values.size() != static_cast<std::size_t>(width) * height)
    return Error{"depth: size mismatch"};
  if (bits != 8 && bits != 16) return Error{"depth: bits: expected 8 or 16"};
  float lo = std::numeric_limits<float>::infinity(), hi = -lo;
  std::size_t valid = 0;
  for (float v : values)
    if (std::isfinite(v)) {
      lo = std::min(lo, v);
      hi = std::max(hi, v);
      ++valid;
    }
  EncodedDepth out;
  out.width = width;
  out.height = height;
  out.values = values;
  out.valid_fraction = static_cast<float>(valid) / static_cast<float>(values.size());
  if (valid == 0) {
    lo = hi = 0;
  }
  out.min_value = lo;
  out.max_value = hi;
  // q = 1 is lo, q = q_max is hi (a flat map gets a unit scale).
  const long q_max = bits == 8 ? 255 : 65535;
  out.scale = hi > lo ? (hi - lo) / static_cast<float>(q_max - 1) : 1.0f;
  out.offset = lo - out.scale;
  cv::Mat q(height, width, bits == 8 ? CV_8UC1 : CV_16UC1);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) {
      const float v = values[static_cast<std::size_t>(y) * width + x];
      const long level =
          std::isfinite(v) ? std::clamp(std::lround((v - out.offset) / out.scale), 1L, q_max) : 0;
      if (bits == 8)
        q.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(level);
      else
        q.at<std::uint16_t>(y, x) = static_cast<std::uint16_t>(level);
    }
  if (!cv::imencode(".png", q, out.png)) return Error{"depth: PNG encoding failed"};
  return out;
}

Expected<std::vector<float>> DecodeDepth(const std::vector<std::uint8_t>& png, float scale,
                                         float offset, int* width, int* height) {
  const cv::Mat q = cv::imdecode(png, cv::IMREAD_UNCHANGED);
  if (q.empty() || (q.type() != CV_16UC1 && q.type() != CV_8UC1))
    return Error{"depth: not an 8- or 16-bit grey PNG"};
  std::vector<float> values(static_cast<std::size_t>(q.rows) * q.cols);
  for (int y = 0; y < q.rows; ++y)
    for (int x = 0; x < q.cols; ++x) {
      const unsigned v = q.type() == CV_8UC1 ? q.at<std::uint8_t>(y, x) : q.at<std::uint16_t>(y, x);
      values[static_cast<std::size_t>(y) * q.cols + x] =
          v == 0 ? std::numeric_limits<float>::quiet_NaN() : offset + scale * v;
    }
  *width = q.cols;
  *height = q.rows;
  return values;
}

Expected<ProcessedFrame> PreviewProcessor::Process(const Frame& frame) {
  const auto start = std::chrono::steady_clock::now();
  auto preview = EncodePreview(frame.image, options_);
  if (!preview) return preview.error();
  ProcessedFrame out;
  out.preview = std::move(*preview);
  out.seconds = SecondsSince(start);
  return out;
}

// Per camera: its calibration and a pool of workspaces (prepared frame,
// depth maps, TF image), one per concurrent Process call. A workspace keeps
// its buffers and the per-camera geometry (devignetting gain, micro-image
// map) from frame to frame: fresh buffers of an R32 frame are about a GB of
// first-touched pages, slower than the processing itself.
struct DepthProcessor::CameraContext {
  MlaCalibration mla;
  std::optional<OwnedImage> white;
  struct Workspace {
    processing::PlenopticFrame prepared;
    processing::VirtualDepthMap raw_depth;
    processing::TfDepthMap tf_depth;
    processing::TfImage tf;
    int width = 0, height = 0;  // of the geometry in `prepared`; 0 = none yet
  };
  std::mutex mutex;
  std::vector<std::unique_ptr<Workspace>> idle;

  std::unique_ptr<Workspace> Acquire() {
    std::lock_guard<std::mutex> lock(mutex);
    if (idle.empty()) return std::make_unique<Workspace>();
    std::unique_ptr<Workspace> w = std::move(idle.back());
    idle.pop_back();
    return w;
  }
  void Release(std::unique_ptr<Workspace> w) {
    std::lock_guard<std::mutex> lock(mutex);
    idle.push_back(std::move(w));
  }
};

DepthProcessor::~DepthProcessor() = default;

Expected<std::unique_ptr<DepthProcessor>> DepthProcessor::ForSequence(
    const std::string& sequence_dir, const std::vector<std::string>& serials,
    PreviewOptions preview) {
  const auto calibration = FindCalibrationFor(sequence_dir);
  if (!calibration)
    return Error{sequence_dir +
                 ": no Calibration/ folder beside the sequence or its scene "
                 "(depth needs the MLA files; --no-processing publishes previews only)"};
  std::unique_ptr<DepthProcessor> processor(new DepthProcessor());
  processor->preview_ = preview;
  for (const std::string& serial : serials) {
    auto context = std::make_unique<CameraContext>();
    auto mla = ReadMlaXml(layout::MlaXmlPath(*calibration, serial));
    if (!mla) return mla.error();
    context->mla = std::move(*mla);
    const auto white_path = layout::WhiteImagePath(*calibration, serial, 0);
    if (std::filesystem::exists(white_path)) {
      auto white = ReadBmp(white_path);
      if (!white) return white.error();
      context->white = std::move(*white);
    }
    processor->cameras_[serial] = std::move(context);
  }
  return processor;
}

Expected<std::unique_ptr<DepthProcessor>> DepthProcessor::FromMlaFiles(
    const std::map<std::string, std::string>& mla_files, PreviewOptions preview) {
  std::unique_ptr<DepthProcessor> processor(new DepthProcessor());
  processor->preview_ = preview;
  for (const auto& [serial, path] : mla_files) {
    auto context = std::make_unique<CameraContext>();
    auto mla = ReadMlaXml(path);
    if (!mla) return mla.error();
    context->mla = std::move(*mla);
    processor->cameras_[serial] = std::move(context);
  }
  return processor;
}

Expected<ProcessedFrame> DepthProcessor::Process(const Frame& frame) {
  const auto start = std::chrono::steady_clock::now();
  const auto it = cameras_.find(frame.serial);
  if (it == cameras_.end()) return Error{"depth: no MLA calibration for camera " + frame.serial};
  const CameraContext& camera = *it->second;
  ProcessedFrame out;
  auto preview = EncodePreview(frame.image, preview_);
  if (!preview) return preview.error();
  out.preview = std::move(*preview);

  CameraContext& context = *it->second;
  std::unique_ptr<CameraContext::Workspace> workspace = context.Acquire();
  struct ReleaseOnExit {
    CameraContext& context;
    std::unique_ptr<CameraContext::Workspace>& workspace;
    ~ReleaseOnExit() { context.Release(std::move(workspace)); }
  } release{context, workspace};
  processing::PlenopticFrame& prepared = workspace->prepared;
  if (workspace->width != frame.image.width || workspace->height != frame.image.height) {
    const processing::MlaGrid grid =
        processing::MlaGrid::FromCalibration(camera.mla, frame.image.width, frame.image.height);
    ConstImageView white;
    if (camera.white && camera.white->width == frame.image.width &&
        camera.white->height == frame.image.height)
      white = camera.white->View();
    workspace->width = workspace->height = 0;
    if (Status s = processing::PrepareGeometry(white, frame.image.width, frame.image.height, grid,
                                               camera.mla, {}, &prepared);
        !s)
      return s.error();
    workspace->width = frame.image.width;
    workspace->height = frame.image.height;
  }
  if (Status s = processing::LoadRaw(frame.image, &prepared); !s) return s.error();
  processing::VirtualDepthMap& raw_depth = workspace->raw_depth;
  if (Status s = processing::EstimateVirtualDepth(prepared, camera.mla, {}, &raw_depth); !s)
    return s.error();
  processing::TfDepthMap& tf_depth = workspace->tf_depth;
  const processing::TfOptions tf_options;
  if (Status s = processing::VirtualDepthToTf(prepared, raw_depth, tf_options, &tf_depth); !s)
    return s.error();
  processing::TfImage& tf = workspace->tf;
  if (Status s = processing::RenderTotalFocus(prepared, camera.mla, tf_depth, tf_options, &tf); !s)
    return s.error();
  // The TF grid is W/2 x H/2 (16 MB of floats on an R32): published as the
  // NaN-aware mean of k x k blocks so the longest side is <= depth_max_side.
  const int k =
      std::max(1, (std::max(tf_depth.width, tf_depth.height) + preview_.depth_max_side - 1) /
                      preview_.depth_max_side);
  const int dw = tf_depth.width / k, dh = tf_depth.height / k;
  std::vector<float> reduced(static_cast<std::size_t>(dw) * dh,
                             std::numeric_limits<float>::quiet_NaN());
  for (int y = 0; y < dh; ++y)
    for (int x = 0; x < dw; ++x) {
      double sum = 0;
      int n = 0;
      for (int v = 0; v < k; ++v)
        for (int u = 0; u < k; ++u) {
          const float d =
              tf_depth
                  .virtual_depth[static_cast<std::size_t>(y * k + v) * tf_depth.width + x * k + u];
          if (std::isfinite(d)) {
            sum += d;
            ++n;
          }
        }
      if (n > 0) reduced[static_cast<std::size_t>(y) * dw + x] = static_cast<float>(sum / n);
    }
  auto depth = EncodeDepth(reduced, dw, dh);
  if (!depth) return depth.error();
  out.depth = std::move(*depth);
  auto tf_preview = EncodePreview(tf.View(), preview_);
  if (!tf_preview) return tf_preview.error();
  out.tf = std::move(*tf_preview);
  out.seconds = SecondsSince(start);
  return out;
}

}  // namespace lifmcr::apps
