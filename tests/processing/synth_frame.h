#pragma once
// One synthetic frame of a preset rendered in memory (a scene of
// replay/synth/scene.h, by default `plain`; the camera where `lifmcr synth`
// places it at t = 0), with its white image, MLA file, true intrinsics and
// ground truth.

#include "config/mla.h"
#include "processing/camera_model.h"
#include "processing/plenoptic_frame.h"
#include "processing/virtual_depth.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr::processing::testing {

struct SynthFrame {
  synth::SynthCameraParams params;
  std::unique_ptr<synth::PlenopticModel> model;
  synth::RawFrame raw;
  synth::RawFrame white;
  synth::TfGroundTruth tf;
  MlaCalibration mla;
  CameraIntrinsics intrinsics;
};

// `scene`: replay/synth/scene.h's name; `bayer`: the sensor writes an RGGB
// mosaic (Mono8) instead of BGR8.
SynthFrame RenderSynthFrame(const std::string& preset = "small", double read_noise_dn = 1.0,
                            const std::string& scene = "plain", bool bayer = false);

// The accuracy gates of a virtual depth map against the frame's truth, over
// the textured pixels with a true depth: coverage, median |dz|/z (z = 1/v),
// share of outliers |dv|/v > 10 % among the covered. Zero coverage when
// fewer than 10000 pixels are textured.
struct DepthGates {
  double coverage = 0, median = 1, outliers = 1;
  long long textured = 0;
};
DepthGates MeasureDepthGates(const SynthFrame& frame, const std::vector<float>& virtual_depth,
                             const std::vector<std::uint8_t>& textured);
// `raw` devignetted by `white` (empty: none) on the frame's MLA file and true
// lambda, virtual depth with the default options, and its gates; `prepared`
// and `depth` keep the intermediate results.
DepthGates DepthGatesOf(const SynthFrame& frame, ConstImageView raw, ConstImageView white,
                        PlenopticFrame* prepared, VirtualDepthMap* depth);

}  // namespace lifmcr::processing::testing
