#include "registration/map_localizer.h"

#include "registration/tf_projection.h"

#include <chrono>
#include <cmath>
#include <limits>

namespace lifmcr::registration {

Status LocalizerOptions::Check() const {
  if (Status s = registration.Check(); !s) return s;
  if (Status s = features.Check(); !s) return s;
  if (!(track_radius_px > 0)) return Error{"localizer options: track_radius_px: expected > 0"};
  if (min_tracked < 3) return Error{"localizer options: min_tracked: expected >= 3"};
  return Status::Ok();
}

Covariance6 ToLeftPerturbationCovariance(const PoseWithCovariance& pose) {
  Covariance6 a = Covariance6::Identity();
  a.topRightCorner<3, 3>() = Skew(pose.pose.translation());
  return a * pose.covariance * a.transpose();
}

MapLocalizerStage::MapLocalizerStage(const ReferenceMap& map, const LocalizerOptions& options)
    : map_(MapIndex::Of(map)), options_(options) {}

Pose MapLocalizerStage::CameraState::Predict(std::int64_t trigger) const {
  if (has_previous && trigger - last_trigger == last_trigger - previous_trigger)
    return last * (previous.inverse() * last);
  return last;
}

void MapLocalizerStage::MonitorChanges(const ExtrinsicsMonitorOptions& options) {
  monitor_.emplace(options);
}

processing::CameraPose MapLocalizerStage::Relate(const std::string& serial,
                                                 std::int64_t /*trigger_index*/,
                                                 const processing::CameraPose& w0_from_c0,
                                                 const processing::CameraPose& w0_from_cx) {
  processing::CameraPose c0_from_cx = processing::ComposeExtrinsics(w0_from_c0, w0_from_cx);
  if (monitor_) c0_from_cx.change = monitor_->Add(serial, c0_from_cx);
  return c0_from_cx;
}

MapLocalizerStage::Counts MapLocalizerStage::counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

FrameRegistration MapLocalizerStage::Track(const processing::CameraModel& camera,
                                           const FrameObservations& obs,
                                           const Pose& predicted) const {
  const auto start = std::chrono::steady_clock::now();
  FrameRegistration result;
  const TfProjection projection = TfProjection::Of(camera);
  const Pose cam_from_w0 = predicted.inverse();
  const double r2 = options_.track_radius_px * options_.track_radius_px;
  // Projected map points (those in front of the camera).
  std::vector<int> visible;
  std::vector<Eigen::Vector2d> projected;
  for (int j = 0; j < map_.size(); ++j) {
    const Eigen::Vector3d p = cam_from_w0 * map_.points_in_w0[j];
    double tf[2];
    if (!projection(p.data(), tf)) continue;
    visible.push_back(j);
    projected.emplace_back(tf[0], tf[1]);
  }
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> tf_px;
  std::vector<double> v;
  for (int i = 0; i < obs.features.size(); ++i) {
    // The best and second-best descriptor distance among the points within the window.
    double best = std::numeric_limits<double>::infinity(), second = best;
    int best_j = -1;
    const float* q = obs.features.Descriptor(i);
    for (std::size_t k = 0; k < visible.size(); ++k) {
      if ((projected[k] - obs.tf_px[i]).squaredNorm() > r2) continue;
      const float* t = map_.descriptors.data() + static_cast<std::size_t>(visible[k]) * kDescriptorSize;
      double d = 0;
      for (int c = 0; c < kDescriptorSize; ++c) d += (q[c] - t[c]) * (q[c] - t[c]);
      if (d < best) {
        second = best;
        best = d;
        best_j = visible[k];
      } else if (d < second) {
        second = d;
      }
    }
    if (best_j < 0) continue;
    const double ratio = options_.registration.match.ratio;
    if (std::isfinite(second) && best >= ratio * ratio * second) continue;
    points.push_back(map_.points_in_w0[best_j]);
    tf_px.push_back(obs.tf_px[i]);
    v.push_back(obs.virtual_depth[i]);
  }
  result.matches = points.size();
  PnpOptions pnp = options_.registration.pnp;
  pnp.final_refinement = false;  // the LO-RANSAC optimum; the live path saves the Ceres polish
  const PnpResult r = EstimatePlenopticPnp(camera, {points, tf_px, v}, pnp);
  result.inliers = r.num_inliers;
  result.rmse_px = r.rmse_px;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!r.success) {
    result.status = r.status;
    return result;
  }
  result.w0_from_cam = Inverse(PoseWithCovariance{r.cam_from_world, r.covariance});
  result.success = true;
  result.status = "ok";
  return result;
}

