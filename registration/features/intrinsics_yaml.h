#pragma once
// Camera intrinsics and the marker plate in the schema of
// GroundTruth/cameras.yaml (replay/synth/cameras_yaml.h), so that
// `lifmcr calibrate` reads nominal values from such a file and writes
// intrinsics.yaml that `lifmcr depth --intrinsics` and every later command
// take:
//   cameras: [{serial, model: {width_px, height_px, pixel_size_mm,
//     main_focal_length_mm, mla_to_main_lens_mm, mla_to_sensor_mm,
//     principal_point_px: [x, y], distortion: {model, k1, k2, p1, p2},
//     tf_width_px, tf_height_px}}]
//   plate: {aruco_dictionary: DICT_6X6_250, aruco_side_mm,
//     aruco_centers_mm: {id: [x, y, z]}}

#include "config/error.h"
#include "processing/camera_model.h"

#include <Eigen/Core>

#include <filesystem>
#include <map>
#include <string>

namespace lifmcr::registration {

// The intrinsics of one camera, principal point included
// (intrinsics.principal_point_px, unset when the file gives none).
struct CameraCalibration {
  processing::CameraIntrinsics intrinsics;
};

// The camera `serial` of a cameras.yaml; a missing principal_point_px means
// the image centre (files written before the model had one). Errors name
// the file and the key.
Expected<CameraCalibration> ReadCameraCalibration(const std::filesystem::path& path,
                                                  const std::string& serial);

// What a calibration adds to the schema: standard deviations (same keys,
// under `calibration: {std_dev: ...}`) and the one-line summary.
struct CalibrationAnnotation {
  std::map<std::string, double> std_dev;  // key -> standard deviation, same unit
  std::string summary;
};

Status WriteIntrinsicsYaml(const std::filesystem::path& path, const std::string& serial,
                           const CameraCalibration& calibration,
                           const CalibrationAnnotation& annotation);

// The ArUco marker plate that defines the world frame (replay/synth/marker_plate.h).
struct PlateLayout {
  int aruco_dictionary = 10;  // cv::aruco::DICT_6X6_250
  double aruco_side_mm = 100;
  std::map<int, Eigen::Vector3d> aruco_centers_mm;  // id -> centre, plate frame (z = 0)
  // Corner c (OpenCV order: top-left, top-right, bottom-right, bottom-left
  // of the upright marker, whose top edge faces +y) of marker `id`.
  Eigen::Vector3d Corner(int id, int c) const;
};

// The `plate:` section of a cameras.yaml or rig file.
Expected<PlateLayout> ReadPlateLayout(const std::filesystem::path& path);

}  // namespace lifmcr::registration
