#include "tests/processing/synth_frame.h"

#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"

namespace lifmcr::processing::testing {

SynthFrame RenderSynthFrame(const std::string& preset, double read_noise_dn,
                            const std::string& scene_name, bool bayer) {
  SynthFrame f;
  const synth::SynthParams params = *synth::MakePreset(preset);
  f.params = params.camera;
  f.params.read_noise_dn = read_noise_dn;
  f.params.bayer = bayer;
  f.model = std::make_unique<synth::PlenopticModel>(f.params);
  const synth::Scene scene = *synth::MakeScene(scene_name, params.rig.seed);
  synth::TrajectoryParams tp;
  tp.target_mm = scene.Target();
  tp.distance_mm = params.rig.viewing_distance_mm;
  const Pose world_from_cam = synth::CameraTrajectory(tp).WorldFromCam(0.0);
  synth::RenderOptions options;
  options.noise_seed = 7;
  f.raw = synth::RenderRaw(*f.model, scene, world_from_cam, options);
  options.noise_seed = 8;
  f.white = synth::RenderRaw(*f.model, synth::MakeWhiteScene(), Pose::Identity(), options);
  f.tf = synth::RenderTfGroundTruth(*f.model, scene, world_from_cam);
  f.mla = f.model->ToMlaCalibration();
  CameraIntrinsics& k = f.intrinsics;
  k.main_focal_length_mm = f.params.main_focal_length_mm;
  k.mla_to_main_lens_mm = f.params.mla_to_main_lens_mm;
  k.mla_to_sensor_mm = f.params.mla_to_sensor_mm;
  k.pixel_size_mm = f.params.pixel_size_mm;
  k.width_px = f.params.width_px;
  k.height_px = f.params.height_px;
  k.k1 = f.params.distortion_k1;
  k.k2 = f.params.distortion_k2;
  k.p1 = f.params.distortion_p1;
  k.p2 = f.params.distortion_p2;
  return f;
}

}  // namespace lifmcr::processing::testing
