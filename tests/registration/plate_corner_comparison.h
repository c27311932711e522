#pragma once
// The plate corners of the calibration's frame loader (placed on the plate
// rendered at its plane's virtual depth) and the corners placed on the TF
// image itself, both measured against the renderer's truth on the same
// frames: the comparison test_plate_plane and test_plate_corners_medium
// make at two sizes.

#include "registration/calibration/calibration_gates.h"
#include "registration/features/aruco_plate.h"
#include "registration/features/calibration_frames.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct PlateCornerComparison {
  PlateCornerBias on_plane;  // the loader's corners
  PlateCornerBias on_tf;     // the same frames' corners on their TF image
};

// Loads `frames` through `loader` and measures both sets of corners against
// the truth of `sequence`; prints both reports. Fails the test (and returns
// nothing) where a frame or a measurement fails.
inline std::optional<PlateCornerComparison> ComparePlateCorners(
    CalibrationFrameLoader& loader, const std::vector<std::int64_t>& frames,
    const PlateLayout& plate, double lambda, const std::filesystem::path& sequence,
    const std::string& serial) {
  std::vector<CalibrationFrame> plane_frames, tf_frames;
  for (const std::int64_t f : frames) {
    Expected<CalibrationFrame> frame = loader.Load(f);
    EXPECT_TRUE(frame) << frame.error().message;
    if (!frame) return std::nullopt;
    plane_frames.push_back(*frame);
    Expected<std::vector<PlateCorner>> on_tf = DetectPlateCorners(loader.last_tf_image(), plate);
    EXPECT_TRUE(on_tf) << on_tf.error().message;
    if (!on_tf) return std::nullopt;
    frame->corners = *on_tf;
    frame->corner_virtual_depth.assign(on_tf->size(), std::nanf(""));
    tf_frames.push_back(*frame);
  }
  Expected<PlateCornerBias> on_plane = MeasurePlateCornerBias(plane_frames, lambda, sequence, serial);
  Expected<PlateCornerBias> on_tf = MeasurePlateCornerBias(tf_frames, lambda, sequence, serial);
  EXPECT_TRUE(on_plane && on_tf);
  if (!on_plane || !on_tf) return std::nullopt;
  std::printf("on the plane's render: %s\n%son the TF image: %s\n%s", on_plane->BriefReport().c_str(),
              on_plane->PerFrameReport().c_str(), on_tf->BriefReport().c_str(),
              on_tf->PerFrameReport().c_str());
  return PlateCornerComparison{*on_plane, *on_tf};
}

}  // namespace lifmcr::registration
