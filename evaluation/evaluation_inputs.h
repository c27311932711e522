#pragma once
// The files `lifmcr evaluate` reads besides the Vicon export and the VSK:
//
//   registration.csv (lifmcr register, docs/registration.md): a header row naming
//     frame,camera,method,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz,inliers,rmse_px,status
//     (any column order), one row per registered frame of c0_from_cx; rows
//     whose status is not `ok` are kept as failures with their reason.
//   (poses CSVs, GroundTruth/poses_<serial>.csv, are read by registration/map/poses_csv.h)
//   marker_from_cam CSV (GroundTruth/marker_from_cam_<serial>.csv): one row.
//   hand-eye YAML (written by lifmcr evaluate, read by --hand-eye FILE):
//     cameras: [{serial: "...", marker_from_cam: {tx_mm, ty_mm, tz_mm, qw, qx, qy, qz}}, ...]
//   GroundTruth/cameras.yaml (lifmcr synth): the parts evaluation needs.
// Quaternions are read as given and must have unit norm within 1e-3 (then
// normalised); errors name the file, line and column.

#include "config/error.h"
#include "config/frames.h"
#include "evaluation/plate_alignment.h"
#include "evaluation/trajectory_metrics.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

struct RegistrationRow {
  std::int64_t frame = 0;
  std::string camera;  // serial of camera X
  std::string method;  // pnp, ransac, ...
  Pose c0_from_cx = Pose::Identity();
  std::int64_t inliers = 0;
  double rmse_px = 0;
  std::string status;  // "ok" or the reason registration failed
  int line = 0;        // in the file
};

struct RegistrationTable {
  std::filesystem::path path;
  std::vector<RegistrationRow> rows;  // file order
};

Expected<RegistrationTable> ReadRegistrationCsv(const std::filesystem::path& path);
// The registration.csv text of `rows` (tests and tools that make inputs).
std::string FormatRegistrationCsv(const std::vector<RegistrationRow>& rows);

Expected<Pose> ReadMarkerFromCamCsv(const std::filesystem::path& path);

// A TUM trajectory whose first column is the frame number (lifmcr
// register's trajectory_<serial>_<method>.tum of w0_from_cam):
// "frame tx ty tz qx qy qz qw" per line, '#' lines are comments.
Expected<FramePoses> ReadFrameTum(const std::filesystem::path& path);

// serial -> marker_from_cam.
using HandEyeOffsets = std::map<std::string, Pose>;
Expected<HandEyeOffsets> ReadHandEyeYaml(const std::filesystem::path& path);
std::string FormatHandEyeYaml(const HandEyeOffsets& offsets, const std::string& comment);

// What GroundTruth/cameras.yaml tells evaluation.
struct SynthGroundTruthInfo {
  std::map<std::string, std::string> vicon_subject;  // serial -> Vicon object
  std::vector<std::string> serials;                  // file order (the reference first)
  std::optional<PlateTemplate> plate;
  std::optional<std::string> handedness, rotation;  // as written (frames.h names)
  std::optional<int> trigger_divider;
  std::optional<std::int64_t> first_trigger_frame;
  std::optional<double> rate_hz;
  std::optional<std::string> plate_subject;
};
Expected<SynthGroundTruthInfo> ReadCamerasYaml(const std::filesystem::path& path);

}  // namespace lifmcr
