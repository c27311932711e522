#include "tests/processing/synth_frame.h"

#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"

#include <algorithm>
#include <cmath>

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

DepthGates MeasureDepthGates(const SynthFrame& frame, const std::vector<float>& virtual_depth,
                             const std::vector<std::uint8_t>& textured) {
  DepthGates g;
  long long covered = 0, outliers = 0;
  std::vector<double> rel_z;
  for (std::size_t i = 0; i < virtual_depth.size(); ++i) {
    const float truth = frame.raw.virtual_depth[i];
    if (!textured[i] || std::isnan(truth)) continue;
    ++g.textured;
    const float v = virtual_depth[i];
    if (std::isnan(v)) continue;
    ++covered;
    rel_z.push_back(std::abs(1.0 / v - 1.0 / truth) * truth);
    if (std::abs(v - truth) / truth > 0.10) ++outliers;
  }
  if (g.textured < 10000 || rel_z.empty()) return g;
  std::nth_element(rel_z.begin(), rel_z.begin() + rel_z.size() / 2, rel_z.end());
  g.coverage = static_cast<double>(covered) / g.textured;
  g.median = rel_z[rel_z.size() / 2];
  g.outliers = static_cast<double>(outliers) / covered;
  return g;
}

DepthGates DepthGatesOf(const SynthFrame& s, ConstImageView raw, ConstImageView white,
                        PlenopticFrame* prepared, VirtualDepthMap* depth) {
  const CameraModel camera(s.intrinsics);
  const MlaGrid grid = MlaGrid::FromCalibration(s.mla, raw.width, raw.height);
  FrameOptions options;
  options.lambda = camera.lambda();
  if (!PrepareFrame(raw, white, grid, s.mla, options, prepared).ok() ||
      !EstimateVirtualDepth(*prepared, s.mla, DepthOptions{}, depth).ok())
    return DepthGates{};
  return MeasureDepthGates(s, depth->virtual_depth, depth->textured);
}

}  // namespace lifmcr::processing::testing
