// LiFCal camera model: hand-computed values, round trips, projX/projY, and
// agreement with the synthetic generator's forward model.

#include "processing/camera_model.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/synth_params.h"

#include <gtest/gtest.h>

#include <random>

namespace lifmcr::processing {
namespace {

CameraIntrinsics HandIntrinsics() {
  CameraIntrinsics k;
  k.main_focal_length_mm = 25.0;
  k.mla_to_main_lens_mm = 24.8;
  k.mla_to_sensor_mm = 0.2;
  k.pixel_size_mm = 0.0055;
  k.width_px = 1024;
  k.height_px = 768;
  return k;
}

TEST(CameraModel, PrincipalPointShiftsTheImageAndTheLensCentres) {
  CameraIntrinsics k = HandIntrinsics();
  EXPECT_EQ(k.PrincipalPointPx(), Eigen::Vector2d(511.5, 383.5));  // unset: the image centre
  k.principal_point_px = Eigen::Vector2d(520.25, 377.0);
  ASSERT_TRUE(k.Check());
  const CameraModel model(k), centred(HandIntrinsics());
  const Eigen::Vector3d p(10, -5, 1000);
  const Eigen::Vector3d v = model.Project(p), v0 = centred.Project(p);
  EXPECT_NEAR(v.x() - v0.x(), 520.25 - 511.5, 1e-9);
  EXPECT_NEAR(v.y() - v0.y(), 377.0 - 383.5, 1e-9);
  EXPECT_NEAR(v.z(), v0.z(), 1e-12);
  EXPECT_NEAR((model.BackProject(v) - p).norm(), 0, 1e-9);
  // l_k = c + (c_k - c) lambda: the lens centre under c itself is c.
  EXPECT_NEAR((model.LensCenterPx(*k.principal_point_px) - *k.principal_point_px).norm(), 0, 1e-12);
  EXPECT_NEAR((model.FeatureImagePoint(v) - (*k.principal_point_px +
                                             p.head<2>() / p.z() * model.FeatureFocalPx()))
                  .norm(),
              0, 1e-9);
  k.principal_point_px = Eigen::Vector2d(-3, 100);
  const Status outside = k.Check();
  ASSERT_FALSE(outside);
  EXPECT_NE(outside.error().message.find("principal_point_px"), std::string::npos);
}

TEST(CameraModel, HandComputedValues) {
  const CameraModel model(HandIntrinsics());
  // (10, -5, 1000) mm: b_L = 25 * 1000 / 975 = 25.641025641 mm,
  // v = (25.641025641 - 24.8) / 0.2 = 4.205128205,
  // x_v = 511.5 + 10 * 25.641025641 / (1000 * 0.0055) = 558.120046620,
  // y_v = 383.5 - 23.310023310 = 360.189976690.
  const Eigen::Vector3d v = model.Project({10, -5, 1000});
  EXPECT_NEAR(v.x(), 558.120046620, 1e-8);
  EXPECT_NEAR(v.y(), 360.189976690, 1e-8);
  EXPECT_NEAR(v.z(), 4.205128205, 1e-8);
  // projX: 46.620046620 * (24.8 + 0.4) / (4.205128205 * 0.2 + 24.8) = 45.818181818.
  const Eigen::Vector2d proj = model.CentralProjection(v);
  EXPECT_NEAR(proj.x(), 511.5 + 45.818181818, 1e-8);
  EXPECT_NEAR(proj.y(), 383.5 - 22.909090909, 1e-8);
  EXPECT_NEAR(model.FeatureFocalPx(), 25.2 / 0.0055, 1e-9);
  // Thin lens: v = 2 at b_L = 25.2 mm, Z = 25 * 25.2 / 0.2 = 3150 mm.
  EXPECT_NEAR(model.DepthOfVirtualDepth(2.0), 3150.0, 1e-9);
  // Lens centre: lambda = 24.8 / 25.0 = 0.992.
  EXPECT_NEAR(model.lambda(), 0.992, 1e-12);
  const Eigen::Vector2d l = model.LensCenterPx({611.5, 383.5});
  EXPECT_NEAR(l.x(), 511.5 + 99.2, 1e-9);
}

TEST(CameraModel, ProjXLeavesVirtualDepthTwoUnchanged) {
  const CameraModel model(HandIntrinsics());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> x(0, 1023), y(0, 767);
  for (int n = 0; n < 100; ++n) {
    const Eigen::Vector3d p(x(rng), y(rng), 2.0);
    EXPECT_LT((model.CentralProjection(p) - p.head<2>()).norm(), 1e-9);
  }
}

TEST(CameraModel, ProjectBackProjectRoundTripsWithDistortion) {
  CameraIntrinsics k = HandIntrinsics();
  k.k1 = 2e-3;
  k.k2 = -1e-5;
  k.p1 = 3e-4;
  k.p2 = -2e-4;
  const CameraModel model(k);
  std::mt19937 rng(7);
  // Points inside the field of view (|x_mla| < 3.5 mm, distortion up to ~3 %).
  std::uniform_real_distribution<double> slope(-0.1, 0.1), z(400, 3000);
  for (int n = 0; n < 500; ++n) {
    const double depth = z(rng);
    const Eigen::Vector3d p(slope(rng) * depth, slope(rng) * depth, depth);
    const Eigen::Vector3d back = model.BackProject(model.Project(p));
    EXPECT_LT((back - p).norm(), 1e-6 * p.norm()) << p.transpose();
    // The feature image of a point is the pinhole image at the main-lens centre.
    const Eigen::Vector2d f = model.FeatureImagePoint(model.Project(p));
    const Eigen::Vector2d pinhole =
        model.principal_point_px() + p.head<2>() / p.z() * model.FeatureFocalPx();
    EXPECT_LT((f - pinhole).norm(), 1e-6);
  }
  for (double v : {2.0, 3.3, 7.5})
    EXPECT_NEAR(model.VirtualDepthOfDepth(model.DepthOfVirtualDepth(v)), v, 1e-9);
}

TEST(CameraModel, AgreesWithSyntheticForwardModel) {
  synth::SynthCameraParams p = synth::MakePreset("small")->camera;
  p.distortion_k1 = 1e-3;
  p.distortion_p2 = 1e-4;
  const synth::PlenopticModel truth(p);
  CameraIntrinsics k;
  k.main_focal_length_mm = p.main_focal_length_mm;
  k.mla_to_main_lens_mm = p.mla_to_main_lens_mm;
  k.mla_to_sensor_mm = p.mla_to_sensor_mm;
  k.pixel_size_mm = p.pixel_size_mm;
  k.width_px = p.width_px;
  k.height_px = p.height_px;
  k.k1 = p.distortion_k1;
  k.k2 = p.distortion_k2;
  k.p1 = p.distortion_p1;
  k.p2 = p.distortion_p2;
  const CameraModel model(k);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> xy(-200, 200), z(500, 2500);
  for (int n = 0; n < 200; ++n) {
    const Eigen::Vector3d pt(xy(rng), xy(rng), z(rng));
    const Eigen::Vector3d mine = model.Project(pt);
    EXPECT_LT((mine - truth.VirtualPoint(pt)).norm(), 1e-9);
    const synth::MicroLens lens = truth.Lens(n % 7 - 3, n % 5 - 2);
    EXPECT_LT(
        (model.ProjectToMicroImage(mine, lens.center_px) - truth.ProjectThroughLens(lens, mine))
            .norm(),
        1e-9);
  }
}

TEST(CameraModel, CheckNamesTheField) {
  CameraIntrinsics k = HandIntrinsics();
  k.mla_to_sensor_mm = -1;
  const Status s = k.Check();
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("mla_to_sensor_mm"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr::processing
