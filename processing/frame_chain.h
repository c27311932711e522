#pragma once
// The processing chain of a camera: the one sequence of steps that turns a
// raw plenoptic frame into depth, used by `lifmcr depth`, replay and
// `record --publish` alike (docs/architecture.md).
//
// Once per camera (CameraChain::Create, and at the first frame of a size):
//   devignetting mode  the white image when the camera has one
//                      (Devignetting::kWhiteImage), else the vignetting
//                      the camera's first frame shows (Devignetting::
//                      kFromFrame, processing/vignetting.h: a white image
//                      built from the mean micro image, or none when the
//                      frame is already devignetted); SelectDevignetting is
//                      the one place that decides;
//   MLA grid           MlaGrid::FromCalibration of the MLA file for the
//                      frame size (the white image's when there is one);
//   lambda             b_L0 / (b_L0 + B) from the intrinsics when known,
//                      else 1 (micro-lens centres = micro-image centres);
//   metric check       with intrinsics, the largest virtual depth searched
//                      (SearchedVirtualDepths of the MLA's lens types) must
//                      map in front of the main lens, b_L0 + v B > f_L;
//                      otherwise Create fails naming the values, as no
//                      frame could give a point.
// Per frame (CameraChain::Process):
//   devignetted grey (plenoptic_frame.h) -> virtual depth on the raw grid
//   (virtual_depth.h) -> TF depth map and the totally focused image
//   (total_focus.h) -> with intrinsics: metric depth on the TF grid and,
//   when asked, the coloured point cloud (point_cloud.h).
//
// Buffers: every product lives in a workspace of the camera's pool, lent to
// the caller as a ChainLease and returned to the pool when the lease ends,
// so a camera processes as many frames at once as it has leases out and a
// workspace reused frame after frame allocates nothing (fresh buffers of an
// R32 frame are about a GB of first-touched pages, slower than the
// processing itself). The raw frame is not copied: the lease views the
// caller's buffer, which must outlive the lease.
//
// Per frame, cheap (CameraChain::ProcessLenses): one virtual depth per micro
// lens from the raw pixels (lens_depth.h) and the TF preview at each lens's
// depth, in a workspace of a pool of their own (LensLease); the estimator's
// geometry is the camera's, made once.
//
// Stages: every per-frame stage runs through the camera's ChainBackend
// (chain_backend.h; the CPU backend unless Create is given another), the
// seam where an accelerator would take the stages over.
//
// Threads: Process and ProcessLenses may be called concurrently (each call takes its own
// workspace); the per-camera geometry is made once under a lock.

