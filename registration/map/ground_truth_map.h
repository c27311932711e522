#pragma once
// A reference map made from a synthetic sequence's ground truth, for
// measuring registration apart from calibration: camera `serial`'s
// keypoints on its ground-truth TF images (registration/features/frame_observations.h),
// back-projected with the ground-truth depth and placed by the ground-truth
// world_from_cam, so w0 is the world (plate) frame and w0_from_c0 is exact.
//
// Tracks by the known poses: every point of the map so far is projected
// into the next frame (its true pose); a keypoint continues the point
// projected within track_radius_px of it whose position lies within
// merge_distance_mm of the keypoint's own back-projection (so a point
// hidden behind nearer texture is not continued), the candidate with the
// nearest descriptor (to any of the point's observations) when it passes
// the ratio test against the next candidate (match.ratio) and, with
// match.max_distance > 0, that bound. A point takes at most one keypoint
// per frame (the nearest descriptor). Matching descriptors against the whole
// map instead fails where a point looks alike from two frames' views: its
// second observation makes a near-duplicate point, and every later ratio
// test between the two fails, so a map of many frames of the same scene
// holds the same texture several times, none of it matchable.
// What a map point then is, over its track of observations x_k (each a
// back-projection of a keypoint with its exact depth, in w0):
//   position    their mean: each is a point of the surface under its own
//               keypoint, off the feature by that keypoint's localisation
//               error in its own view; the mean of n views averages the
//               errors of the views that differ (a single frame's point
//               carries its one keypoint's error into every other view);
//               observations more than merge_distance_mm / 2 from the
//               track's component-wise median are left out of the mean;
//   descriptor  the track's medoid (the observation whose descriptor has
//               the least sum of distances to the others'), the appearance
//               nearest to all views it was seen in, as ORB-SLAM keeps one
//               descriptor per map point.
// `match`: only its ratio and max_distance are read (the candidates come
// from the projection, not from a descriptor search).

#include "config/error.h"
#include "processing/camera_model.h"
#include "registration/features/features.h"
#include "registration/map/reference_map.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct GroundTruthMapOptions {
  FeatureOptions features;
  MatchOptions match;
  double merge_distance_mm = 5.0;  // > 0
  double track_radius_px = 3.0;    // TF px, > 0
  Status Check() const;            // every field (features, match: their own); the message names it
};

Expected<ReferenceMap> BuildGroundTruthMap(const std::filesystem::path& sequence_dir,
                                           const std::string& serial,
                                           const std::vector<std::int64_t>& frames,
                                           const processing::CameraModel& camera,
                                           const GroundTruthMapOptions& options);

}  // namespace lifmcr::registration
