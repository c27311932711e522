#include "registration/features/intrinsics_yaml.h"

#include "config/decimal_number.h"
#include "config/input_file.h"
#include "config/text_escape.h"
#include "config/yaml_reader.h"
#include "replay/synth/cameras_yaml.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>

namespace lifmcr::registration {
namespace {

namespace fs = std::filesystem;

// Through the safe open (config/input_file.h): a regular file within the
// bound of the schema's other reader (replay/synth/cameras_yaml.h), never a
// FIFO or /dev/zero read until memory runs out.
Expected<YamlNode> ParseFile(const fs::path& path) {
  Expected<std::string> text = ReadInputText(
      path, {"a cameras.yaml / intrinsics.yaml (YAML)", synth::kCameraModelLimits.max_file_bytes});
  if (!text) return text.error();
  return YamlNode::Parse(*text, EscapeText(path.string()));
}

// A list of `n` numbers at `node`.
bool ReadNumbers(const YamlNode& node, int n, double* out, YamlErrors* errors) {
  const std::vector<YamlNode> e = node.Elements();
  if (static_cast<int>(e.size()) != n) {
    errors->Add(node.ErrorHere("expected a list of " + std::to_string(n) + " numbers, got " +
                               node.Describe()));
    return false;
  }
  for (int k = 0; k < n; ++k) {
    const std::string& s = e[k].Scalar();
    const auto [end, ec] = FromCharsRounded(s.data(), s.data() + s.size(), out[k]);
    if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(out[k])) {
      errors->Add(e[k].ErrorHere("expected a number, got " + e[k].Describe()));
      return false;
    }
  }
  return true;
}

}  // namespace

Expected<CameraCalibration> ReadCameraCalibration(const fs::path& path,
                                                  const std::string& serial) {
  Expected<YamlNode> root = ParseFile(path);
  if (!root) return root.error();
  YamlErrors errors;
  YamlMap top(*root, &errors);
  std::optional<std::vector<YamlNode>> cameras = top.List("cameras", Presence::kRequired);
  if (!errors.ok()) return errors.status().error();
  for (const YamlNode& node : *cameras) {
    YamlMap cam(node, &errors);
    std::string s;
    cam.Read("serial", &s, Presence::kRequired);
    if (!errors.ok()) return errors.status().error();
    if (s != serial) continue;
    std::optional<YamlMap> m = cam.Map("model", Presence::kRequired);
    if (!m) return errors.status().error();
    CameraCalibration c;
    processing::CameraIntrinsics& k = c.intrinsics;
    m->Read("width_px", &k.width_px, Presence::kRequired);
    m->Read("height_px", &k.height_px, Presence::kRequired);
    m->Read("pixel_size_mm", &k.pixel_size_mm, Presence::kRequired);
    m->Read("main_focal_length_mm", &k.main_focal_length_mm, Presence::kRequired);
    m->Read("mla_to_main_lens_mm", &k.mla_to_main_lens_mm, Presence::kRequired);
    m->Read("mla_to_sensor_mm", &k.mla_to_sensor_mm, Presence::kRequired);
    if (std::optional<YamlNode> pp = m->Child("principal_point_px", Presence::kOptional)) {
      Eigen::Vector2d c_px;
      ReadNumbers(*pp, 2, c_px.data(), &errors);
      k.principal_point_px = c_px;
    }
    if (std::optional<YamlMap> d = m->Map("distortion", Presence::kOptional)) {
      d->Read("k1", &k.k1, Presence::kOptional);
      d->Read("k2", &k.k2, Presence::kOptional);
      d->Read("p1", &k.p1, Presence::kOptional);
      d->Read("p2", &k.p2, Presence::kOptional);
    }
    if (!errors.ok()) return errors.status().error();
    if (Status st = k.Check(); !st) return node.ErrorHere("model: " + st.error().message);
    return c;
  }
  return root->ErrorAtPath("/cameras", "no camera with serial '" + Excerpt(serial) + "'");
}

