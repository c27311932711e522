#pragma once
// The stage after processing in the live pipeline: where registration
// plugs in (docs/architecture.md). The pipeline calls it for every processed
// frame and groups its answers per trigger; what comes out is published as
// camera_extrinsics_t on <PREFIX>_<SERIAL>_EXTRINSICS (apps/pipeline/publisher.h).
//
// Per frame (Localize, on a processing worker, concurrently for different
// frames; at most one call per camera at a time is NOT guaranteed): camera
// X's frame in (the raw frame, and the chain's products when it was
// processed first), optionally its pose w0_from_cx out
// (maps camera X's coordinates into the world frame W0 of camera 0's
// reference map; mm).
//
// Per trigger (Relate, on the pipeline's publishing thread, once for each
// camera X != reference that has a pose of the same trigger as the
// reference camera): by default
//   c0_from_cx = (w0_from_c0)^-1 * w0_from_cx
// with covariance propagated to first order when both poses carry one
// (Ad: adjoint of SE(3) in the (t, r) order of CameraPose::covariance):
//   Sigma_c0_from_cx ~ Ad(c0_from_w0) (Sigma_w0_from_cx + Sigma_w0_from_c0) Ad(c0_from_w0)^T
// A stage that fuses over time overrides Relate.
//
// The default stage (PassThroughStage) localises nothing: frames pass
// through and no extrinsics are published.

#include "config/error.h"
#include "processing/camera_model.h"
#include "processing/frame_chain.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>

namespace lifmcr::processing {

// What the pipeline hands a stage for one processed frame. Pointers are
// valid for the duration of the call only.
struct StageFrame {
  int camera_index = 0;             // in the rig file / sequence; 0 = the reference camera
  std::string serial;
  std::int64_t trigger_index = 0;   // the FrameSet's (the recording's file number)
  std::optional<std::int64_t> vicon_frame;  // the Vicon frame of that trigger, when known
  std::int64_t host_ns = 0;         // arrival of the frame at the host (CLOCK_REALTIME)
  // The raw frame as the chain takes it (Mono8 or BGR8, a Bayer mosaic
  // demosaiced); never empty.
  ConstImageView raw;
  // The chain's products of this frame (TF image and depth) when it was
  // processed before registration; null when registration runs ahead of
  // processing (the live pipeline under newest_wins: apps/pipeline/pipeline.h).
  const ChainProducts* products = nullptr;
  CameraChain* camera = nullptr;  // MLA, model (camera_model() when intrinsics known), sampler
};

// What change detection (registration/live/extrinsics_monitor.h) says about one
// c0_from_cx of a rigidly mounted camera.
struct ExtrinsicsChange {
  enum class State { kSettling, kSteady, kDeparting, kChanged } state = State::kSettling;
  double departure = 0;       // squared Mahalanobis distance to the running estimate (6 dof)
  int departures_in_row = 0;  // consecutive triggers beyond the gate
  Eigen::Isometry3d running = Eigen::Isometry3d::Identity();  // running estimate of c0_from_cx
  // The running estimate's covariance (CameraPose::covariance's convention):
  // the mean of the fused triggers' covariances over their number, as if
  // their errors were independent; and that number.
  Eigen::Matrix<double, 6, 6> running_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  int running_triggers = 0;
};
const char* ToString(ExtrinsicsChange::State state);  // "settling", "steady", ...

// A pose of camera X: w0_from_cx from Localize, or c0_from_cx from Relate.
struct CameraPose {
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();  // translation in mm
  // 6 x 6 in the order tx ty tz (mm), rx ry rz (rad) of a perturbation on
  // the left, T = exp(xi) T_hat (xi in the frame T maps into); zero: unknown.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  std::string method;        // estimator: "pnp", "ransac", ...
  // live localizer: "tracked", "re-anchored" (tracked, then matched against the map guided by
  // that pose), "relocalised" or "skipped" (not localised: status says why);
  // empty otherwise
  std::string localisation;
  int inliers = 0;
  double rmse_px = 0;
  std::string status = "ok";  // "ok" or why it failed (then transform is meaningless)
  std::optional<ExtrinsicsChange> change;  // c0_from_cx of a monitored rigid mount only
};

class RegistrationStage {
 public:
  virtual ~RegistrationStage() = default;
  virtual std::string name() const = 0;
  // Pose w0_from_cx of this frame's camera, or nullopt (not localised: the
  // frame passes through). An error is counted as a failed frame and named
  // in the pipeline's report.
  virtual Expected<std::optional<CameraPose>> Localize(const StageFrame& frame) = 0;
  // c0_from_cx of one trigger from both poses (default: the composition in
  // the header comment). Called on one thread (the pipeline's publishing
  // node), in trigger order per camera as far as frames finish in order.
  // `serial`: camera X's.
  virtual CameraPose Relate(const std::string& serial, std::int64_t trigger_index,
                            const CameraPose& w0_from_c0, const CameraPose& w0_from_cx);
};

// Frames pass through; nothing is localised.
class PassThroughStage final : public RegistrationStage {
 public:
  std::string name() const override { return "pass-through"; }
  Expected<std::optional<CameraPose>> Localize(const StageFrame&) override {
    return std::optional<CameraPose>();
  }
};

// c0_from_cx = (w0_from_c0)^-1 * w0_from_cx with its first-order covariance.
CameraPose ComposeExtrinsics(const CameraPose& w0_from_c0, const CameraPose& w0_from_cx);

}  // namespace lifmcr::processing
