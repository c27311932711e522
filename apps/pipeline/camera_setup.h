#pragma once
// The calibration of each camera read into processing::CameraSetup, by the
// one lookup rule (replay/camera_calibration.h), for every command that
// processes frames: `lifmcr depth`, replay, `record --publish`.

#include "config/error.h"
#include "config/rig_config.h"
#include "processing/frame_chain.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::apps {

// The camera `serial` of a cameras.yaml (GroundTruth of `lifmcr synth`, or
// `lifmcr calibrate`): cameras: [{serial, model: {width_px, height_px,
// pixel_size_mm, main_focal_length_mm, mla_to_main_lens_mm,
// mla_to_sensor_mm, distortion: {k1, k2, p1, p2}}}].
Expected<processing::CameraIntrinsics> ReadIntrinsics(const std::filesystem::path& path,
                                                      const std::string& serial);

// The intrinsics of camera `serial` from the first of `files` that lists it
// (cameras.yaml schema: GroundTruth/cameras.yaml, intrinsics.yaml of
// `lifmcr calibrate`); nullopt when none does. A file that cannot be read or
// that lists the camera with bad values is an error.
Expected<std::optional<processing::CameraIntrinsics>> FindIntrinsics(
    const std::vector<std::filesystem::path>& files, const std::string& serial);

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
// Every camera of a sequence, by serial; the intrinsics of each from
// `intrinsics` (FindIntrinsics; a camera none lists has none: no metric
// depth, not localised).
Expected<std::vector<processing::CameraSetup>> LoadSequenceCameras(
    const std::filesystem::path& sequence_dir, const std::vector<std::string>& serials,
    const std::vector<std::filesystem::path>& intrinsics = {});
// Every camera of a rig file: its mla_file (required of every camera) and
// the white image beside it, intrinsics as above. Cameras without an
// mla_file: an error naming them.
Expected<std::vector<processing::CameraSetup>> LoadRigCameras(
    const RigConfig& rig, const std::vector<std::filesystem::path>& intrinsics = {});

// `--cameras SERIAL[,SERIAL...]` (replay, record): the cameras of `available`
// that `list` names, in the order of `available` (the camera indices keep
// the sequence's or rig's order). An empty list selects every camera. A
// serial given twice, an empty item, or a serial not in `available` is an
// error naming it, `where` (the sequence folder or rig file) and the
// serials there.
Expected<std::vector<std::string>> SelectCameras(const std::string& list,
                                                 const std::vector<std::string>& available,
                                                 const std::string& where);

}  // namespace lifmcr::apps
