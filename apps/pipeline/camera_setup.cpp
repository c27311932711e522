// Calibration files -> processing::CameraSetup (camera_setup.h).

#include "apps/pipeline/camera_setup.h"

#include "replay/raw_image.h"
#include "replay/camera_calibration.h"
#include "replay/mla_xml.h"
#include "replay/synth/cameras_yaml.h"

#include <algorithm>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;

Expected<processing::CameraSetup> Load(const std::string& serial,
                                       const CameraCalibrationPaths& paths,
                                       const std::vector<fs::path>& intrinsics) {
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
  auto k = FindIntrinsics(intrinsics, serial);
  if (!k) return k.error();
  setup.intrinsics = *k;
  return setup;
}

}  // namespace

// Through the strict YAML reader (replay/synth/cameras_yaml.h): a regular
// file of at most 1 MiB, typed keys, ranges of a real camera, errors with
// file:line:column and key path (yaml-cpp exceptions used to escape here).
Expected<processing::CameraIntrinsics> ReadIntrinsics(const fs::path& path,
                                                      const std::string& serial) {
  Expected<synth::CameraModelYaml> model = synth::ReadCameraModelYaml(path, serial);
  if (!model) return model.error();
  processing::CameraIntrinsics k;
  k.width_px = model->width_px;
  k.height_px = model->height_px;
  k.pixel_size_mm = model->pixel_size_mm;
  k.main_focal_length_mm = model->main_focal_length_mm;
  k.mla_to_main_lens_mm = model->mla_to_main_lens_mm;
  k.mla_to_sensor_mm = model->mla_to_sensor_mm;
  k.k1 = model->k1;
  k.k2 = model->k2;
  k.p1 = model->p1;
  k.p2 = model->p2;
  if (model->principal_point_px)
    k.principal_point_px = Eigen::Vector2d((*model->principal_point_px)[0],
                                           (*model->principal_point_px)[1]);
  if (Status s = k.Check(); !s) return Error{path.string() + ": " + s.error().message};
  return k;
}

Expected<std::optional<processing::CameraIntrinsics>> FindIntrinsics(
    const std::vector<fs::path>& files, const std::string& serial) {
  for (const fs::path& file : files) {
    Expected<std::vector<std::string>> serials = synth::ReadCameraSerialsYaml(file);
    if (!serials) return serials.error();
    if (std::find(serials->begin(), serials->end(), serial) == serials->end()) continue;
    auto k = ReadIntrinsics(file, serial);
    if (!k) return k.error();
    return std::optional<processing::CameraIntrinsics>(*k);
  }
  return std::optional<processing::CameraIntrinsics>();
}

Expected<processing::CameraSetup> LoadSequenceCamera(const fs::path& sequence_dir,
                                                     const std::string& serial,
                                                     const CameraFileOverrides& files) {
  auto paths = CalibrationPathsForSequence(sequence_dir, serial, files.mla, files.white);
  if (!paths) return paths.error();
  if (!files.look_up_white && files.white.empty()) paths->white.reset();
  std::vector<fs::path> intrinsics;
  if (!files.intrinsics.empty()) intrinsics.push_back(files.intrinsics);
  auto setup = Load(serial, *paths, intrinsics);
  if (setup && !files.intrinsics.empty() && !setup->intrinsics)
    return Error{files.intrinsics.string() + ": no camera with serial '" + serial + "'"};
  return setup;
}

Expected<std::vector<processing::CameraSetup>> LoadSequenceCameras(
    const fs::path& sequence_dir, const std::vector<std::string>& serials,
    const std::vector<fs::path>& intrinsics) {
  std::vector<processing::CameraSetup> out;
  for (const std::string& serial : serials) {
    auto paths = CalibrationPathsForSequence(sequence_dir, serial, {}, {});
    if (!paths) return paths.error();
    auto setup = Load(serial, *paths, intrinsics);
    if (!setup) return setup.error();
    out.push_back(std::move(*setup));
  }
  return out;
}

Expected<std::vector<processing::CameraSetup>> LoadRigCameras(
    const RigConfig& rig, const std::vector<fs::path>& intrinsics) {
  std::vector<processing::CameraSetup> out;
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraConfig& camera = rig.cameras[i];
    if (camera.mla_file.empty())
      return Error{"/cameras/" + std::to_string(i) + "/mla_file: camera " + camera.serial +
                   " has none (depth needs the MLA file of every camera)"};
    auto paths = CalibrationPathsForMla(camera.serial, camera.mla_file);
    if (!paths) return paths.error();
    auto setup = Load(camera.serial, *paths, intrinsics);
    if (!setup) return setup.error();
    out.push_back(std::move(*setup));
  }
  return out;
}

Expected<std::vector<std::string>> SelectCameras(const std::string& list,
                                                 const std::vector<std::string>& available,
                                                 const std::string& where) {
  if (list.empty()) return available;
  const auto there = [&] {
    std::string serials;
    for (const std::string& s : available) serials += (serials.empty() ? "" : ", ") + s;
    return serials;
  };
  std::vector<std::string> named;
  std::size_t begin = 0;
  for (;;) {
    const std::size_t comma = list.find(',', begin);
    const std::string item =
        list.substr(begin, comma == std::string::npos ? std::string::npos : comma - begin);
    if (item.empty())
      return Error{"--cameras '" + list + "': an empty serial (expected SERIAL[,SERIAL...])"};
    if (std::find(available.begin(), available.end(), item) == available.end())
      return Error{"--cameras: camera '" + item + "' is not in " + where +
                   " (its cameras: " + there() + ")"};
    if (std::find(named.begin(), named.end(), item) != named.end())
      return Error{"--cameras: camera '" + item + "' given twice"};
    named.push_back(item);
    if (comma == std::string::npos) break;
    begin = comma + 1;
  }
  std::vector<std::string> selected;
  for (const std::string& serial : available)
    if (std::find(named.begin(), named.end(), serial) != named.end()) selected.push_back(serial);
  return selected;
}

}  // namespace lifmcr::apps
