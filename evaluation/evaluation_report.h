#pragma once
// What `lifmcr evaluate` found, and the files it writes from it:
// evaluation.md (the paper's tables, with and without the hand-eye
// correction), evaluation.json (every figure, the git revision, the inputs),
// hand_eye.yaml (estimated offsets, readable by --hand-eye FILE) and TUM
// trajectories (timestamp tx ty tz qx qy qz qw; timestamp = the trigger's
// Vicon frame / Vicon rate, s; metres are NOT used: translations stay in mm,
// so `evo_ape` figures read in mm).

#include "config/error.h"
#include "config/frames.h"
#include "evaluation/evaluation.h"
#include "evaluation/plate_alignment.h"
#include "evaluation/trajectory_metrics.h"
#include "evaluation/vicon_ground_truth.h"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

struct CameraTruth {
  std::string serial;
  std::string subject;
  std::size_t asked = 0;                 // frames with a registration (or the reference's frames)
  std::vector<std::int64_t> untracked;   // of those, without a Vicon pose
  FramePoses vicon_from_marker;          // the tracked ones
  std::optional<Pose> true_marker_from_cam;  // GroundTruth/marker_from_cam_<serial>.csv
};

struct EvaluationRun {
  std::filesystem::path sequence_dir;
  std::string sequence_name;  // SCENE/SEQ
  std::vector<std::filesystem::path> registration_files;
  std::filesystem::path vicon_csv, vsk;
  std::string git_revision;
  std::string command_line;
  std::string rotation, handedness;
  double rate_hz = 80;
  FrameAssociationOptions association;
  std::string hand_eye_mode;  // estimate | truth | FILE
  std::string split;          // half | sequence | none
  std::string hand_eye_from;  // --split sequence: the sequence the offsets were estimated on
  std::string reference_serial;
  std::vector<CameraTruth> cameras;  // the reference first
  std::optional<PlateAlignment> plate;
  std::string plate_note;  // why there is no plate alignment
  std::string aruco_source;  // where the ArUco centres in the map came from (empty: none)
  std::string z_prior_note;  // how the joint map-frame hand-eye held the plate correction Z
  std::vector<CameraEvaluation> evaluations;      // c0_from_cx per method and camera
  std::vector<CameraEvaluation> map_evaluations;  // with --reference-poses: poses in the map
  std::vector<MethodDifference> differences;
  std::vector<std::string> warnings;

  const CameraTruth* Camera(const std::string& serial) const;
  double TimestampOf(std::int64_t frame) const {
    return association.ViconFrameOf(frame) / rate_hz;
  }
};

// evaluation.md
std::string FormatEvaluationMarkdown(const EvaluationRun& run,
                                     const std::vector<std::string>& files);
// evaluation.json
std::string FormatEvaluationJson(const EvaluationRun& run, const std::vector<std::string>& files);
// One TUM file: "timestamp tx ty tz qx qy qz qw" per pose, mm.
std::string FormatTum(const EvaluationRun& run, const FramePoses& poses);
// The paper-shaped summary lines printed on stdout at the end.
std::string FormatSummaryTable(const EvaluationRun& run);

}  // namespace lifmcr
