#pragma once
// One frame of one camera against the reference map: descriptor matching
// (kNN with Lowe's ratio and a cross check, as the paper's PnP method;
// registration/features/features.h), then either estimator:
//   pnp     plenoptic PnP (registration/estimators/pnp.h) on the matched map points and
//           TF keypoints: cam_from_w0, inverted to w0_from_cam;
//   ransac  3D RANSAC (registration/estimators/rigid_3d.h) on the matched map points and
//           the frame's back-projected points, each with the plenoptic
//           uncertainty of its virtual depth: w0_from_cam directly.
// The result carries w0_from_cam with its 6x6 covariance, the inliers and the
// RMS reprojection error of the inliers in TF pixels (for both methods, so
// that registration.csv compares them).

#include "config/error.h"
#include "processing/camera_model.h"
#include "registration/features/features.h"
#include "registration/features/frame_observations.h"
#include "registration/features/fundamental_filter.h"
#include "registration/estimators/pnp.h"
#include "registration/estimators/pose_checks.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/map/reference_map.h"
#include "registration/estimators/rigid_3d.h"

#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::registration {

enum class RegistrationMethod { kPnp, kRansac3d };
std::string_view ToString(RegistrationMethod method);  // "pnp", "ransac"
std::optional<RegistrationMethod> ParseRegistrationMethod(std::string_view name);

// The map's points and descriptors in the buffers matching needs: one
// contiguous P x 128 copy of the descriptors (the map keeps one vector per
// point) with its kd-trees (built at the first approximate match and kept:
// features.h), made once per map and shared by the copies of the index.
// Each point's observations (keyframe, TF keypoint) for the fundamental
// filter: point j's are observations[observation_begin[j] ..
// observation_begin[j + 1]).
struct MapIndex {
  struct Observation {
    int image = 0;  // index into ReferenceMap::images
    Eigen::Vector2f tf_px = Eigen::Vector2f::Zero();
  };
  std::vector<Eigen::Vector3d> points_in_w0;
  std::shared_ptr<const DescriptorIndex> descriptors;
  std::vector<int> observation_begin;  // size() + 1
  std::vector<Observation> observations;
  int images = 0;
  int size() const { return static_cast<int>(points_in_w0.size()); }
  static MapIndex Of(const ReferenceMap& map);
};

struct FrameRegistrationOptions {
  // The map's kd-forest (MapMatching(), features.h); ExactMatching() for
  // brute force, the reference (`lifmcr register --matching exact`).
  MatchOptions match = MapMatching();
  // PnP only: the matches first checked against a fundamental matrix with
  // the map keyframe that saw most of the matched points (off here; the
  // live localizer turns it on: registration/live/map_localizer.h says why).
  FundamentalFilterOptions fundamental;
  PnpOptions pnp;
  Rigid3dOptions rigid;
  // Virtual-depth noise / v (processing: median 0.69 %), > 0: the 3D
  // RANSAC's point covariances and PnP's sample check (it replaces
  // pnp.sigma_v_relative).
  double sigma_v_relative = 0.007;
  double sigma_tf_px = 0.3;         // keypoint noise on the TF grid (px), > 0
  // PnP: guided re-matching. The descriptor search against the whole map
  // keeps a keypoint only when its nearest map point is much nearer than
  // the second (the ratio test): a view far from the map's, whose
  // descriptors have changed, keeps few, and a pose from few matches
  // bunched in part of the image is refused (pose_checks.h) or inaccurate.
  // With a first pose, each map point it projects into the image is a
  // candidate only for the keypoints within guided_radius_px of its
  // projection, and the ratio test is taken among those candidates
  // (guided_ratio): the rest of the map no longer competes, so the same
  // keypoints find their points where the global test could not tell them
  // apart. Each point keeps its nearest keypoint; the pose's inliers not
  // matched so join them; PnP runs again (LO-RANSAC from scratch) on them.
  // Only for a pose the checks refuse, up to guided_rounds times until one
  // passes: the guided matches add weaker keypoints, so a pose the search
  // alone already supports is no better with them (docs/registration.md).
  // 0: off, the live localizer's default (its relocalisations are followed
  // by tracking).
  int guided_rounds = 0;          // >= 0
  double guided_radius_px = 4.0;  // TF px, > 0
  double guided_ratio = 0.8;      // (0, 1]
  // The checks every PnP pose passes (pose_checks.h; its depth check with
  // sigma_v_relative); a pose that fails is returned with success false and
  // the reason as status.
  PoseCheckOptions checks;
  Status Check() const;
};

struct FrameRegistration {
  bool success = false;
  std::string status = "not run";  // "ok" or why it failed
  PoseWithCovariance w0_from_cam;
  std::size_t matches = 0;
  int guided_matches = -1;  // of the last guided round (-1: none ran)
  std::size_t inliers = 0;
  double rmse_px = 0;
  double seconds = 0;        // matching and estimation
  double match_seconds = 0;  // of which matching (and the fundamental filter)
  int fundamental_outliers = -1;  // matches the fundamental filter removed; -1: not applied
  // PnP: the inliers' map points (MapIndex order) and TF keypoints.
  std::vector<int> inlier_points;
  std::vector<Eigen::Vector2d> inlier_tf_px;
  std::vector<int> inlier_queries;  // the inliers' keypoints (FrameObservations order)
  // PnP: what the pose checks measured; `estimated` is true when the
  // estimator returned a pose, which w0_from_cam then holds even if the
  // checks refused it (for reports against a ground truth).
  PoseCheckFigures checks;
  bool estimated = false;
  // "pnp ok: 412 inliers of 655 matches, rmse 0.42 px, 12.3 ms".
  std::string BriefReport(RegistrationMethod method) const;
};

FrameRegistration RegisterFrame(const MapIndex& map, const processing::CameraModel& camera,
                                const FrameObservations& frame, RegistrationMethod method,
                                const FrameRegistrationOptions& options);

}  // namespace lifmcr::registration
