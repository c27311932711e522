#pragma once
// The processing stage of the live pipeline, as an interface: one camera
// frame in, the products that go on LCM out (plain buffers, no LCM types, so
// processing stays testable without a bus).
//
// Implementations (frame_processor.cpp):
//   PreviewProcessor  downscale (INTER_AREA) to at most max_side pixels and
//                     JPEG-encode: the raw preview, always cheap;
//   DepthProcessor    the preview plus processing/: devignetted frame,
//                     virtual depth, TF depth map and the totally focused
//                     image; the TF virtual depth, reduced by block means
//                     to at most depth_max_side and quantised to 8-bit PNG;
//                     and the per-lens virtual depth (16-bit PNG on the lens
//                     grid). ProcessLenses: the per-lens depth and the TF
//                     preview at each lens's depth only (cheap: every frame).
// Process is called concurrently for different frames (bounded by the
// pipeline); implementations keep per-call state only.

#include "config/error.h"
#include "config/rig_config.h"
#include "drivers/frame.h"
#include "processing/lens_depth.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::processing {
struct ChainOptions;
struct ChainProducts;
struct LensProducts;
class CameraChain;
class ProcessingChain;
struct CameraSetup;
}  // namespace lifmcr::processing

namespace lifmcr::apps {

struct EncodedImage {
  int source_width = 0, source_height = 0;
  int width = 0, height = 0;
  int channels = 1;
  enum class Encoding { kJpeg, kPng } encoding = Encoding::kJpeg;
  std::vector<std::uint8_t> bytes;
};

// Virtual depth quantised: value = offset + scale * q, q in 1..255 (8-bit,
// published) or 1..65535 (16-bit), q = 0 no estimate; PNG-encoded grey.
// 8 bits over the frame's own range keep a depth message well inside a stock
// receiver's UDP buffer (bench/bench_lcm_sizes.cpp); the step, (max - min) /
// 254, is below the estimate's own error over the usual ranges.
struct EncodedDepth {
  int width = 0, height = 0;
  float scale = 0, offset = 0;
  float valid_fraction = 0;
  float min_value = 0, max_value = 0;
  std::vector<std::uint8_t> png;
  std::vector<float> values;  // the published depth before quantisation (NaN: none)
  int raw_width = 0, raw_height = 0;  // the raw frame it was made from
};

// The per-lens virtual depth as published (depth_image_t GEOMETRY_LENS_GRID):
// one value per cell of the lens grid (processing/lens_depth.h), 16-bit.
struct EncodedLensDepth {
  EncodedDepth depth;  // grid.cols x grid.rows
  processing::LensGrid grid;
};

struct ProcessedFrame {
  std::optional<EncodedImage> preview;  // <PREFIX>_<SERIAL>_PREVIEW
  std::optional<EncodedDepth> depth;    // <PREFIX>_<SERIAL>_DEPTH, TF grid
  std::optional<EncodedLensDepth> lens_depth;  // <PREFIX>_<SERIAL>_DEPTH, lens grid
  std::optional<EncodedImage> tf;  // <PREFIX>_<SERIAL>_TF (the TF image or the lens preview)
  // The chain's products (TF image, depth, metric depth) and the camera's
  // model when its intrinsics are known: null for previews only. They view
  // the frame's pooled buffer, which the pipeline keeps until the frame is
  // published.
  std::shared_ptr<const processing::ChainProducts> products;
  // A Bayer camera's frame demosaiced (BGR8): what the products view instead
  // of the pooled mosaic, kept alive with them.
  std::shared_ptr<const OwnedImage> demosaiced;
  // ProcessLenses: the per-lens products (depth, TF preview) in their pooled
  // workspace, kept so the dense chain of the same frame is seeded by this
  // depth instead of computing it again (ProcessDense).
  std::shared_ptr<const processing::LensProducts> lenses;
  processing::CameraChain* camera = nullptr;
  double seconds = 0;
  // ProcessLenses' parts (wall s): the per-lens depth, the TF preview at
  // each lens's depth, and the encodings (16-bit PNG, JPEG).
  double lens_depth_s = 0, lens_preview_s = 0, lens_encode_s = 0;
  // Their CPU time on the calling thread (config/thread_cpu.h).
  double lens_depth_cpu_s = 0, lens_preview_cpu_s = 0, lens_encode_cpu_s = 0;
};

// What the registration stage needs of a frame without processing it: the
// camera's chain (its model and TF sampler) and the image the chain takes.
struct RegistrationInput {
  processing::CameraChain* camera = nullptr;  // null: the processor has no chain for it
  ConstImageView image;
  // A Bayer camera's frame demosaiced (BGR8): what `image` views.
  std::shared_ptr<const OwnedImage> demosaiced;
};

struct PreviewOptions {
  int max_side = 512;  // longest side of the preview and TF images, pixels
  int jpeg_quality = 85;
  int depth_max_side = 640;  // longest side of the published depth map (block means)
  Status Check() const;      // every field; the message names the field
};

class FrameProcessor {
 public:
  virtual ~FrameProcessor() = default;
  virtual Expected<ProcessedFrame> Process(const Frame& frame) = 0;
  virtual std::string name() const = 0;  // "preview", "depth"
  // Process without publishing the per-lens depth: what the depth lane runs
  // on frames whose per-lens depth ProcessLenses gave already. `lenses`:
  // that ProcessLenses' result (its `lenses` seed the dense map and its
  // `demosaiced` image is reused), or null: computed here (default: Process).
  virtual Expected<ProcessedFrame> ProcessDense(const Frame& frame,
                                                const ProcessedFrame* /*lenses*/ = nullptr) {
    return Process(frame);
  }
  // The per-lens depth and the TF preview at each lens's depth of the frame
  // (lens_depth, tf, lenses), for every frame (default: nothing). `input`:
  // the frame's ForRegistration, whose demosaiced image is reused, or null.
  virtual Expected<ProcessedFrame> ProcessLenses(const Frame&,
                                                 const RegistrationInput* /*input*/ = nullptr) {
    return ProcessedFrame{};
  }
  // The frame for the registration stage, unprocessed (default: no chain).
  virtual Expected<RegistrationInput> ForRegistration(const Frame&) {
    return RegistrationInput{};
  }
  // Whether ForRegistration makes an image of the frame that ProcessLenses
  // would make again (a Bayer frame demosaiced): the pipeline then hands
  // the frame to ProcessLenses with the registration's input, after its
  // localisation, rather than beside it (default: no).
  virtual bool SharesRegistrationImage(const Frame&) const { return false; }
};

// Downscaled JPEG of `image` (Mono8 or BGR8).
Expected<EncodedImage> EncodePreview(ConstImageView image, const PreviewOptions& options);
// The same of an image that samples a source of source_width x
// source_height on a coarser grid (a TF image of every s-th TF pixel,
// TfImageStepForPreview): the preview has the size, and names the source
// size, the source's own preview would have.
Expected<EncodedImage> EncodePreview(ConstImageView image, const PreviewOptions& options,
                                     int source_width, int source_height);
// The TF image step (processing::TfOptions::image_step) for a preview of at
// most max_side pixels of a TF grid of tf_width x tf_height: the largest s
// (at most 16) whose image keeps at least three times max_side on its
// longest side, so INTER_AREA still averages 3 x 3 rendered pixels or more
// per preview pixel; 1 for a grid below 6 max_side. R32 (3280 x 2474, 512):
// 2; `medium`'s 1640 x 1237: 1. Step 3 on R32 saved no more CPU than 2
// (the rendering is bound by its reads of the raw frame, which a sparser
// sampling shares less) and lost more of the preview's PSNR
// (docs/processing.md, "The depth lane's TF image for its preview").
int TfImageStepForPreview(int tf_width, int tf_height, int max_side);
// OpenCV has the JPEG and PNG encoders the previews and depth maps use.
// Called before the pipeline's workers start: it also builds OpenCV's codec
// registry in this thread (see the .cpp).
Status CheckImageEncoders();
// The lens grid's virtual depth, quantised to 16 bits.
Expected<EncodedLensDepth> EncodeLensDepth(const processing::LensDepthMap& depth, int raw_width,
                                           int raw_height);
// PNG quantisation of `values` (w x h, NaN = none) to `bits` (8 or 16);
// inverse of DecodeDepth.
Expected<EncodedDepth> EncodeDepth(const std::vector<float>& values, int width, int height,
                                   int bits = 8);
// Decoded values (NaN where q = 0) of a PNG written by EncodeDepth.
Expected<std::vector<float>> DecodeDepth(const std::vector<std::uint8_t>& png, float scale,
                                         float offset, int* width, int* height);

// Serial -> the camera's pixel format, for the cameras whose frames are Bayer
// mosaics (rig file `pixel_format: BayerRG8` ...): their frames are
// demosaiced (replay/bayer.h, one BGR8 copy per frame) before the preview and
// the chain, so previews and the TF image are in colour and depth runs on
// the luminance. Cameras not listed are taken as they come.
using PixelFormats = std::map<std::string, CameraPixelFormat>;

class PreviewProcessor final : public FrameProcessor {
 public:
  explicit PreviewProcessor(PreviewOptions options = {}, PixelFormats formats = {})
      : options_(options), formats_(std::move(formats)) {}
  Expected<ProcessedFrame> Process(const Frame& frame) override;
  std::string name() const override { return "preview"; }

