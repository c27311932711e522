// The processing chain (frame_chain.h).

#include "processing/frame_chain.h"

#include "config/thread_cpu.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <utility>

namespace lifmcr::processing {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A frame narrower or lower than one micro image holds no whole micro image,
// so no depth, and its TF grid (half its size) may be empty: said here, with
// the sizes, instead of failing deep inside a stage. Empty when it is large
// enough.
std::string SmallerThanAMicroImage(int width, int height, const MlaCalibration& mla) {
  const int least = static_cast<int>(std::ceil(mla.diameter_px));
  if (width >= least && height >= least) return "";
  return std::to_string(width) + "x" + std::to_string(height) +
         " px, smaller than one micro image (diameter " + std::to_string(least) +
         " px in the MLA file); expected a frame of the camera, at least " +
         std::to_string(least) + "x" + std::to_string(least) + " px";
}

}  // namespace

std::string_view ToString(Devignetting mode) {
  switch (mode) {
    case Devignetting::kWhiteImage:
      return "white image";
    case Devignetting::kFromFrame:
      return "from the frame";
  }
  return "?";
}

Devignetting SelectDevignetting(const CameraSetup& setup) {
  return setup.white ? Devignetting::kWhiteImage : Devignetting::kFromFrame;
}

Status ChainOptions::Check() const {
  if (Status s = frame.Check(); !s) return Error{"chain options: frame: " + s.error().message};
  if (Status s = depth.Check(); !s) return Error{"chain options: depth: " + s.error().message};
  if (Status s = tf.Check(); !s) return Error{"chain options: tf: " + s.error().message};
  if (Status s = lens.Check(); !s) return Error{"chain options: lens: " + s.error().message};
  if (Status s = vignetting.Check(); !s)
    return Error{"chain options: vignetting: " + s.error().message};
  if (dense_for_tf_only && !seeded_depth)
    return Error{"chain options: dense_for_tf_only needs seeded_depth (without it the TF depth "
                 "map reads every dense pixel)"};
  // metric_depth, point_cloud, cloud_measured_only, seeded_depth: any value.
  return Status::Ok();
}

std::string ChainProducts::BriefReport() const {
  const double n = static_cast<double>(tf_depth.width) * tf_depth.height;
  char buf[512];
  std::snprintf(buf, sizeof buf, "%dx%d: %s | TF %dx%d %.1f %% measured %.1f %% filled%s | %.3f s",
                raw_depth.width, raw_depth.height, raw_depth.stats.BriefReport().c_str(),
                tf_depth.width, tf_depth.height, n > 0 ? 100.0 * tf_depth.measured / n : 0.0,
                n > 0 ? 100.0 * tf_depth.filled / n : 0.0, metric ? " | metric" : "", Seconds());
  return buf;
}

std::string LensProducts::BriefReport() const {
  char buf[128];
  std::snprintf(buf, sizeof buf, " | preview %dx%d %.4f s", preview.width, preview.height,
                preview_s);
  return depth.stats.BriefReport() + buf;
}

void LensWorkspaceReturn::operator()(LensProducts* products) const {
  if (!chain) {
    delete products;
    return;
  }
  std::lock_guard lock(chain->lens_mutex_);
  chain->idle_lens_.emplace_back(products);
}

void WorkspaceReturn::operator()(ChainProducts* products) const {
  if (chain)
    chain->Release(products);
  else
    delete products;
}

CameraChain::~CameraChain() = default;

