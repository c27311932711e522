#pragma once
// The plate's ArUco corners as camera 0 saw them during calibration, and the
// marker centres they give in the map frame: the map side of the plate
// alignment (evaluation/plate_alignment.h), so that `lifmcr evaluate
// --map DIR` needs no hand-made centres.
//
// `lifmcr calibrate` writes DIR/aruco_corners.csv beside the map:
//   frame,marker_id,corner,tf_x_px,tf_y_px,virtual_depth
// one row per corner detected (registration/features/aruco_plate.h) in a frame it
// placed, on the TF grid, with the measured virtual depth under the corner
// (empty when the depth map had none).
//
// Triangulation. Each observation is a ray from the main-lens centre of its
// frame: the corner's virtual point (x_v, v) back-projected through the
// plenoptic model (processing/camera_model.h) gives its direction d in the
// camera frame (the direction depends on v through b_L = b_L0 + v B, so an
// observation without a virtual depth is left out), and w0_from_c0 of the
// frame carries it into the map. A corner seen in two or more frames is the
// point nearest all its rays in the least-squares sense,
//   p = (sum_i (I - d_i d_i^T))^-1 sum_i (I - d_i d_i^T) o_i,
// and its residual is the RMS distance of the rays from p. A marker's centre
// is the mean of its four corners; every corner of ids 0..3 must be
// triangulated.

#include "config/error.h"
#include "config/frames.h"
#include "processing/camera_model.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct ArucoCornerObservation {
  std::int64_t frame = 0;
  int marker_id = 0;
  int corner = 0;  // 0..3, OpenCV order
  Eigen::Vector2d tf_px = Eigen::Vector2d::Zero();
  double virtual_depth = 0;  // NaN: none measured
};

std::string FormatArucoCornersCsv(const std::vector<ArucoCornerObservation>& observations);
// Errors name the file, the line and the column.
Expected<std::vector<ArucoCornerObservation>> ReadArucoCornersCsv(
    const std::filesystem::path& path);

struct ArucoCentersInMap {
  std::array<Eigen::Vector3d, 4> centers_mm;  // ids 0..3, map frame
  int corners = 0;                            // triangulated (16)
  int observations = 0;                       // rays used
  int frames = 0;                             // frames the rays come from
  double ray_rms_mm = 0;                      // over every ray of every corner
  // "ArUco centres from 16 corners (112 rays in 7 frames), rays 0.41 mm RMS from their corners"
  std::string BriefReport() const;
};

// `w0_from_c0`: the poses of the frames (frame -> pose); observations of
// other frames are left out. Errors: a corner of ids 0..3 with fewer than
// two usable rays, or rays too parallel to meet.
Expected<ArucoCentersInMap> TriangulateArucoCenters(
    const std::vector<ArucoCornerObservation>& observations,
    const std::map<std::int64_t, Pose>& w0_from_c0, const processing::CameraModel& camera);

}  // namespace lifmcr::registration
