#pragma once
// What `lifmcr calibrate --rig` writes beside the shared map (the reference
// map of camera 0's frames, reference_map.h):
//
//   rig.yaml   each camera's pose in the rig, in the rig file's `cameras[]`
//              terms (docs/rig_file.md): serial, role, and for every camera
//              X its `c0_from_cx`: translation_mm [x, y, z], rotation_wxyz
//              (unit quaternion), covariance_rad_mm (36 numbers, row-major
//              6 x 6 over [rotation vector rad (left perturbation, in c0),
//              translation mm]), the frames registered at the start;
//              `mount: rigid | non_rigid`; non-rigid: c0_from_cx is the
//              robust mean of c0_from_cx_per_frame (frame, pose, covariance).
//   colmap/    the whole rig as a COLMAP (>= 3.12) text model:
//              cameras.txt  one PINHOLE (TF pinhole, reference_map.h) per camera;
//              rigs.txt     one rig, camera 0 (CAMERA_ID 1) the reference
//                           sensor, camera X's sensor_from_rig = cx_from_c0;
//              frames.txt   per trigger its rig_from_world = c0_from_w0 and
//                           the images (CAMERA, camera id, IMAGE_ID) taken;
//              images.txt   per camera and trigger cam_from_world and every
//                           keypoint (TF pinhole px) with its point;
//              points3D.txt the shared points (mm in w0), their tracks over
//                           every camera's images.

#include "config/error.h"
#include "registration/calibration/rig_calibration.h"

#include <filesystem>
#include <vector>

namespace lifmcr::registration {

// `cameras` are CalibrateRig's inputs (the keypoints of camera X's images).
Status WriteRigCalibration(const std::filesystem::path& dir, const RigCalibrationResult& result,
                           const std::vector<CalibrationInput>& cameras);

}  // namespace lifmcr::registration
