#include "replay/synth/synth_params.h"

#include "config/frames.h"

#include "config/input_file.h"
#include "config/text_escape.h"
#include "config/yaml_reader.h"

#include <cmath>
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
  if (knock_frame < -1 || knock_frame >= frames)
    return FieldError("rig.knock_frame", "expected -1 (never) or a trigger 0..frames-1");
  if (knock_frame >= 0 && !rigid) return FieldError("rig.knock_frame", "needs rig.rigid: true");
  for (const int f : render_frames)
    if (f < 0 || f >= frames)
      return FieldError("rig.render_frames", "expected triggers 0..frames-1, got " + std::to_string(f));
  if (!(std::abs(knock_t_mm) <= 100)) return FieldError("rig.knock_t_mm", "expected -100..100 mm");
  if (!(std::abs(knock_r_deg) <= 10)) return FieldError("rig.knock_r_deg", "expected -10..10 deg");
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

constexpr Presence kOptional = Presence::kOptional;

void ReadCamera(YamlMap& m, SynthCameraParams* c) {
  m.Read("width_px", &c->width_px, kOptional);
  m.Read("height_px", &c->height_px, kOptional);
  m.Read("pixel_size_mm", &c->pixel_size_mm, kOptional);
  m.Read("main_focal_length_mm", &c->main_focal_length_mm, kOptional);
  m.Read("f_number", &c->f_number, kOptional);
  m.Read("mla_to_main_lens_mm", &c->mla_to_main_lens_mm, kOptional);
  m.Read("mla_to_sensor_mm", &c->mla_to_sensor_mm, kOptional);
  m.Read("micro_image_pitch_px", &c->micro_image_pitch_px, kOptional);
  m.Read("mla_rotation_rad", &c->mla_rotation_rad, kOptional);
  std::vector<double> offset = {c->mla_offset_px.x(), c->mla_offset_px.y()};
  m.ReadNumbers("mla_offset_px", 2, &offset, kOptional);
  c->mla_offset_px = {offset[0], offset[1]};
  m.Read("mla_tilt_x_rad", &c->mla_tilt_x_rad, kOptional);
  m.Read("mla_tilt_y_rad", &c->mla_tilt_y_rad, kOptional);
  std::vector<double> focal(c->micro_lens_focal_mm.begin(), c->micro_lens_focal_mm.end());
  m.ReadNumbers("micro_lens_focal_mm", 3, &focal, kOptional);
  for (int t = 0; t < 3; ++t) c->micro_lens_focal_mm[t] = focal[t];
  m.Read("sharp_blur_px", &c->sharp_blur_px, kOptional);
  m.Read("lens_border_px", &c->lens_border_px, kOptional);
  m.Read("distortion_k1", &c->distortion_k1, kOptional);
  m.Read("distortion_k2", &c->distortion_k2, kOptional);
  m.Read("distortion_p1", &c->distortion_p1, kOptional);
  m.Read("distortion_p2", &c->distortion_p2, kOptional);
  m.Read("bayer", &c->bayer, kOptional);
  m.Read("white_level_dn", &c->white_level_dn, kOptional);
  m.Read("full_well_e", &c->full_well_e, kOptional);
  m.Read("read_noise_dn", &c->read_noise_dn, kOptional);
  m.Finish();
}

void ReadRig(YamlMap& m, SynthRigParams* r) {
  m.Read("cameras", &r->cameras, kOptional);
  m.Read("frames", &r->frames, kOptional);
  m.Read("motion", &r->motion, kOptional);
  m.Read("viewing_distance_mm", &r->viewing_distance_mm, kOptional);
  m.Read("baseline_mm", &r->baseline_mm, kOptional);
  m.Read("speed_scale", &r->speed_scale, kOptional);
  m.Read("rigid", &r->rigid, kOptional);
  m.Read("knock_frame", &r->knock_frame, kOptional);
  m.Read("knock_t_mm", &r->knock_t_mm, kOptional);
  m.Read("knock_r_deg", &r->knock_r_deg, kOptional);
  m.Read("scene", &r->scene, kOptional);
  m.Read("scene_folder", &r->scene_folder, kOptional);
  m.Read("sequence", &r->sequence, kOptional);
  std::int64_t seed = static_cast<std::int64_t>(r->seed);
  m.Read("seed", &seed, kOptional);
  if (seed < 0) {
    m.Fail(*m.Child("seed", kOptional), "expected an integer >= 0, got " + std::to_string(seed));
  }
  r->seed = static_cast<std::uint64_t>(seed);
  m.Finish();
}

void ReadVicon(YamlMap& m, SynthViconParams* v) {
  m.Read("rate_hz", &v->rate_hz, kOptional);
  m.Read("trigger_divider", &v->trigger_divider, kOptional);
  m.Read("first_trigger_frame", &v->first_trigger_frame, kOptional);
  m.Read("lead_in_frames", &v->lead_in_frames, kOptional);
  m.Read("marker_noise_mm", &v->marker_noise_mm, kOptional);
  m.Read("occlusion_gaps", &v->occlusion_gaps, kOptional);
  m.Read("occlusion_gap_frames", &v->occlusion_gap_frames, kOptional);
  m.Read("handedness", &v->handedness, kOptional);
  m.Read("rotation", &v->rotation, kOptional);
  m.Finish();
}

}  // namespace

// Through the strict reader (config/yaml_reader.h): quoted numbers, empty
// values, duplicate and unknown keys are errors with file:line:column.
Expected<SynthParams> ParseSynthConfig(const std::string& text, const std::string& label,
                                       SynthParams base) {
  Expected<YamlNode> root_node = YamlNode::Parse(text, label);
  if (!root_node) return root_node.error();
  if (root_node->IsNull()) return base;
  YamlErrors errors;
  YamlMap root(*root_node, &errors);
  // A preset named in the file replaces the base before the other keys apply.
  std::string preset;
  const std::optional<YamlNode> preset_node = root.Child("preset", kOptional);
  root.Read("preset", &preset, kOptional);
  if (errors.ok() && preset_node) {
    Expected<SynthParams> named = MakePreset(preset);
    if (named) {
      base = *named;
    } else {
      root.Fail(*preset_node, named.error().message);
    }
  }
  if (auto camera = root.Map("camera", kOptional)) ReadCamera(*camera, &base.camera);
  if (auto rig = root.Map("rig", kOptional)) ReadRig(*rig, &base.rig);
  if (auto vicon = root.Map("vicon", kOptional)) ReadVicon(*vicon, &base.vicon);
  root.Finish();
  if (!errors.ok()) return errors.status().error();
  if (Status s = base.Check(); !s) return MakeErrorAt(label, "/", s.error().message);
  return base;
}

Expected<SynthParams> LoadSynthConfig(const std::filesystem::path& path, SynthParams base) {
  Expected<std::string> text = ReadInputText(path, {"a synth config (YAML)", 1 << 20});
  if (!text) return text.error();
  return ParseSynthConfig(*text, EscapeText(path.string()), std::move(base));
}

}  // namespace lifmcr::synth
