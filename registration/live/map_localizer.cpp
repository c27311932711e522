#include "registration/live/map_localizer.h"

#include "registration/map/guided_matches.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

namespace lifmcr::registration {

// One attempt at a frame's pose.
struct MapLocalizerStage::Outcome {
  bool success = false;
  std::string status = "not run";
  PoseWithCovariance w0_from_cam;
  int inliers = 0;
  double rmse_px = 0;
  // The inliers: map point (MapIndex order), TF position in this frame and,
  // when tracked, the template they were tracked against.
  std::vector<TrackedPoint> kept;
  int anchored_inliers = 0;  // of the kept, TrackedPoint::anchored
  // Relocalisation's stages (s); zero when not relocalised.
  double render_s = 0, sift_s = 0, match_s = 0, pnp_s = 0;
  int matches = 0, fundamental_outliers = 0;
  int windows = 0;  // guided re-anchoring: map points in view
  int refined = 0;  // guided re-anchoring: matches found again at the finer step
  // Tracking's correction of its prediction (Track): its time and status,
  // "" when none was tried.
  double correction_s = 0;
  std::string correction_status;
  std::optional<Pose> corrected;  // the correction's pose when it succeeded
  // Refind: its coarse matching failed from every guide; it succeeded from
  // the fallback guide (the last pose) only.
  bool coarse_failed = false, from_fallback = false;
};

namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// The step a_from_b raised to the power alpha (rotation angle and
// translation scaled; exact for a screw of constant axis to first order).
Pose ScaledStep(const Pose& step, double alpha) {
  Eigen::AngleAxisd rotation(step.rotation());
  rotation.angle() *= alpha;
  Pose out = Pose::Identity();
  out.linear() = rotation.toRotationMatrix();
  out.translation() = alpha * step.translation();
  return out;
}

// The warp of a patch made at TF position tf_a, virtual depth v_a in view
// a into view b (LocalizerOptions::warp_patches): the plane through the
// point fronto-parallel in view a (constant v), its points at tf_a, tf_a +
// (h, 0) and tf_a + (0, h) projected into b; the columns are the
// differences over h. False when one is not seen or the warp is degenerate
// (its area scale outside [1/4, 4]).
bool PatchWarp(const processing::CameraModel& camera, const Pose& a_from_w0,
               const Eigen::Vector2d& tf_a, double v_a, const Pose& b_from_w0,
               Eigen::Matrix2d* warp) {
  constexpr double h = 4;
  const Pose b_from_a = b_from_w0 * a_from_w0.inverse();
  const Eigen::Vector2d offsets[3] = {{0, 0}, {h, 0}, {0, h}};
  Eigen::Vector2d p[3];
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(tf_a + offsets[k]);
    const Eigen::Vector3d x_a = camera.BackProject(Eigen::Vector3d(raw.x(), raw.y(), v_a));
    const Eigen::Vector3d virtual_px = camera.Project(b_from_a * x_a);
    if (!virtual_px.allFinite() || !(virtual_px.z() > 1)) return false;
    p[k] = processing::CameraModel::TfOfRaw(virtual_px.head<2>());
  }
  warp->col(0) = (p[1] - p[0]) / h;
  warp->col(1) = (p[2] - p[0]) / h;
  const double area = warp->determinant();
  return area > 0.25 && area < 4;
}

}  // namespace

GuidedMatchOptions LocalizerOptions::CoarseGuidedOptions() {
  GuidedMatchOptions coarse;
  coarse.max_side_px = 420;
  coarse.radius_px = 120;
  coarse.mask_keypoints = false;  // its radius reaches most of the image
  coarse.render_margin_px = -1;  // likewise
  coarse.refine_step = 0;  // it only places the tracks' prediction
  return coarse;
}

int LocalizerOptions::ReanchorEvery(int tf_longer_side_px) const {
  if (reanchor_every == 0) return 0;
  return guided.Refines(tf_longer_side_px) ? reanchor_every_refined : reanchor_every;
}

int LocalizerOptions::RelocaliseStep(int tf_longer_side_px) const {
  int step = relocalise_step;
  while (step < 4 && tf_longer_side_px / (step + 1) >= relocalise_min_side_px) ++step;
  return step;
}

Status LocalizerOptions::Check() const {
  if (Status s = registration.Check(); !s) return s;
  if (Status s = features.Check(); !s) return s;
  if (Status s = patches.Check(); !s) return s;
  if (Status s = checks.Check(); !s) return s;
  if (min_tracked < 3) return Error{"localizer options: min_tracked: expected >= 3"};
  if (max_tracks < min_tracked)
    return Error{"localizer options: max_tracks: expected >= min_tracked"};
  if (track_cells < 1) return Error{"localizer options: track_cells: expected >= 1"};
  if (relocalise_step < 1 || relocalise_step > 4)
    return Error{"localizer options: relocalise_step: expected 1..4"};
  if (relocalise_refocus_cells < 0)
    return Error{"localizer options: relocalise_refocus_cells: expected >= 0"};
  if (relocalise_min_side_px < 1)
    return Error{"localizer options: relocalise_min_side_px: expected >= 1"};
  if (!(track_margin_px >= 0)) return Error{"localizer options: track_margin_px: expected >= 0"};
  // track, wait_for_earlier_frames: either value.
  if (!(min_anchored_fraction >= 0 && min_anchored_fraction <= 1))
    return Error{"localizer options: min_anchored_fraction: expected in [0, 1]"};
  if (Status s = guided.Check(); !s) return s;  // guided_reanchoring: either value
  // average_anchors: either value.
  if (!(max_anchor_weight >= 1))
    return Error{"localizer options: max_anchor_weight: expected >= 1"};
  if (!(max_anchor_shift_ratio == 0 || max_anchor_shift_ratio > 1))
    return Error{"localizer options: max_anchor_shift_ratio: expected 0 or > 1"};
  if (!(min_anchor_shift_px >= 0))
    return Error{"localizer options: min_anchor_shift_px: expected >= 0"};
  if (min_anchor_history < 1)
    return Error{"localizer options: min_anchor_history: expected >= 1"};
  if (reanchor_after_gap != 0 && reanchor_after_gap < 2)
    return Error{"localizer options: reanchor_after_gap: expected 0 or >= 2"};
  if (!(step_off_shift_ratio > 1))
    return Error{"localizer options: step_off_shift_ratio: expected > 1"};
  // refind_before_relocalising: either value.
  if (Status s = coarse.Check(); !s) return s;  // correct_predictions: either value
  if (reanchor_every < 0) return Error{"localizer options: reanchor_every: expected >= 0"};
  if (reanchor_every_refined < 1)
    return Error{"localizer options: reanchor_every_refined: expected >= 1"};
  if (cold_reanchor_rounds < 0)
    return Error{"localizer options: cold_reanchor_rounds: expected >= 0"};
  if (max_correction_ahead < 1)
    return Error{"localizer options: max_correction_ahead: expected >= 1"};
  if (widen_ahead < 2) return Error{"localizer options: widen_ahead: expected >= 2"};
  if (!(min_far_track_success >= 0 && min_far_track_success <= 1))
    return Error{"localizer options: min_far_track_success: expected in [0, 1]"};
  if (far_track_probe_every < 1)
    return Error{"localizer options: far_track_probe_every: expected >= 1"};
  return Status::Ok();
}

Covariance6 ToLeftPerturbationCovariance(const PoseWithCovariance& pose) {
  Covariance6 a = Covariance6::Identity();
  a.topRightCorner<3, 3>() = Skew(pose.pose.translation());
  return a * pose.covariance * a.transpose();
}

