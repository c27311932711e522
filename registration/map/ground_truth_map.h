#pragma once
// A reference map made from a synthetic sequence's ground truth, for
// measuring registration apart from calibration: camera `serial`'s
// keypoints on its ground-truth TF images (registration/features/frame_observations.h),
// back-projected with the ground-truth depth and placed by the ground-truth
// world_from_cam, so w0 is the world (plate) frame and w0_from_c0 is exact.
// A keypoint of a later frame that matches an existing point (ratio and cross
// check) and lands within merge_distance_mm of it joins that point's track
// instead of making a second point with the same descriptor (which would
// fail every later ratio test).

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
  Status Check() const;            // every field (features, match: their own); the message names it
};

Expected<ReferenceMap> BuildGroundTruthMap(const std::filesystem::path& sequence_dir,
                                           const std::string& serial,
                                           const std::vector<std::int64_t>& frames,
                                           const processing::CameraModel& camera,
                                           const GroundTruthMapOptions& options);

}  // namespace lifmcr::registration
