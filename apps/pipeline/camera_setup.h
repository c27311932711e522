#pragma once
// The calibration of each camera read into processing::CameraSetup, by the
// one lookup rule (replay/camera_calibration.h), for every command that
// processes frames: `lifmcr depth`, replay, `record --publish`.

#include "config/error.h"
#include "config/rig_config.h"
#include "processing/frame_chain.h"

#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::apps {

// The camera `serial` of a cameras.yaml (GroundTruth of `lifmcr synth`, or
// `lifmcr calibrate`): cameras: [{serial, model: {width_px, height_px,
// pixel_size_mm, main_focal_length_mm, mla_to_main_lens_mm,
// mla_to_sensor_mm, distortion: {k1, k2, p1, p2}}}].
Expected<processing::CameraIntrinsics> ReadIntrinsics(const std::filesystem::path& path,
                                                      const std::string& serial);

// Explicit files; empty paths fall back to the lookup rule.
struct CameraFileOverrides {
  std::filesystem::path mla;
  std::filesystem::path white;
  std::filesystem::path intrinsics;  // cameras.yaml; empty: no intrinsics
  // false: no white image unless `white` names one (`lifmcr depth --no-white`,
  // --raw): the vignetting then comes from the frame.
  bool look_up_white = true;
};

// One camera of a recorded sequence (or, with files.mla given, of any MLA
// file; sequence_dir may then be empty).
Expected<processing::CameraSetup> LoadSequenceCamera(const std::filesystem::path& sequence_dir,
                                                     const std::string& serial,
                                                     const CameraFileOverrides& files = {});
// Every camera of a sequence, by serial.
Expected<std::vector<processing::CameraSetup>> LoadSequenceCameras(
    const std::filesystem::path& sequence_dir, const std::vector<std::string>& serials);
// Every camera of a rig file: its mla_file (required of every camera) and
// the white image beside it. Cameras without an mla_file: an error naming them.
Expected<std::vector<processing::CameraSetup>> LoadRigCameras(const RigConfig& rig);

}  // namespace lifmcr::apps
