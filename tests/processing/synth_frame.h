#pragma once
// One synthetic frame of the `small` preset rendered in memory (table-top
// scene, camera 1100 mm from the plate as `lifmcr synth` places it), with its
// white image, MLA file, true intrinsics and ground truth.

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

// `bayer`: the sensor writes an RGGB mosaic (Mono8) instead of BGR8.
SynthFrame RenderSynthFrame(const std::string& preset = "small", double read_noise_dn = 1.0,
                            bool bayer = false);

}  // namespace lifmcr::processing::testing
