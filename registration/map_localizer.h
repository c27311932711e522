#pragma once
// The live registration stage (processing/registration_stage.h) of the
// pipeline: a per-camera localizer against camera 0's reference map, for
// camera 0 and every camera X.
//
// Per frame of a camera: SIFT on the processed TF image, each keypoint's
// virtual depth from the TF depth map (registration/frame_observations.h),
// then
//   track        when the camera has a pose: the pose is predicted by constant
//                velocity, w_pred = w_last (w_prev^-1 w_last) (w = w0_from_cam;
//                for a step of as many triggers as the last one),
//                the map's points are projected with it (registration/tf_projection.h),
//                and each keypoint is matched only against the points projected
//                within track_radius_px of it (ratio test among those). PnP
//                then needs few trials (the inlier ratio is high).
//   relocalise   otherwise, or when tracking finds fewer than min_tracked
//                inliers: global matching against every map point (ratio and
//                cross check) and full LO-RANSAC PnP.
// The pose carries `method` "pnp", `localisation` "tracked" or "relocalised" and the
// covariance in the stage's convention (a left SE(3) perturbation, (t, r)),
// converted from pose_covariance.h's (additive translation):
//   rho = dt + [t]x dr   (t the translation of w0_from_cam),
// so Sigma_stage = A Sigma A^T, A = [[I, [t]x], [0, I]].
// SIFT detection still runs on the whole TF image; tracking saves the global
// matching and most RANSAC trials, not the detection.

#include "processing/registration_stage.h"
#include "registration/extrinsics_monitor.h"
#include "registration/frame_registration.h"
#include "registration/reference_map.h"

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>

namespace lifmcr::registration {

struct LocalizerOptions {
  // The strongest 4000 keypoints per frame, as `lifmcr register` keeps: all
  // of a medium TF image's (tens of thousands) made a relocalisation's
  // global matching take 100 s on 2 loaded cores (bench_live).
  LocalizerOptions() { features.max_features = 4000; }
  FrameRegistrationOptions registration;
  FeatureOptions features;
  double track_radius_px = 12;  // local matching window on the TF grid (> 0)
  int min_tracked = 30;         // fewer inliers when tracking: relocalise (>= 3)
  bool track = true;            // false: relocalise every frame (the baseline of bench_live)
  Status Check() const;
};

class MapLocalizerStage final : public processing::RegistrationStage {
 public:
  MapLocalizerStage(const ReferenceMap& map, const LocalizerOptions& options);
  std::string name() const override { return "map-localizer"; }
  Expected<std::optional<processing::CameraPose>> Localize(
      const processing::StageFrame& frame) override;
  // The composition, then, with MonitorChanges, the change detection's verdict.
  processing::CameraPose Relate(const std::string& serial, std::int64_t trigger_index,
                                const processing::CameraPose& w0_from_c0,
                                const processing::CameraPose& w0_from_cx) override;
  // Rigidly mounted cameras: every c0_from_cx goes through change detection
  // (registration/extrinsics_monitor.h). Before the first frame.
  void MonitorChanges(const ExtrinsicsMonitorOptions& options);

  // Frames tracked and relocalised so far (all cameras).
  struct Counts {
    long long tracked = 0, relocalised = 0, failed = 0;
    // Localize's time (features, matching, PnP) of the frames so counted; a
    // frame whose tracking failed pays both and counts as relocalised.
    double tracked_s = 0, relocalised_s = 0, failed_s = 0;
  };
  Counts counts() const;

 private:
  // The camera's newest poses. Frames of one camera may be localised
  // concurrently and finish out of order: a frame that reached the host
  // before the last one that set the state (host_ns) never replaces it. A
  // frame that reached the host later but has a lower trigger index starts a
  // new pass (replay --loop numbers its triggers from 0 again): the state is
  // dropped, the frame relocalised.
  struct CameraState {
    bool has_pose = false;
    Pose last = Pose::Identity(), previous = Pose::Identity();
    std::int64_t last_trigger = -1, previous_trigger = -1;
    std::int64_t last_host_ns = 0;
    bool has_previous = false;
    // Prediction for `trigger`: constant velocity when the step from the
    // previous pose to the last spans as many triggers as the step ahead
    // (w_pred = w_last (w_prev^-1 w_last)), else the last pose.
    Pose Predict(std::int64_t trigger) const;
  };
  FrameRegistration Track(const processing::CameraModel& camera, const FrameObservations& obs,
                          const Pose& predicted_w0_from_cam) const;

  MapIndex map_;
  std::optional<ExtrinsicsMonitor> monitor_;  // Relate's thread only
  LocalizerOptions options_;
  mutable std::mutex mutex_;
  std::map<std::string, CameraState> cameras_;
  Counts counts_;
};

// Localizer covariance (pose_covariance.h) -> the stage's convention (comment above).
Covariance6 ToLeftPerturbationCovariance(const PoseWithCovariance& pose);

}  // namespace lifmcr::registration
