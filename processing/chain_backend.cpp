#include "processing/chain_backend.h"

namespace lifmcr::processing {
namespace {

class CpuBackend final : public ChainBackend {
 public:
  std::string_view Name() const override { return "cpu"; }

  Status LensDepth(const LensDepthEstimator& estimator, ConstImageView raw,
                   LensDepthMap* out) override {
    return estimator.Estimate(raw, out);
  }
  Status LensPreview(const LensDepthEstimator& estimator, ConstImageView raw, int max_side,
                     LensDepthMap* depth, TfImage* out) override {
    return estimator.RenderPreview(raw, max_side, depth, out);
  }
  Status Prepare(ConstImageView raw, PlenopticFrame* frame) override {
    return LoadRaw(raw, frame);
  }
  Status Seed(const PlenopticFrame& frame, const LensDepthMap& lens_depth,
              LensSeed* out) override {
    return SeedFromLensDepth(frame, lens_depth, out);
  }
  Status DenseDepth(const PlenopticFrame& frame, const MlaCalibration& mla,
                    const DepthOptions& options, const LensSeed* seed,
                    VirtualDepthMap* out) override {
    return EstimateVirtualDepth(frame, mla, options, seed, out);
  }
  Status TfDepth(const PlenopticFrame& frame, const VirtualDepthMap& raw_depth,
                 const LensDepthMap* lens_depth, const TfOptions& options,
                 TfDepthMap* out) override {
    return lens_depth != nullptr ? VirtualDepthToTf(frame, raw_depth, *lens_depth, options, out)
                                 : VirtualDepthToTf(frame, raw_depth, options, out);
  }
  Status TfRender(const PlenopticFrame& frame, const MlaCalibration& mla,
                  const TfDepthMap& depth, const TfOptions& options, TfImage* out) override {
    return RenderTotalFocus(frame, mla, depth, options, out);
  }
};

}  // namespace

std::shared_ptr<ChainBackend> MakeCpuBackend() { return std::make_shared<CpuBackend>(); }

}  // namespace lifmcr::processing
