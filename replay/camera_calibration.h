#pragma once
// Where a camera's calibration files are: the one rule every command uses
// (`lifmcr depth`, replay, `record --publish`).
//
//   MLA file     given explicitly (a rig's cameras[].mla_file, `--mla`), else
//                Calibration/02_MLA_Calibration/TypeE_<serial>_MLA.xml of the
//                Calibration/ folder of the sequence (FindCalibrationFor:
//                beside the scenes, else beside the sequence); required.
//   white image  given explicitly (`--white`; must exist), else
//                01_White_Images/TypeE_<serial>_00_Raw.bmp of the
//                Calibration/ folder that holds the MLA file, when the MLA
//                file lies in a 02_MLA_Calibration/ folder and the white
//                image exists; else none (the processing chain then runs
//                without devignetting: processing/frame_chain.h).

#include "config/error.h"

#include <filesystem>
#include <optional>
#include <string>

namespace lifmcr {

struct CameraCalibrationPaths {
  std::filesystem::path mla;
  std::optional<std::filesystem::path> white;
};

// The paths for a camera whose MLA file is known. `white_override` empty:
// the white image beside the MLA file, if any.
Expected<CameraCalibrationPaths> CalibrationPathsForMla(const std::string& serial,
                                                        const std::filesystem::path& mla_file,
                                                        const std::filesystem::path& white_override = {});

// The paths for a camera of a recorded sequence; the overrides, when not
// empty, replace the MLA file and the white image.
Expected<CameraCalibrationPaths> CalibrationPathsForSequence(
    const std::filesystem::path& sequence_dir, const std::string& serial,
    const std::filesystem::path& mla_override = {},
    const std::filesystem::path& white_override = {});

}  // namespace lifmcr