Expected<std::unique_ptr<CameraChain>> CameraChain::Create(CameraSetup setup,
                                                           const ChainOptions& options,
                                                           std::shared_ptr<ChainBackend> backend) {
  if (Status s = options.Check(); !s) return s.error();
  const std::string who = "camera " + setup.serial + ": ";
  std::unique_ptr<CameraChain> chain(new CameraChain());
  chain->options_ = options;
  chain->backend_ = backend ? std::move(backend) : MakeCpuBackend();
  chain->devignetting_ = SelectDevignetting(setup);
  if (setup.intrinsics) {
    if (Status s = setup.intrinsics->Check(); !s)
      return Error{who + "intrinsics: " + s.error().message};
    // Metric depth Z = f_L b / (b - f_L) with b = b_L0 + v B (camera_model.h)
    // is in front of the camera only where b > f_L. When even the largest
    // virtual depth the lens types are searched for stays below, no measured
    // point can be in front: the intrinsics and the MLA file disagree (a B or
    // b_L0 far too small), which is named here instead of a frame without
    // points later.
    const CameraIntrinsics& k = *setup.intrinsics;
    double v_max = 0;
    for (const MlaLensType& type : setup.mla.lens_types)
      v_max = std::max(v_max, SearchedVirtualDepths(type).max);
    const double b = k.mla_to_main_lens_mm + v_max * k.mla_to_sensor_mm;
    if (!(b > k.main_focal_length_mm)) {
      char text[512];
      std::snprintf(text, sizeof text,
                    "intrinsics: mla_to_main_lens_mm b_L0 = %.6g mm and mla_to_sensor_mm B = "
                    "%.6g mm put every virtual depth the MLA file's lens types cover (up to "
                    "v = %.6g) behind the main lens: b_L0 + v B = %.6g mm, expected more than "
                    "main_focal_length_mm f_L = %.6g mm (is B or b_L0 far too small?)",
                    k.mla_to_main_lens_mm, k.mla_to_sensor_mm, v_max, b, k.main_focal_length_mm);
      return Error{who + text};
    }
    chain->camera_.emplace(*setup.intrinsics);
    chain->options_.frame.lambda = chain->camera_->lambda();
    chain->options_.frame.principal_point_px = chain->camera_->principal_point_px();
  }
  if (setup.white && (setup.white->width <= 0 || setup.white->height <= 0))
    return Error{who + "white image: empty"};
  if (setup.white) {
    if (const std::string small =
            SmallerThanAMicroImage(setup.white->width, setup.white->height, setup.mla);
        !small.empty())
      return Error{who + "white image: " + small};
  }
  if (setup.white && setup.intrinsics &&
      (setup.white->width != setup.intrinsics->width_px ||
       setup.white->height != setup.intrinsics->height_px))
    return Error{who + "white image is " + std::to_string(setup.white->width) + "x" +
                 std::to_string(setup.white->height) + ", the intrinsics say " +
                 std::to_string(setup.intrinsics->width_px) + "x" +
                 std::to_string(setup.intrinsics->height_px)};
  chain->setup_ = std::move(setup);
  // The grid now when the frame size is known already.
  if (chain->setup_.white) {
    if (auto grid = chain->GridFor(chain->setup_.white->width, chain->setup_.white->height); !grid)
      return grid.error();
  } else if (chain->setup_.intrinsics) {
    if (auto grid =
            chain->GridFor(chain->setup_.intrinsics->width_px, chain->setup_.intrinsics->height_px);
        !grid)
      return grid.error();
  }
  return chain;
}

std::string CameraChain::Describe() const {
  char lambda[64];
  std::snprintf(lambda, sizeof lambda, "lambda %.4f", options_.frame.lambda);
  std::string devignetting(ToString(devignetting_));
  {
    std::lock_guard lock(mutex_);
    if (estimate_) devignetting += " (" + estimate_->BriefReport() + ")";
  }
  return setup_.serial + ": devignetting " + devignetting + ", " + lambda +
         (!camera_ ? " (no intrinsics: virtual depth only)"
          : options_.metric_depth || options_.point_cloud ? " (intrinsics; metric depth)"
                                                          : " (intrinsics; no metric depth asked)");
}

