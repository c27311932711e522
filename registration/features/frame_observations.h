#pragma once
// What registration needs of one frame of one camera: SIFT keypoints on the
// totally focused (TF) image with their descriptors, the virtual depth there
// and the back-projected camera point (mm). PnP uses the keypoints and
// virtual depths, the 3D RANSAC the camera points (with the plenoptic
// uncertainty of registration/estimators/rigid_3d.h).
//
// Sources:
//   raw           the raw frame through processing/ (devignetting, virtual
//                 depth, TF depth and image) and SIFT: the calibration's frame
//                 loader (registration/features/calibration_frames.h), as in use.
//   ground truth  a synthetic sequence's GroundTruth/all_in_focus image (the
//                 exact TF grid) and GroundTruth/depth/*_depth_mm.tiff (camera
//                 z on the TF grid, v = CameraModel::VirtualDepthOfDepth):
//                 registration measured apart from depth estimation.
// A keypoint takes the depth at its position (the TF depth map's nearest
// pixel for raw frames, bilinear in the exact ground truth); one without depth
// (NaN) is used by PnP for scoring only and not by the 3D RANSAC.

#include "config/error.h"
#include "processing/camera_model.h"
#include "registration/features/features.h"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct FrameObservations {
  std::int64_t frame = 0;
  Features features;                      // on the TF grid
  std::vector<Eigen::Vector2d> tf_px;     // keypoint positions (TF pixels)
  std::vector<double> virtual_depth;      // NaN where unknown
  std::vector<Eigen::Vector3d> p_in_cam;  // back-projected (mm), NaN where unknown
  double seconds = 0;                     // time to make them
};

// tf_px and p_in_cam from features and virtual_depth (already filled).
void CompleteObservations(const processing::CameraModel& camera, FrameObservations* frame);

enum class ObservationSource { kRaw, kGroundTruth };

// Frames of one camera of a sequence, from either source.
class FrameObserver {
 public:
  // `plate_yaml` (may be empty) names a file with a `plate:` section; the
  // raw source reads the white image and MLA file of the dataset's
  // Calibration folder once.
  static Expected<std::unique_ptr<FrameObserver>> Open(ObservationSource source,
                                                       const std::filesystem::path& sequence_dir,
                                                       const std::string& serial,
                                                       const processing::CameraModel& camera,
                                                       const std::filesystem::path& plate_yaml,
                                                       const FeatureOptions& features);
  virtual ~FrameObserver() = default;
  // Frames the camera has, ascending.
  virtual const std::vector<std::int64_t>& frames() const = 0;
  // Errors name the file.
  virtual Expected<FrameObservations> Observe(std::int64_t frame) = 0;
};

}  // namespace lifmcr::registration
