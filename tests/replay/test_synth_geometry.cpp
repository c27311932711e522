// The synthetic plenoptic camera: its forward model is self-consistent, the
// rendered image agrees with it (photo-consistency between neighbouring micro
// images at the ground-truth virtual depth), the white image shows the micro
// images where the written MLA file says, and each lens type is sharpest in
// its own depth range.

#include "config/mla.h"
#include "replay/mla_xml.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <array>
#include <cmath>
#include <random>
#include <vector>

namespace lifmcr::synth {
namespace {

SynthCameraParams SmallCamera() {
  Expected<SynthParams> params = MakePreset("small");
  EXPECT_TRUE(params.ok());
  return params->camera;
}

// Grey value (mean of the three channels) at a sub-pixel position, bilinear.
double GreyAt(const RawFrame& frame, const Eigen::Vector2d& p) {
  const int x0 = static_cast<int>(std::floor(p.x())), y0 = static_cast<int>(std::floor(p.y()));
  const double tx = p.x() - x0, ty = p.y() - y0;
  auto at = [&](int x, int y) {
    x = std::clamp(x, 0, frame.width - 1);
    y = std::clamp(y, 0, frame.height - 1);
    const std::uint8_t* px =
        frame.pixels.data() + (static_cast<std::size_t>(y) * frame.width + x) * 3;
    return (px[0] + px[1] + px[2]) / 3.0;
  };
  return (1 - ty) * ((1 - tx) * at(x0, y0) + tx * at(x0 + 1, y0)) +
         ty * ((1 - tx) * at(x0, y0 + 1) + tx * at(x0 + 1, y0 + 1));
}

float DepthAt(const RawFrame& frame, const Eigen::Vector2d& p) {
  const int x = static_cast<int>(std::lround(p.x())), y = static_cast<int>(std::lround(p.y()));
  if (x < 0 || y < 0 || x >= frame.width || y >= frame.height) return NAN;
  return frame.virtual_depth[static_cast<std::size_t>(y) * frame.width + x];
}

TEST(SynthModel, ChiefRayAndVirtualPointAgreeForRandomPixels) {
  SynthCameraParams camera = SmallCamera();
  camera.mla_rotation_rad = 0.01;
  camera.mla_tilt_x_rad = 5e-4;
  const PlenopticModel model(camera);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> x(0, camera.width_px - 1), y(0, camera.height_px - 1);
  std::uniform_real_distribution<double> depth(300, 5000);
  int checked = 0;
  for (int k = 0; k < 2000; ++k) {
    const Eigen::Vector2d p(x(rng), y(rng));
    const std::optional<PixelSample> sample = model.TraceRawPixel(p);
    if (!sample) continue;
    // A point on the pixel's object ray images, through the same micro lens,
    // back onto the pixel: p_k = l_k + (x_v - l_k) / v.
    const double z = depth(rng);
    const Eigen::Vector3d point = sample->ray.origin + sample->ray.direction * z;
    const Eigen::Vector3d virtual_px = model.VirtualPoint(point);
    EXPECT_NEAR(virtual_px.z(), model.VirtualDepthOfDepth(z), 1e-9);
    const Eigen::Vector2d back = model.ProjectThroughLens(sample->lens, virtual_px);
    ASSERT_LT((back - p).norm(), 1e-6) << "pixel " << p.transpose() << " depth " << z;
    ++checked;
  }
  EXPECT_GT(checked, 1000);
}

TEST(SynthModel, DistortedPixelsStillReprojectAtTheirDepth) {
  SynthCameraParams camera = SmallCamera();
  camera.distortion_k1 = -2e-4;
  camera.distortion_p1 = 1e-5;
  const PlenopticModel model(camera);
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> x(0, camera.width_px - 1), y(0, camera.height_px - 1);
  int checked = 0;
  for (int k = 0; k < 500; ++k) {
    const Eigen::Vector2d p(x(rng), y(rng));
    const std::optional<PixelSample> sample = model.TraceRawPixel(p);
    if (!sample) continue;
    const double z = 900.0;
    const double b = model.ImageDistanceOfDepth(z);
    const Ray ray = model.ObjectRayOfImagePoint(model.RawLineAt(*sample, p, b));
    const Eigen::Vector3d point = ray.direction * z;  // from the main-lens centre
    const Eigen::Vector2d back = model.ProjectThroughLens(sample->lens, model.VirtualPoint(point));
    ASSERT_LT((back - p).norm(), 1e-6);
    ++checked;
  }
  EXPECT_GT(checked, 200);
}

TEST(SynthModel, PresetsHavePlausibleR32Geometry) {
  const Expected<SynthParams> r32 = MakePreset("r32");
  ASSERT_TRUE(r32.ok());
  const PlenopticModel model(r32->camera);
  EXPECT_EQ(model.width(), 6560);
  EXPECT_EQ(model.height(), 4948);
  EXPECT_DOUBLE_EQ(r32->camera.pixel_size_mm, 0.0032);
  EXPECT_DOUBLE_EQ(r32->camera.main_focal_length_mm, 25.0);
  // As the real MLA files: pitch 23..39 px, TCP about 2.1..2.2, type ranges
  // ordered and overlapping or touching, the far type open towards 100.
  const MlaCalibration mla = model.ToMlaCalibration();
  EXPECT_GT(mla.diameter_px, 23.0);
  EXPECT_LT(mla.diameter_px, 39.0);
  EXPECT_GT(mla.tcp_virtual_depth, 2.0);
  EXPECT_LT(mla.tcp_virtual_depth, 2.4);
  for (int t = 0; t + 1 < 3; ++t) {
    EXPECT_LT(mla.lens_types[t].depth_min, mla.lens_types[t + 1].depth_min);
    EXPECT_GE(mla.lens_types[t].depth_max * 1.05, mla.lens_types[t + 1].depth_min);
  }
  // A table-top scene at 0.5..1.5 m lies in v of about 3..7.
  EXPECT_GT(model.VirtualDepthOfDepth(1500), 2.5);
  EXPECT_LT(model.VirtualDepthOfDepth(500), 9.0);
}

// Renders the table-top scene from the default trajectory, without noise,
// blur or cos^4 falloff, so that a scene point has one grey value wherever it
// appears.
TEST(SynthRender, NeighbouringMicroImagesAgreeAtTheGroundTruthVirtualDepth) {
  const PlenopticModel model(SmallCamera());
  const Scene scene = MakePlainScene(5);
  TrajectoryParams tp;
  tp.target_mm = scene.Target();
  tp.distance_mm = 1100;
  const Pose world_from_cam = CameraTrajectory(tp).WorldFromCam(0.3);
  RenderOptions options;
  options.defocus = false;
  options.vignetting = false;
  options.sensor_noise = false;
  const RawFrame frame = RenderRaw(model, scene, world_from_cam, options);

  const double pitch = model.params().micro_image_pitch_px;
  const double inner = 0.32 * pitch;
  const double s = model.params().pixel_size_mm;
  std::vector<double> right, wrong;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> x(2 * pitch, frame.width - 2 * pitch),
      y(2 * pitch, frame.height - 2 * pitch);
  const std::array<Eigen::Vector2i, 6> ring{Eigen::Vector2i(1, 0),  Eigen::Vector2i(-1, 0),
                                            Eigen::Vector2i(0, 1),  Eigen::Vector2i(0, -1),
                                            Eigen::Vector2i(1, -1), Eigen::Vector2i(-1, 1)};
  for (int k = 0; k < 4000; ++k) {
    const Eigen::Vector2d p(std::round(x(rng)), std::round(y(rng)));
    int i = 0, j = 0;
    model.NearestLens(p, &i, &j);
    const MicroLens lens = model.Lens(i, j);
    if ((p - lens.center_px).norm() > inner) continue;
    const double v = DepthAt(frame, p);
    if (!std::isfinite(v)) continue;
    // The virtual point this pixel sees: x_v = l_k + (p - l_k) v.
    const Eigen::Vector2d l_px = lens.lens_mm.head<2>() / s + model.principal_point_px();
    for (double scale : {1.0, 1.5}) {
      const double v_try = v * scale;
      const Eigen::Vector2d x_v = l_px + (p - l_px) * v_try;
      for (const Eigen::Vector2i& step : ring) {
        const MicroLens other = model.Lens(i + step.x(), j + step.y());
        const Eigen::Vector2d q = model.ProjectThroughLens(other, {x_v.x(), x_v.y(), v_try});
        if ((q - other.center_px).norm() > inner) continue;
        // Same surface seen there (not an occlusion edge).
        if (!(std::abs(DepthAt(frame, q) - v) < 0.02 * v)) continue;
        (scale == 1.0 ? right : wrong).push_back(std::abs(GreyAt(frame, q) - GreyAt(frame, p)));
      }
    }
  }
  ASSERT_GT(right.size(), 500u);
  ASSERT_GT(wrong.size(), 200u);
  auto mean = [](const std::vector<double>& d) {
    double sum = 0;
    for (double e : d) sum += e;
    return sum / d.size();
  };
  // Right depth: only interpolation and 8-bit rounding differ.
  std::printf("photo-consistency: mean |difference| %.3f DN at the true v, %.3f DN at 1.5 v (%zu / %zu pairs)\n",
              mean(right), mean(wrong), right.size(), wrong.size());
  EXPECT_LT(mean(right), 2.0) << "over " << right.size() << " pairs";
  EXPECT_GT(mean(wrong), 2.5 * mean(right)) << "a 50 % wrong depth must not look consistent";
}

// The two ground-truth maps describe one surface: a TF pixel's metric depth,
// mapped to its virtual point, projects into a micro image whose raw
// virtual-depth ground truth is the same v.
TEST(SynthRender, TfDepthAndRawVirtualDepthDescribeTheSameSurface) {
  const PlenopticModel model(SmallCamera());
  const Scene scene = MakePlainScene(6);
  TrajectoryParams tp;
  tp.target_mm = scene.Target();
  tp.distance_mm = 1100;
  const Pose world_from_cam = CameraTrajectory(tp).WorldFromCam(0.7);
  RenderOptions options;
  options.sensor_noise = false;
  const RawFrame raw = RenderRaw(model, scene, world_from_cam, options);
  const TfGroundTruth tf = RenderTfGroundTruth(model, scene, world_from_cam);
  ASSERT_EQ(tf.width, raw.width / 2);
  int agree = 0, checked = 0;
  const double inner = 0.3 * model.params().micro_image_pitch_px;
  for (int w = 4; w < tf.height - 4; w += 3)
    for (int u = 4; u < tf.width - 4; u += 3) {
      const float z = tf.depth_mm[static_cast<std::size_t>(w) * tf.width + u];
      if (!std::isfinite(z)) continue;
      const Ray ray = model.TfPixelRay({u, w});
      const Eigen::Vector3d point = ray.origin + ray.direction * (z - ray.origin.z());
      const Eigen::Vector3d virtual_px = model.VirtualPoint(point);
      ASSERT_NEAR(virtual_px.x(), 2 * u + 0.5, 1e-6);
      ASSERT_NEAR(virtual_px.y(), 2 * w + 0.5, 1e-6);
      int i = 0, j = 0;
      model.NearestLens(virtual_px.head<2>(), &i, &j);
      const Eigen::Vector2d p = model.ProjectThroughLens(model.Lens(i, j), virtual_px);
      if ((p - model.Lens(i, j).center_px).norm() > inner) continue;
      ++checked;
      if (std::abs(DepthAt(raw, p) - virtual_px.z()) < 0.01 * virtual_px.z()) ++agree;
    }
  ASSERT_GT(checked, 1000);
  // Only occlusion edges (a pixel's neighbour on another surface) disagree.
  EXPECT_GT(agree, 0.97 * checked) << agree << " of " << checked;
}

// The marker plate defines the world frame: seen from above in the
// all-in-focus image (a pinhole at the front focal point), each ArUco
// marker's black border lies where the layout puts it, and world +x runs to
// the right of the image when the camera looks down with its y along -world y.
TEST(SynthRender, MarkerPlateAppearsWhereTheWorldFrameSaysInTheAllInFocusImage) {
  const PlenopticModel model(SmallCamera());
  const Scene scene = MakePlainScene(1);
  const Eigen::Vector3d eye = scene.Target() + Eigen::Vector3d(0, -1.0, 2000.0);
  const Pose world_from_cam = LookAt(eye, scene.Target());
  const TfGroundTruth tf = RenderTfGroundTruth(model, scene, world_from_cam);
  const double f = model.params().main_focal_length_mm, s = model.params().pixel_size_mm;
  auto project = [&](const Eigen::Vector3d& p_in_world) {
    const Eigen::Vector3d p = world_from_cam.inverse() * p_in_world;
    const Eigen::Vector2d raw = p.head<2>() * f / (p.z() - f) / s + model.principal_point_px();
    return Eigen::Vector2d((raw - Eigen::Vector2d(0.5, 0.5)) / 2.0);
  };
  auto grey = [&](const Eigen::Vector2d& q) {
    const int u = static_cast<int>(std::lround(q.x())), w = static_cast<int>(std::lround(q.y()));
    EXPECT_TRUE(u >= 0 && w >= 0 && u < tf.width && w < tf.height) << q.transpose();
    const std::uint8_t* px = tf.bgr.data() + (static_cast<std::size_t>(w) * tf.width + u) * 3;
    return (px[0] + px[1] + px[2]) / 3.0;
  };
  const MarkerPlateLayout& plate = scene.plate;
  for (int id = 0; id < 4; ++id) {
    const double half = plate.aruco_side_mm / 2;
    for (const Eigen::Vector2d& corner : {Eigen::Vector2d(-1, -1), Eigen::Vector2d(1, -1),
                                          Eigen::Vector2d(1, 1), Eigen::Vector2d(-1, 1)}) {
      const Eigen::Vector2d c = plate.aruco_centers_mm[id];
      const Eigen::Vector3d inside(c.x() + corner.x() * (half - 4), c.y() + corner.y() * (half - 4),
                                   0);
      const Eigen::Vector3d outside(c.x() + corner.x() * (half + 6),
                                    c.y() + corner.y() * (half + 6), 0);
      EXPECT_LT(grey(project(inside)), 60)
          << "marker " << id << " border corner " << corner.transpose();
      EXPECT_GT(grey(project(outside)), 120) << "marker " << id << " margin " << corner.transpose();
    }
  }
  // Image right = world +x (id 3 right of id 2), image up = world +y (id 0 above id 2).
  EXPECT_GT(project({300, 80, 0}).x(), project({100, 80, 0}).x() + 50);
  EXPECT_LT(project({100, 200, 0}).y(), project({100, 80, 0}).y() - 30);
  // And the depth there is the distance of the plate.
  const Eigen::Vector2d centre = project(scene.Target());
  const float z = tf.depth_mm[static_cast<std::size_t>(std::lround(centre.y())) * tf.width +
                              std::lround(centre.x())];
  EXPECT_NEAR(z, 2000.0, 2.0);
}

// Micro-image centres found in the white image by a peak search and a
// centroid above half the local peak, against the centres the written MLA
// file gives (decoded here independently from the XML's conventions).
TEST(SynthRender, WhiteImageCentresMatchTheWrittenMlaFile) {
  SynthCameraParams camera = SmallCamera();
  camera.mla_rotation_rad = 0.004;
  camera.mla_offset_px = {3.3, -2.6};
  const PlenopticModel model(camera);
  test::TempDir dir;
  ASSERT_TRUE(WriteMlaXml(dir / "mla.xml", model.ToMlaCalibration()).ok());
  const Expected<MlaCalibration> mla = ReadMlaXml(dir / "mla.xml");
  ASSERT_TRUE(mla.ok()) << mla.error().message;
  RenderOptions options;
  options.sensor_noise = false;
  const RawFrame white = RenderRaw(model, MakeWhiteScene(), Pose::Identity(), options);

  const Eigen::Vector2d reference = mla->ReferenceLensCenterPx(white.width, white.height);
  const double d = mla->diameter_px, c = std::cos(mla->rotation_rad),
               s = std::sin(mla->rotation_rad);
  std::vector<double> errors;
  for (int j = -40; j <= 40; ++j)
    for (int i = -60; i <= 60; ++i) {
      // XML convention: y up, rotation counter-clockwise, hex basis (1,0), (1/2, sqrt(3)/2).
      const Eigen::Vector2d up(d * (i + 0.5 * j), d * std::sqrt(3.0) / 2 * j);
      const Eigen::Vector2d rotated(c * up.x() - s * up.y(), s * up.x() + c * up.y());
      const Eigen::Vector2d expected = reference + Eigen::Vector2d(rotated.x(), -rotated.y());
      if (expected.x() < d || expected.y() < d || expected.x() > white.width - 1 - d ||
          expected.y() > white.height - 1 - d)
        continue;
      // Peak search in the window, then centroid of the pixels above half of it.
      const int r = static_cast<int>(d / 2);
      const int cx = static_cast<int>(std::lround(expected.x())),
                cy = static_cast<int>(std::lround(expected.y()));
      double peak = 0;
      for (int y = cy - r; y <= cy + r; ++y)
        for (int x = cx - r; x <= cx + r; ++x) peak = std::max(peak, GreyAt(white, {x, y}));
      Eigen::Vector2d sum = Eigen::Vector2d::Zero();
      double weight = 0;
      for (int y = cy - r; y <= cy + r; ++y)
        for (int x = cx - r; x <= cx + r; ++x) {
          const double g = GreyAt(white, {x, y});
          // Own disc only: neighbours start beyond half a pitch.
          if (g < 0.5 * peak || (Eigen::Vector2d(x, y) - expected).norm() > 0.5 * d) continue;
          sum += Eigen::Vector2d(x, y);
          weight += 1;
        }
      errors.push_back((sum / weight - expected).norm());
    }
  ASSERT_GT(errors.size(), 1000u);
  std::sort(errors.begin(), errors.end());
  double mean = 0;
  for (double e : errors) mean += e / errors.size();
  std::printf("white-image centres vs MLA file: mean %.4f px, p95 %.4f px over %zu micro images\n", mean,
              errors[errors.size() * 95 / 100], errors.size());
  EXPECT_LT(mean, 0.15);
  EXPECT_LT(errors[errors.size() * 95 / 100], 0.35);
}

// A tilted MLA: the micro-image centres move off the ideal lattice by a
// fraction of a pixel, and the written file is the best lattice through them.
TEST(SynthModel, TiltedMlaFileIsTheBestLatticeThroughTheTrueCentres) {
  SynthCameraParams camera = SmallCamera();
  camera.mla_tilt_x_rad = 1e-3;
  camera.mla_tilt_y_rad = -6e-4;
  const PlenopticModel model(camera);
  const MlaCalibration mla = model.ToMlaCalibration();
  SynthCameraParams fitted_camera = camera;
  fitted_camera.mla_tilt_x_rad = fitted_camera.mla_tilt_y_rad = 0;
  fitted_camera.mla_offset_px = mla.offset_px;
  fitted_camera.micro_image_pitch_px = mla.diameter_px;
  fitted_camera.mla_rotation_rad = mla.rotation_rad;
  const PlenopticModel fitted(fitted_camera);
  double max_true_vs_nominal = 0, max_true_vs_fit = 0;
  for (int j = -20; j <= 20; ++j)
    for (int i = -40; i <= 40; ++i) {
      const Eigen::Vector2d c = model.Lens(i, j).center_px;
      if (c.x() < 0 || c.y() < 0 || c.x() > camera.width_px - 1 || c.y() > camera.height_px - 1)
        continue;
      max_true_vs_nominal = std::max(max_true_vs_nominal, (c - model.LatticeCenterPx(i, j)).norm());
      max_true_vs_fit = std::max(max_true_vs_fit, (c - fitted.LatticeCenterPx(i, j)).norm());
    }
  EXPECT_GT(max_true_vs_nominal, 0.005) << "a tilt must move the centres";
  EXPECT_LT(max_true_vs_nominal, 0.5);
  EXPECT_LE(max_true_vs_fit, max_true_vs_nominal);
  EXPECT_LT(max_true_vs_fit, 0.1);
}

// Mean squared gradient inside the micro images of each type, for a textured
// plane facing the camera at virtual depth v.
std::array<double, 3> ContrastPerType(const PlenopticModel& model, double v) {
  const Scene scene = MakePlaneScene(8.0, 21);
  const double z = model.DepthOfVirtualDepth(v);
  const Pose world_from_cam = LookAt({0, 0, z}, {0, 0, 0});
  RenderOptions options;
  options.vignetting = false;
  options.sensor_noise = false;
  const RawFrame frame = RenderRaw(model, scene, world_from_cam, options);
  std::array<double, 3> energy{0, 0, 0};
  std::array<int, 3> count{0, 0, 0};
  const double inner = 0.3 * model.params().micro_image_pitch_px;
  for (int y = 20; y < frame.height - 20; ++y)
    for (int x = 20; x < frame.width - 20; ++x) {
      int i = 0, j = 0;
      model.NearestLens({x, y}, &i, &j);
      const MicroLens lens = model.Lens(i, j);
      if ((Eigen::Vector2d(x, y) - lens.center_px).norm() > inner) continue;
      const double gx = GreyAt(frame, {x + 1.0, y}) - GreyAt(frame, {x - 1.0, y});
      const double gy = GreyAt(frame, {x, y + 1.0}) - GreyAt(frame, {x, y - 1.0});
      energy[lens.type] += gx * gx + gy * gy;
      ++count[lens.type];
    }
  for (int t = 0; t < 3; ++t) energy[t] /= count[t];
  return energy;
}

TEST(SynthRender, EachLensTypeIsSharpestInItsOwnRange) {
  SynthCameraParams camera = SmallCamera();
  camera.width_px = 512;  // the centre of the small sensor: enough micro images
  camera.height_px = 384;
  const PlenopticModel model(camera);
  for (int type = 0; type < 3; ++type) {
    // The virtual depth at which the type is focused.
    const double v =
        1.0 / (1.0 - model.params().mla_to_sensor_mm / model.params().micro_lens_focal_mm[type]);
    const Eigen::Vector2d range = model.SharpRange(type);
    ASSERT_GT(v, range.x());
    ASSERT_LT(v, range.y());
    const std::array<double, 3> contrast = ContrastPerType(model, v);
    const int sharpest =
        static_cast<int>(std::max_element(contrast.begin(), contrast.end()) - contrast.begin());
    EXPECT_EQ(sharpest, type) << "at v = " << v << ": contrast " << contrast[0] << ", "
                              << contrast[1] << ", " << contrast[2];
    // And the others ordered by their defocus at v: less blur, more contrast.
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b)
        if (model.BlurDiameterPx(a, v) + 1.0 < model.BlurDiameterPx(b, v)) {
          EXPECT_GT(contrast[a], 1.1 * contrast[b])
              << "v = " << v << ": types " << a << " and " << b << ", contrast " << contrast[0]
              << ", " << contrast[1] << ", " << contrast[2];
        }
  }
}

}  // namespace
}  // namespace lifmcr::synth