#include "config/error.h"
#include "config/image.h"
#include "config/mla.h"
#include "processing/camera_model.h"
#include "processing/chain_backend.h"
#include "processing/lens_depth.h"
#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/point_cloud.h"
#include "processing/tf_sampler.h"
#include "processing/total_focus.h"
#include "processing/vignetting.h"
#include "processing/virtual_depth.h"

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::processing {

// How a camera's frames are devignetted (chosen once per camera).
enum class Devignetting {
  kWhiteImage,  // I_n = I * W_ref / W (plenoptic_frame.h)
  kFromFrame,   // no white image: estimated once from the camera's first frame (vignetting.h)
};
std::string_view ToString(Devignetting mode);  // "white image", "from the frame"

// What a camera brings to the chain: its MLA calibration, and when known its
// white image and intrinsics. Files are found and read outside processing
// (replay/camera_calibration.h has the rule for Calibration/).
struct CameraSetup {
  std::string serial;
  MlaCalibration mla;
  std::optional<OwnedImage> white;
  std::optional<CameraIntrinsics> intrinsics;
};

// The devignetting a setup gets: the one branch point of the per-camera setup.
Devignetting SelectDevignetting(const CameraSetup& setup);

struct ChainOptions {
  // Devignetting and micro-image geometry; `frame.lambda` is replaced by the
  // camera's lambda when its intrinsics are known.
  FrameOptions frame;
  DepthOptions depth;  // virtual depth on the raw grid
  LensDepthOptions lens;  // per-lens virtual depth (ProcessLenses)
  // The dense virtual depth seeded by the frame's per-lens depth
  // (virtual_depth.h, "Seeded"); false: the full search.
  bool seeded_depth = true;
  // With seeded_depth: the dense map only where the TF depth map reads it,
  // for a caller that reads only the TF products (tf_depth, tf, depth_mm,
  // cloud): the micro images whose TF depth comes from their lens depth
  // (LensesHeldForTf) are not estimated, so raw_depth has no value there
  // (LensSeed::skip). The live pipeline's chain (apps/pipeline); false
  // for `lifmcr depth`, which writes the dense map. Without seeded_depth
  // the TF depth reads every dense pixel: Check() refuses it.
  bool dense_for_tf_only = false;
  TfOptions tf;        // TF depth map and totally focused image
  // Without a white image. With vignetting_auto_rows, frames taller than
  // 2000 rows are sampled every 4th row (an R32 frame: plenty of micro images).
  VignettingOptions vignetting;
  bool vignetting_auto_rows = true;
  bool metric_depth = true;   // with intrinsics: camera z (mm) per TF pixel
  bool point_cloud = false;   // with intrinsics: the coloured point cloud (mm)
  bool cloud_measured_only = true;  // cloud of measured TF pixels only, not filled ones
  Status Check() const;  // every field; the message names the field
};

// The products of one frame, in a workspace of the camera's pool.
struct ChainProducts {
  PlenopticFrame prepared;       // devignetted grey; views the raw frame
  LensDepthMap lens_depth;       // the seed, when Process made it (seeded_depth, no map given)
  LensSeed seed;                 // per micro image of `prepared` (seeded_depth)
  VirtualDepthMap raw_depth;     // virtual depth on the raw grid
  TfDepthMap tf_depth;           // virtual depth on the TF grid (W/2 x H/2)
  TfImage tf;                    // totally focused image
  std::vector<float> depth_mm;   // camera z per TF pixel (metric_depth with intrinsics), else empty
  PointCloud cloud;              // point_cloud with intrinsics, else empty
  bool metric = false;           // depth_mm (and cloud when asked) were computed
  double prepare_s = 0, seed_s = 0, depth_s = 0, tf_s = 0, metric_s = 0;
  double Seconds() const { return prepare_s + seed_s + depth_s + tf_s + metric_s; }
  // "1024x768: virtual depth ... | TF 512x384 61.0 % measured 30.1 % filled | metric | 0.412 s"
  std::string BriefReport() const;

 private:
  friend class CameraChain;
  int geometry_width_ = 0, geometry_height_ = 0;  // of the geometry in `prepared`; 0 = none
};

// The per-lens products of one frame, in a workspace of the camera's pool.
struct LensProducts {
  LensDepthMap depth;
  TfImage preview;  // empty when not asked for
  double depth_s = 0, preview_s = 0;
  // The same parts' CPU time on the calling thread (config/thread_cpu.h):
  // exact where it computes alone (the pipeline's lens lane).
  double depth_cpu_s = 0, preview_cpu_s = 0;
  // "lens depth: ... | preview 512x386 0.004 s"
  std::string BriefReport() const;
};

class CameraChain;
// Returns a workspace to its camera's pool.
struct WorkspaceReturn {
  CameraChain* chain = nullptr;
  void operator()(ChainProducts* products) const;
};
using ChainLease = std::unique_ptr<ChainProducts, WorkspaceReturn>;
struct LensWorkspaceReturn {
  CameraChain* chain = nullptr;
  void operator()(LensProducts* products) const;
};
using LensLease = std::unique_ptr<LensProducts, LensWorkspaceReturn>;

class CameraChain {
 public:
  // `backend` null: MakeCpuBackend().
  static Expected<std::unique_ptr<CameraChain>> Create(
      CameraSetup setup, const ChainOptions& options,
      std::shared_ptr<ChainBackend> backend = nullptr);
  ~CameraChain();
  CameraChain(const CameraChain&) = delete;
  CameraChain& operator=(const CameraChain&) = delete;

  // The chain on one raw frame (Mono8 or BGR8). `raw` must outlive the lease.
  // With seeded_depth, the dense search is seeded by `lens_depth` (the
  // frame's per-lens depth from ProcessLenses) or, when null, by the
  // per-lens depth Process computes itself (seed_s).
  Expected<ChainLease> Process(ConstImageView raw, const LensDepthMap* lens_depth = nullptr);

  // Per-lens virtual depth of one raw frame (Mono8 or BGR8) and, with
  // preview_max_side > 0, the TF preview at each lens's depth of at most that
  // many pixels on its longest side (LensDepthEstimator::RenderPreview).
  Expected<LensLease> ProcessLenses(ConstImageView raw, int preview_max_side);
  // The camera's per-lens estimator for frames of raw's size: made at the
  // first call (the geometry, like a workspace's), then shared.
  Expected<const LensDepthEstimator*> LensEstimator(ConstImageView raw);

  // The camera's TF sampler (processing/tf_sampler.h) for frames of raw's
  // size, with the chain's devignetting: made at the first call (a
  // geometry like a workspace's, ~0.2 s at 8 MP), then shared; the live
  // registration samples the TF image there instead of running the chain.
  Expected<const TfSampler*> Sampler(ConstImageView raw);
  // Whether the per-lens estimator (and, with `sampler`, the TF sampler) for
  // frames of width x height are made, so the camera's next frame of that
  // size pays only its own work.
  bool Prepared(int width, int height, bool sampler) const;

  const std::string& serial() const { return setup_.serial; }
  // The white image the camera is devignetted with (kWhiteImage; empty view
  // otherwise): its size is the camera's frame size.
  ConstImageView white() const {
    return setup_.white ? ConstImageView(setup_.white->View()) : ConstImageView{};
  }
  const MlaCalibration& mla() const { return setup_.mla; }
  const std::optional<CameraModel>& camera_model() const { return camera_; }
  Devignetting devignetting() const { return devignetting_; }
  const ChainBackend& backend() const { return *backend_; }
  // "40398678: devignetting white image, lambda 0.9920 (intrinsics; metric
  // depth)" for the operator; with kFromFrame, after the first frame, what
  // the estimate decided.
  std::string Describe() const;

 private:
  friend struct WorkspaceReturn;
  friend struct LensWorkspaceReturn;
  CameraChain() = default;
  // The grid of frames of width x height (made once per size).
  Expected<MlaGrid> GridFor(int width, int height);
  // The white image to devignette with (empty view: none), estimated from
  // `raw` at the first frame with kFromFrame.
  Expected<ConstImageView> WhiteFor(ConstImageView raw, const MlaGrid& grid);
  ChainLease Acquire();
  void Release(ChainProducts* products);
  // The geometry of frames of raw's size with the chain's devignetting.
  Expected<PlenopticFrame> Geometry(ConstImageView raw);

  CameraSetup setup_;
  ChainOptions options_;
  std::shared_ptr<ChainBackend> backend_;
  Devignetting devignetting_ = Devignetting::kWhiteImage;
  std::optional<CameraModel> camera_;
  mutable std::mutex mutex_;  // guards grid_, estimate_ and idle_
  std::optional<MlaGrid> grid_;
  int grid_width_ = 0, grid_height_ = 0;
  // kFromFrame: the estimate from the camera's first frame (guarded by mutex_).
  std::optional<VignettingEstimate> estimate_;
  std::vector<std::unique_ptr<ChainProducts>> idle_;
  mutable std::mutex sampler_mutex_;  // guards sampler_ (made outside mutex_: GridFor takes it)
  std::unique_ptr<TfSampler> sampler_;
  mutable std::mutex lens_mutex_;  // guards lens_ and idle_lens_ (made outside mutex_: GridFor takes it)
  std::unique_ptr<LensDepthEstimator> lens_;
  std::vector<std::unique_ptr<LensProducts>> idle_lens_;
};

// The chains of a rig's cameras, by serial.
class ProcessingChain {
 public:
  // One backend for every camera; null: MakeCpuBackend().
  static Expected<std::unique_ptr<ProcessingChain>> Create(
      std::vector<CameraSetup> cameras, const ChainOptions& options,
      std::shared_ptr<ChainBackend> backend = nullptr);
  // Null when the serial has no chain.
  CameraChain* Find(const std::string& serial) const;
  std::vector<std::string> serials() const;

 private:
  std::map<std::string, std::unique_ptr<CameraChain>> cameras_;
};

}  // namespace lifmcr::processing
