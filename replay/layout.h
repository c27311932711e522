#pragma once
// The LiFMCR dataset layout (paper, supplementary "Dataset Structure"), and
// the ground truth that `lifmcr synth` adds (docs/synth.md), in one place:
//
//   ROOT/SCENE/SEQ/Vicon/sequence_XX.csv
//   ROOT/SCENE/SEQ/TypeE_<serial>/TypeE_<serial>_<frame>_Raw.bmp
//   ROOT/SCENE/SEQ/GroundTruth/cameras.yaml
//                             /poses_<serial>.csv
//                             /marker_from_cam_<serial>.csv
//                             /depth/<serial>_<frame>_virtual_depth.tiff
//                             /depth/<serial>_<frame>_depth_mm.tiff
//   ROOT/Calibration/01_White_Images/TypeE_<serial>_<XX>_Raw.bmp
//   ROOT/Calibration/02_MLA_Calibration/TypeE_<serial>_MLA.xml
//   ROOT/Calibration/03_Vicon/Object.vsk
//
// Decisions where the paper is not precise:
// - Serials are letters, digits and '-' (the real ones are "40398673" and
//   "40398678"); no '_', which separates the fields of a file name.
// - Frame numbers: the paper writes `_XX_`, the real padding is unknown and
//   sequences hold up to 781 frames. Reading accepts any count of decimal
//   digits (at most 18) and maps a file to the integer ("_7_", "_07_" and
//   "_000007_" are all frame 7). Writing zero-pads to kFrameDigits = 6 digits,
//   so names sort by frame in any file browser for recordings of up to
//   100000 triggers (almost 3 hours at 10 Hz); larger frames just get longer.
// - White images are numbered with 2 digits as the paper writes (`_XX_`); their
//   names follow the raw frame rule, so they parse with ParseRawFrameFileName.
// - Vicon CSVs: `sequence_` followed by exactly 2 digits, as the paper writes.
// - The extension `.bmp` is matched without regard to case (`.BMP` from
//   Windows tools); every other part is case-sensitive.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace lifmcr::layout {

inline constexpr int kFrameDigits = 6;
// The largest frame number a file name may carry (18 digits: fits int64).
inline constexpr std::int64_t kMaxFrameNumber = 999999999999999999;
inline constexpr int kWhiteImageDigits = 2;
inline constexpr int kViconCsvDigits = 2;

inline constexpr std::string_view kViconFolder = "Vicon";
inline constexpr std::string_view kGroundTruthFolder = "GroundTruth";
inline constexpr std::string_view kDepthFolder = "depth";
inline constexpr std::string_view kCamerasYaml = "cameras.yaml";
inline constexpr std::string_view kCalibrationFolder = "Calibration";
inline constexpr std::string_view kWhiteImagesFolder = "01_White_Images";
inline constexpr std::string_view kMlaCalibrationFolder = "02_MLA_Calibration";
inline constexpr std::string_view kViconCalibrationFolder = "03_Vicon";
inline constexpr std::string_view kObjectVsk = "Object.vsk";

// True if `serial` is non-empty and only letters, digits and '-'.
bool IsValidSerial(std::string_view serial);

// "TypeE_<serial>": a camera's folder in a sequence.
std::string CameraFolderName(std::string_view serial);
// The serial of a camera folder name, or nullopt if `name` is not one.
std::optional<std::string> ParseCameraFolderName(std::string_view name);

// "TypeE_<serial>_<frame, 6 digits>_Raw.bmp"; frame >= 0 (negative numbers do not parse back).
std::string RawFrameFileName(std::string_view serial, std::int64_t frame);
// "TypeE_<serial>_<index, 2 digits>_Raw.bmp" (in Calibration/01_White_Images).
std::string WhiteImageFileName(std::string_view serial, int index);

struct RawFrameName {
  std::string serial;
  std::int64_t frame = 0;  // >= 0
};
// Parses "TypeE_<serial>_<digits>_Raw.bmp" (any digit count; see above).
std::optional<RawFrameName> ParseRawFrameFileName(std::string_view name);

// "sequence_<XX>.csv" in Vicon/.
std::string ViconCsvFileName(int sequence);
std::optional<int> ParseViconCsvFileName(std::string_view name);

// "TypeE_<serial>_MLA.xml" in Calibration/02_MLA_Calibration.
std::string MlaXmlFileName(std::string_view serial);
std::optional<std::string> ParseMlaXmlFileName(std::string_view name);

// Ground truth file names (in SEQ/GroundTruth and SEQ/GroundTruth/depth).
std::string PosesCsvFileName(std::string_view serial);          // poses_<serial>.csv
std::string MarkerFromCamCsvFileName(std::string_view serial);  // marker_from_cam_<serial>.csv
std::string VirtualDepthFileName(std::string_view serial, std::int64_t frame);
std::string DepthMmFileName(std::string_view serial, std::int64_t frame);

// Full paths from a sequence folder.
std::filesystem::path CameraDir(const std::filesystem::path& sequence_dir, std::string_view serial);
std::filesystem::path RawFramePath(const std::filesystem::path& sequence_dir,
                                   std::string_view serial, std::int64_t frame);
std::filesystem::path ViconCsvPath(const std::filesystem::path& sequence_dir, int sequence);
std::filesystem::path GroundTruthDir(const std::filesystem::path& sequence_dir);
std::filesystem::path CamerasYamlPath(const std::filesystem::path& sequence_dir);
std::filesystem::path PosesCsvPath(const std::filesystem::path& sequence_dir,
                                   std::string_view serial);
std::filesystem::path MarkerFromCamCsvPath(const std::filesystem::path& sequence_dir,
                                           std::string_view serial);
std::filesystem::path VirtualDepthPath(const std::filesystem::path& sequence_dir,
                                       std::string_view serial, std::int64_t frame);
std::filesystem::path DepthMmPath(const std::filesystem::path& sequence_dir,
                                  std::string_view serial, std::int64_t frame);

// Full paths from a Calibration folder.
std::filesystem::path WhiteImagePath(const std::filesystem::path& calibration_dir,
                                     std::string_view serial, int index);
std::filesystem::path MlaXmlPath(const std::filesystem::path& calibration_dir,
                                 std::string_view serial);
std::filesystem::path VskPath(const std::filesystem::path& calibration_dir);

}  // namespace lifmcr::layout
