// Presets, YAML overrides and their errors; the sensor model (Bayer mosaic,
// noise) of the synthetic camera; `lifmcr synth` on the command line.

#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"
#include "tests/test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace lifmcr::synth {
namespace {

TEST(SynthParams, PresetsAreValidAndSized) {
  for (const char* name : {"small", "medium", "r32"}) {
    const Expected<SynthParams> params = MakePreset(name);
    ASSERT_TRUE(params.ok()) << name;
    EXPECT_TRUE(params->Check().ok()) << name << ": " << params->Check().error().message;
  }
  const Expected<SynthParams> small = MakePreset("small");
  EXPECT_EQ(small->camera.width_px, 1024);
  EXPECT_EQ(small->camera.height_px, 768);
  const PlenopticModel model(small->camera);
  EXPECT_GE(model.params().micro_image_pitch_px, 15.0);
  EXPECT_LE(model.params().micro_image_pitch_px, 20.0);
}

TEST(SynthParams, UnknownPresetNamesTheChoices) {
  const Expected<SynthParams> params = MakePreset("r33");
  ASSERT_FALSE(params.ok());
  EXPECT_NE(params.error().message.find("'r33'"), std::string::npos);
  EXPECT_NE(params.error().message.find("small|medium|r32"), std::string::npos);
}

TEST(SynthParams, YamlOverridesFields) {
  const Expected<SynthParams> params = ParseSynthConfig(
      "preset: r32\ncamera:\n  read_noise_dn: 2.5\n  bayer: true\n  mla_offset_px: [1.5, -2]\n"
      "rig:\n  frames: 7\n  motion: circle\nvicon:\n  occlusion_gaps: 2\n",
      "synth.yaml", *MakePreset("small"));
  ASSERT_TRUE(params.ok()) << params.error().message;
  EXPECT_EQ(params->preset, "r32");
  EXPECT_EQ(params->camera.width_px, 6560);
  EXPECT_DOUBLE_EQ(params->camera.read_noise_dn, 2.5);
  EXPECT_TRUE(params->camera.bayer);
  EXPECT_DOUBLE_EQ(params->camera.mla_offset_px.y(), -2.0);
  EXPECT_EQ(params->rig.frames, 7);
  EXPECT_EQ(params->rig.motion, "circle");
  EXPECT_EQ(params->rig.scene, "table");
  EXPECT_EQ(params->rig.scene_folder, "00_Synthetic");
  const Expected<SynthParams> folder = ParseSynthConfig(
      "rig:\n  scene: plain\n  scene_folder: 07_Plain\n", "synth.yaml", *MakePreset("small"));
  ASSERT_TRUE(folder.ok()) << folder.error().message;
  EXPECT_EQ(folder->rig.scene, "plain");
  EXPECT_EQ(folder->rig.scene_folder, "07_Plain");
  EXPECT_EQ(params->vicon.occlusion_gaps, 2);
}

TEST(SynthParams, YamlErrorsNameFileLineColumnAndKey) {
  const SynthParams base = *MakePreset("small");
  struct Case {
    std::string text, expected[3];
  };
  const Case cases[] = {
      {"camera:\n  widht_px: 100\n", {"synth.yaml:2:3", "/camera/widht_px", "unknown key"}},
      {"camera:\n  f_number: fast\n", {"synth.yaml:2:13", "/camera/f_number", "expected a finite number"}},
      {"rig:\n  frames: [1, 2]\n", {"synth.yaml:2:11", "/rig/frames", "expected an integer"}},
      // `scene` names the content; a folder name there points to scene_folder.
      {"rig:\n  scene: 00_Synthetic\n", {"rig.scene", "table|plain", "rig.scene_folder"}},
      {"rig:\n  scene_folder: a/b\n", {"synth.yaml", "rig.scene_folder", "letters"}},
      {"lens:\n  x: 1\n", {"synth.yaml:1:1", "/lens", "expected one of: preset"}},
      {"camera:\n  f_number: 0.1\n", {"synth.yaml", "camera.f_number", "0.5..64"}},
      {"preset: tiny\n", {"synth.yaml:1:9", "/preset", "unknown preset 'tiny'"}},
      {"camera: [\n", {"synth.yaml:", "malformed YAML", ""}},
      {"camera:\n  width_px: \"100\"\n", {"synth.yaml:2:13", "/camera/width_px", "expected an integer"}},
      {"rig:\n  seed: -1\n", {"synth.yaml:2:9", "/rig/seed", "expected an integer >= 0"}},
      {"camera:\n  mla_offset_px: [1]\n", {"synth.yaml:2:18", "/camera/mla_offset_px", "2 numbers"}},
      {"camera: {f_number: 2, f_number: 3}\n", {"synth.yaml", "/camera/f_number", "duplicate key"}},
  };
  for (const Case& c : cases) {
    const Expected<SynthParams> params = ParseSynthConfig(c.text, "synth.yaml", base);
    ASSERT_FALSE(params.ok()) << c.text;
    for (const std::string& part : c.expected)
      EXPECT_NE(params.error().message.find(part), std::string::npos)
          << "'" << params.error().message << "' lacks '" << part << "'";
  }
}

TEST(SynthParams, MissingConfigFileIsAnError) {
  const Expected<SynthParams> params = LoadSynthConfig("/nonexistent/synth.yaml", SynthParams{});
  ASSERT_FALSE(params.ok());
  EXPECT_NE(params.error().message.find("/nonexistent/synth.yaml"), std::string::npos);
}

// The mosaic keeps, at each site, the channel of the RGGB pattern.
TEST(SynthSensor, BayerMosaicSamplesTheRggbChannel) {
  SynthCameraParams camera = MakePreset("small")->camera;
  camera.width_px = 256;
  camera.height_px = 192;
  const Scene scene = MakePlainScene(2);
  TrajectoryParams tp;
  tp.target_mm = scene.Target();
  tp.distance_mm = 1100;
  const Pose world_from_cam = CameraTrajectory(tp).WorldFromCam(0);
  RenderOptions options;
  options.sensor_noise = false;
  const RawFrame colour = RenderRaw(PlenopticModel(camera), scene, world_from_cam, options);
  camera.bayer = true;
  const RawFrame mosaic = RenderRaw(PlenopticModel(camera), scene, world_from_cam, options);
  ASSERT_EQ(mosaic.format, PixelFormat::kMono8);
  ASSERT_EQ(colour.format, PixelFormat::kBgr8);
  for (int y = 0; y < 192; ++y)
    for (int x = 0; x < 256; ++x) {
      const int rgb = (y % 2 == 0) ? (x % 2 == 0 ? 0 : 1) : (x % 2 == 0 ? 1 : 2);
      const std::size_t pixel = static_cast<std::size_t>(y) * 256 + x;
      ASSERT_EQ(mosaic.pixels[pixel], colour.pixels[pixel * 3 + (2 - rgb)]) << x << "," << y;
    }
}

// Flat white micro-image centres: the spread matches read noise plus shot
// noise (variance = signal / (electrons per DN)).
TEST(SynthSensor, NoiseHasTheModelledVariance) {
  SynthCameraParams camera = MakePreset("small")->camera;
  camera.read_noise_dn = 2.0;
  camera.full_well_e = 6000;
  const PlenopticModel model(camera);
  RenderOptions options;
  options.vignetting = false;
  const RawFrame noisy = RenderRaw(model, MakeWhiteScene(), Pose::Identity(), options);
  options.sensor_noise = false;
  const RawFrame clean = RenderRaw(model, MakeWhiteScene(), Pose::Identity(), options);
  double sum = 0, sum2 = 0, mean_signal = 0;
  int n = 0;
  for (int y = 0; y < model.height(); ++y)
    for (int x = 0; x < model.width(); ++x) {
      int i = 0, j = 0;
      model.NearestLens({x, y}, &i, &j);
      if ((Eigen::Vector2d(x, y) - model.Lens(i, j).center_px).norm() > 4) continue;
      const std::size_t k = (static_cast<std::size_t>(y) * model.width() + x) * 3 + 1;
      const double d = static_cast<double>(noisy.pixels[k]) - clean.pixels[k];
      sum += d;
      sum2 += d * d;
      mean_signal += clean.pixels[k];
      ++n;
    }
  mean_signal /= n;
  const double variance = sum2 / n - (sum / n) * (sum / n);
  const double expected = 4.0 + mean_signal / (6000.0 / 255.0) + 1.0 / 12;  // + quantisation
  EXPECT_NEAR(std::abs(sum / n), 0.0, 0.1);
  EXPECT_NEAR(variance, expected, 0.1 * expected) << "over " << n << " pixels";
}

// Every motion kind is smooth at the Vicon rate, keeps the plate in front of
// the camera, moves, and differs between cameras (seeds).
TEST(SynthMotion, TrajectoriesAreSmoothAndLookAtThePlate) {
  const Scene scene = MakePlainScene(1);
  for (const char* motion : {"smooth", "handheld", "axis", "circle", "orbit"}) {
    TrajectoryParams tp;
    tp.motion = motion;
    tp.target_mm = scene.Target();
    tp.distance_mm = 800;
    tp.duration_s = 6.0;
    tp.seed = 1;
    const CameraTrajectory a(tp);
    tp.seed = 2;
    tp.lateral_offset_mm = 120;
    const CameraTrajectory b(tp);
    double travel = 0, max_step = 0, max_turn_deg = 0;
    Pose previous = a.WorldFromCam(0);
    for (int f = 1; f <= 480; ++f) {  // 6 s at 80 Hz
      const Pose pose = a.WorldFromCam(f / 80.0);
      const double step = (pose.translation() - previous.translation()).norm();
      travel += step;
      max_step = std::max(max_step, step);
      max_turn_deg = std::max(
          max_turn_deg,
          Eigen::AngleAxisd(previous.linear().transpose() * pose.linear()).angle() * 180 / M_PI);
      const Eigen::Vector3d target_in_cam = pose.inverse() * scene.Target();
      ASSERT_GT(target_in_cam.z(), 400) << motion;
      ASSERT_LT(target_in_cam.head<2>().norm(), 0.5 * target_in_cam.z()) << motion;
      previous = pose;
    }
    EXPECT_GT(travel, 20.0) << motion << " hardly moves";
    EXPECT_LT(max_step, 5.0) << motion << ": a jump of " << max_step << " mm in 12.5 ms";
    EXPECT_LT(max_turn_deg, 1.0) << motion;
    EXPECT_GT((a.WorldFromCam(1.0).translation() - b.WorldFromCam(1.0).translation()).norm(), 50)
        << motion;
  }
}

TEST(SynthCli, BadPresetAndConfigFailWithTheirNames) {
  test::TempDir dir;
  const test::CommandResult preset =
      test::RunLifmcr("synth --out " + (dir / "out").string() + " --preset huge --quiet");
  EXPECT_EQ(preset.exit_code, 2);
  EXPECT_NE(preset.err.find("unknown preset 'huge'"), std::string::npos) << preset.err;
  test::WriteFile(dir / "bad.yaml", "camera:\n  pixel_size: 3\n");
  const test::CommandResult config = test::RunLifmcr("synth --out " + (dir / "out").string() +
                                                     " --config " + (dir / "bad.yaml").string());
  EXPECT_EQ(config.exit_code, 2);
  EXPECT_NE(config.err.find("bad.yaml:2:3"), std::string::npos) << config.err;
  EXPECT_NE(config.err.find("/camera/pixel_size"), std::string::npos) << config.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "out"));
}

TEST(SynthCli, WritesASmallRig) {
  test::TempDir dir;
  test::WriteFile(dir / "tiny.yaml", "camera:\n  width_px: 256\n  height_px: 192\n");
  const test::CommandResult result = test::RunLifmcr(
      "synth --out " + (dir / "out").string() + " --config " + (dir / "tiny.yaml").string() +
      " --frames 2 --cameras 3 --motion handheld --noise 1 --seed 3 --scene-folder 01_Test");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_NE(result.out.find("3 camera(s) x 2 frame(s)"), std::string::npos) << result.out;
  EXPECT_NE(result.err.find("6/6 rendered"), std::string::npos) << result.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "out/01_Test/Sequence_00/TypeE_40398674"));
  EXPECT_TRUE(std::filesystem::exists(dir / "out/Calibration/03_Vicon/Object.vsk"));
}

}  // namespace
}  // namespace lifmcr::synth
