#pragma once
// Per-frame pose files in the columns of GroundTruth/poses_<serial>.csv
// (replay/synth/synth_writer.h): frame,vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz
// with one row per frame; the pose maps camera coordinates into the world
// (world_from_cam of the ground truth, w0_from_c0 of `lifmcr calibrate`).

#include "config/error.h"
#include "config/frames.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct FramePose {
  std::int64_t frame = 0;
  std::int64_t vicon_frame = 0;  // -1 when unknown
  Pose world_from_cam = Pose::Identity();
};

std::string FormatPosesCsv(const std::vector<FramePose>& poses);
Status WritePosesCsv(const std::filesystem::path& path, const std::vector<FramePose>& poses);
// Errors name the file, the line and the column that is not a number.
Expected<std::vector<FramePose>> ReadPosesCsv(const std::filesystem::path& path);

}  // namespace lifmcr::registration
