// The natural-image-like patterns (replay/synth/patterns.h) and the textured
// table scene (scene.h): deterministic per seed, in range, band-limited
// without shifting the local mean, dead leaves covering the surface; the
// scene's objects never hide the markers from the default viewpoints.

#include "replay/synth/patterns.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <vector>

namespace lifmcr::synth {
namespace {

std::vector<std::unique_ptr<SurfacePattern>> Patterns(std::uint32_t seed) {
  std::vector<std::unique_ptr<SurfacePattern>> patterns;
  DeadLeavesParams leaves;
  leaves.min_radius_mm = 0.5;
  leaves.max_radius_mm = 30;
  leaves.palette = PaletteCloth();
  leaves.seed = seed;
  leaves.grain.noise.seed = seed + 1;
  patterns.push_back(std::make_unique<DeadLeaves>(leaves));
  BandedNoiseParams banded;
  banded.palette = PaletteStone();
  banded.noise.seed = seed;
  banded.grain.noise.seed = seed + 3;
  patterns.push_back(std::make_unique<BandedNoise>(banded));
  PrintedPageParams page;
  page.photo = leaves;
  page.seed = seed;
  page.grain.noise.seed = seed + 2;
  patterns.push_back(std::make_unique<PrintedPage>(page));
  return patterns;
}

double Luminance(const Eigen::Vector3d& rgb) { return rgb.mean(); }

TEST(SynthPatterns, DeterministicPerSeedAndInRange) {
  const auto a = Patterns(7), b = Patterns(7), c = Patterns(8);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> at(-500, 500);
  for (std::size_t k = 0; k < a.size(); ++k) {
    int differs = 0;
    for (int n = 0; n < 2000; ++n) {
      const double u = at(rng), v = at(rng), footprint = 0.05 + 0.001 * n;
      const Eigen::Vector3d x = a[k]->Reflectance(u, v, footprint);
      EXPECT_EQ(x, b[k]->Reflectance(u, v, footprint)) << "pattern " << k;
      EXPECT_GE(x.minCoeff(), 0.0);
      EXPECT_LE(x.maxCoeff(), 1.0);
      differs += (x - c[k]->Reflectance(u, v, footprint)).norm() > 1e-6;
    }
    EXPECT_GT(differs, 1800) << "pattern " << k << ": another seed, another pattern";
  }
}

// A coarse footprint drops detail, not brightness: the mean luminance over a
// region is the same (within 5 %) whether the samples are fine or coarse,
// and the coarse samples vary less (the detail below them is gone).
TEST(SynthPatterns, BandLimitingKeepsTheLocalMean) {
  const auto patterns = Patterns(3);
  for (std::size_t k = 0; k < patterns.size(); ++k) {
    double mean[2] = {0, 0}, var[2] = {0, 0};
    const double footprint[2] = {0.05, 3.0};
    for (int f = 0; f < 2; ++f) {
      std::mt19937 rng(2);
      std::uniform_real_distribution<double> at(0, 300);
      const int n = 40000;
      double sum = 0, sum2 = 0;
      for (int s = 0; s < n; ++s) {
        const double l = Luminance(patterns[k]->Reflectance(at(rng), at(rng), footprint[f]));
        sum += l;
        sum2 += l * l;
      }
      mean[f] = sum / n;
      var[f] = sum2 / n - mean[f] * mean[f];
    }
    std::printf("pattern %zu: mean %.3f (fine) / %.3f (3 mm), sd %.3f / %.3f\n", k, mean[0],
                mean[1], std::sqrt(var[0]), std::sqrt(var[1]));
    EXPECT_NEAR(mean[1], mean[0], 0.05 * mean[0]) << "pattern " << k;
    EXPECT_LT(var[1], var[0]) << "pattern " << k;
  }
}

// Dead leaves cover the surface (the background shows through rarely) and
// have leaves of every octave on top somewhere: the luminance differences
// between points d apart grow with d over the whole range of radii.
TEST(SynthPatterns, DeadLeavesHaveStructureAtEveryScale) {
  DeadLeavesParams p;
  p.min_radius_mm = 0.5;
  p.max_radius_mm = 32;
  p.palette = PalettePhoto();
  p.grain.amplitude = 0;
  p.seed = 11;
  const DeadLeaves leaves(p);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> at(0, 2000);
  double previous = 0;
  for (double d : {0.5, 2.0, 8.0, 32.0}) {
    double sum = 0;
    for (int n = 0; n < 20000; ++n) {
      const double u = at(rng), v = at(rng);
      sum += std::abs(Luminance(leaves.Reflectance(u, v, 0.05)) -
                      Luminance(leaves.Reflectance(u + d, v, 0.05)));
    }
    const double mean_difference = sum / 20000;
    std::printf("dead leaves: mean |dL| at %.1f mm: %.3f\n", d, mean_difference);
    EXPECT_GT(mean_difference, previous * 1.1) << d << " mm";
    previous = mean_difference;
  }
}

// From the first pose of the default and the orbit motion, at medium and
// small, the lines of sight to the centres of the four ArUco markers end on
// the plate, not on an object of the scene.
TEST(SynthTableScene, ObjectsNeverHideTheMarkers) {
  const Scene scene = MakeTexturedTableScene(1);
  int plate_material = -1;
  for (std::size_t m = 0; m < scene.materials.size(); ++m)
    if (scene.materials[m].plate) plate_material = static_cast<int>(m);
  ASSERT_GE(plate_material, 0);
  for (const char* preset : {"medium", "small"})
    for (const char* motion : {"smooth", "orbit"}) {
      SynthParams params = *MakePreset(preset);
      params.rig.motion = motion;
      params.rig.frames = 12;
      for (const std::vector<Pose>& camera : TriggerPoses(params, scene))
        for (const Pose& world_from_cam : camera)
          for (const Eigen::Vector2d& c : scene.plate.aruco_centers_mm) {
            const Eigen::Vector3d eye = world_from_cam.translation();
            const Eigen::Vector3d dir = Eigen::Vector3d(c.x(), c.y(), 0) - eye;
            const auto hit = scene.Intersect(eye, dir);
            ASSERT_TRUE(hit.has_value());
            EXPECT_NEAR(hit->t, 1.0, 1e-6) << preset << " " << motion << ": marker at "
                                           << c.transpose() << " hidden";
            EXPECT_EQ(hit->material, plate_material);
          }
    }
}

TEST(SynthTableScene, SameSeedSameSceneOtherSeedOtherPlacement) {
  const Scene a = MakeTexturedTableScene(4), b = MakeTexturedTableScene(4),
              c = MakeTexturedTableScene(5);
  ASSERT_EQ(a.boxes.size(), b.boxes.size());
  ASSERT_EQ(a.boxes.size(), c.boxes.size());
  int moved = 0;
  for (std::size_t k = 0; k < a.boxes.size(); ++k) {
    EXPECT_EQ(a.boxes[k].min_mm, b.boxes[k].min_mm);
    EXPECT_EQ(a.boxes[k].x_axis, b.boxes[k].x_axis);
    moved += (a.boxes[k].min_mm - c.boxes[k].min_mm).norm() > 1e-9;
  }
  EXPECT_GT(moved, 5);
  EXPECT_EQ(a.clusters.size(), 1u);
  EXPECT_GE(a.clusters[0].quads.size(), 40u);
  EXPECT_EQ(MakeScene("table", 4)->boxes.size(), a.boxes.size());
  EXPECT_FALSE(MakeScene("tabel", 4).ok());
}

}  // namespace
}  // namespace lifmcr::synth
