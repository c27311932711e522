#pragma once
// What a synthetic scene offers registration and depth, measured on one
// rendered frame (tests/processing/test_synth_scene.cpp, bench/bench_scene.cpp):
// - SIFT (OpenCV cv::SIFT, default settings) keypoints on the all-in-focus
//   ground truth and on the TF image that processing/ renders from the raw
//   frame (the one registration uses; the image `lifmcr depth` writes);
// - virtual depth (processing/ with lifmcr depth's options and the true
//   lambda) as a share of ALL raw pixels, and of the textured ones;
// - photo-consistency of the raw images with their ground-truth depth: for
//   every pixel p of micro image k with a ground-truth v and every ring-1
//   neighbour n, the squared grey difference between p and its image
//   q(v) = p + lambda (c_n - c_k) (1 - 1 / v) in n (virtual_depth.h), on the
//   devignetted grey without smoothing; its mean at the true v, at 1.25 v
//   and at 0.8 v over the same (p, n) pairs (those where all three q fall on
//   valid pixels). The ratios cost(1.25 v) / cost(v) and cost(0.8 v) /
//   cost(v) say how clearly the true depth explains the neighbours. Ring-1
//   neighbours are always of another lens type (another defocus), so the
//   same is measured over the ring-2 neighbours (same type, baseline
//   sqrt(3) D), where only noise and sampling separate the true depth from
//   a perfect match.

#include "processing/total_focus.h"
#include "tests/processing/synth_frame.h"

#include <string>

namespace lifmcr::processing::testing {

struct SceneFigures {
  int sift_ground_truth = 0;
  int sift_processed = 0;
  double depth_coverage = 0;     // raw pixels with a virtual depth / all raw pixels
  double textured_share = 0;     // raw pixels passing the gradient gate / all raw pixels
  double textured_coverage = 0;  // with a virtual depth / textured
  struct Consistency {
    long long pairs = 0;
    double cost_true = 0, cost_far = 0, cost_near = 0;  // mean squared DN at v, 1.25 v, 0.8 v
    double FarRatio() const { return cost_far / cost_true; }
    double NearRatio() const { return cost_near / cost_true; }
  };
  Consistency ring1, ring2;  // neighbours of another / the same lens type
  std::string BriefReport() const;
};

// `tf` (optional) receives the processed TF image.
SceneFigures MeasureSceneFigures(const SynthFrame& frame, TfImage* tf = nullptr);

}  // namespace lifmcr::processing::testing
