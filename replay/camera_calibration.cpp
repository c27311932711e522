// The calibration lookup rule (camera_calibration.h).

#include "replay/camera_calibration.h"

#include "config/input_file.h"
#include "config/text_escape.h"
#include "replay/layout.h"
#include "replay/sequence.h"

namespace lifmcr {

namespace fs = std::filesystem;

Expected<CameraCalibrationPaths> CalibrationPathsForMla(const std::string& serial,
                                                        const fs::path& mla_file,
                                                        const fs::path& white_override) {
  std::error_code ec;
  // What is there instead (config/input_file.h): "is a folder", "a symbolic
  // link loop", "no such file or folder", never just "no file".
  if (const std::string why = DescribeNonRegular(mla_file); !why.empty())
    return Error{EscapeText(mla_file.string()) + ": " + why +
                 ", expected a regular file: the MLA file of camera " + serial};
  CameraCalibrationPaths paths;
  paths.mla = mla_file;
  if (!white_override.empty()) {
    if (const std::string why = DescribeNonRegular(white_override); !why.empty())
      return Error{EscapeText(white_override.string()) + ": " + why +
                   ", expected a regular file: the white image of camera " + serial};
    paths.white = white_override;
    return paths;
  }
  if (mla_file.parent_path().filename() == layout::kMlaCalibrationFolder) {
    const fs::path white = layout::WhiteImagePath(mla_file.parent_path().parent_path(), serial, 0);
    if (fs::is_regular_file(white, ec)) paths.white = white;
  }
  return paths;
}

Expected<CameraCalibrationPaths> CalibrationPathsForSequence(const fs::path& sequence_dir,
                                                             const std::string& serial,
                                                             const fs::path& mla_override,
                                                             const fs::path& white_override) {
  if (!mla_override.empty()) return CalibrationPathsForMla(serial, mla_override, white_override);
  const auto calibration = FindCalibrationFor(sequence_dir);
  if (!calibration)
    return Error{sequence_dir.string() +
                 ": no Calibration/ folder beside the sequence or its scene (it holds the MLA "
                 "file of camera " +
                 serial + ")"};
  return CalibrationPathsForMla(serial, layout::MlaXmlPath(*calibration, serial), white_override);
}

}  // namespace lifmcr
