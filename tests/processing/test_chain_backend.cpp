// The chain's backend seam (processing/chain_backend.h): every per-frame
// stage of CameraChain runs through the camera's ChainBackend, in the
// documented order, with the CPU backend's products; a backend's error is
// the frame's, naming the camera.

#include "processing/chain_backend.h"
#include "processing/frame_chain.h"
#include "tests/processing/synth_frame.h"

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

namespace lifmcr::processing {
namespace {

// Forwards every stage to the CPU backend and records its name; with
// `fail_at`, that stage returns an error instead.
class RecordingBackend final : public ChainBackend {
 public:
  explicit RecordingBackend(std::string fail_at = "") : fail_at_(std::move(fail_at)) {}
  std::string_view Name() const override { return "recording"; }
  Status LensDepth(const LensDepthEstimator& e, ConstImageView raw, LensDepthMap* out) override {
    if (Status s = Enter("LensDepth"); !s) return s;
    return cpu_->LensDepth(e, raw, out);
  }
  Status LensPreview(const LensDepthEstimator& e, ConstImageView raw, int max_side,
                     LensDepthMap* depth, TfImage* out) override {
    if (Status s = Enter("LensPreview"); !s) return s;
    return cpu_->LensPreview(e, raw, max_side, depth, out);
  }
  Status Prepare(ConstImageView raw, PlenopticFrame* frame) override {
    if (Status s = Enter("Prepare"); !s) return s;
    return cpu_->Prepare(raw, frame);
  }
  Status Seed(const PlenopticFrame& frame, const LensDepthMap& lens, LensSeed* out) override {
    if (Status s = Enter("Seed"); !s) return s;
    return cpu_->Seed(frame, lens, out);
  }
  Status DenseDepth(const PlenopticFrame& frame, const MlaCalibration& mla,
                    const DepthOptions& options, const LensSeed* seed,
                    VirtualDepthMap* out) override {
    if (Status s = Enter("DenseDepth"); !s) return s;
    return cpu_->DenseDepth(frame, mla, options, seed, out);
  }
  Status TfDepth(const PlenopticFrame& frame, const VirtualDepthMap& raw_depth,
                 const LensDepthMap* lens_depth, const TfOptions& options,
                 TfDepthMap* out) override {
    if (Status s = Enter("TfDepth"); !s) return s;
    return cpu_->TfDepth(frame, raw_depth, lens_depth, options, out);
  }
  Status TfRender(const PlenopticFrame& frame, const MlaCalibration& mla, const TfDepthMap& depth,
                  const TfOptions& options, TfImage* out) override {
    if (Status s = Enter("TfRender"); !s) return s;
    return cpu_->TfRender(frame, mla, depth, options, out);
  }

  std::vector<std::string> calls;

 private:
  Status Enter(const std::string& stage) {
    calls.push_back(stage);
    if (stage == fail_at_) return Error{"device lost in " + stage};
    return Status::Ok();
  }
  std::string fail_at_;
  std::shared_ptr<ChainBackend> cpu_ = MakeCpuBackend();
};

CameraSetup SetupOf(const testing::SynthFrame& s) {
  CameraSetup setup;
  setup.serial = "40398678";
  setup.mla = s.mla;
  setup.white = OwnedImage::Allocate(s.white.width, s.white.height, s.white.format);
  std::memcpy(setup.white->pixels.data(), s.white.pixels.data(), setup.white->pixels.size());
  return setup;
}

const testing::SynthFrame& Frame() {
  static const testing::SynthFrame frame = testing::RenderSynthFrame();
  return frame;
}

TEST(ChainBackend, EveryStageRunsThroughTheBackendWithTheCpuProducts) {
  const testing::SynthFrame& s = Frame();
  auto recording = std::make_shared<RecordingBackend>();
  auto chain = CameraChain::Create(SetupOf(s), ChainOptions{}, recording);
  auto reference = CameraChain::Create(SetupOf(s), ChainOptions{});
  ASSERT_TRUE(chain.ok() && reference.ok());
  EXPECT_EQ((*chain)->backend().Name(), "recording");
  EXPECT_EQ((*reference)->backend().Name(), "cpu");

  auto lenses = (*chain)->ProcessLenses(s.raw.View(), 256);
  ASSERT_TRUE(lenses.ok()) << lenses.error().message;
  EXPECT_EQ(recording->calls, (std::vector<std::string>{"LensDepth", "LensPreview"}));
  recording->calls.clear();
  auto lease = (*chain)->Process(s.raw.View(), &(*lenses)->depth);
  ASSERT_TRUE(lease.ok()) << lease.error().message;
  EXPECT_EQ(recording->calls, (std::vector<std::string>{"Prepare", "Seed", "DenseDepth",
                                                        "TfDepth", "TfRender"}));
  recording->calls.clear();
  // Without a per-lens map the chain asks the backend for one.
  auto own = (*chain)->Process(s.raw.View());
  ASSERT_TRUE(own.ok()) << own.error().message;
  EXPECT_EQ(recording->calls, (std::vector<std::string>{"Prepare", "LensDepth", "Seed",
                                                        "DenseDepth", "TfDepth", "TfRender"}));

  // The products are the CPU backend's, bit for bit.
  auto expected = (*reference)->Process(s.raw.View());
  ASSERT_TRUE(expected.ok());
  EXPECT_EQ((*own)->raw_depth.stats.estimated, (*expected)->raw_depth.stats.estimated);
  EXPECT_EQ((*own)->tf.pixels, (*expected)->tf.pixels);
  auto expected_lenses = (*reference)->ProcessLenses(s.raw.View(), 256);
  ASSERT_TRUE(expected_lenses.ok());
  EXPECT_EQ((*lenses)->preview.pixels, (*expected_lenses)->preview.pixels);
}

TEST(ChainBackend, ABackendsErrorIsTheFramesAndNamesTheCamera) {
  const testing::SynthFrame& s = Frame();
  for (const char* stage : {"Prepare", "DenseDepth", "TfRender"}) {
    auto failing = std::make_shared<RecordingBackend>(stage);
    auto chain = CameraChain::Create(SetupOf(s), ChainOptions{}, failing);
    ASSERT_TRUE(chain.ok());
    auto lease = (*chain)->Process(s.raw.View());
    ASSERT_FALSE(lease.ok()) << stage;
    EXPECT_EQ(lease.error().message, std::string("camera 40398678: device lost in ") + stage);
    // The stages after the failing one did not run.
    EXPECT_EQ(failing->calls.back(), stage);
  }
  auto failing = std::make_shared<RecordingBackend>("LensPreview");
  auto chain = CameraChain::Create(SetupOf(s), ChainOptions{}, failing);
  ASSERT_TRUE(chain.ok());
  auto lenses = (*chain)->ProcessLenses(s.raw.View(), 256);
  ASSERT_FALSE(lenses.ok());
  EXPECT_EQ(lenses.error().message, "camera 40398678: device lost in LensPreview");
}

}  // namespace
}  // namespace lifmcr::processing
