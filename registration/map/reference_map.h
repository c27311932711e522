#pragma once
// The reference map of a calibrated camera (camera 0 of the rig): metric 3D
// points in the world frame w0 (the marker plate frame when the plate was
// seen), each with colour, uncertainty, one SIFT descriptor and the
// observations that made it, and the pose w0_from_c0 of every frame.
//
// On disk (one folder), so that COLMAP and any PLY viewer open it:
//   cameras.txt    COLMAP text: `1 PINHOLE W H f f cx cy`, the central
//                  perspective (TF pinhole) camera of the TF grid:
//                  f = (b_L0 + 2B) / (2 s), c_tf = (c_raw - 0.5) / 2
//                  (processing/camera_model.h, eqs. projX/projY).
//   images.txt     COLMAP text: per frame `IMAGE_ID QW QX QY QZ TX TY TZ
//                  CAMERA_ID NAME` of c0_from_w0 (COLMAP stores
//                  cam_from_world), then `X Y POINT3D_ID` per keypoint in
//                  TF pinhole pixels (-1 for keypoints without a point).
//   points3D.txt   COLMAP text: `POINT3D_ID X Y Z R G B ERROR TRACK[]` with
//                  X, Y, Z in mm and TRACK = (IMAGE_ID, POINT2D_IDX) pairs.
//   points.ply     ASCII PLY: x y z (mm, float), red green blue (uchar),
//                  sigma_mm (float, the largest standard deviation).
//   ERROR of points3D.txt: RMS micro-image residual of the point (raw px).
//   descriptors.bin  binary, little-endian, documented below.
//   poses_<serial>.csv  w0_from_c0 per frame (registration/map/poses_csv.h).
//
// descriptors.bin:
//   char[8]  magic "LFMCRMAP"
//   uint32   version (1)
//   uint32   descriptor size (128, SIFT, float32)
//   uint64   number of points P
//   P times: int64 POINT3D_ID, float32 sigma_xyz_mm[3] (standard deviations
//            along world x, y, z), float32 descriptor[128]
//   uint64   number of observations O
//   O times: int64 POINT3D_ID, int32 IMAGE_ID, int32 POINT2D_IDX,
//            float32 tf_x_px, tf_y_px (the keypoint on the TF grid, before
//            distortion correction), float32 virtual_depth (measured, NaN
//            when the TF depth map had none); only keypoints in a track
//            carry these (the others keep their pinhole position alone)

#include "config/error.h"
#include "config/frames.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::registration {

// The TF pinhole camera (COLMAP PINHOLE with fx = fy).
struct MapCamera {
  std::string serial;
  int width_px = 0, height_px = 0;  // TF grid
  double focal_px = 0;
  Eigen::Vector2d principal_point_px = Eigen::Vector2d::Zero();
};

struct MapKeypoint {
  Eigen::Vector2d pinhole_px = Eigen::Vector2d::Zero();  // TF pinhole pixels (images.txt)
  Eigen::Vector2f tf_px = Eigen::Vector2f::Zero();       // TF grid, as detected
  float virtual_depth = 0;                               // measured v (NaN: none)
  std::int64_t point_id = -1;                            // -1: no map point
};

struct MapImage {
  int image_id = 0;  // COLMAP IMAGE_ID (1-based)
  std::int64_t frame = 0;
  std::int64_t vicon_frame = -1;
  std::string name;  // the raw frame's file name
  Pose w0_from_c0 = Pose::Identity();
  std::vector<MapKeypoint> keypoints;
};

struct TrackElement {
  int image_id = 0;
  int keypoint = 0;  // POINT2D_IDX in that image
};

struct MapPoint {
  std::int64_t id = 0;  // COLMAP POINT3D_ID
  Eigen::Vector3d p_in_w0_mm = Eigen::Vector3d::Zero();
  std::array<std::uint8_t, 3> rgb{0, 0, 0};
  Eigen::Vector3f sigma_mm = Eigen::Vector3f::Zero();  // std dev along world x, y, z
  double error_px = 0;                                 // mean reprojection error
  std::vector<float> descriptor;                       // kDescriptorSize floats
  std::vector<TrackElement> track;
};

struct ReferenceMap {
  MapCamera camera;
  std::vector<MapImage> images;
  std::vector<MapPoint> points;
};

// Writes every file listed above into `dir` (created if needed).
Status WriteReferenceMap(const std::filesystem::path& dir, const ReferenceMap& map);
// Reads them back (points.ply is not needed: points3D.txt holds the same);
// errors name the file and line.
Expected<ReferenceMap> ReadReferenceMap(const std::filesystem::path& dir);

}  // namespace lifmcr::registration