MapLocalizerStage::MapLocalizerStage(const ReferenceMap& map, const LocalizerOptions& options)
    : map_(MapIndex::Of(map)), options_(options) {
  // One set of checks for every pose: relocalisation's RegisterFrame runs
  // them too (registration/map/frame_registration.h).
  options_.registration.checks = options_.checks;
  // The map's kd-trees before the first frame, not in its relocalisation.
  if (options_.registration.match.kd_tree_checks > 0 && map_.size() >= 2)
    map_.descriptors->Prepare(options_.registration.match.kd_trees);
  std::vector<double> v;
  for (const MapImage& image : map.images)
    for (const MapKeypoint& k : image.keypoints)
      if (k.point_id >= 0 && std::isfinite(k.virtual_depth) && k.virtual_depth > 1)
        v.push_back(k.virtual_depth);
  if (!v.empty()) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    map_virtual_depth_ = v[v.size() / 2];
  }
}

Pose MapLocalizerStage::CameraState::Predict(std::int64_t trigger) const {
  const std::int64_t step = last_trigger - previous_trigger, ahead = trigger - last_trigger;
  if (!has_previous || step <= 0 || ahead <= 0) return last;
  // A long extrapolation is worse than none.
  const double alpha = std::min(4.0, static_cast<double>(ahead) / static_cast<double>(step));
  return last * ScaledStep(previous.inverse() * last, alpha);
}

void MapLocalizerStage::MonitorChanges(const ExtrinsicsMonitorOptions& options) {
  relater_.MonitorChanges(options);
}

processing::CameraPose MapLocalizerStage::Relate(const std::string& serial,
                                                 std::int64_t /*trigger_index*/,
                                                 const processing::CameraPose& w0_from_c0,
                                                 const processing::CameraPose& w0_from_cx) {
  return relater_.Relate(serial, w0_from_c0, w0_from_cx);
}

MapLocalizerStage::Counts MapLocalizerStage::counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

std::string MapLocalizerStage::Counts::StageReport() const {
  const double n = relocalise_attempts > 0 ? static_cast<double>(relocalise_attempts) : 1.0;
  char line[384];
  std::snprintf(line, sizeof line,
                "relocalisations %lld (%lld to re-anchor tracking), per attempt: render %.0f ms, SIFT %.0f ms, matching %.0f "
                "ms, PnP %.0f ms, seeding tracks %.0f ms; %.0f matches, %.0f inliers (%.0f %%), "
                "%.1f removed by the fundamental filter",
                relocalise_attempts, reanchor_relocalised, 1e3 * render_s / n, 1e3 * sift_s / n, 1e3 * match_s / n,
                1e3 * pnp_s / n, 1e3 * retrack_s / n, relocalise_matches / n,
                relocalise_inliers / n,
                relocalise_matches > 0 ? 100.0 * relocalise_inliers / relocalise_matches : 0.0,
                fundamental_outliers / n);
  std::string out = line;
  if (guided_attempts > 0) {
    const double g = static_cast<double>(guided_attempts);
    std::snprintf(
        line, sizeof line,
        "; re-anchored by guided matching %lld of %lld attempts, per attempt: render "
        "%.0f ms, SIFT %.0f ms, matching %.1f ms (refinement included), PnP %.0f ms; %.0f "
        "matches (%.0f map points in view, %.0f refined), %.0f inliers",
        guided + cold_reanchored, guided_attempts, 1e3 * guided_render_s / g, 1e3 * guided_sift_s / g,
        1e3 * guided_match_s / g, 1e3 * guided_pnp_s / g, guided_matches / g, guided_windows / g,
        guided_refined / g, guided_inliers / g);
    out += line;
    if (!last_guided_failure.empty()) out += " (last failure: " + last_guided_failure + ")";
    std::snprintf(line, sizeof line,
                  "; frames due for re-anchoring %lld: %lld averaged into the tracks' offsets, "
                  "%lld published tracked (guided matching failed), %lld relocalised, %lld "
                  "overtaken by a later frame (taken over); relocalisations without a pose "
                  "re-anchored in their frame %lld",
                  reanchored, averaged, reanchor_kept_tracked, reanchor_relocalised,
                  late_reanchors, cold_reanchored);
    out += line;
  }
  if (corrections > 0) {
    std::snprintf(line, sizeof line,
                  "; predictions corrected by coarse guided matching after tracking failed "
                  "%lld of %lld (%.0f ms each)",
                  corrected, corrections, 1e3 * correction_s / static_cast<double>(corrections));
    out += line;
    if (!last_correction_failure.empty())
      out += " (last failure: " + last_correction_failure + ")";
  }
  if (far_attempts + far_relocalised > 0) {
    std::snprintf(line, sizeof line,
                  "; frames more than the correction's reach after their last pose: tracked %lld "
                  "of %lld attempts, %lld relocalised without an attempt",
                  far_tracked, far_attempts, far_relocalised);
    out += line;
  }
  if (refind_attempts > 0) {
    std::snprintf(line, sizeof line,
                  "; frames re-found around their prediction instead of relocalised %lld of "
                  "%lld attempts (%.0f ms each; failed: coarse %lld, fine %lld; coarse from the "
                  "last pose only %lld)",
                  refound, refind_attempts, 1e3 * refind_s / static_cast<double>(refind_attempts),
                  refind_coarse_failed, refind_fine_failed, refind_from_last);
    out += line;
  }
  if (refused_anchors > 0) {
    std::snprintf(line, sizeof line, "; anchors refused before averaging %lld (up to %.2f TF px)",
                  refused_anchors, refused_anchor_shift_px);
    out += line;
  }
  if (gap_reanchors > 0) {
    std::snprintf(line, sizeof line,
                  "; frames re-anchored at once after a gap %lld: tracked poses caught stepping "
                  "off %lld (up to %.2f TF px), guided matching failed %lld",
                  gap_reanchors, stepped_off, stepped_off_shift_px, gap_unchecked);
    out += line;
  }
  if (!last_tracking_failure.empty()) out += "; last tracking failure: " + last_tracking_failure;
  return out;
}

MapLocalizerStage::Outcome MapLocalizerStage::Track(const processing::CameraModel& camera,
                                                    const processing::TfSampler& sampler,
                                                    const ConstImageView& raw,
                                                    const CameraState& state,
                                                    std::int64_t trigger) const {
  const Pose predicted = state.Predict(trigger);
  PatchTrackOptions patches = options_.patches;
  const std::int64_t ahead = trigger - state.last_trigger;
  // No velocity yet (the frame after a relocalisation): the camera may have
  // moved the whole gap; two more levels and four times the shift (medium,
  // every 3rd trigger: that frame tracked, 0.95 mm, where one more level
  // and twice the shift followed 15 of 131 points). With a velocity only
  // one more and twice: four times let the patches lock onto a wrong pose
  // 57 mm from a good prediction (refused by the pose checks).
  if (!state.has_previous) {
    patches.levels = std::min(4, patches.levels + 2);
    patches.max_shift_px *= 4;
  } else if (ahead >= options_.widen_ahead) {
    patches.levels = std::min(4, patches.levels + 1);
    patches.max_shift_px *= 2;
  }
  Outcome out = TrackFrom(camera, sampler, raw, *state.tracks, predicted, patches);
  if (out.success || !options_.correct_predictions || ahead < 2 ||
      ahead > options_.max_correction_ahead)
    return out;
  // The prediction corrected, then tracked again from the corrected pose at
  // the usual levels and shift (tried second: when the prediction serves,
  // as it mostly does, the correction's SIFT is not paid).
  const auto start = std::chrono::steady_clock::now();
  // The corrected pose only places the patches (the tracked pose needs
  // min_tracked inliers of its own): the pose checks' minimum suffices.
  const Outcome c = GuidedSolve(camera, sampler, raw, predicted, options_.coarse,
                                /*check_jump=*/false, "correction", options_.checks.min_inliers);
  if (c.success) {
    const Pose corrected = c.w0_from_cam.pose;
    Outcome retried = TrackFrom(camera, sampler, raw, *state.tracks, c.w0_from_cam.pose,
                                options_.patches);
    if (!retried.success)
      retried.status += " (from the corrected prediction; before: " + out.status + ")";
    out = std::move(retried);
    out.corrected = corrected;
  } else {
    out.status += " (" + c.status + ")";
  }
  out.correction_s = SecondsSince(start);
  out.correction_status = c.status;
  return out;
}

