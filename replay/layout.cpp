#include "replay/layout.h"

#include <algorithm>
#include <cctype>

namespace lifmcr::layout {
namespace {

constexpr std::string_view kCameraPrefix = "TypeE_";
constexpr std::string_view kRawSuffix = "_Raw";
constexpr std::string_view kBmpExtension = ".bmp";
constexpr std::string_view kMlaSuffix = "_MLA.xml";
constexpr std::string_view kViconCsvPrefix = "sequence_";
constexpr std::string_view kViconCsvExtension = ".csv";
// 18 decimal digits always fit an int64_t.
constexpr std::size_t kMaxParsedDigits = 18;

std::string Padded(std::int64_t value, int digits) {
  std::string text = std::to_string(value);
  if (value >= 0 && static_cast<int>(text.size()) < digits) {
    text.insert(0, static_cast<std::size_t>(digits) - text.size(), '0');
  }
  return text;
}

std::optional<std::int64_t> ParseDigits(std::string_view text) {
  if (text.empty() || text.size() > kMaxParsedDigits) return std::nullopt;
  std::int64_t value = 0;
  for (char c : text) {
    if (c < '0' || c > '9') return std::nullopt;
    value = value * 10 + (c - '0');
  }
  return value;
}

bool EndsWithNoCase(std::string_view text, std::string_view suffix) {
  if (text.size() < suffix.size()) return false;
  return std::equal(suffix.begin(), suffix.end(), text.end() - suffix.size(), [](char a, char b) {
    return std::tolower(static_cast<unsigned char>(a)) ==
           std::tolower(static_cast<unsigned char>(b));
  });
}

std::string RawName(std::string_view serial, std::int64_t number, int digits) {
  return CameraFolderName(serial) + "_" + Padded(number, digits) + std::string(kRawSuffix) +
         std::string(kBmpExtension);
}

std::string SerialAndFrame(std::string_view serial, std::int64_t frame) {
  return std::string(serial) + "_" + Padded(frame, kFrameDigits);
}

}  // namespace

bool IsValidSerial(std::string_view serial) {
  return !serial.empty() && std::all_of(serial.begin(), serial.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '-';
  });
}

std::string CameraFolderName(std::string_view serial) {
  return std::string(kCameraPrefix) + std::string(serial);
}

std::optional<std::string> ParseCameraFolderName(std::string_view name) {
  if (!name.starts_with(kCameraPrefix)) return std::nullopt;
  name.remove_prefix(kCameraPrefix.size());
  if (!IsValidSerial(name)) return std::nullopt;
  return std::string(name);
}

std::string RawFrameFileName(std::string_view serial, std::int64_t frame) {
  return RawName(serial, frame, kFrameDigits);
}

std::string WhiteImageFileName(std::string_view serial, int index) {
  return RawName(serial, index, kWhiteImageDigits);
}

std::optional<RawFrameName> ParseRawFrameFileName(std::string_view name) {
  if (!name.starts_with(kCameraPrefix) || !EndsWithNoCase(name, kBmpExtension)) {
    return std::nullopt;
  }
  name.remove_prefix(kCameraPrefix.size());
  name.remove_suffix(kBmpExtension.size());
  if (!name.ends_with(kRawSuffix)) return std::nullopt;
  name.remove_suffix(kRawSuffix.size());
  const std::size_t split = name.rfind('_');
  if (split == std::string_view::npos) return std::nullopt;
  const std::string_view serial = name.substr(0, split);
  const std::optional<std::int64_t> frame = ParseDigits(name.substr(split + 1));
  if (!IsValidSerial(serial) || !frame) return std::nullopt;
  return RawFrameName{std::string(serial), *frame};
}

std::string ViconCsvFileName(int sequence) {
  return std::string(kViconCsvPrefix) + Padded(sequence, kViconCsvDigits) +
         std::string(kViconCsvExtension);
}

