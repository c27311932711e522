#pragma once
// GroundTruth/cameras.yaml of a synthetic sequence: every parameter of each
// camera model and its MLA (the true values the renderer used, and derived
// quantities such as the sharp range of each lens type), the Vicon set-up,
// the marker plate layout that defines the world frame, and each camera's
// true marker_from_cam. Poses are written as tx_mm, ty_mm, tz_mm, qw, qx, qy, qz.

#include "config/frames.h"
#include "replay/synth/marker_plate.h"
#include "replay/synth/synth_writer.h"

#include "config/error.h"

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::synth {

// The part of one camera's `model` that metric depth needs (`lifmcr depth
// --intrinsics`; `lifmcr calibrate` writes the same schema).
struct CameraModelYaml {
  int width_px = 0;
  int height_px = 0;
  double pixel_size_mm = 0;
  double main_focal_length_mm = 0;  // f_L
  double mla_to_main_lens_mm = 0;   // b_L0
  double mla_to_sensor_mm = 0;      // B
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0;
  // principal_point_px [x, y] (raw pixels) when the file gives it (inside
  // the image); files without it mean the image centre.
  std::optional<std::array<double, 2>> principal_point_px;
};

// Ranges of a real plenoptic camera (docs/formats.md, "Limits of every input").
struct CameraModelLimits {
  std::uint64_t max_file_bytes = 1 << 20;
  int max_side_px = 32768;
  double max_pixel_size_mm = 0.1;           // real: 0.002 .. 0.02
  double max_focal_length_mm = 5000;        // f_L and b_L0
  double max_mla_to_sensor_mm = 10;         // B: real ~0.2 .. 2
  double max_abs_distortion = 1e3;
};
inline constexpr CameraModelLimits kCameraModelLimits{};

// Reads /cameras/<i>/model of the camera whose `serial` matches, through
// the strict YAML reader (config/yaml_reader.h). Keys not needed here are
// allowed (the file holds much more); the ones read are typed and range
// checked, and errors name file:line:column and the key path.
Expected<CameraModelYaml> ParseCameraModelYaml(std::string_view text, const std::string& label,
                                               std::string_view serial);
Expected<CameraModelYaml> ReadCameraModelYaml(const std::filesystem::path& path,
                                              std::string_view serial);

// The serials /cameras/<i>/serial of a cameras.yaml, in file order (which
// cameras a file describes, before reading one), through the same reader.
Expected<std::vector<std::string>> ReadCameraSerialsYaml(const std::filesystem::path& path);

std::string FormatCamerasYaml(const SynthParams& params, const std::vector<SynthCamera>& cameras,
                              const MarkerPlateLayout& plate, const Pose& vicon_from_world,
                              const Pose& world_from_plate_marker);

}  // namespace lifmcr::synth
