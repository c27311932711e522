// The files `lifmcr calibrate` writes and `register` / `evaluate` read back,
// which a user may edit or bring from elsewhere: intrinsics.yaml (camera
// model and plate layout), poses_<serial>.csv and aruco_corners.csv. The
// first byte picks the reader; the rest is the file (memfd).

#include "registration/map/aruco_corners.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/map/poses_csv.h"
#include "tests/fuzz/fuzz_util.h"

#include <cmath>
#include <string>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace lifmcr;
  using namespace lifmcr::registration;
  if (size < 1) return 0;
  fuzz::MemFile file(data + 1, size - 1);
  switch (data[0] % 4) {
    case 0: {
      Expected<CameraCalibration> calibration = ReadCameraCalibration(file.path(), "40398673");
      if (calibration) {
        const processing::CameraIntrinsics& k = calibration->intrinsics;
        fuzz::Require(k.width_px >= 1 && k.height_px >= 1 && std::isfinite(k.pixel_size_mm) &&
                          k.pixel_size_mm > 0,
                      "accepted intrinsics have a positive image and pixel size");
      }
      break;
    }
    case 1: {
      Expected<PlateLayout> plate = ReadPlateLayout(file.path());
      if (plate) {
        fuzz::Require(std::isfinite(plate->aruco_side_mm) && plate->aruco_side_mm > 0,
                      "an accepted plate has a positive marker side");
        for (const auto& [id, centre] : plate->aruco_centers_mm) (void)plate->Corner(id, 3);
      }
      break;
    }
    case 2: {
      Expected<std::vector<FramePose>> poses = ReadPosesCsv(file.path());
      if (poses) {
        const std::string text = FormatPosesCsv(*poses);
        fuzz::MemFile again(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
        Expected<std::vector<FramePose>> read = ReadPosesCsv(again.path());
        fuzz::Require(read.ok() && read->size() == poses->size(), "written poses read back");
      }
      break;
    }
    default: {
      Expected<std::vector<ArucoCornerObservation>> corners = ReadArucoCornersCsv(file.path());
      if (corners) {
        const std::string text = FormatArucoCornersCsv(*corners);
        fuzz::MemFile again(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
        Expected<std::vector<ArucoCornerObservation>> read = ReadArucoCornersCsv(again.path());
        fuzz::Require(read.ok() && read->size() == corners->size(), "written corners read back");
      }
      break;
    }
  }
  return 0;
}
