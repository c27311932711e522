// Preview and depth stages of the pipeline. OpenCV is used here only, at the
// encoding boundary: cv::Mat headers wrap the pooled frame (no copy).

#include "apps/pipeline/frame_processor.h"

#include "apps/pipeline/camera_setup.h"
#include "config/thread_cpu.h"
#include "processing/frame_chain.h"
#include "replay/bayer.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

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
  // A divisor of the block size of the published depth map.
  if (depth_max_side < 16 || depth_max_side > 8192)
    return Error{"preview: depth_max_side: expected 16..8192"};
  return Status::Ok();
}

// cv::haveImageWriter looks the extension up in OpenCV's codec registry, a
// function-local static of libopencv_imgcodecs built by its first user. Left
// to the first imencode in a TBB worker, its construction was ordered before
// the other workers' reads only by the static's guard, read inline in
// uninstrumented OpenCV code, which ThreadSanitizer cannot see: with a
// TSan-built oneTBB it reported a worker's copy of an encoder's 31-byte
// string as racing with another worker's construction of it (lifmcr replay,
// DepthProcessor::Process -> EncodePreview). Built here, before the workers,
// the thread hand-over orders it (as CheckImageWriters does for lifmcr
// synth, replay/synth/gt_images.cpp).
Status CheckImageEncoders() {
  for (const char* extension : {".jpg", ".png"}) {
    if (!cv::haveImageWriter(extension))
      return Error{std::string("this OpenCV build has no ") + extension +
                   " encoder (previews are JPEG, depth maps PNG)"};
  }
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

Expected<EncodedLensDepth> EncodeLensDepth(const processing::LensDepthMap& depth, int raw_width,
                                           int raw_height) {
  auto encoded = EncodeDepth(depth.virtual_depth, depth.grid.cols, depth.grid.rows, 16);
  if (!encoded) return encoded.error();
  EncodedLensDepth out;
  out.depth = std::move(*encoded);
  out.depth.raw_width = raw_width;
  out.depth.raw_height = raw_height;
  out.grid = depth.grid;
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

namespace {

// The frame's image, demosaiced when its camera is a Bayer camera (the copy
// is kept in `*holder`), else the pooled buffer itself.
Expected<ConstImageView> ColourView(const Frame& frame, const PixelFormats& formats,
                                    std::shared_ptr<const OwnedImage>* holder) {
  const auto it = formats.find(frame.serial);
  if (it == formats.end() || !IsBayer(it->second) || frame.image.format != PixelFormat::kMono8)
    return ConstImageView(frame.image);
  auto colour = std::make_shared<OwnedImage>(
      OwnedImage::Allocate(frame.image.width, frame.image.height, PixelFormat::kBgr8));
  if (Status s = DemosaicBayer(frame.image, it->second, colour->View()); !s)
    return Error{"camera " + frame.serial + ": " + s.error().message};
  *holder = colour;
  return ConstImageView(colour->View());
}

}  // namespace

Status DemosaicWhiteImages(const PixelFormats& formats,
                           std::vector<processing::CameraSetup>* setups) {
  for (processing::CameraSetup& setup : *setups) {
    const auto it = formats.find(setup.serial);
    if (it == formats.end() || !IsBayer(it->second) || !setup.white ||
        setup.white->format != PixelFormat::kMono8)
      continue;
    OwnedImage colour =
        OwnedImage::Allocate(setup.white->width, setup.white->height, PixelFormat::kBgr8);
    if (Status s = DemosaicBayer(setup.white->View(), it->second, colour.View()); !s)
      return Error{"white image of camera " + setup.serial + ": " + s.error().message};
    setup.white = std::move(colour);
  }
  return Status::Ok();
}

Expected<ProcessedFrame> PreviewProcessor::Process(const Frame& frame) {
  const auto start = std::chrono::steady_clock::now();
  std::shared_ptr<const OwnedImage> demosaiced;
  auto image = ColourView(frame, formats_, &demosaiced);
  if (!image) return image.error();
  auto preview = EncodePreview(*image, options_);
  if (!preview) return preview.error();
  ProcessedFrame out;
  out.preview = std::move(*preview);
  out.seconds = SecondsSince(start);
  return out;
}

DepthProcessor::DepthProcessor(std::unique_ptr<processing::ProcessingChain> chain,
                               PreviewOptions preview, PixelFormats formats)
    : preview_(preview), chain_(std::move(chain)), formats_(std::move(formats)) {
  for (const std::string& serial : chain_->serials())
    spdlog::info("processing chain: {}", chain_->Find(serial)->Describe());
}

DepthProcessor::~DepthProcessor() = default;

Expected<std::unique_ptr<DepthProcessor>> DepthProcessor::ForSequence(
    const std::string& sequence_dir, const std::vector<std::string>& serials,
    PreviewOptions preview, PixelFormats formats,
    const std::vector<std::filesystem::path>& intrinsics) {
  if (Status s = preview.Check(); !s) return s.error();
  auto setups = LoadSequenceCameras(sequence_dir, serials, intrinsics);
  if (!setups)
    return Error{setups.error().message +
                 " (depth needs the MLA files; --no-processing publishes previews only)"};
  if (Status s = DemosaicWhiteImages(formats, &*setups); !s) return s.error();
  auto chain = processing::ProcessingChain::Create(std::move(*setups), ChainOptionsForPipeline());
  if (!chain) return chain.error();
  return std::make_unique<DepthProcessor>(std::move(*chain), preview, std::move(formats));
}

processing::ChainOptions DepthProcessor::ChainOptionsForPipeline() {
  processing::ChainOptions options;
  options.metric_depth = false;
  // The pipeline reads the TF products alone (the published depth is the TF
  // depth map's block means, the TF preview the TF image's; the localizer
  // reads tf and tf_depth): no dense map where the TF depth map takes the
  // lens depth (docs/processing.md, "The dense map where the TF depth reads it").
  options.dense_for_tf_only = true;
  return options;
}

Expected<RegistrationInput> DepthProcessor::ForRegistration(const Frame& frame) {
  RegistrationInput input;
  input.camera = chain_->Find(frame.serial);
  if (input.camera == nullptr) return Error{"depth: no MLA calibration for camera " + frame.serial};
  auto image = ColourView(frame, formats_, &input.demosaiced);
  if (!image) return image.error();
  input.image = *image;
  return input;
}

bool DepthProcessor::SharesRegistrationImage(const Frame& frame) const {
  // ColourView's copy: a Bayer camera's mosaic demosaiced.
  const auto it = formats_.find(frame.serial);
  return it != formats_.end() && IsBayer(it->second) && frame.image.format == PixelFormat::kMono8;
}

Status DepthProcessor::Warm(const Frame& frame, bool sampler) {
  processing::CameraChain* camera = chain_->Find(frame.serial);
  if (camera == nullptr) return Error{"depth: no MLA calibration for camera " + frame.serial};
  std::shared_ptr<const OwnedImage> demosaiced;
  auto image = ColourView(frame, formats_, &demosaiced);
  if (!image) return image.error();
  if (auto lenses = camera->LensEstimator(*image); !lenses) return lenses.error();
  // The dense chain's pooled workspace too, by one dense map of the frame
  // (returned to the camera's pool, where the depth lane's first map of the
  // camera finds it): its geometry, the TF renderer's tables and its
  // buffers' first-touched pages cost that map about 0.25 CPU-s more per
  // camera at medium (0.68 against 0.41-0.43 CPU-s) in the live window.
  if (auto dense = camera->Process(*image); !dense) return dense.error();
  if (sampler) {
    if (auto made = camera->Sampler(*image); !made) return made.error();
  }
  return Status::Ok();
}

Expected<std::vector<std::string>> DepthProcessor::WarmWithoutFrames(bool sampler) {
  std::vector<std::string> left;
  for (const std::string& serial : chain_->serials()) {
    const processing::CameraChain* camera = chain_->Find(serial);
    const ConstImageView white = camera->white();
    if (camera->devignetting() != processing::Devignetting::kWhiteImage || white.data == nullptr) {
      left.push_back(serial);
      continue;
    }
    // In the white image's format (demosaiced already for a Bayer camera),
    // so Warm demosaics nothing; with a white image the geometry reads only
    // the frame's size, never its pixels.
    OwnedImage blank = OwnedImage::Allocate(white.width, white.height, white.format);
    Frame frame;
    frame.serial = serial;
    frame.image = blank.View();
    if (Status s = Warm(frame, sampler); !s) return s.error();
  }
  return left;
}

Expected<ProcessedFrame> DepthProcessor::Process(const Frame& frame) {
  return Run(frame, true, nullptr);
}

Expected<ProcessedFrame> DepthProcessor::ProcessDense(const Frame& frame,
                                                      const ProcessedFrame* lenses) {
  return Run(frame, false, lenses != nullptr && lenses->lenses ? lenses : nullptr);
}

Expected<ProcessedFrame> DepthProcessor::Run(const Frame& frame, bool lenses,
                                             const ProcessedFrame* given) {
  const auto start = std::chrono::steady_clock::now();
  processing::CameraChain* camera = chain_->Find(frame.serial);
  if (camera == nullptr) return Error{"depth: no MLA calibration for camera " + frame.serial};
  ProcessedFrame out;
  // The image ProcessLenses took (a Bayer frame's demosaiced copy: made once
  // per frame), else this frame's own.
  Expected<ConstImageView> image = ConstImageView{};
  if (given != nullptr && given->demosaiced) {
    out.demosaiced = given->demosaiced;
    image = ConstImageView(out.demosaiced->View());
  } else {
    image = ColourView(frame, formats_, &out.demosaiced);
  }
  if (!image) return image.error();
  auto preview = EncodePreview(*image, preview_);
  if (!preview) return preview.error();
  out.preview = std::move(*preview);
  // The per-lens depth first (every frame gets it): it seeds the dense search.
  processing::LensLease lenses_lease(nullptr, processing::LensWorkspaceReturn{});
  if (lenses) {
    auto made = camera->ProcessLenses(*image, 0);
    if (!made) return made.error();
    lenses_lease = std::move(*made);
  }
  // The seed: this call's per-lens depth, else ProcessLenses' of the frame
  // (the depth lane's), else none (the chain computes it).
  const processing::LensDepthMap* seed =
      lenses ? &lenses_lease->depth : given != nullptr ? &given->lenses->depth : nullptr;
  auto lease = camera->Process(*image, seed);
  if (!lease) return lease.error();
  const processing::TfDepthMap& tf_depth = (*lease)->tf_depth;
  const processing::TfImage& tf = (*lease)->tf;
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
  out.depth->raw_width = image->width;
  out.depth->raw_height = image->height;
  // The per-lens depth too (every frame gets it); the TF channel carries the
  // chain's own TF image here, so no lens preview.
  if (lenses) {
    auto lens_depth = EncodeLensDepth(lenses_lease->depth, image->width, image->height);
    if (!lens_depth) return lens_depth.error();
    out.lens_depth = std::move(*lens_depth);
  }
  auto tf_preview = EncodePreview(tf.View(), preview_);
  if (!tf_preview) return tf_preview.error();
  out.tf = std::move(*tf_preview);
  out.products = std::shared_ptr<const processing::ChainProducts>(std::move(*lease));
  out.camera = camera;
  out.seconds = SecondsSince(start);
  return out;
}

Expected<ProcessedFrame> DepthProcessor::ProcessLenses(const Frame& frame,
                                                       const RegistrationInput* input) {
  const auto start = std::chrono::steady_clock::now();
  processing::CameraChain* camera = chain_->Find(frame.serial);
  if (camera == nullptr) return Error{"depth: no MLA calibration for camera " + frame.serial};
  ProcessedFrame out;
  // The registration's view of the frame (a Bayer frame demosaiced once for
  // both), else the frame's own.
  Expected<ConstImageView> image = ConstImageView{};
  if (input != nullptr && input->image.data != nullptr) {
    out.demosaiced = input->demosaiced;
    image = input->image;
  } else {
    image = ColourView(frame, formats_, &out.demosaiced);
  }
  if (!image) return image.error();
  auto lenses = camera->ProcessLenses(*image, preview_.max_side);
  if (!lenses) return lenses.error();
  out.lens_depth_s = (*lenses)->depth_s;
  out.lens_preview_s = (*lenses)->preview_s;
  out.lens_depth_cpu_s = (*lenses)->depth_cpu_s;
  out.lens_preview_cpu_s = (*lenses)->preview_cpu_s;
  const auto encode_start = std::chrono::steady_clock::now();
  const double encode_cpu = ThreadCpuSeconds();
  auto lens_depth = EncodeLensDepth((*lenses)->depth, image->width, image->height);
  if (!lens_depth) return lens_depth.error();
  out.lens_depth = std::move(*lens_depth);
  auto tf_preview = EncodePreview((*lenses)->preview.View(), preview_);
  if (!tf_preview) return tf_preview.error();
  // The preview is made from the TF grid (raw / 2), as the chain's TF image.
  tf_preview->source_width = image->width / 2;
  tf_preview->source_height = image->height / 2;
  out.tf = std::move(*tf_preview);
  out.lens_encode_s = SecondsSince(encode_start);
  out.lens_encode_cpu_s = ThreadCpuSeconds() - encode_cpu;
  // The workspace stays leased while the dense chain may still seed from it
  // (ProcessDense); it returns to the camera's pool with the last holder.
  out.lenses = std::shared_ptr<const processing::LensProducts>(std::move(*lenses));
  out.camera = camera;
  out.seconds = SecondsSince(start);
  return out;
}

}  // namespace lifmcr::apps
