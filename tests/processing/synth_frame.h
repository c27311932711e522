#pragma once
// One synthetic frame of a preset rendered in memory (a scene of
// replay/synth/scene.h, by default `plain`; the camera where `lifmcr synth`
// places it at t = 0), with its white image, MLA file, true intrinsics and
// ground truth.

#include "config/mla.h"
#include "processing/camera_model.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"

#include <memory>
#include <string>

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

}  // namespace lifmcr::processing::testing