std::optional<int> ParseViconCsvFileName(std::string_view name) {
  if (!name.starts_with(kViconCsvPrefix) || !name.ends_with(kViconCsvExtension)) {
    return std::nullopt;
  }
  name.remove_prefix(kViconCsvPrefix.size());
  name.remove_suffix(kViconCsvExtension.size());
  if (name.size() != static_cast<std::size_t>(kViconCsvDigits)) return std::nullopt;
  const std::optional<std::int64_t> number = ParseDigits(name);
  if (!number) return std::nullopt;
  return static_cast<int>(*number);
}

std::string MlaXmlFileName(std::string_view serial) {
  return CameraFolderName(serial) + std::string(kMlaSuffix);
}

std::optional<std::string> ParseMlaXmlFileName(std::string_view name) {
  if (!name.starts_with(kCameraPrefix) || !name.ends_with(kMlaSuffix)) return std::nullopt;
  name.remove_prefix(kCameraPrefix.size());
  name.remove_suffix(kMlaSuffix.size());
  if (!IsValidSerial(name)) return std::nullopt;
  return std::string(name);
}

std::string PosesCsvFileName(std::string_view serial) {
  return "poses_" + std::string(serial) + ".csv";
}

std::string MarkerFromCamCsvFileName(std::string_view serial) {
  return "marker_from_cam_" + std::string(serial) + ".csv";
}

std::string VirtualDepthFileName(std::string_view serial, std::int64_t frame) {
  return SerialAndFrame(serial, frame) + "_virtual_depth.tiff";
}

std::string DepthMmFileName(std::string_view serial, std::int64_t frame) {
  return SerialAndFrame(serial, frame) + "_depth_mm.tiff";
}

std::filesystem::path CameraDir(const std::filesystem::path& sequence_dir,
                                std::string_view serial) {
  return sequence_dir / CameraFolderName(serial);
}

std::filesystem::path RawFramePath(const std::filesystem::path& sequence_dir,
                                   std::string_view serial, std::int64_t frame) {
  return CameraDir(sequence_dir, serial) / RawFrameFileName(serial, frame);
}

std::filesystem::path ViconCsvPath(const std::filesystem::path& sequence_dir, int sequence) {
  return sequence_dir / kViconFolder / ViconCsvFileName(sequence);
}

std::filesystem::path GroundTruthDir(const std::filesystem::path& sequence_dir) {
  return sequence_dir / kGroundTruthFolder;
}

std::filesystem::path CamerasYamlPath(const std::filesystem::path& sequence_dir) {
  return GroundTruthDir(sequence_dir) / kCamerasYaml;
}

std::filesystem::path PosesCsvPath(const std::filesystem::path& sequence_dir,
                                   std::string_view serial) {
  return GroundTruthDir(sequence_dir) / PosesCsvFileName(serial);
}

std::filesystem::path MarkerFromCamCsvPath(const std::filesystem::path& sequence_dir,
                                           std::string_view serial) {
  return GroundTruthDir(sequence_dir) / MarkerFromCamCsvFileName(serial);
}

std::filesystem::path VirtualDepthPath(const std::filesystem::path& sequence_dir,
                                       std::string_view serial, std::int64_t frame) {
  return GroundTruthDir(sequence_dir) / kDepthFolder / VirtualDepthFileName(serial, frame);
}

std::filesystem::path DepthMmPath(const std::filesystem::path& sequence_dir,
                                  std::string_view serial, std::int64_t frame) {
  return GroundTruthDir(sequence_dir) / kDepthFolder / DepthMmFileName(serial, frame);
}

std::filesystem::path WhiteImagePath(const std::filesystem::path& calibration_dir,
                                     std::string_view serial, int index) {
  return calibration_dir / kWhiteImagesFolder / WhiteImageFileName(serial, index);
}

std::filesystem::path MlaXmlPath(const std::filesystem::path& calibration_dir,
                                 std::string_view serial) {
  return calibration_dir / kMlaCalibrationFolder / MlaXmlFileName(serial);
}

std::filesystem::path VskPath(const std::filesystem::path& calibration_dir) {
  return calibration_dir / kViconCalibrationFolder / kObjectVsk;
}

}  // namespace lifmcr::layout
