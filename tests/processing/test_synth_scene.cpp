// The textured synthetic scene (`lifmcr synth --scene table`, the default)
// is rich enough to test feature-based registration and depth on, measured
// on one `small` frame (tests/processing/scene_figures.h says how), beside
// the `plain` scene: SIFT >= 500 keypoints on the processed TF image and on
// the all-in-focus ground truth; the ground-truth depth explains neighbouring
// micro images clearly better than a depth 25 % off (mean squared difference
// at least 1.5 times larger at 1.25 v and at 0.8 v); `lifmcr depth`'s
// virtual depth (step 5 filling untextured pixels, processing/virtual_depth.h)
// on at least 40 % of all raw pixels, and on more than the plain scene gives.
// The `medium` figures (SIFT >= 1500) come from bench/bench_scene.

#include "tests/processing/scene_figures.h"

#include <gtest/gtest.h>

#include <cstdio>

namespace lifmcr::processing {
namespace {

TEST(SynthScene, TexturedTableIsRichEnoughForFeaturesAndDepth) {
  const testing::SceneFigures table =
      testing::MeasureSceneFigures(testing::RenderSynthFrame("small", 1.0, "table"));
  const testing::SceneFigures plain =
      testing::MeasureSceneFigures(testing::RenderSynthFrame("small", 1.0, "plain"));
  std::printf("small, scene table: %s\nsmall, scene plain: %s\n", table.BriefReport().c_str(),
              plain.BriefReport().c_str());
  EXPECT_GE(table.sift_processed, 500);
  EXPECT_GE(table.sift_ground_truth, 500);
  for (const auto* c : {&table.ring1, &table.ring2}) {
    ASSERT_GT(c->pairs, 100000);
    EXPECT_GE(c->FarRatio(), 1.5);
    EXPECT_GE(c->NearRatio(), 1.5);
  }
  EXPECT_GE(table.depth_coverage, 0.40);
  EXPECT_GE(table.depth_coverage, 1.5 * plain.depth_coverage);
}

}  // namespace
}  // namespace lifmcr::processing
