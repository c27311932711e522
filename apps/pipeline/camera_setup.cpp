// Calibration files -> processing::CameraSetup (camera_setup.h).

#include "apps/pipeline/camera_setup.h"

#include "replay/raw_image.h"
#include "replay/camera_calibration.h"
#include "replay/mla_xml.h"

#include <yaml-cpp/yaml.h>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;

Expected<processing::CameraSetup> Load(const std::string& serial,
                                       const CameraCalibrationPaths& paths,
                                       const fs::path& intrinsics) {
  processing::CameraSetup setup;
  setup.serial = serial;
  auto mla = ReadMlaXml(paths.mla);
  if (!mla) return Error{mla.error().message + " (MLA file of camera " + serial + ")"};
  setup.mla = std::move(*mla);
  if (paths.white) {
    auto white = ReadRawImage(*paths.white);
    if (!white) return Error{white.error().message + " (white image of camera " + serial + ")"};
    setup.white = std::move(*white);
  }
  if (!intrinsics.empty()) {
    auto k = ReadIntrinsics(intrinsics, serial);
    if (!k) return k.error();
    setup.intrinsics = *k;
  }
  return setup;
}

}  // namespace

Expected<processing::CameraIntrinsics> ReadIntrinsics(const fs::path& path,
                                                      const std::string& serial) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::Exception& e) {
    return Error{path.string() + ": " + e.what()};
  }
  if (!root["cameras"] || !root["cameras"].IsSequence())
    return Error{path.string() + ": /cameras: expected a list of cameras"};
  for (std::size_t n = 0; n < root["cameras"].size(); ++n) {
    const YAML::Node cam = root["cameras"][n];
    if (!cam["serial"] || cam["serial"].as<std::string>() != serial) continue;
    const std::string where = path.string() + ": /cameras/" + std::to_string(n) + "/model/";
    const YAML::Node m = cam["model"];
    processing::CameraIntrinsics k;
    try {
      auto num = [&](const char* key) {
        if (!m[key]) throw YAML::Exception(YAML::Mark::null_mark(), std::string("missing ") + key);
        return m[key].as<double>();
      };
      k.width_px = static_cast<int>(num("width_px"));
      k.height_px = static_cast<int>(num("height_px"));
      k.pixel_size_mm = num("pixel_size_mm");
      k.main_focal_length_mm = num("main_focal_length_mm");
      k.mla_to_main_lens_mm = num("mla_to_main_lens_mm");
      k.mla_to_sensor_mm = num("mla_to_sensor_mm");
      if (const YAML::Node d = m["distortion"]) {
        k.k1 = d["k1"] ? d["k1"].as<double>() : 0.0;
        k.k2 = d["k2"] ? d["k2"].as<double>() : 0.0;
        k.p1 = d["p1"] ? d["p1"].as<double>() : 0.0;
        k.p2 = d["p2"] ? d["p2"].as<double>() : 0.0;
      }
    } catch (const YAML::Exception& e) {
      return Error{where + ": " + e.msg};
    }
    if (Status s = k.Check(); !s) return Error{where + ": " + s.error().message};
    return k;
  }
  return Error{path.string() + ": /cameras: no camera with serial " + serial};
}

Expected<processing::CameraSetup> LoadSequenceCamera(const fs::path& sequence_dir,
                                                     const std::string& serial,
                                                     const CameraFileOverrides& files) {
  auto paths = CalibrationPathsForSequence(sequence_dir, serial, files.mla, files.white);
  if (!paths) return paths.error();
  if (!files.look_up_white && files.white.empty()) paths->white.reset();
  return Load(serial, *paths, files.intrinsics);
}

Expected<std::vector<processing::CameraSetup>> LoadSequenceCameras(
    const fs::path& sequence_dir, const std::vector<std::string>& serials) {
  std::vector<processing::CameraSetup> out;
  for (const std::string& serial : serials) {
    auto setup = LoadSequenceCamera(sequence_dir, serial);
    if (!setup) return setup.error();
    out.push_back(std::move(*setup));
  }
  return out;
}

Expected<std::vector<processing::CameraSetup>> LoadRigCameras(const RigConfig& rig) {
  std::vector<processing::CameraSetup> out;
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraConfig& camera = rig.cameras[i];
    if (camera.mla_file.empty())
      return Error{"/cameras/" + std::to_string(i) + "/mla_file: camera " + camera.serial +
                   " has none (depth needs the MLA file of every camera)"};
    auto paths = CalibrationPathsForMla(camera.serial, camera.mla_file);
    if (!paths) return paths.error();
    auto setup = Load(camera.serial, *paths, {});
    if (!setup) return setup.error();
    out.push_back(std::move(*setup));
  }
  return out;
}

}  // namespace lifmcr::apps