Expected<std::optional<processing::CameraPose>> MapLocalizerStage::Localize(
    const processing::StageFrame& frame) {
  const auto start = std::chrono::steady_clock::now();
  if (!frame.camera->camera_model())
    return std::optional<processing::CameraPose>();  // no intrinsics: nothing to localise
  const processing::CameraModel& camera = *frame.camera->camera_model();
  const processing::ChainProducts& products = *frame.products;
  FrameObservations obs;
  obs.frame = frame.trigger_index;
  if (Status s = DetectSift(products.tf.View(), options_.features, &obs.features); !s)
    return s.error();
  obs.virtual_depth.resize(obs.features.keypoints.size(), std::numeric_limits<double>::quiet_NaN());
  const processing::TfDepthMap& depth = products.tf_depth;
  for (std::size_t i = 0; i < obs.features.keypoints.size(); ++i) {
    const int u = static_cast<int>(std::lround(obs.features.keypoints[i].xy_px.x()));
    const int w = static_cast<int>(std::lround(obs.features.keypoints[i].xy_px.y()));
    if (u < 0 || w < 0 || u >= depth.width || w >= depth.height) continue;
    obs.virtual_depth[i] = depth.virtual_depth[static_cast<std::size_t>(w) * depth.width + u];
  }
  CompleteObservations(camera, &obs);

  CameraState state;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    CameraState& s = cameras_[frame.serial];
    if (frame.host_ns > s.last_host_ns && frame.trigger_index <= s.last_trigger)
      s = CameraState{};  // a new pass
    state = s;
  }
  FrameRegistration r;
  std::string localisation = "relocalised";
  if (state.has_pose && options_.track) {
    r = Track(camera, obs, state.Predict(frame.trigger_index));
    if (r.success && r.inliers >= static_cast<std::size_t>(options_.min_tracked))
      localisation = "tracked";
    else
      r = FrameRegistration{};
  }
  if (!r.success)
    r = RegisterFrame(map_, camera, obs, RegistrationMethod::kPnp, options_.registration);

  processing::CameraPose pose;
  pose.method = std::string(ToString(RegistrationMethod::kPnp));
  pose.localisation = localisation;
  pose.inliers = static_cast<int>(r.inliers);
  pose.rmse_px = r.rmse_px;
  pose.status = r.status;
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::lock_guard<std::mutex> lock(mutex_);
  CameraState& s = cameras_[frame.serial];
  const bool newest = frame.host_ns >= s.last_host_ns && frame.trigger_index > s.last_trigger;
  if (!r.success) {
    ++counts_.failed;
    counts_.failed_s += seconds;
    if (newest) {  // relocalise next time
      s = CameraState{};
      s.last_trigger = frame.trigger_index;
      s.last_host_ns = frame.host_ns;
    }
    return std::optional<processing::CameraPose>(pose);
  }
  if (localisation == "tracked") {
    ++counts_.tracked;
    counts_.tracked_s += seconds;
  } else {
    ++counts_.relocalised;
    counts_.relocalised_s += seconds;
  }
  if (newest) {
    s.previous = s.last;
    s.previous_trigger = s.last_trigger;
    s.has_previous = s.has_pose;
    s.last = r.w0_from_cam.pose;
    s.last_trigger = frame.trigger_index;
    s.last_host_ns = frame.host_ns;
    s.has_pose = true;
  }
  pose.transform = r.w0_from_cam.pose;
  pose.covariance = ToLeftPerturbationCovariance(r.w0_from_cam);
  return std::optional<processing::CameraPose>(pose);
}

}  // namespace lifmcr::registration
