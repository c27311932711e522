#include "replay/synth/synth_params.h"

#include "config/frames.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <sstream>
#include <vector>

namespace lifmcr::synth {
namespace {

Status FieldError(const std::string& field, const std::string& what) {
  return Error{field + ": " + what};
}

// Micro-lens focal length that makes a type sharp at virtual depth v:
// B / f = 1 - 1 / v (plenoptic_model.h, "Defocus").
double FocalForSharpDepth(double mla_to_sensor_mm, double v) {
  return mla_to_sensor_mm / (1.0 - 1.0 / v);
}

// Fills the optics from the few numbers that define a preset: the MLA -> sensor
// distance B follows from f-number matching (micro images nearly touch, with
// a 3 % gap as in real white images), b_L0 from the distance at which
// v = 2 (the total covering plane), the micro-lens focal lengths from the
// virtual depths at which the three types are sharp.
void DeriveOptics(SynthCameraParams* c, double v2_distance_mm) {
  const double aperture_mm = c->main_focal_length_mm / c->f_number;
  // disc = A B / (b_L0 s) = 0.97 D, with b_L0 ~ f_L for the first estimate.
  double b_l0 = c->main_focal_length_mm;
  for (int i = 0; i < 3; ++i) {
    c->mla_to_sensor_mm = 0.97 * c->micro_image_pitch_px * c->pixel_size_mm * b_l0 / aperture_mm;
    const double b_at_v2 =
        c->main_focal_length_mm * v2_distance_mm / (v2_distance_mm - c->main_focal_length_mm);
    b_l0 = b_at_v2 - 2.0 * c->mla_to_sensor_mm;
  }
  c->mla_to_main_lens_mm = b_l0;
  const std::array<double, 3> sharp_v{2.0, 3.3, 6.0};
  for (int t = 0; t < 3; ++t)
    c->micro_lens_focal_mm[t] = FocalForSharpDepth(c->mla_to_sensor_mm, sharp_v[t]);
  c->sharp_blur_px = 0.1 * c->micro_image_pitch_px;
}

}  // namespace

Status SynthCameraParams::Check() const {
  if (width_px < 64 || height_px < 64 || width_px > 20000 || height_px > 20000)
    return FieldError("camera.width_px/height_px", "expected 64..20000 pixels");
  if (!(pixel_size_mm > 0 && pixel_size_mm < 0.1))
    return FieldError("camera.pixel_size_mm", "expected 0 < s < 0.1 mm");
  if (!(main_focal_length_mm > 1 && main_focal_length_mm < 1000))
    return FieldError("camera.main_focal_length_mm", "expected 1..1000 mm");
  if (!(f_number >= 0.5 && f_number < 64)) return FieldError("camera.f_number", "expected 0.5..64");
  if (!(mla_to_sensor_mm > 0 && mla_to_sensor_mm < 0.2 * mla_to_main_lens_mm))
    return FieldError("camera.mla_to_sensor_mm", "expected 0 < B < b_L0 / 5");
  if (!(mla_to_main_lens_mm > 0.5 * main_focal_length_mm &&
        mla_to_main_lens_mm < 2 * main_focal_length_mm))
    return FieldError("camera.mla_to_main_lens_mm", "expected f_L/2 < b_L0 < 2 f_L");
  if (!(micro_image_pitch_px >= 6 && micro_image_pitch_px <= 200))
    return FieldError("camera.micro_image_pitch_px", "expected 6..200 px");
  if (!(std::abs(mla_rotation_rad) < 0.2))
    return FieldError("camera.mla_rotation_rad", "expected |rotation| < 0.2 rad");
  if (!(std::abs(mla_offset_px.x()) <= micro_image_pitch_px &&
        std::abs(mla_offset_px.y()) <= micro_image_pitch_px))
    return FieldError("camera.mla_offset_px", "expected |offset| <= one pitch");
  if (!(std::abs(mla_tilt_x_rad) <= 1e-3 && std::abs(mla_tilt_y_rad) <= 1e-3))
    return FieldError("camera.mla_tilt_x_rad/mla_tilt_y_rad", "expected |tilt| <= 1e-3 rad");
  for (int t = 0; t < 3; ++t)
    if (!(micro_lens_focal_mm[t] > mla_to_sensor_mm &&
          micro_lens_focal_mm[t] < 20 * mla_to_sensor_mm))
      return FieldError("camera.micro_lens_focal_mm[" + std::to_string(t) + "]",
                        "expected B < f < 20 B (Galilean mode, sharp at v > 1)");
  if (!(sharp_blur_px > 0)) return FieldError("camera.sharp_blur_px", "expected > 0");
  if (!(lens_border_px >= 0 && lens_border_px < micro_image_pitch_px / 4))
    return FieldError("camera.lens_border_px", "expected 0 <= border < D/4");
  for (double k : {distortion_k1, distortion_k2, distortion_p1, distortion_p2})
    if (!std::isfinite(k) || std::abs(k) > 0.1)
      return FieldError("camera.distortion_*", "expected |coefficient| <= 0.1");
  if (!(white_level_dn > 0 && white_level_dn <= 255))
    return FieldError("camera.white_level_dn", "expected 0 < level <= 255");
  if (!(full_well_e >= 0)) return FieldError("camera.full_well_e", "expected >= 0");
  if (!(read_noise_dn >= 0 && read_noise_dn < 100))
    return FieldError("camera.read_noise_dn", "expected 0..100 DN");
  return Status::Ok();
}

Status SynthRigParams::Check() const {
  if (cameras < 1 || cameras > 8) return FieldError("rig.cameras", "expected 1..8");
  if (frames < 1 || frames > 100000) return FieldError("rig.frames", "expected 1..100000");
  if (motion != "smooth" && motion != "handheld" && motion != "axis" && motion != "circle" &&
      motion != "orbit")
    return FieldError("rig.motion",
                      "expected smooth|handheld|axis|circle|orbit, got '" + motion + "'");
  if (!(viewing_distance_mm >= 200 && viewing_distance_mm <= 5000))
    return FieldError("rig.viewing_distance_mm", "expected 200..5000 mm");
  if (!(baseline_mm >= 0 && baseline_mm <= 1000))
    return FieldError("rig.baseline_mm", "expected 0..1000 mm");
  if (!(speed_scale >= 0 && speed_scale <= 10))
    return FieldError("rig.speed_scale", "expected 0..10");
  auto plain = [](const std::string& name) {
    if (name.empty() || name == "." || name == "..") return false;
    for (char ch : name)
      if (!(std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-')) return false;
    return true;
  };
  if (scene != "table" && scene != "plain")
    return FieldError("rig.scene", "expected table|plain, got '" + scene +
                                       "' (the folder name is rig.scene_folder, --scene-folder)");
  if (!plain(scene_folder))
    return FieldError("rig.scene_folder", "expected letters, digits, '_' or '-'");
  if (!plain(sequence)) return FieldError("rig.sequence", "expected letters, digits, '_' or '-'");
  return Status::Ok();
}

Status SynthViconParams::Check() const {
  if (rate_hz < 1 || rate_hz > 2000) return FieldError("vicon.rate_hz", "expected 1..2000 Hz");
  if (trigger_divider < 1 || trigger_divider > 1000)
    return FieldError("vicon.trigger_divider", "expected 1..1000");
  if (first_trigger_frame < 0) return FieldError("vicon.first_trigger_frame", "expected >= 0");
  if (lead_in_frames < 0 || lead_in_frames > 100000)
    return FieldError("vicon.lead_in_frames", "expected 0..100000");
  if (!(marker_noise_mm >= 0 && marker_noise_mm < 10))
    return FieldError("vicon.marker_noise_mm", "expected 0..10 mm");
  if (occlusion_gaps < 0 || occlusion_gap_frames < 1)
    return FieldError("vicon.occlusion_gaps", "expected gaps >= 0 of >= 1 frame");
  if (!ParseHandedness(handedness))
    return FieldError("vicon.handedness", "expected right|left_flip_x|left_flip_y|left_flip_z");
  if (!ParseRotationRepresentation(rotation))
    return FieldError("vicon.rotation", "expected " + RotationRepresentationNames());
  return Status::Ok();
}

Status SynthParams::Check() const {
  if (Status s = camera.Check(); !s) return s;
  if (Status s = rig.Check(); !s) return s;
  return vicon.Check();
}

std::string_view PresetNames() { return "small|medium|r32"; }

Expected<SynthParams> MakePreset(std::string_view name) {
  SynthParams params;
  params.preset = std::string(name);
  SynthCameraParams& c = params.camera;
  if (name == "small") {
    c.width_px = 1024;
    c.height_px = 768;
    c.pixel_size_mm = 0.0055;
    c.micro_image_pitch_px = 16.0;
    c.mla_offset_px = {0.3, -0.2};
    DeriveOptics(&c, 3000.0);
    params.rig.viewing_distance_mm = 1100;
  } else if (name == "medium") {
    c.width_px = 3280;
    c.height_px = 2474;
    c.pixel_size_mm = 0.0064;
    c.micro_image_pitch_px = 24.0;
    c.mla_offset_px = {4.1, -3.3};
    c.mla_rotation_rad = 1.5e-4;
    DeriveOptics(&c, 3000.0);
    params.rig.viewing_distance_mm = 800;
  } else if (name == "r32") {
    c.width_px = 6560;
    c.height_px = 4948;
    c.pixel_size_mm = 0.0032;
    c.micro_image_pitch_px = 34.0;
    c.mla_offset_px = {17.4, 14.8};  // of the order of the real R42 file
    c.mla_rotation_rad = 2.5e-5;     // of the order of the real R29 file
    DeriveOptics(&c, 3000.0);
    params.rig.viewing_distance_mm = 800;
  } else {
    return Error{"unknown preset '" + std::string(name) + "', expected " +
                 std::string(PresetNames())};
  }
  return params;
}

namespace {

// One settable field: its YAML key and how to read it.
struct Field {
  std::string key;
  std::function<bool(const YAML::Node&)> set;  // false: wrong type
  std::string expected;
};

template <typename T>
Field Scalar(const std::string& key, T* target, const std::string& expected) {
  return {key,
          [target](const YAML::Node& node) {
            if (!node.IsScalar()) return false;
            try {
              *target = node.as<T>();
            } catch (const YAML::Exception&) {
              return false;
            }
            return true;
          },
          expected};
}

Field Vec2(const std::string& key, Eigen::Vector2d* target) {
  return {key,
          [target](const YAML::Node& node) {
            if (!node.IsSequence() || node.size() != 2) return false;
            try {
              *target = {node[0].as<double>(), node[1].as<double>()};
            } catch (const YAML::Exception&) {
              return false;
            }
            return true;
          },
          "a list of two numbers [x, y]"};
}

Field Vec3(const std::string& key, std::array<double, 3>* target) {
  return {key,
          [target](const YAML::Node& node) {
            if (!node.IsSequence() || node.size() != 3) return false;
            try {
              for (int i = 0; i < 3; ++i) (*target)[i] = node[i].as<double>();
            } catch (const YAML::Exception&) {
              return false;
            }
            return true;
          },
          "a list of three numbers"};
}

std::vector<Field> CameraFields(SynthCameraParams* c) {
  const std::string num = "a number";
  return {Scalar("width_px", &c->width_px, "an integer"),
          Scalar("height_px", &c->height_px, "an integer"),
          Scalar("pixel_size_mm", &c->pixel_size_mm, num),
          Scalar("main_focal_length_mm", &c->main_focal_length_mm, num),
          Scalar("f_number", &c->f_number, num),
          Scalar("mla_to_main_lens_mm", &c->mla_to_main_lens_mm, num),
          Scalar("mla_to_sensor_mm", &c->mla_to_sensor_mm, num),
          Scalar("micro_image_pitch_px", &c->micro_image_pitch_px, num),
          Scalar("mla_rotation_rad", &c->mla_rotation_rad, num),
          Vec2("mla_offset_px", &c->mla_offset_px),
          Scalar("mla_tilt_x_rad", &c->mla_tilt_x_rad, num),
          Scalar("mla_tilt_y_rad", &c->mla_tilt_y_rad, num),
          Vec3("micro_lens_focal_mm", &c->micro_lens_focal_mm),
          Scalar("sharp_blur_px", &c->sharp_blur_px, num),
          Scalar("lens_border_px", &c->lens_border_px, num),
          Scalar("distortion_k1", &c->distortion_k1, num),
          Scalar("distortion_k2", &c->distortion_k2, num),
          Scalar("distortion_p1", &c->distortion_p1, num),
          Scalar("distortion_p2", &c->distortion_p2, num),
          Scalar("bayer", &c->bayer, "true or false"),
          Scalar("white_level_dn", &c->white_level_dn, num),
          Scalar("full_well_e", &c->full_well_e, num),
          Scalar("read_noise_dn", &c->read_noise_dn, num)};
}

std::vector<Field> RigFields(SynthRigParams* r) {
  return {Scalar("cameras", &r->cameras, "an integer"),
          Scalar("frames", &r->frames, "an integer"),
          Scalar("motion", &r->motion, "a string"),
          Scalar("viewing_distance_mm", &r->viewing_distance_mm, "a number"),
          Scalar("baseline_mm", &r->baseline_mm, "a number"),
          Scalar("speed_scale", &r->speed_scale, "a number"),
          Scalar("scene", &r->scene, "a string"),
          Scalar("scene_folder", &r->scene_folder, "a string"),
          Scalar("sequence", &r->sequence, "a string"),
          Scalar("seed", &r->seed, "an unsigned integer")};
}

std::vector<Field> ViconFields(SynthViconParams* v) {
  return {Scalar("rate_hz", &v->rate_hz, "an integer"),
          Scalar("trigger_divider", &v->trigger_divider, "an integer"),
          Scalar("first_trigger_frame", &v->first_trigger_frame, "an integer"),
          Scalar("lead_in_frames", &v->lead_in_frames, "an integer"),
          Scalar("marker_noise_mm", &v->marker_noise_mm, "a number"),
          Scalar("occlusion_gaps", &v->occlusion_gaps, "an integer"),
          Scalar("occlusion_gap_frames", &v->occlusion_gap_frames, "an integer"),
          Scalar("handedness", &v->handedness, "a string"),
          Scalar("rotation", &v->rotation, "a string")};
}

Error At(const std::string& label, const YAML::Mark& mark, const std::string& key,
         const std::string& what) {
  return MakeError(label, mark.line + 1, mark.column + 1, key + ": " + what);
}

Status ApplyGroup(const std::string& label, const std::string& group, const YAML::Node& node,
                  const std::vector<Field>& fields) {
  if (!node.IsMap()) return At(label, node.Mark(), "/" + group, "expected a mapping");
  for (const auto& entry : node) {
    const std::string key = entry.first.as<std::string>();
    const std::string path = "/" + group + "/" + key;
    const Field* field = nullptr;
    for (const Field& f : fields)
      if (f.key == key) field = &f;
    if (field == nullptr) {
      std::string known;
      for (const Field& f : fields) known += (known.empty() ? "" : ", ") + f.key;
      return At(label, entry.first.Mark(), path, "unknown key, expected one of: " + known);
    }
    if (!field->set(entry.second))
      return At(label, entry.second.Mark(), path, "expected " + field->expected);
  }
  return Status::Ok();
}

}  // namespace

Expected<SynthParams> ParseSynthConfig(const std::string& text, const std::string& label,
                                       SynthParams base) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    return MakeError(label, e.mark.line + 1, e.mark.column + 1, "YAML syntax: " + e.msg);
  }
  if (root.IsNull()) return base;
  if (!root.IsMap()) return At(label, root.Mark(), "/", "expected a mapping");
  // A preset named in the file replaces the base before the other keys apply.
  if (const YAML::Node preset = root["preset"]) {
    if (!preset.IsScalar()) return At(label, preset.Mark(), "/preset", "expected a preset name");
    Expected<SynthParams> named = MakePreset(preset.as<std::string>());
    if (!named) return At(label, preset.Mark(), "/preset", named.error().message);
    base = *named;
  }
  for (const auto& entry : root) {
    const std::string key = entry.first.as<std::string>();
    Status status;
    if (key == "preset") continue;
    if (key == "camera")
      status = ApplyGroup(label, key, entry.second, CameraFields(&base.camera));
    else if (key == "rig")
      status = ApplyGroup(label, key, entry.second, RigFields(&base.rig));
    else if (key == "vicon")
      status = ApplyGroup(label, key, entry.second, ViconFields(&base.vicon));
    else
      return At(label, entry.first.Mark(), "/" + key,
                "unknown key, expected one of: preset, camera, rig, vicon");
    if (!status) return status.error();
  }
  if (Status s = base.Check(); !s) return MakeErrorAt(label, "/", s.error().message);
  return base;
}

Expected<SynthParams> LoadSynthConfig(const std::filesystem::path& path, SynthParams base) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeErrorAt(path.string(), "/", "cannot open the synth config file");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseSynthConfig(text.str(), path.string(), std::move(base));
}

}  // namespace lifmcr::synth
