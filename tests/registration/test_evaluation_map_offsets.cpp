// A rigidly mounted pair: the c0_from_cx evaluation cannot estimate its
// own hand-eye offsets (marker0_from_markerX does not turn), but each
// camera's map-frame evaluation can, and CorrectWithMapFrameOffsets uses
// them. Built as lifmcr evaluate builds the evaluations (apps/cmd_evaluate.cpp).
#include "registration/evaluation.h"
#include "registration/trajectory_metrics.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace lifmcr {
namespace {

constexpr double kDeg = M_PI / 180.0;

Pose MakePose(const Eigen::Vector3d& rotation_deg, const Eigen::Vector3d& t_mm) {
  Pose p = Pose::Identity();
  p.linear() = (Eigen::AngleAxisd(rotation_deg.z() * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(rotation_deg.y() * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(rotation_deg.x() * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  p.translation() = t_mm;
  return p;
}

Pose Noise(std::mt19937_64& rng, double sigma_deg, double sigma_mm) {
  std::normal_distribution<double> n(0, 1);
  return MakePose(sigma_deg * Eigen::Vector3d(n(rng), n(rng), n(rng)),
                  sigma_mm * Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

struct RigidPair {
  Pose x0 = MakePose({3, -2, 5}, {40, -25, 60});     // marker_from_cam, camera 0
  Pose xx = MakePose({-4, 1, 2}, {-30, 55, 70});     // marker_from_cam, camera X
  Pose c0_from_cx = MakePose({0, 12, 0}, {250, 0, 10});
  Pose vicon_from_map = MakePose({0, 0, 30}, {1200, -800, 0});
  FramePoses w0_from_c0, w0_from_cx, c0_from_cx_registered;
  FramePoses vicon_from_map_each, vicon_from_marker0, vicon_from_markerx;
};

// The rig turns about two axes in the map (so each camera's map-frame
// hand-eye is determined); the pair itself never turns. Registrations carry
// 0.2 mm / 0.01 deg of noise.
RigidPair MakeRigidPair(int frames) {
  RigidPair r;
  std::mt19937_64 rng(7);
  for (int f = 0; f < frames; ++f) {
    const double s = static_cast<double>(f) / frames;
    const Pose w0_from_c0 = MakePose({25 * std::sin(6.3 * s), 30 * std::cos(4.1 * s), 10 * s},
                                     {400 * std::cos(3 * s), 300 * std::sin(3 * s), 1500});
    const Pose w0_from_cx = w0_from_c0 * r.c0_from_cx;
    r.w0_from_c0.emplace(f, w0_from_c0 * Noise(rng, 0.01, 0.2));
    r.w0_from_cx.emplace(f, w0_from_cx * Noise(rng, 0.01, 0.2));
    r.c0_from_cx_registered.emplace(f, r.c0_from_cx * Noise(rng, 0.01, 0.2));
    r.vicon_from_map_each.emplace(f, r.vicon_from_map);
    r.vicon_from_marker0.emplace(f, r.vicon_from_map * w0_from_c0 * r.x0.inverse());
    r.vicon_from_markerx.emplace(f, r.vicon_from_map * w0_from_cx * r.xx.inverse());
  }
  return r;
}

// The three evaluations lifmcr evaluate makes of a pair with camera 0's
// poses in the map: c0_from_cx against Vicon, and each camera in the map.
struct PairEvaluations {
  CameraEvaluation pair, map0, mapx;
};
PairEvaluations Evaluate(const RigidPair& r, const EvaluationOptions& options) {
  return {EvaluateCamera("pnp", "X", "0", r.c0_from_cx_registered, r.vicon_from_marker0,
                         r.vicon_from_markerx, std::nullopt, options),
          EvaluateCamera("reference", "0", "map", r.w0_from_c0, r.vicon_from_map_each,
                         r.vicon_from_marker0, std::nullopt, options),
          EvaluateCamera("pnp", "X", "map", r.w0_from_cx, r.vicon_from_map_each,
                         r.vicon_from_markerx, std::nullopt, options)};
}

TEST(EvaluationMapOffsets, RigidPairIsCorrectedWithEachCamerasMapFrameOffsets) {
  const RigidPair r = MakeRigidPair(60);
  const EvaluationOptions options;  // split half
  ASSERT_TRUE(options.Check());
  auto [pair, map0, mapx] = Evaluate(r, options);
  ASSERT_FALSE(pair.has_correction()) << "a rigid pair cannot determine its own offsets";
  ASSERT_EQ(map0.correction_source, "estimated") << map0.correction_note;
  ASSERT_EQ(mapx.correction_source, "estimated") << mapx.correction_note;

  const double before = pair.uncorrected.ape_summary.translation_mm.rmse;
  ASSERT_TRUE(CorrectWithMapFrameOffsets(&pair, map0, mapx));
  EXPECT_EQ(pair.correction_source, "map frame");
  EXPECT_FALSE(pair.fit_to_itself);
  EXPECT_TRUE(pair.has_offsets());
  const double after = pair.corrected.ape_summary.translation_mm.rmse;
  std::cout << "rigid pair c0_from_cx: absolute " << before << " mm uncorrected, " << after
            << " mm with the map-frame offsets (" << pair.correction_note << ")\n";
  // Uncorrected: the two offsets' effect (tens of mm). Corrected: the
  // registration noise (0.2 mm on each of three poses) and the offsets'
  // estimation error, well below a millimetre or two.
  EXPECT_GT(before, 20.0);
  EXPECT_LT(after, 2.0);
  EXPECT_LT(pair.corrected.ape_summary.rotation_deg.rmse, 0.1);
  EXPECT_LT((pair.marker_from_cam.translation() - r.xx.translation()).norm(), 2.0);
  EXPECT_LT((pair.marker_from_cam_reference.translation() - r.x0.translation()).norm(), 2.0);
}

TEST(EvaluationMapOffsets, EachFrameIsCorrectedByTheFoldThatDidNotSeeIt) {
  const RigidPair r = MakeRigidPair(40);
  const EvaluationOptions options;
  auto [pair, map0, mapx] = Evaluate(r, options);
  ASSERT_EQ(mapx.folds.size(), 2u);
  // Spoil camera X's first-half fold by 50 mm along x: only frames of the
  // second half (the ones that fold did not see) may show it.
  mapx.folds[0].x.translation() += Eigen::Vector3d(50, 0, 0);
  ASSERT_TRUE(CorrectWithMapFrameOffsets(&pair, map0, mapx));
  for (const auto& [frame, truth] : pair.truth_corrected) {
    const double error =
        (pair.estimate.at(frame).translation() - truth.translation()).norm();
    if (frame <= mapx.half_last)
      EXPECT_LT(error, 5.0) << "frame " << frame;
    else
      EXPECT_GT(error, 40.0) << "frame " << frame;
  }
}

TEST(EvaluationMapOffsets, RefusedWhenAMapFrameEvaluationHasNoOffsets) {
  const RigidPair r = MakeRigidPair(30);
  const EvaluationOptions options;
  auto [pair, map0, mapx] = Evaluate(r, options);
  mapx = map0;
  mapx.serial = "X";
  mapx.correction_source = "none";
  mapx.correction_note = "the motions cannot determine the offset";
  EXPECT_FALSE(CorrectWithMapFrameOffsets(&pair, map0, mapx));
  EXPECT_FALSE(pair.has_correction());
  EXPECT_NE(pair.correction_note.find("camera X has none"), std::string::npos)
      << pair.correction_note;
}

}  // namespace
}  // namespace lifmcr
