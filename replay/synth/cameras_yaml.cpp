#include "replay/synth/cameras_yaml.h"

#include "config/input_file.h"
#include "config/text_escape.h"
#include "config/yaml_reader.h"
#include "replay/synth/plenoptic_model.h"

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <optional>

namespace lifmcr::synth {
namespace {

// Shortest text that reads back to the same double, for messages.
std::string ShortestNumber(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

void EmitPose(YAML::Emitter& out, const char* key, const Pose& pose) {
  const Eigen::Quaterniond q(pose.linear());
  const Eigen::Vector3d t = pose.translation();
  out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "tx_mm" << YAML::Value << t.x() << YAML::Key << "ty_mm" << YAML::Value
      << t.y() << YAML::Key << "tz_mm" << YAML::Value << t.z();
  out << YAML::Key << "qw" << YAML::Value << q.w() << YAML::Key << "qx" << YAML::Value << q.x()
      << YAML::Key << "qy" << YAML::Value << q.y() << YAML::Key << "qz" << YAML::Value << q.z();
  out << YAML::EndMap;
}

template <typename V>
void EmitVector(YAML::Emitter& out, const char* key, const V& v) {
  out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (int k = 0; k < v.size(); ++k) out << v[k];
  out << YAML::EndSeq;
}

void EmitCameraModel(YAML::Emitter& out, const SynthCameraParams& c) {
  const PlenopticModel model(c);
  out << YAML::Key << "model" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "width_px" << YAML::Value << c.width_px;
  out << YAML::Key << "height_px" << YAML::Value << c.height_px;
  out << YAML::Key << "pixel_size_mm" << YAML::Value << c.pixel_size_mm;
  out << YAML::Key << "main_focal_length_mm" << YAML::Value << c.main_focal_length_mm;
  out << YAML::Key << "f_number" << YAML::Value << c.f_number;
  out << YAML::Key << "aperture_mm" << YAML::Value << model.aperture_mm();
  out << YAML::Key << "mla_to_main_lens_mm" << YAML::Value << c.mla_to_main_lens_mm;
  out << YAML::Key << "mla_to_sensor_mm" << YAML::Value << c.mla_to_sensor_mm;
  EmitVector(out, "principal_point_px", model.principal_point_px());
  out << YAML::Key << "micro_image_pitch_px" << YAML::Value << c.micro_image_pitch_px;
  out << YAML::Key << "micro_lens_pitch_mm" << YAML::Value << model.micro_lens_pitch_mm();
  out << YAML::Key << "micro_image_disc_px" << YAML::Value << model.micro_image_disc_px();
  out << YAML::Key << "mla_rotation_rad" << YAML::Value << c.mla_rotation_rad;
  EmitVector(out, "mla_offset_px", c.mla_offset_px);
  out << YAML::Key << "mla_tilt_x_rad" << YAML::Value << c.mla_tilt_x_rad;
  out << YAML::Key << "mla_tilt_y_rad" << YAML::Value << c.mla_tilt_y_rad;
  out << YAML::Key << "lens_border_px" << YAML::Value << c.lens_border_px;
  out << YAML::Key << "total_covering_plane" << YAML::Value << model.TotalCoveringPlane();
  out << YAML::Key << "sharp_blur_px" << YAML::Value << c.sharp_blur_px;
  out << YAML::Key << "lens_types" << YAML::Value << YAML::BeginSeq;
  for (int t = 0; t < 3; ++t) {
    const double f = c.micro_lens_focal_mm[t];
    const Eigen::Vector2d range = model.SharpRange(t);
    out << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "id" << YAML::Value << t;
    out << YAML::Key << "focal_length_mm" << YAML::Value << f;
    out << YAML::Key << "sharp_virtual_depth" << YAML::Value
        << 1.0 / (1.0 - c.mla_to_sensor_mm / f);
    out << YAML::Key << "depth_min" << YAML::Value << range.x();
    out << YAML::Key << "depth_max" << YAML::Value << range.y();
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "distortion" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "model" << YAML::Value << "lifcal_mla_plane_mm";
  out << YAML::Key << "k1" << YAML::Value << c.distortion_k1 << YAML::Key << "k2" << YAML::Value
      << c.distortion_k2 << YAML::Key << "p1" << YAML::Value << c.distortion_p1 << YAML::Key << "p2"
      << YAML::Value << c.distortion_p2;
  out << YAML::EndMap;
  out << YAML::Key << "bayer" << YAML::Value << (c.bayer ? "RGGB" : "none");
  out << YAML::Key << "white_level_dn" << YAML::Value << c.white_level_dn;
  out << YAML::Key << "full_well_e" << YAML::Value << c.full_well_e;
  out << YAML::Key << "read_noise_dn" << YAML::Value << c.read_noise_dn;
  out << YAML::Key << "tf_width_px" << YAML::Value << model.tf_width();
  out << YAML::Key << "tf_height_px" << YAML::Value << model.tf_height();
  out << YAML::Key << "tf_pixel_to_raw" << YAML::Value << "raw = 2 * tf + 0.5";
  out << YAML::EndMap;
  const MlaCalibration mla = model.ToMlaCalibration();
  out << YAML::Key << "mla_file" << YAML::Value << YAML::BeginMap;
  EmitVector(out, "offset_px", mla.offset_px);
  out << YAML::Key << "diameter_px" << YAML::Value << mla.diameter_px;
  out << YAML::Key << "rotation_rad" << YAML::Value << mla.rotation_rad;
  out << YAML::Key << "tcp" << YAML::Value << mla.tcp_virtual_depth;
  EmitVector(out, "reference_lens_center_px", mla.ReferenceLensCenterPx(c.width_px, c.height_px));
  out << YAML::EndMap;
}

}  // namespace

std::string FormatCamerasYaml(const SynthParams& params, const std::vector<SynthCamera>& cameras,
                              const MarkerPlateLayout& plate, const Pose& vicon_from_world,
                              const Pose& world_from_plate_marker) {
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "generator" << YAML::Value << "lifmcr synth";
  out << YAML::Key << "preset" << YAML::Value << params.preset;
  out << YAML::Key << "seed" << YAML::Value << params.rig.seed;
  out << YAML::Key << "motion" << YAML::Value << params.rig.motion;
  out << YAML::Key << "frames" << YAML::Value << params.rig.frames;
  out << YAML::Key << "conventions" << YAML::Value
      << "world = marker plate (origin bottom-left Vicon marker, x along the table, z up); camera "
         "x right, y down, z forward; poses a_from_b map b into a; mm, rad";
  out << YAML::Key << "plate" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "aruco_dictionary" << YAML::Value << "DICT_6X6_250";
  out << YAML::Key << "aruco_side_mm" << YAML::Value << plate.aruco_side_mm;
  out << YAML::Key << "aruco_centers_mm" << YAML::Value << YAML::BeginMap;
  for (int id = 0; id < 4; ++id) {
    out << YAML::Key << id;
    out << YAML::Value << YAML::Flow << YAML::BeginSeq << plate.aruco_centers_mm[id].x()
        << plate.aruco_centers_mm[id].y() << 0.0 << YAML::EndSeq;
  }
  out << YAML::EndMap;
  out << YAML::Key << "vicon_markers_mm" << YAML::Value << YAML::BeginSeq;
  for (const Eigen::Vector3d& m : plate.ViconMarkers()) {
    out << YAML::Flow << YAML::BeginSeq << m.x() << m.y() << m.z() << YAML::EndSeq;
  }
  out << YAML::EndSeq;
  out << YAML::EndMap;
  out << YAML::Key << "vicon" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "rate_hz" << YAML::Value << params.vicon.rate_hz;
  out << YAML::Key << "trigger_divider" << YAML::Value << params.vicon.trigger_divider;
  out << YAML::Key << "first_trigger_frame" << YAML::Value << params.vicon.first_trigger_frame;
  out << YAML::Key << "handedness" << YAML::Value << params.vicon.handedness;
  out << YAML::Key << "rotation" << YAML::Value << params.vicon.rotation;
  out << YAML::Key << "marker_noise_mm" << YAML::Value << params.vicon.marker_noise_mm;
  out << YAML::Key << "csv_file_index" << YAML::Value << kSequenceCsvIndex;
  out << YAML::Key << "plate_subject" << YAML::Value << std::string(kPlateSubject);
  EmitPose(out, "vicon_from_world", vicon_from_world);
  EmitPose(out, "world_from_plate_marker", world_from_plate_marker);
  out << YAML::EndMap;
  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginSeq;
  for (const SynthCamera& camera : cameras) {
    out << YAML::BeginMap;
    out << YAML::Key << "serial" << YAML::Value << YAML::DoubleQuoted << camera.serial;
    out << YAML::Key << "vicon_subject" << YAML::Value << camera.vicon_subject;
    EmitPose(out, "marker_from_cam", camera.marker_from_cam);
    out << YAML::Key << "cluster_markers_mm" << YAML::Value << YAML::BeginSeq;
    for (const Eigen::Vector3d& m : camera.cluster.markers_mm)
      out << YAML::Flow << YAML::BeginSeq << m.x() << m.y() << m.z() << YAML::EndSeq;
    out << YAML::EndSeq;
    EmitCameraModel(out, camera.params);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

Expected<CameraModelYaml> ParseCameraModelYaml(std::string_view text, const std::string& label,
                                               std::string_view serial) {
  constexpr Presence kRequired = Presence::kRequired;
  constexpr Presence kOptional = Presence::kOptional;
  Expected<YamlNode> root_node = YamlNode::Parse(text, label);
  if (!root_node) return root_node.error();
  YamlErrors errors;
  YamlMap root(*root_node, &errors);
  const std::optional<std::vector<YamlNode>> cameras = root.List("cameras", kRequired);
  if (!errors.ok()) return errors.status().error();
  for (const YamlNode& node : *cameras) {
    YamlMap camera(node, &errors);
    std::string camera_serial;
    camera.Read("serial", &camera_serial, kRequired);
    if (!errors.ok()) return errors.status().error();
    if (camera_serial != serial) continue;
    std::optional<YamlMap> model = camera.Map("model", kRequired);
    if (!errors.ok()) return errors.status().error();
    CameraModelYaml k;
    model->Read("width_px", &k.width_px, kRequired);
    model->Read("height_px", &k.height_px, kRequired);
    model->Read("pixel_size_mm", &k.pixel_size_mm, kRequired);
    model->Read("main_focal_length_mm", &k.main_focal_length_mm, kRequired);
    model->Read("mla_to_main_lens_mm", &k.mla_to_main_lens_mm, kRequired);
    model->Read("mla_to_sensor_mm", &k.mla_to_sensor_mm, kRequired);
    if (model->Child("principal_point_px", kOptional)) {
      std::vector<double> c;
      model->ReadNumbers("principal_point_px", 2, &c, kOptional);
      if (c.size() == 2) k.principal_point_px = std::array<double, 2>{c[0], c[1]};
    }
    if (std::optional<YamlMap> d = model->Map("distortion", kOptional)) {
      d->Read("k1", &k.k1, kOptional);
      d->Read("k2", &k.k2, kOptional);
      d->Read("p1", &k.p1, kOptional);
      d->Read("p2", &k.p2, kOptional);
    }
    if (!errors.ok()) return errors.status().error();
    const std::string at = node.path() + "/model/";
    const CameraModelLimits& l = kCameraModelLimits;
    const auto range = [&](const char* key, double value, double low, double high,
                           bool low_open) -> std::optional<Error> {
      if ((low_open ? value > low : value >= low) && value <= high) return std::nullopt;
      return root_node->ErrorAtPath(at + key, std::string("expected ") + (low_open ? "> " : "") +
                                                   ShortestNumber(low) + " .. " +
                                                   ShortestNumber(high) + ", got " +
                                                   ShortestNumber(value));
    };
    const std::optional<Error> problems[] = {
        range("width_px", k.width_px, 1, l.max_side_px, false),
        range("height_px", k.height_px, 1, l.max_side_px, false),
        range("pixel_size_mm", k.pixel_size_mm, 0, l.max_pixel_size_mm, true),
        range("main_focal_length_mm", k.main_focal_length_mm, 0, l.max_focal_length_mm, true),
        range("mla_to_main_lens_mm", k.mla_to_main_lens_mm, 0, l.max_focal_length_mm, true),
        range("mla_to_sensor_mm", k.mla_to_sensor_mm, 0, l.max_mla_to_sensor_mm, true),
        range("distortion/k1", std::abs(k.k1), 0, l.max_abs_distortion, false),
        range("distortion/k2", std::abs(k.k2), 0, l.max_abs_distortion, false),
        range("distortion/p1", std::abs(k.p1), 0, l.max_abs_distortion, false),
        range("distortion/p2", std::abs(k.p2), 0, l.max_abs_distortion, false),
        k.principal_point_px
            ? range("principal_point_px/0", (*k.principal_point_px)[0], 0, k.width_px - 1, false)
            : std::nullopt,
        k.principal_point_px
            ? range("principal_point_px/1", (*k.principal_point_px)[1], 0, k.height_px - 1, false)
            : std::nullopt,
    };
    for (const std::optional<Error>& problem : problems)
      if (problem) return *problem;
    // B < b_L0 relates two keys; the message names both values, so a tiny
    // b_L0 is not reported as a B out of range.
    if (!(k.mla_to_sensor_mm < k.mla_to_main_lens_mm))
      return root_node->ErrorAtPath(
          at + "mla_to_sensor_mm",
          "expected B less than mla_to_main_lens_mm b_L0 = " +
              ShortestNumber(k.mla_to_main_lens_mm) + " mm (the MLA sits between the main lens "
              "and the sensor), got " + ShortestNumber(k.mla_to_sensor_mm) + " mm");
    return k;
  }
  return root_node->ErrorAtPath("/cameras", "no camera with serial '" + Excerpt(serial) + "'");
}

Expected<CameraModelYaml> ReadCameraModelYaml(const std::filesystem::path& path,
                                              std::string_view serial) {
  Expected<std::string> text = ReadInputText(
      path, {"a cameras.yaml / intrinsics.yaml (YAML)", kCameraModelLimits.max_file_bytes});
  if (!text) return text.error();
  return ParseCameraModelYaml(*text, EscapeText(path.string()), serial);
}

Expected<std::vector<std::string>> ReadCameraSerialsYaml(const std::filesystem::path& path) {
  Expected<std::string> text = ReadInputText(
      path, {"a cameras.yaml / intrinsics.yaml (YAML)", kCameraModelLimits.max_file_bytes});
  if (!text) return text.error();
  Expected<YamlNode> root_node = YamlNode::Parse(*text, EscapeText(path.string()));
  if (!root_node) return root_node.error();
  YamlErrors errors;
  YamlMap root(*root_node, &errors);
  const std::optional<std::vector<YamlNode>> cameras = root.List("cameras", Presence::kRequired);
  if (!errors.ok()) return errors.status().error();
  std::vector<std::string> serials;
  for (const YamlNode& node : *cameras) {
    YamlMap camera(node, &errors);
    std::string serial;
    camera.Read("serial", &serial, Presence::kRequired);
    if (!errors.ok()) return errors.status().error();
    serials.push_back(serial);
  }
  return serials;
}

}  // namespace lifmcr::synth
