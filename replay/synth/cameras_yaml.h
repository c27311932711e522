#pragma once
// GroundTruth/cameras.yaml of a synthetic sequence: every parameter of each
// camera model and its MLA (the true values the renderer used, and derived
// quantities such as the sharp range of each lens type), the Vicon set-up,
// the marker plate layout that defines the world frame, and each camera's
// true marker_from_cam. Poses are written as tx_mm, ty_mm, tz_mm, qw, qx, qy, qz.

#include "config/frames.h"
#include "replay/synth/marker_plate.h"
#include "replay/synth/synth_writer.h"

#include <string>
#include <vector>

namespace lifmcr::synth {

std::string FormatCamerasYaml(const SynthParams& params, const std::vector<SynthCamera>& cameras,
                              const MarkerPlateLayout& plate, const Pose& vicon_from_world,
                              const Pose& world_from_plate_marker);

}  // namespace lifmcr::synth
