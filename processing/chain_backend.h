#pragma once
// The seam between the processing chain (frame_chain.h) and the code that
// runs its per-frame stages. CameraChain decides what runs, in which
// workspace and in what order; a ChainBackend runs each stage. The CPU
// backend (MakeCpuBackend) is the one built: the scalar and Highway kernels
// of lens_depth.h, virtual_depth.h and total_focus.h, chosen by the options
// as before.
//
// The contract an accelerator backend would implement (docs/processing.md,
// "Backends"):
//  - Stages of one frame are called in the order below, one thread per
//    workspace; different workspaces (frames) may run concurrently, and a
//    backend must allow that (or serialise inside).
//  - Products are the host structures the callers read (ChainProducts,
//    LensProducts); their buffers belong to the chain's pooled workspaces,
//    so a backend that keeps device copies can key them by the product's
//    address, which stays the same while the workspace is reused. A stage
//    must leave its host product complete when it returns: the next stage
//    may be the caller reading it (the live pipeline publishes the per-lens
//    depth before the dense stages run).
//  - Errors a frame can cause are returned as values; the chain prefixes
//    the camera's serial.
//  - The per-camera geometry (MLA grid, white image, the per-lens
//    estimator's tables) is made once by the chain and passed in; a backend
//    may upload it at its first use.
// Per frame, in order (CameraChain::ProcessLenses, then CameraChain::Process):
//   LensDepth       one virtual depth per micro lens (LensDepthEstimator)
//   LensPreview     the TF preview at each lens's depth, when asked
//   Prepare         the devignetted grey of the raw frame (LoadRaw)
//   LensDepth       again only when Process is given no per-lens depth
//   Seed            the dense search's windows from the per-lens depth
//   DenseDepth      the virtual depth on the raw grid
//   TfDepth         the virtual depth on the TF grid (from the per-lens depth where it
//                   holds when the dense search was seeded: total_focus.h)
//   TfRender        the totally focused image, of every options.image_step-th TF
//                   pixel (the live depth lane's, for its preview: TfOptions)
// The metric depth and the point cloud (point_cloud.h) stay on the host:
// they are a per-TF-pixel formula over the TF depth, cheap beside the rest.

#include "config/error.h"
#include "config/image.h"
#include "config/mla.h"
#include "processing/lens_depth.h"
#include "processing/plenoptic_frame.h"
#include "processing/total_focus.h"
#include "processing/virtual_depth.h"

#include <memory>
#include <string_view>

namespace lifmcr::processing {

class ChainBackend {
 public:
  virtual ~ChainBackend() = default;
  // "cpu"; an accelerator backend names its device.
  virtual std::string_view Name() const = 0;

  virtual Status LensDepth(const LensDepthEstimator& estimator, ConstImageView raw,
                           LensDepthMap* out) = 0;
  // `depth` is the frame's per-lens depth; the preview may add its own
  // scratch to it (LensDepthEstimator::RenderPreview).
  virtual Status LensPreview(const LensDepthEstimator& estimator, ConstImageView raw,
                             int max_side, LensDepthMap* depth, TfImage* out) = 0;
  // `frame` holds the camera's geometry (PrepareGeometry); the stage fills
  // its grey from `raw`.
  virtual Status Prepare(ConstImageView raw, PlenopticFrame* frame) = 0;
  virtual Status Seed(const PlenopticFrame& frame, const LensDepthMap& lens_depth,
                      LensSeed* out) = 0;
  // `seed` null: the full search.
  virtual Status DenseDepth(const PlenopticFrame& frame, const MlaCalibration& mla,
                            const DepthOptions& options, const LensSeed* seed,
                            VirtualDepthMap* out) = 0;
  // `lens_depth` the frame's per-lens depth (the dense search's seed): the
  // TF depth from it where it holds (total_focus.h); null: from every dense pixel.
  virtual Status TfDepth(const PlenopticFrame& frame, const VirtualDepthMap& raw_depth,
                         const LensDepthMap* lens_depth, const TfOptions& options,
                         TfDepthMap* out) = 0;
  virtual Status TfRender(const PlenopticFrame& frame, const MlaCalibration& mla,
                          const TfDepthMap& depth, const TfOptions& options, TfImage* out) = 0;
};

// The CPU implementation: the functions named above, on the calling thread
// (with their own TBB parallelism). Stateless, so one instance may serve
// every camera.
std::shared_ptr<ChainBackend> MakeCpuBackend();

}  // namespace lifmcr::processing