Expected<ConstImageView> CameraChain::WhiteFor(ConstImageView raw, const MlaGrid& grid) {
  switch (devignetting_) {
    case Devignetting::kWhiteImage:
      return ConstImageView(std::as_const(*setup_.white).View());
    case Devignetting::kFromFrame: {
      std::lock_guard lock(mutex_);
      if (!estimate_ || estimate_->width != raw.width || estimate_->height != raw.height) {
        VignettingOptions options = options_.vignetting;
        if (options_.vignetting_auto_rows && raw.height > 2000) options.row_step = 4;
        auto estimate = EstimateVignetting(raw, grid, setup_.mla, options);
        if (!estimate) return Error{"camera " + setup_.serial + ": " + estimate.error().message};
        estimate_ = std::move(*estimate);
      }
      // The estimate lives as long as the chain; it is replaced only for
      // frames of another size (a camera that changes its ROI mid-run).
      return estimate_->White();
    }
  }
  return ConstImageView{};
}

Expected<MlaGrid> CameraChain::GridFor(int width, int height) {
  std::lock_guard lock(mutex_);
  if (grid_ && grid_width_ == width && grid_height_ == height) return *grid_;
  if (setup_.white && (setup_.white->width != width || setup_.white->height != height))
    return Error{"camera " + setup_.serial + ": frame " + std::to_string(width) + "x" +
                 std::to_string(height) + ", its white image " +
                 std::to_string(setup_.white->width) + "x" + std::to_string(setup_.white->height)};
  if (const std::string small = SmallerThanAMicroImage(width, height, setup_.mla); !small.empty())
    return Error{"camera " + setup_.serial + ": raw frame: " + small};
  grid_ = MlaGrid::FromCalibration(setup_.mla, width, height);
  grid_width_ = width;
  grid_height_ = height;
  return *grid_;
}

ChainLease CameraChain::Acquire() {
  std::lock_guard lock(mutex_);
  if (idle_.empty()) return ChainLease(new ChainProducts(), WorkspaceReturn{this});
  ChainLease lease(idle_.back().release(), WorkspaceReturn{this});
  idle_.pop_back();
  return lease;
}

void CameraChain::Release(ChainProducts* products) {
  std::lock_guard lock(mutex_);
  idle_.emplace_back(products);
}

Expected<const TfSampler*> CameraChain::Sampler(ConstImageView raw) {
  if (raw.data == nullptr || raw.width <= 0 || raw.height <= 0)
    return Error{"camera " + setup_.serial + ": empty frame"};
  std::lock_guard lock(sampler_mutex_);
  if (sampler_ && sampler_->raw_width() == raw.width && sampler_->raw_height() == raw.height)
    return sampler_.get();
  auto geometry = Geometry(raw);
  if (!geometry) return geometry.error();
  sampler_ = std::make_unique<TfSampler>(std::move(*geometry), setup_.mla);
  return sampler_.get();
}

bool CameraChain::Prepared(int width, int height, bool sampler) const {
  {
    std::lock_guard lock(lens_mutex_);
    if (!lens_ || lens_->geometry().width != width || lens_->geometry().height != height)
      return false;
  }
  if (!sampler) return true;
  std::lock_guard lock(sampler_mutex_);
  return sampler_ && sampler_->raw_width() == width && sampler_->raw_height() == height;
}

Expected<PlenopticFrame> CameraChain::Geometry(ConstImageView raw) {
  auto grid = GridFor(raw.width, raw.height);
  if (!grid) return grid.error();
  auto white = WhiteFor(raw, *grid);
  if (!white) return white.error();
  PlenopticFrame geometry;
  if (Status s = PrepareGeometry(*white, raw.width, raw.height, *grid, setup_.mla, options_.frame,
                                 &geometry);
      !s)
    return s.error();
  if (geometry.lenses.empty())
    return Error{"camera " + setup_.serial + ": no whole micro image fits the " +
                 std::to_string(raw.width) + "x" + std::to_string(raw.height) + " frame"};
  return geometry;
}

