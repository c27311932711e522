#include "replay/synth/cameras_yaml.h"

#include "replay/synth/plenoptic_model.h"

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

namespace lifmcr::synth {
namespace {

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

}  // namespace lifmcr::synth