MapLocalizerStage::Outcome MapLocalizerStage::TrackFrom(const processing::CameraModel& camera,
                                                        const processing::TfSampler& sampler,
                                                        const ConstImageView& raw,
                                                        const Tracks& tracks,
                                                        const Pose& predicted,
                                                        const PatchTrackOptions& patches) const {
  Outcome out;
  const Pose cam_from_w0 = predicted.inverse();
  std::vector<double> v;
  std::vector<TrackedPoint> found;
  for (const TrackedPoint& track : tracks) {
    Eigen::Vector2d predicted_tf;
    double vp = 0;
    if (!ProjectMapPoint(camera, cam_from_w0, map_.points_in_w0[track.point], &predicted_tf, &vp))
      continue;
    Eigen::Matrix2d warp = Eigen::Matrix2d::Identity();
    if (options_.warp_patches && track.template_v > 1 &&
        !PatchWarp(camera, track.template_cam_from_w0, track.template_tf, track.template_v,
                   cam_from_w0, &warp))
      warp.setIdentity();
    const PatchTrack r = TrackPatch(sampler, raw, *track.patch, predicted_tf, vp, patches, warp);
    if (!r.ok) continue;
    TrackedPoint followed = track;
    // Where its map point lies by the anchors the template has seen.
    followed.tf_px = r.tf_px - warp * track.offset;
    followed.warp = warp;
    found.push_back(std::move(followed));
    v.push_back(vp);
  }
  // The pose checks' minimum (min_tracked only makes the next frame due for
  // re-anchoring, Localize).
  const int min_ok = std::max(3, std::min(options_.min_tracked, options_.checks.min_inliers));
  if (found.size() < static_cast<std::size_t>(min_ok)) {
    out.status = "tracking: " + std::to_string(found.size()) + " of " +
                 std::to_string(tracks.size()) + " points followed (< " +
                 std::to_string(min_ok) + ")";
    return out;
  }
  return Solve(camera, sampler, found, v, predicted, "tracking", min_ok);
}

MapLocalizerStage::Outcome MapLocalizerStage::Solve(const processing::CameraModel& camera,
                                                    const processing::TfSampler& sampler,
                                                    const std::vector<TrackedPoint>& found,
                                                    const std::vector<double>& v,
                                                    const std::optional<Pose>& predicted,
                                                    const std::string& what,
                                                    int min_inliers) const {
  Outcome out;
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> tf;
  for (const TrackedPoint& f : found) {
    points.push_back(map_.points_in_w0[f.point]);
    tf.push_back(f.tf_px);
  }
  const auto pnp_start = std::chrono::steady_clock::now();
  PnpOptions pnp = options_.registration.pnp;
  pnp.final_refinement = true;
  pnp.sigma_v_relative = options_.registration.sigma_v_relative;
  const PnpResult r = EstimatePlenopticPnp(camera, {points, tf, v}, pnp);
  out.pnp_s = SecondsSince(pnp_start);
  out.inliers = static_cast<int>(r.num_inliers);
  out.rmse_px = r.rmse_px;
  if (!r.success) {
    out.status = what + ": " + r.status;
    return out;
  }
  out.w0_from_cam = Inverse(PoseWithCovariance{r.cam_from_world, r.covariance});
  std::vector<Eigen::Vector2d> inlier_tf;
  for (std::size_t i = 0; i < found.size(); ++i) {
    if (!r.inlier_mask[i]) continue;
    out.kept.push_back(found[i]);
    if (found[i].anchored) ++out.anchored_inliers;
    inlier_tf.push_back(tf[i]);
  }
  PoseEvidence evidence;
  evidence.inliers = out.inliers;
  evidence.inlier_tf_px = inlier_tf;
  evidence.tf_width = sampler.tf_width();
  evidence.tf_height = sampler.tf_height();
  evidence.rmse_px = out.rmse_px;
  evidence.covariance = ToLeftPerturbationCovariance(out.w0_from_cam);
  evidence.w0_from_cam = out.w0_from_cam.pose;
  evidence.predicted_w0_from_cam = predicted;
  out.status = CheckPose(evidence, options_.checks);
  if (out.inliers < min_inliers)
    out.status = what + ": " + std::to_string(out.inliers) + " inliers (< " +
                 std::to_string(min_inliers) + ")";
  out.success = out.status == "ok";
  return out;
}