Expected<const LensDepthEstimator*> CameraChain::LensEstimator(ConstImageView raw) {
  if (raw.data == nullptr || raw.width <= 0 || raw.height <= 0)
    return Error{"camera " + setup_.serial + ": empty frame"};
  std::lock_guard lock(lens_mutex_);
  if (lens_ && lens_->geometry().width == raw.width && lens_->geometry().height == raw.height)
    return lens_.get();
  auto geometry = Geometry(raw);
  if (!geometry) return geometry.error();
  auto estimator = LensDepthEstimator::Create(std::move(*geometry), setup_.mla, options_.lens);
  if (!estimator) return Error{"camera " + setup_.serial + ": " + estimator.error().message};
  lens_ = std::move(*estimator);
  return lens_.get();
}

Expected<LensLease> CameraChain::ProcessLenses(ConstImageView raw, int preview_max_side) {
  auto estimator = LensEstimator(raw);
  if (!estimator) return estimator.error();
  LensLease lease(nullptr, LensWorkspaceReturn{this});
  {
    std::lock_guard lock(lens_mutex_);
    if (idle_lens_.empty()) {
      lease.reset(new LensProducts());
    } else {
      lease.reset(idle_lens_.back().release());
      idle_lens_.pop_back();
    }
  }
  LensProducts& p = *lease;
  auto t = std::chrono::steady_clock::now();
  double cpu = ThreadCpuSeconds();
  if (Status s = backend_->LensDepth(**estimator, raw, &p.depth); !s)
    return Error{"camera " + setup_.serial + ": " + s.error().message};
  p.depth_s = SecondsSince(t);
  p.depth_cpu_s = ThreadCpuSeconds() - cpu;
  p.preview_s = p.preview_cpu_s = 0;
  p.preview.width = p.preview.height = 0;
  if (preview_max_side > 0) {
    t = std::chrono::steady_clock::now();
    cpu = ThreadCpuSeconds();
    if (Status s =
            backend_->LensPreview(**estimator, raw, preview_max_side, &p.depth, &p.preview);
        !s)
      return Error{"camera " + setup_.serial + ": " + s.error().message};
    p.preview_s = SecondsSince(t);
    p.preview_cpu_s = ThreadCpuSeconds() - cpu;
  }
  return lease;
}