 private:
  PreviewOptions options_;
  PixelFormats formats_;
};

// The processing chain (processing/frame_chain.h) of every camera, then the
// encodings that go on LCM. The chain's products of the frame are kept in
// ProcessedFrame::products (for the stage after processing: registration).
class DepthProcessor final : public FrameProcessor {
 public:
  // The cameras of a sequence, by the lookup rule of replay/camera_calibration.h;
  // their intrinsics from `intrinsics` (camera_setup.h, FindIntrinsics).
  static Expected<std::unique_ptr<DepthProcessor>> ForSequence(
      const std::string& sequence_dir, const std::vector<std::string>& serials,
      PreviewOptions preview = {}, PixelFormats formats = {},
      const std::vector<std::filesystem::path>& intrinsics = {});
  // `formats`: the Bayer cameras; their white images in the chain's setups
  // must already be demosaiced (DemosaicWhiteImages).
  DepthProcessor(std::unique_ptr<processing::ProcessingChain> chain, PreviewOptions preview,
                 PixelFormats formats = {});
  ~DepthProcessor() override;
  Expected<ProcessedFrame> Process(const Frame& frame) override;
  Expected<ProcessedFrame> ProcessDense(const Frame& frame,
                                        const ProcessedFrame* lenses = nullptr) override;
  Expected<ProcessedFrame> ProcessLenses(const Frame& frame,
                                         const RegistrationInput* input = nullptr) override;
  std::string name() const override { return "depth"; }
  Expected<RegistrationInput> ForRegistration(const Frame& frame) override;
  bool SharesRegistrationImage(const Frame& frame) const override;
  // The set-up the first frame of the camera would pay, made now from
  // `frame` (one of the camera's frames: its size, and its pixels where the
  // devignetting is estimated from a frame): the per-lens estimator
  // (ProcessLenses: the geometry, gain and micro-image map, about 0.6 s per
  // camera at medium), a workspace of the dense chain (one dense map of the
  // frame: the depth lane's first map of the camera then pays its own work
  // only) and, with `sampler`, the registration's TF sampler. A
  // replay calls it before its cameras start, so a timed replay's first
  // frames are not skipped while the lens lane builds them.
  Status Warm(const Frame& frame, bool sampler);
  // Warm for every camera whose set-up needs no frame's pixels, before any
  // frame exists: a camera devignetted by its white image needs only the
  // frame size, the white image's (CameraChain::GridFor rejects any other),
  // so it is warmed with a blank frame of that size. `record --publish`
  // calls it before the cameras start. Returns the serials left to their
  // first frame (no white image: the vignetting is estimated from that
  // frame's pixels).
  Expected<std::vector<std::string>> WarmWithoutFrames(bool sampler);
  const processing::ProcessingChain& chain() const { return *chain_; }
  // The chain options the pipeline's processor is made with (ForSequence,
  // `record --publish`): the defaults without the metric depth, which
  // nothing the pipeline publishes or localises with reads (the TF depth
  // map is published; the registration reads the TF image and depth).
  static processing::ChainOptions ChainOptionsForPipeline();

 private:
  // `lenses`: publish the per-lens depth (Process); `given`: ProcessLenses'
  // result of the frame, whose depth seeds the dense map (ProcessDense).
  Expected<ProcessedFrame> Run(const Frame& frame, bool lenses, const ProcessedFrame* given);
  PreviewOptions preview_;
  std::unique_ptr<processing::ProcessingChain> chain_;
  PixelFormats formats_;
};

// The white images of the Bayer cameras in `setups`, demosaiced in place, so
// their devignetting gain matches the demosaiced frames.
Status DemosaicWhiteImages(const PixelFormats& formats,
                           std::vector<processing::CameraSetup>* setups);

}  // namespace lifmcr::apps