MapLocalizerStage::Outcome MapLocalizerStage::Relocalise(const processing::CameraModel& camera,
                                                         const processing::StageFrame& frame,
                                                         const processing::TfSampler* sampler,
                                                         const CameraState& state) const {
  Outcome out;
  FrameObservations obs;
  obs.frame = frame.trigger_index;
  // The chain's TF image and depth when the frame was processed, else the
  // TF grid refocused at one virtual depth (this frame's own TF image).
  // Reused by the worker's next relocalisation.
  thread_local processing::TfImage refocused;
  const processing::TfImage* tf = nullptr;
  double render_v = map_virtual_depth_;
  int step = options_.relocalise_step;
  // The chain's TF image at its full resolution: the frame was processed
  // (block mode), which cost far more than SIFT; the tracks seeded at
  // half-resolution keypoints carry their error on (test_cli_live_registration:
  // 1.28 mm / 0.074 deg median against 0.72 mm / 0.054 deg).
  double to_tf = 1;  // rendered pixel -> TF pixel (ScaleKeypoints)
  std::optional<processing::RefocusDepths> depths;  // per region, else render_v throughout
  if (frame.products) {
    tf = &frame.products->tf;
  } else {
    step = options_.RelocaliseStep(std::max(sampler->tf_width(), sampler->tf_height()));
    to_tf = step;
    if (state.has_pose) {
      // The median virtual depth of the map points the last pose shows, and
      // per region (relocalise_refocus_cells).
      const Pose cam_from_w0 = state.last.inverse();
      std::vector<double> v;
      std::vector<Eigen::Vector2d> at;
      for (const Eigen::Vector3d& p : map_.points_in_w0) {
        Eigen::Vector2d tf_px;
        double vp = 0;
        if (ProjectMapPoint(camera, cam_from_w0, p, &tf_px, &vp) && tf_px.x() >= 0 &&
            tf_px.y() >= 0 && tf_px.x() < sampler->tf_width() && tf_px.y() < sampler->tf_height()) {
          v.push_back(vp);
          at.push_back(tf_px);
        }
      }
      if (!v.empty()) {
        std::vector<double> sorted = v;
        std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
        render_v = sorted[sorted.size() / 2];
        if (options_.relocalise_refocus_cells > 0) {
          const int cells = options_.relocalise_refocus_cells;
          const int cells_y = std::max(1, static_cast<int>(std::lround(
                                              cells * static_cast<double>(sampler->tf_height()) /
                                              sampler->tf_width())));
          depths = processing::RefocusDepths::FromPoints(
              sampler->tf_width(), sampler->tf_height(), cells, cells_y, at, v, render_v, 3);
        }
      }
    }
    const auto render_start = std::chrono::steady_clock::now();
    if (Status s = depths ? sampler->RenderAtDepths(frame.raw, *depths, step, &refocused)
                          : sampler->RenderAtDepth(frame.raw, render_v, step, &refocused);
        !s) {
      out.status = s.error().message;
      return out;
    }
    out.render_s = SecondsSince(render_start);
    tf = &refocused;
  }
  const auto sift_start = std::chrono::steady_clock::now();
  if (Status s = DetectSift(tf->View(), options_.features, &obs.features); !s) {
    out.status = s.error().message;
    return out;
  }
  if (to_tf != 1) ScaleKeypoints(to_tf, &obs.features);
  out.sift_s = SecondsSince(sift_start);
  obs.virtual_depth.resize(obs.features.keypoints.size(), std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < obs.features.keypoints.size(); ++i) {
    if (!frame.products) {
      const Eigen::Vector2f& k = obs.features.keypoints[i].xy_px;
      obs.virtual_depth[i] = depths ? depths->At(k.x(), k.y()) : render_v;
      continue;
    }
    const processing::TfDepthMap& depth = frame.products->tf_depth;
    const int u = static_cast<int>(std::lround(obs.features.keypoints[i].xy_px.x()));
    const int w = static_cast<int>(std::lround(obs.features.keypoints[i].xy_px.y()));
    if (u < 0 || w < 0 || u >= depth.width || w >= depth.height) continue;
    obs.virtual_depth[i] = depth.virtual_depth[static_cast<std::size_t>(w) * depth.width + u];
  }
  CompleteObservations(camera, &obs);
  const FrameRegistration r =
      RegisterFrame(map_, camera, obs, RegistrationMethod::kPnp, options_.registration);
  out.match_s = r.match_seconds;
  out.matches = static_cast<int>(r.matches);
  out.fundamental_outliers = std::max(0, r.fundamental_outliers);
  out.pnp_s = r.seconds - r.match_seconds;
  out.inliers = static_cast<int>(r.inliers);
  out.rmse_px = r.rmse_px;
  if (!r.success) {
    out.status = r.status;
    return out;
  }
  out.w0_from_cam = r.w0_from_cam;
  for (std::size_t i = 0; i < r.inlier_points.size(); ++i)
    out.kept.push_back({r.inlier_points[i], r.inlier_tf_px[i], nullptr, true});
  out.anchored_inliers = static_cast<int>(out.kept.size());
  PoseEvidence evidence;
  evidence.inliers = out.inliers;
  evidence.inlier_tf_px = r.inlier_tf_px;
  evidence.tf_width = sampler ? sampler->tf_width() : tf->width;
  evidence.tf_height = sampler ? sampler->tf_height() : tf->height;
  evidence.rmse_px = out.rmse_px;
  evidence.covariance = ToLeftPerturbationCovariance(out.w0_from_cam);
  evidence.w0_from_cam = out.w0_from_cam.pose;
  out.status = CheckPose(evidence, options_.checks);
  out.success = out.status == "ok";
  return out;
}

MapLocalizerStage::Outcome MapLocalizerStage::GuidedSolve(
    const processing::CameraModel& camera, const processing::TfSampler& sampler,
    const ConstImageView& raw, const Pose& guide, const GuidedMatchOptions& options,
    bool check_jump, const std::string& what, int min_inliers) const {
  Outcome out;
  const GuidedMatches g = FindGuidedMatches(map_, camera, sampler, raw, guide, options);
  out.render_s = g.render_s;
  out.sift_s = g.sift_s;
  out.match_s = g.match_s;
  out.windows = g.in_view;
  out.matches = static_cast<int>(g.points.size());
  out.refined = g.refined;
  if (g.status != "ok") {
    out.status = what + ": " + g.status;
    return out;
  }
  if (out.matches < min_inliers) {
    out.status = what + ": " + std::to_string(out.matches) + " of " + std::to_string(g.in_view) +
                 " map points in view matched (< " + std::to_string(min_inliers) + ")";
    return out;
  }
  // Every inlier anchored: its position is a SIFT keypoint matched against
  // the map, not a projection from the guiding pose.
  std::vector<TrackedPoint> found;
  for (std::size_t i = 0; i < g.points.size(); ++i)
    found.push_back({g.points[i], g.tf_px[i], nullptr, true});
  Outcome solved = Solve(camera, sampler, found, g.virtual_depth,
                         check_jump ? std::optional<Pose>(guide) : std::nullopt, what, min_inliers);
  solved.render_s = out.render_s;
  solved.sift_s = out.sift_s;
  solved.match_s = out.match_s;
  solved.windows = out.windows;
  solved.matches = out.matches;
  solved.refined = out.refined;
  return solved;
}

MapLocalizerStage::Outcome MapLocalizerStage::AverageAnchor(
    const processing::CameraModel& camera, const processing::TfSampler& sampler,
    const Outcome& tracked, const Pose& w0_from_anchor) const {
  const Pose cam_from_w0 = w0_from_anchor.inverse();
  std::vector<TrackedPoint> found;
  std::vector<double> v;
  for (TrackedPoint t : tracked.kept) {
    Eigen::Vector2d projected;
    double vp = 0;
    if (!ProjectMapPoint(camera, cam_from_w0, map_.points_in_w0[t.point], &projected, &vp))
      continue;
    // d = W^-1 (tracked - projected): this anchor's measure of the offset;
    // the offset the weighted mean of it and the anchors before (their
    // weight capped at max_anchor_weight - 1, so that the newest weighs at
    // least 1 / max_anchor_weight).
    const Eigen::Vector2d tracked_px = t.tf_px + t.warp * t.offset;
    const Eigen::Vector2d d = t.warp.inverse() * (tracked_px - projected);
    const double w = std::min(t.offset_weight, options_.max_anchor_weight - 1);
    t.offset = (w * t.offset + d) / (w + 1);
    t.offset_weight = w + 1;
    t.tf_px = tracked_px - t.warp * t.offset;
    t.anchored = true;
    found.push_back(std::move(t));
    v.push_back(vp);
  }
  return Solve(camera, sampler, found, v, w0_from_anchor, "re-anchoring (averaged)",
               std::max(3, std::min(options_.min_tracked, options_.checks.min_inliers)));
}