Expected<ChainLease> CameraChain::Process(ConstImageView raw, const LensDepthMap* lens_depth) {
  if (raw.data == nullptr || raw.width <= 0 || raw.height <= 0)
    return Error{"camera " + setup_.serial + ": empty frame"};
  ChainLease lease = Acquire();
  ChainProducts& p = *lease;
  auto t = std::chrono::steady_clock::now();
  if (p.geometry_width_ != raw.width || p.geometry_height_ != raw.height) {
    auto grid = GridFor(raw.width, raw.height);
    if (!grid) return grid.error();
    p.geometry_width_ = p.geometry_height_ = 0;
    auto white = WhiteFor(raw, *grid);
    if (!white) return white.error();
    if (Status s = PrepareGeometry(*white, raw.width, raw.height, *grid, setup_.mla,
                                   options_.frame, &p.prepared);
        !s)
      return s.error();
    if (p.prepared.lenses.empty())
      return Error{"camera " + setup_.serial + ": no whole micro image of diameter " +
                   std::to_string(setup_.mla.diameter_px) + " px fits the " +
                   std::to_string(raw.width) + "x" + std::to_string(raw.height) +
                   " frame; expected a raw frame of the camera the MLA file belongs to"};
    p.geometry_width_ = raw.width;
    p.geometry_height_ = raw.height;
  }
  if (Status s = backend_->Prepare(raw, &p.prepared); !s)
    return Error{"camera " + setup_.serial + ": " + s.error().message};
  p.prepare_s = SecondsSince(t);

  t = std::chrono::steady_clock::now();
  p.seed_s = 0;
  const LensSeed* seed = nullptr;
  if (options_.seeded_depth) {
    if (lens_depth == nullptr) {
      auto estimator = LensEstimator(raw);
      if (!estimator) return estimator.error();
      if (Status s = backend_->LensDepth(**estimator, raw, &p.lens_depth); !s)
        return Error{"camera " + setup_.serial + ": " + s.error().message};
      lens_depth = &p.lens_depth;
    }
    if (Status s = backend_->Seed(p.prepared, *lens_depth, &p.seed); !s)
      return Error{"camera " + setup_.serial + ": " + s.error().message};
    // The TF depth map splats these micro images' lens depth, not their
    // dense pixels: with dense_for_tf_only none of them is estimated.
    if (options_.dense_for_tf_only) LensesHeldForTf(p.prepared, p.seed, &p.seed.skip);
    seed = &p.seed;
    p.seed_s = SecondsSince(t);
    t = std::chrono::steady_clock::now();
  }
  if (Status s = backend_->DenseDepth(p.prepared, setup_.mla, options_.depth, seed, &p.raw_depth);
      !s)
    return Error{"camera " + setup_.serial + ": " + s.error().message};
  p.depth_s = SecondsSince(t);

  t = std::chrono::steady_clock::now();
  // The seeded chain's per-lens depth also makes the TF depth (total_focus.h).
  if (Status s = backend_->TfDepth(p.prepared, p.raw_depth, seed != nullptr ? lens_depth : nullptr,
                                   options_.tf, &p.tf_depth);
      !s)
    return Error{"camera " + setup_.serial + ": " + s.error().message};
  if (Status s = backend_->TfRender(p.prepared, setup_.mla, p.tf_depth, options_.tf, &p.tf); !s)
    return Error{"camera " + setup_.serial + ": " + s.error().message};
  p.tf_s = SecondsSince(t);

  t = std::chrono::steady_clock::now();
  p.metric = false;
  p.depth_mm.clear();
  p.cloud = PointCloud{};
  if (camera_) {
    if (camera_->intrinsics().width_px != raw.width ||
        camera_->intrinsics().height_px != raw.height)
      return Error{"camera " + setup_.serial + ": frame " + std::to_string(raw.width) + "x" +
                   std::to_string(raw.height) + ", its intrinsics " +
                   std::to_string(camera_->intrinsics().width_px) + "x" +
                   std::to_string(camera_->intrinsics().height_px)};
    if (options_.metric_depth) MetricDepthTf(*camera_, p.tf_depth, &p.depth_mm);
    if (options_.point_cloud)
      BuildPointCloud(*camera_, p.tf_depth, p.tf, options_.cloud_measured_only, &p.cloud);
    p.metric = options_.metric_depth || options_.point_cloud;
  }
  p.metric_s = SecondsSince(t);
  return lease;
}

Expected<std::unique_ptr<ProcessingChain>> ProcessingChain::Create(
    std::vector<CameraSetup> cameras, const ChainOptions& options,
    std::shared_ptr<ChainBackend> backend) {
  if (!backend) backend = MakeCpuBackend();
  if (Status s = options.Check(); !s) return s.error();
  auto chain = std::make_unique<ProcessingChain>();
  for (CameraSetup& setup : cameras) {
    const std::string serial = setup.serial;
    if (chain->cameras_.count(serial)) return Error{"camera " + serial + ": given twice"};
    auto camera = CameraChain::Create(std::move(setup), options, backend);
    if (!camera) return camera.error();
    chain->cameras_[serial] = std::move(*camera);
  }
  return chain;
}

CameraChain* ProcessingChain::Find(const std::string& serial) const {
  const auto it = cameras_.find(serial);
  return it == cameras_.end() ? nullptr : it->second.get();
}

std::vector<std::string> ProcessingChain::serials() const {
  std::vector<std::string> out;
  for (const auto& [serial, chain] : cameras_) out.push_back(serial);
  return out;
}

}  // namespace lifmcr::processing