Status WriteIntrinsicsYaml(const fs::path& path, const std::string& serial,
                           const CameraCalibration& c, const CalibrationAnnotation& annotation) {
  const processing::CameraIntrinsics& k = c.intrinsics;
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "generator" << YAML::Value << "lifmcr calibrate";
  out << YAML::Key << "conventions" << YAML::Value
      << "schema of GroundTruth/cameras.yaml; LiFCal model (processing/camera_model.h); mm, px";
  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginSeq << YAML::BeginMap;
  out << YAML::Key << "serial" << YAML::Value << YAML::DoubleQuoted << serial;
  out << YAML::Key << "model" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "width_px" << YAML::Value << k.width_px;
  out << YAML::Key << "height_px" << YAML::Value << k.height_px;
  out << YAML::Key << "pixel_size_mm" << YAML::Value << k.pixel_size_mm;
  out << YAML::Key << "main_focal_length_mm" << YAML::Value << k.main_focal_length_mm;
  out << YAML::Key << "mla_to_main_lens_mm" << YAML::Value << k.mla_to_main_lens_mm;
  out << YAML::Key << "mla_to_sensor_mm" << YAML::Value << k.mla_to_sensor_mm;
  const Eigen::Vector2d c_px = k.PrincipalPointPx();
  out << YAML::Key << "principal_point_px" << YAML::Value << YAML::Flow << YAML::BeginSeq
      << c_px.x() << c_px.y() << YAML::EndSeq;
  out << YAML::Key << "distortion" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "model" << YAML::Value << "lifcal_mla_plane_mm";
  out << YAML::Key << "k1" << YAML::Value << k.k1 << YAML::Key << "k2" << YAML::Value << k.k2
      << YAML::Key << "p1" << YAML::Value << k.p1 << YAML::Key << "p2" << YAML::Value << k.p2;
  out << YAML::EndMap;
  out << YAML::Key << "tf_width_px" << YAML::Value << k.width_px / 2;
  out << YAML::Key << "tf_height_px" << YAML::Value << k.height_px / 2;
  out << YAML::Key << "tf_pixel_to_raw" << YAML::Value << "raw = 2 * tf + 0.5";
  out << YAML::EndMap;
  out << YAML::Key << "calibration" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "summary" << YAML::Value << annotation.summary;
  out << YAML::Key << "std_dev" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : annotation.std_dev)
    out << YAML::Key << key << YAML::Value << value;
  out << YAML::EndMap << YAML::EndMap;
  out << YAML::EndMap << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path, std::ios::binary);
  file << out.c_str() << "\n";
  if (!file) return Error{path.string() + ": could not write"};
  return Status::Ok();
}

Eigen::Vector3d PlateLayout::Corner(int id, int c) const {
  const Eigen::Vector3d centre = aruco_centers_mm.at(id);
  const double h = aruco_side_mm / 2;
  static constexpr double kSign[4][2] = {{-1, 1}, {1, 1}, {1, -1}, {-1, -1}};
  return centre + Eigen::Vector3d(kSign[c][0] * h, kSign[c][1] * h, 0);
}

Expected<PlateLayout> ReadPlateLayout(const fs::path& path) {
  Expected<YamlNode> root = ParseFile(path);
  if (!root) return root.error();
  YamlErrors errors;
  YamlMap top(*root, &errors);
  std::optional<YamlMap> plate = top.Map("plate", Presence::kRequired);
  if (!plate) return errors.status().error();
  PlateLayout layout;
  std::string dictionary = "DICT_6X6_250";
  plate->Read("aruco_dictionary", &dictionary, Presence::kOptional);
  if (dictionary != "DICT_6X6_250")
    plate->Fail(plate->node(), "aruco_dictionary: only DICT_6X6_250 is supported, got '" +
                                   Excerpt(dictionary) + "'");
  plate->Read("aruco_side_mm", &layout.aruco_side_mm, Presence::kRequired);
  if (std::optional<YamlMap> centres = plate->Map("aruco_centers_mm", Presence::kRequired)) {
    for (int id = 0; id < 250; ++id) {
      std::optional<YamlNode> c = centres->Child(std::to_string(id), Presence::kOptional);
      if (!c) continue;
      Eigen::Vector3d p;
      if (ReadNumbers(*c, 3, p.data(), &errors)) layout.aruco_centers_mm[id] = p;
    }
  }
  if (!errors.ok()) return errors.status().error();
  if (!(layout.aruco_side_mm > 0))
    return root->ErrorAtPath("/plate/aruco_side_mm", "expected a number > 0");
  if (layout.aruco_centers_mm.empty())
    return root->ErrorAtPath("/plate/aruco_centers_mm", "expected at least one marker");
  return layout;
}

}  // namespace lifmcr::registration