MapLocalizerStage::Outcome MapLocalizerStage::Refind(const processing::CameraModel& camera,
                                                     const processing::TfSampler& sampler,
                                                     const ConstImageView& raw, const Pose* guide,
                                                     bool guide_is_corrected, const Tracks* tracks,
                                                     const Pose* fallback) const {
  Pose from = guide ? *guide : Pose::Identity();
  double coarse_s = 0;
  bool from_fallback = false;
  if (!guide_is_corrected) {
    // The pose checks' minimum: this pose only guides the finer matching.
    const auto start = std::chrono::steady_clock::now();
    Outcome c;
    c.status = "re-finding (coarse): no guide";
    if (guide)
      c = GuidedSolve(camera, sampler, raw, *guide, options_.coarse, /*check_jump=*/false,
                      "re-finding (coarse)", options_.checks.min_inliers);
    if (!c.success && fallback) {
      // From the last pose (refind_from_last_pose).
      Outcome again = GuidedSolve(camera, sampler, raw, *fallback, options_.coarse,
                                  /*check_jump=*/false, "re-finding (coarse, from the last pose)",
                                  options_.checks.min_inliers);
      if (!again.success) again.status += "; " + c.status;
      c = std::move(again);
      from_fallback = c.success;
    }
    coarse_s = SecondsSince(start);
    if (!c.success) {
      c.coarse_failed = true;
      c.correction_s = coarse_s;
      return c;
    }
    from = c.w0_from_cam.pose;
    // The tracks followed from the coarse pose first (Track's correction,
    // at any distance): a tracked frame costs ~10 CPU-ms against a fine
    // guided matching's ~150 at medium, and a frame that costs several
    // frame periods leaves the next one far again.
    if (tracks && !tracks->empty()) {
      Outcome tracked = TrackFrom(camera, sampler, raw, *tracks, from, options_.patches);
      if (tracked.success) {
        tracked.correction_s = coarse_s;
        tracked.corrected = from;
        tracked.from_fallback = from_fallback;
        return tracked;
      }
    }
  }
  // Checked against the coarse pose: a fine pose far from it is wrong.
  Outcome out = GuidedSolve(camera, sampler, raw, from, options_.guided, /*check_jump=*/true,
                            "re-finding", options_.min_tracked);
  out.correction_s = coarse_s;
  out.from_fallback = from_fallback;
  return out;
}

double MapLocalizerStage::MedianShiftPx(const processing::CameraModel& camera,
                                        const std::vector<TrackedPoint>& kept,
                                        const Pose& a_w0_from_cam,
                                        const Pose& b_w0_from_cam) const {
  const Pose a = a_w0_from_cam.inverse(), b = b_w0_from_cam.inverse();
  std::vector<double> d;
  for (const TrackedPoint& k : kept) {
    Eigen::Vector2d pa, pb;
    double va = 0, vb = 0;
    if (ProjectMapPoint(camera, a, map_.points_in_w0[k.point], &pa, &va) &&
        ProjectMapPoint(camera, b, map_.points_in_w0[k.point], &pb, &vb))
      d.push_back((pa - pb).norm());
  }
  if (d.empty()) return std::numeric_limits<double>::infinity();
  std::nth_element(d.begin(), d.begin() + d.size() / 2, d.end());
  return d[d.size() / 2];
}

std::shared_ptr<const MapLocalizerStage::Tracks> MapLocalizerStage::Retrack(
    const processing::CameraModel& camera, const processing::TfSampler& sampler,
    const ConstImageView& raw, const Pose& w0_from_cam,
    const std::vector<TrackedPoint>& kept, bool relocalised, bool next_has_velocity,
    double new_weight) const {
  auto tracks = std::make_shared<Tracks>();
  const int cells = options_.track_cells;
  const int cap = (options_.max_tracks + cells * cells - 1) / (cells * cells);
  std::vector<int> in_cell(static_cast<std::size_t>(cells) * cells, 0);
  std::vector<int> tried(in_cell.size(), 0);
  const double w = sampler.tf_width(), h = sampler.tf_height(), margin = options_.track_margin_px;
  const Pose cam_from_w0 = w0_from_cam.inverse();
  std::vector<char> used(static_cast<std::size_t>(map_.size()), 0);
  // One level more than tracking uses: Track's weak predictions need it;
  // two where they can be made when the next frame has no velocity (Track),
  // else one (larger patches fail near the border and the vignetting: made
  // for every track, they left the small rig's tracks bunched in the
  // middle, 3 mm by frame 7).
  PatchTrackOptions template_options = options_.patches;
  template_options.levels = std::min(4, template_options.levels + 1);
  PatchTrackOptions coarse_options = template_options;
  coarse_options.levels = std::min(4, options_.patches.levels + (next_has_velocity ? 1 : 2));
  // Adds map point `point` seen at tf_px (virtual depth v) when its cell has
  // room, with `patch` or, when null, a template made here.
  const auto add = [&](int point, const Eigen::Vector2d& tf_px, double v,
                       std::shared_ptr<const PatchTemplate> patch, bool anchored,
                       const TrackedPoint* view) {
    if (used[point] || static_cast<int>(tracks->size()) >= options_.max_tracks) return;
    if (tf_px.x() < margin || tf_px.y() < margin || tf_px.x() >= w - margin ||
        tf_px.y() >= h - margin)
      return;
    const int cx = std::min(cells - 1, static_cast<int>(tf_px.x() / w * cells));
    const int cy = std::min(cells - 1, static_cast<int>(tf_px.y() / h * cells));
    const std::size_t cell = static_cast<std::size_t>(cy) * cells + cx;
    // Untextured candidates cost a template each: a few per cell only.
    if (in_cell[cell] >= cap || tried[cell] >= 4 * cap) return;
    ++tried[cell];
    if (!patch) {
      auto made = std::make_shared<PatchTemplate>();
      if (!MakePatchTemplate(sampler, raw, tf_px, v, coarse_options, made.get()) &&
          (coarse_options.levels == template_options.levels ||
           !MakePatchTemplate(sampler, raw, tf_px, v, template_options, made.get())))
        return;
      patch = std::move(made);
    }
    used[point] = 1;
    ++in_cell[cell];
    TrackedPoint t{point, tf_px, std::move(patch), anchored};
    if (view) {  // a kept template: the view it was made in, its offset
      t.template_cam_from_w0 = view->template_cam_from_w0;
      t.template_tf = view->template_tf;
      t.template_v = view->template_v;
      t.offset = view->offset;
      t.offset_weight = view->offset_weight;
      t.warp = view->warp;
    } else {  // made here, off its map point by the pose's error
      t.template_cam_from_w0 = cam_from_w0;
      t.template_tf = tf_px;
      t.template_v = v;
      t.offset_weight = new_weight;
    }
    tracks->push_back(std::move(t));
  };
  for (const TrackedPoint& k : kept) {
    Eigen::Vector2d projected;
    double v = 0;
    if (ProjectMapPoint(camera, cam_from_w0, map_.points_in_w0[k.point], &projected, &v))
      add(k.point, k.patch ? k.tf_px : projected, v, k.patch, k.anchored, k.patch ? &k : nullptr);
  }
  for (int j = 0; j < map_.size(); ++j) {
    if (static_cast<int>(tracks->size()) >= options_.max_tracks) break;
    Eigen::Vector2d tf_px;
    double v = 0;
    if (ProjectMapPoint(camera, cam_from_w0, map_.points_in_w0[j], &tf_px, &v))
      add(j, tf_px, v, nullptr, relocalised, nullptr);
  }
  return tracks;
}

Expected<std::optional<processing::CameraPose>> MapLocalizerStage::Localize(
    const processing::StageFrame& frame) {
  const auto start = std::chrono::steady_clock::now();
  if (!frame.camera->camera_model())
    return std::optional<processing::CameraPose>();  // no intrinsics: nothing to localise
  const processing::CameraModel& camera = *frame.camera->camera_model();
  auto sampler = frame.camera->Sampler(frame.raw);
  if (!sampler) return sampler.error();

  // With wait_for_earlier_frames the frame is in flight from here to its
  // return (the guard ends it on every path).
  struct InFlight {
    MapLocalizerStage* stage;
    const std::string& serial;
    std::multiset<std::int64_t>::iterator at;
    bool active = false;
    ~InFlight() {
      if (!active) return;
      {
        std::lock_guard<std::mutex> lock(stage->mutex_);
        stage->in_flight_[serial].erase(at);
      }
      stage->done_cv_.notify_all();
    }
  } in_flight{this, frame.serial, {}, false};
  CameraState state;
  bool can_track = false, reanchor = false;
  bool far = false;           // a far frame whose tracking is attempted
  bool far_skipped = false;   // a far frame relocalised without the attempt
  bool gap_check = false;     // re-anchored at once after a gap (reanchor_after_gap)
  {
    std::unique_lock<std::mutex> lock(mutex_);
    if (options_.wait_for_earlier_frames) {
      std::multiset<std::int64_t>& triggers = in_flight_[frame.serial];
      in_flight.at = triggers.insert(frame.trigger_index);
      in_flight.active = true;
      done_cv_.wait(lock, [&] {
        return *triggers.begin() == frame.trigger_index && !cameras_[frame.serial].relocalising;
      });
    }
    CameraState& s = cameras_[frame.serial];
    if (frame.host_ns > s.last_host_ns && frame.trigger_index <= s.last_trigger)
      s = CameraState{};  // a new pass
    can_track = s.has_pose && options_.track && s.tracks && !s.tracks->empty();
    if (can_track && frame.trigger_index - s.last_trigger > options_.max_correction_ahead) {
      FarTracking& f = far_[frame.serial];
      if (f.success < options_.min_far_track_success &&
          ++f.skipped % options_.far_track_probe_every != 0) {
        can_track = false;
        far_skipped = true;
      } else {
        far = true;
      }
    }
    // Re-anchoring when due, unless another worker relocalises the camera
    // already (then this frame tracks).
    // Sooner while the tracks average few anchors (LocalizerOptions::reanchor_every;
    // reanchor_every_refined where the re-anchoring is refined).
    const int every = options_.ReanchorEvery(
        std::max((*sampler)->tf_width(), (*sampler)->tf_height()));
    const int interval = std::min(
        every, std::max(1, static_cast<int>(options_.average_anchors ? s.anchor_weight : 1e9)));
    // Counted in frames tracked, not triggers: a camera whose frames come
    // several triggers apart (a loaded machine) would otherwise re-anchor
    // nearly every frame it gets, each re-anchoring leaving the next frame
    // further behind.
    const bool periodic = every > 0 && s.last_anchor_trigger >= 0 &&
                          s.tracked_since_anchor + 1 >= interval;
    reanchor = can_track && (s.reanchor || periodic) && !s.relocalising;
    // A frame tracked after a gap is re-anchored at once and its tracked
    // pose checked against the anchor (LocalizerOptions::reanchor_after_gap);
    // tracks begun at a relocalisation without a pose are begun anew at
    // their next re-anchoring anyway.
    gap_check = can_track && !s.relocalising && !s.cold && options_.guided_reanchoring &&
                options_.average_anchors && options_.reanchor_after_gap > 0 &&
                frame.trigger_index - s.last_trigger >= options_.reanchor_after_gap;
    reanchor = reanchor || gap_check;
    if (!can_track && s.relocalising) {
      // Published with this status (no pose): the frame was seen, not lost.
      ++counts_.skipped;
      processing::CameraPose skipped;
      skipped.method = std::string(ToString(RegistrationMethod::kPnp));
      skipped.localisation = "skipped";
      skipped.status = "not localised: camera " + frame.serial + " is being relocalised";
      return std::optional<processing::CameraPose>(skipped);
    }
    if (!can_track || reanchor) s.relocalising = true;
    state = s;
  }
  // Cleared whatever the outcome (also on an error return).
  struct Done {
    MapLocalizerStage* stage;
    const std::string& serial;
    bool active;
    ~Done() {
      if (!active) return;
      {
        std::lock_guard<std::mutex> lock(stage->mutex_);
        stage->cameras_[serial].relocalising = false;
      }
      stage->done_cv_.notify_all();
    }
  } done{this, frame.serial, !can_track || reanchor};
  Outcome r;
  std::string localisation = "relocalised";
  bool relocalised_attempt = false;  // Relocalise ran (its stages count)
  bool guided_attempt = false;       // re-anchoring's GuidedSolve ran
  Outcome guided;
  double correction_s = 0;        // Track's correction of its prediction
  std::string correction_status;  // "" when none was tried
  bool tracking_ok = false;       // Track ran and succeeded
  bool averaged = false;          // re-anchored by averaging the tracks' offsets
  bool kept_tracked = false;      // due for re-anchoring, published tracked
  bool cold_reanchored = false;   // a relocalisation without a pose, re-anchored here
  int relocalised_inliers = -1;   // then the relocalisation's inliers (Counts)
  bool refind_attempt = false, refound = false;  // LocalizerOptions::refind_before_relocalising
  bool refind_from_last = false;  // its coarse matching succeeded from the last pose only
  double refind_s = 0;
  bool anchor_refused = false;     // a bad anchor refused (max_anchor_shift_ratio)
  bool stepped_off = false;        // gap_check: the tracked pose stepped off, the anchor published
  bool keep_tracks = false;        // the tracks go on as before the frame (gap_check)
  double anchor_shift_px = -1;     // an averaged anchor's shift against the tracked pose
  // A frame whose tracking failed (`attempt`: its outcome, "not run" for a
  // far frame relocalised without the attempt) re-found around its
  // prediction before a relocalisation; true when it was.
  const auto try_refind = [&](const Outcome& attempt) {
    if (!options_.refind_before_relocalising || !options_.track || !state.has_pose) return false;
    // Track's correction was that coarse matching from the prediction, and
    // it failed: only the last pose is left to try (refind_from_last_pose).
    const bool correction_failed = !attempt.corrected && !attempt.correction_status.empty() &&
                                   attempt.correction_status != "ok";
    // The prediction is the last pose without a previous one.
    const bool last_differs = options_.refind_from_last_pose && state.has_previous;
    if (correction_failed && !last_differs) return false;
    const auto refind_start = std::chrono::steady_clock::now();
    refind_attempt = true;
    const bool corrected = attempt.corrected.has_value();
    const Pose guide =
        corrected ? *attempt.corrected : state.Predict(frame.trigger_index);
    Outcome found = Refind(camera, **sampler, frame.raw, correction_failed ? nullptr : &guide,
                           corrected, state.tracks.get(), last_differs ? &state.last : nullptr);
    refind_s = SecondsSince(refind_start);
    refind_from_last = found.from_fallback;
    if (!found.success) {
      std::lock_guard<std::mutex> lock(mutex_);
      counts_.last_guided_failure = found.status;
      if (found.coarse_failed)
        ++counts_.refind_coarse_failed;
      else
        ++counts_.refind_fine_failed;
      return false;
    }
    // Tracked from the coarse pose (`corrected` set), else re-anchored.
    const bool tracked_from_coarse = found.corrected.has_value() && !corrected;
    if (!tracked_from_coarse) {
      guided_attempt = true;
      guided = found;
    }
    r = std::move(found);
    localisation = tracked_from_coarse ? "tracked" : "re-anchored";
    refound = true;
    return true;
  };
  if (reanchor) {
    // Tracked first; its pose guides the matching against the map
    // (guided_matches.h): an absolute pose at a fraction of a
    // relocalisation's cost. When that fails the tracked pose (it passed
    // every check; re-anchoring is due again at the next frame); relocalised
    // when tracking failed.
    Outcome tracked = Track(camera, **sampler, frame.raw, state, frame.trigger_index);
    tracking_ok = tracked.success;
    correction_s = tracked.correction_s;
    correction_status = tracked.correction_status;
    if (!tracked.success) {
      std::lock_guard<std::mutex> lock(mutex_);
      counts_.last_tracking_failure = tracked.status + " (a frame due for re-anchoring)";
    }
    if (tracked.success && options_.guided_reanchoring) {
      guided_attempt = true;
      guided = GuidedSolve(camera, **sampler, frame.raw, tracked.w0_from_cam.pose,
                           options_.guided, /*check_jump=*/true, "re-anchoring",
                           options_.min_tracked);
      // A bad anchor refused before it is averaged (max_anchor_shift_ratio):
      // its shift against the tracked pose against the camera's accepted
      // anchors'; never twice in a row (the tracked pose may be the one off).
      if (guided.success && options_.average_anchors && !state.cold) {
        anchor_shift_px = MedianShiftPx(camera, tracked.kept, tracked.w0_from_cam.pose,
                                        guided.w0_from_cam.pose);
        if (gap_check) {
          // After a gap the tracked pose is the one in doubt: an anchor
          // beyond the camera's anchors' spread says it stepped off.
          if (state.anchor_history >= options_.min_anchor_history) {
            const double rms = std::sqrt(state.anchor_shift2_sum / state.anchor_history);
            const double limit =
                std::max(options_.min_anchor_shift_px, options_.step_off_shift_ratio * rms);
            stepped_off = !(anchor_shift_px <= limit);
          }
        } else if (options_.max_anchor_shift_ratio > 0 &&
                   state.anchor_history >= options_.min_anchor_history &&
                   !state.last_anchor_refused) {
          const double rms = std::sqrt(state.anchor_shift2_sum / state.anchor_history);
          const double limit =
              std::max(options_.min_anchor_shift_px, options_.max_anchor_shift_ratio * rms);
          anchor_refused = !(anchor_shift_px <= limit);
        }
      }
      if (guided.success && stepped_off) {
        // The anchor's own pose; the tracked positions (and any template
        // they would make) are dropped, the tracks' offsets kept.
        r = guided;
        localisation = "re-anchored";
        keep_tracks = true;
      } else if (guided.success && !anchor_refused) {
        r = guided;
        localisation = "re-anchored";
        if (options_.average_anchors && !state.cold) {
          Outcome mean = AverageAnchor(camera, **sampler, tracked, guided.w0_from_cam.pose);
          if (mean.success) {
            mean.render_s = guided.render_s;
            mean.sift_s = guided.sift_s;
            mean.match_s = guided.match_s;
            mean.windows = guided.windows;
            mean.matches = guided.matches;
            r = std::move(mean);
            averaged = true;
          }
        }
      } else if (tracked.success) {
        r = std::move(tracked);
        localisation = "tracked";
        kept_tracked = true;
        // After a gap, unchecked: it seeds no templates (and re-anchoring
        // is due at the next frame, below).
        keep_tracks = gap_check;
      }
    }
    if (localisation == "relocalised" && !tracked.success) try_refind(tracked);
    if (localisation == "relocalised") {
      relocalised_attempt = true;
      r = Relocalise(camera, frame, *sampler, state);
      if (!r.success && tracked.success) {
        // The relocalisation's stages still count (Counts::StageReport).
        tracked.render_s = r.render_s;
        tracked.sift_s = r.sift_s;
        tracked.match_s = r.match_s;
        tracked.pnp_s = r.pnp_s;
        tracked.matches = r.matches;
        tracked.fundamental_outliers = r.fundamental_outliers;
        r = std::move(tracked);
        localisation = "tracked";
      } else if (!r.success) {
        r.status += " (re-anchoring; tracking: " + tracked.status + ")";
      }
    }
  } else if (can_track) {
    r = Track(camera, **sampler, frame.raw, state, frame.trigger_index);
    tracking_ok = r.success;
    correction_s = r.correction_s;
    correction_status = r.correction_status;
    if (r.success) localisation = "tracked";
  }
  if (!r.success && !reanchor) {
    if (r.status != "not run") {
      std::lock_guard<std::mutex> lock(mutex_);
      counts_.last_tracking_failure = r.status;
    }
  }
  if (!r.success && !reanchor && try_refind(r)) {
    // re-found: r is its pose
  } else if (!r.success && !reanchor) {
    relocalised_attempt = true;
    Outcome relocalised = Relocalise(camera, frame, *sampler, state);
    // A refused or failed relocalisation says why tracking did not serve either.
    if (!relocalised.success && localisation == "relocalised" && r.status != "not run")
      relocalised.status += " (after " + r.status + ")";
    r = std::move(relocalised);
  }
  // A relocalisation without a pose rendered the whole grid at one depth:
  // re-anchored here from its pose, on a render refocused per region, so
  // that the tracks begin at a pose measured in focus (the first frames'
  // error otherwise stays until the next re-anchoring).
  // Each round guided from the last one's pose (LocalizerOptions::cold_reanchor_rounds).
  for (int round = 0; round < options_.cold_reanchor_rounds && r.success &&
                      localisation == "relocalised" && !state.has_pose && !frame.products &&
                      options_.relocalise_refocus_cells > 0 && options_.guided_reanchoring;
       ++round) {
    guided_attempt = true;
    guided = GuidedSolve(camera, **sampler, frame.raw, r.w0_from_cam.pose, options_.guided,
                         /*check_jump=*/true, "re-anchoring", options_.min_tracked);
    if (!guided.success) break;
    if (relocalised_inliers < 0) relocalised_inliers = r.inliers;
    r.w0_from_cam = guided.w0_from_cam;
    r.inliers = guided.inliers;
    r.rmse_px = guided.rmse_px;
    r.kept = guided.kept;
    r.anchored_inliers = guided.anchored_inliers;
    r.status = guided.status;
    cold_reanchored = true;
  }
  double retrack_s = 0;
  std::shared_ptr<const Tracks> tracks;
  double weight = 1;  // the anchors the pose averages (Retrack's new_weight)
  if (r.success && options_.track) {
    const auto retrack_start = std::chrono::steady_clock::now();
    // Tracked inliers go on with their templates. A relocalised frame's
    // tracks begin at their map points' projections from the relocalised
    // pose (the inliers first): a track keeps the error of the position its
    // template was made at for as long as it lives, and the pose from all
    // the relocalisation's inliers is better than the few hundred SIFT
    // keypoints the tracks would otherwise keep (test_map_localizer small
    // 0.954 -> 0.631 mm median; the demo's sequence on its ground-truth map,
    // c0_from_cx wander 1.88 -> 1.24 mm RMS in one replay each; with
    // calibrate's map, three replays each, within the runs' spread:
    // corrected absolute 2.18 against 2.26 mm, wander 1.69 against 1.85).
    // When templates were re-made every frame it was the other way round
    // (medium 2.2 against 1.7 mm).
    // Re-anchored tracks begin at projections from an absolute pose, as
    // relocalised ones do.
    // New tracks made from a tracked or averaged pose weigh as the anchors
    // it averages (the mean of its inliers' weights); from a single absolute
    // pose, 1.
    if (localisation == "tracked" || averaged) {
      double sum = 0;
      for (const TrackedPoint& k : r.kept) sum += k.offset_weight;
      if (!r.kept.empty()) weight = sum / static_cast<double>(r.kept.size());
    }
    if (keep_tracks) {
      // A stepped-off or unchecked pose after a gap (reanchor_after_gap):
      // the tracks as they were before the frame, their weight with them.
      tracks = state.tracks;
      weight = state.anchor_weight;
    } else {
      tracks = Retrack(camera, **sampler, frame.raw, r.w0_from_cam.pose, r.kept,
                       localisation != "tracked", state.has_pose, weight);
    }
    retrack_s = SecondsSince(retrack_start);
  }

  processing::CameraPose pose;
  pose.method = std::string(ToString(RegistrationMethod::kPnp));
  pose.localisation = localisation;
  pose.inliers = r.inliers;
  pose.rmse_px = r.rmse_px;
  pose.status = r.status;
  const double seconds = SecondsSince(start);
  std::lock_guard<std::mutex> lock(mutex_);
  if (reanchor) {
    ++counts_.reanchored;
    if (relocalised_attempt) ++counts_.reanchor_relocalised;
    if (kept_tracked) ++counts_.reanchor_kept_tracked;
  }
  if (averaged) ++counts_.averaged;
  if (gap_check) {
    ++counts_.gap_reanchors;
    if (stepped_off && localisation == "re-anchored") {
      ++counts_.stepped_off;
      counts_.stepped_off_shift_px = std::max(counts_.stepped_off_shift_px, anchor_shift_px);
    }
    if (keep_tracks && localisation == "tracked") ++counts_.gap_unchecked;
  }
  if (anchor_refused) {
    ++counts_.refused_anchors;
    counts_.refused_anchor_shift_px = std::max(counts_.refused_anchor_shift_px, anchor_shift_px);
  }
  if (refind_attempt) {
    ++counts_.refind_attempts;
    counts_.refind_s += refind_s;
    if (refound) ++counts_.refound;
    if (refind_from_last) ++counts_.refind_from_last;
  }
  if (cold_reanchored) ++counts_.cold_reanchored;
  if (far_skipped) ++counts_.far_relocalised;
  if (far) {
    // Each attempt weighs 1/4 (LocalizerOptions::min_far_track_success).
    FarTracking& f = far_[frame.serial];
    f.success = 0.75 * f.success + 0.25 * (tracking_ok ? 1.0 : 0.0);
    ++counts_.far_attempts;
    if (tracking_ok) ++counts_.far_tracked;
  }
  if (!correction_status.empty()) {
    ++counts_.corrections;
    counts_.correction_s += correction_s;
    if (correction_status == "ok")
      ++counts_.corrected;
    else
      counts_.last_correction_failure = correction_status;
  }
  if (guided_attempt) {
    ++counts_.guided_attempts;
    counts_.guided_render_s += guided.render_s;
    counts_.guided_sift_s += guided.sift_s;
    counts_.guided_match_s += guided.match_s;
    counts_.guided_pnp_s += guided.pnp_s;
    counts_.guided_windows += guided.windows;
    counts_.guided_matches += guided.matches;
    counts_.guided_inliers += guided.inliers;
    counts_.guided_refined += guided.refined;
    if (!guided.success) counts_.last_guided_failure = guided.status;
  }
  if (relocalised_attempt) {
    ++counts_.relocalise_attempts;
    counts_.render_s += r.render_s;
    counts_.sift_s += r.sift_s;
    counts_.match_s += r.match_s;
    counts_.pnp_s += r.pnp_s;
    counts_.retrack_s += retrack_s;
    counts_.relocalise_matches += r.matches;
    counts_.relocalise_inliers += relocalised_inliers >= 0 ? relocalised_inliers : r.inliers;
    counts_.fundamental_outliers += r.fundamental_outliers;
  }
  CameraState& s = cameras_[frame.serial];
  const bool newest = frame.host_ns >= s.last_host_ns && frame.trigger_index > s.last_trigger;
  // A re-anchoring that a later frame of its camera overtook (tracked from
  // the state before it, on another worker): its measurement is not thrown
  // away. Averaged, its offsets go to the same templates among the camera's
  // tracks; begun anew, its tracks replace the camera's (each template
  // keeps the view it was made in, so a later prediction tracks them).
  if (r.success && !newest && localisation == "re-anchored" && !keep_tracks && tracks &&
      s.has_pose &&
      s.tracks && frame.trigger_index < s.last_trigger && frame.trigger_index + 8 >= s.last_trigger) {
    ++counts_.late_reanchors;
    if (averaged) {
      std::map<const PatchTemplate*, const TrackedPoint*> measured;
      for (const TrackedPoint& t : *tracks) measured[t.patch.get()] = &t;
      auto merged = std::make_shared<Tracks>(*s.tracks);
      for (TrackedPoint& t : *merged) {
        const auto it = measured.find(t.patch.get());
        if (it == measured.end()) continue;
        t.offset = it->second->offset;
        t.offset_weight = it->second->offset_weight;
        t.anchored = it->second->anchored;
      }
      s.tracks = std::move(merged);
    } else {
      s.tracks = tracks;
      s.cold = false;
    }
    s.reanchor = false;
  }
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
  } else if (localisation == "re-anchored") {
    ++counts_.guided;
    counts_.guided_s += seconds;
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
    s.tracks = std::move(tracks);
    if (localisation != "tracked") s.last_anchor_trigger = frame.trigger_index;
    s.tracked_since_anchor = localisation == "tracked" ? s.tracked_since_anchor + 1 : 0;
    s.anchor_weight = weight;
    // Re-anchored next frame: a tracked pose with too few anchored inliers
    // (min_anchored_fraction), or a relocalisation without a pose to refocus
    // its render per region (the map's median depth throughout), so that the
    // tracks are soon seeded from a pose measured in focus.
    // Re-anchored in its frame or not, a relocalisation without a pose is
    // re-anchored anew at the next frame too: at r32 the frame's own guided
    // matching, even iterated from its pose, left trigger 0 at 1.28 mm (2.96
    // relocalised), where the next trigger's re-anchoring from its tracked
    // pose came to 0.26 mm (test_map_localizer, 8 triggers).
    const bool cold = localisation == "relocalised" && !state.has_pose && !frame.products &&
                      options_.relocalise_refocus_cells > 0;
    s.cold = cold || (localisation == "tracked" && state.cold);
    // Or one with fewer than min_tracked inliers, or whose anchor was refused.
    s.reanchor = cold || anchor_refused || (keep_tracks && localisation == "tracked") ||
                 (localisation == "tracked" &&
                  (r.anchored_inliers < options_.min_anchored_fraction * r.inliers ||
                   r.inliers < options_.min_tracked));
    // The anchors' shifts against the tracked poses (max_anchor_shift_ratio),
    // from the last relocalisation on.
    if (localisation == "relocalised") {
      s.anchor_history = 0;
      s.anchor_shift2_sum = 0;
    } else if (averaged && !stepped_off && anchor_shift_px >= 0 &&
               std::isfinite(anchor_shift_px)) {
      ++s.anchor_history;
      s.anchor_shift2_sum += anchor_shift_px * anchor_shift_px;
    }
    s.last_anchor_refused = anchor_refused;
  }
  pose.transform = r.w0_from_cam.pose;
  pose.covariance = ToLeftPerturbationCovariance(r.w0_from_cam);
  return std::optional<processing::CameraPose>(pose);
}

}  // namespace lifmcr::registration
