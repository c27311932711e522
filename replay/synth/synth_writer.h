#pragma once
// `lifmcr synth`: writes a synthetic LiFMCR dataset with ground truth, in the
// layout of replay/layout.h:
//   OUT/Calibration/01_White_Images/TypeE_<serial>_00_Raw.bmp   white image per camera
//   OUT/Calibration/02_MLA_Calibration/TypeE_<serial>_MLA.xml   the MLA the renderer used
//   OUT/Calibration/03_Vicon/Object.vsk                         clusters of cameras and plate
//   OUT/SCENE/SEQ/Vicon/sequence_01.csv                         Tracker-style Objects export
//   OUT/SCENE/SEQ/TypeE_<serial>/TypeE_<serial>_<frame>_Raw.bmp raw frames, frame 0..N-1
//   OUT/SCENE/SEQ/GroundTruth/cameras.yaml, poses_<serial>.csv, marker_from_cam_<serial>.csv,
//       depth/<serial>_<frame>_virtual_depth.tiff (raw grid), depth/<serial>_<frame>_depth_mm.tiff
//       (TF grid), all_in_focus/<serial>_<frame>_all_in_focus.png (TF grid)
// Cameras: serials 40398678 (Vicon "cam0", the reference) and 40398673
// ("cam2") as in the paper, then 40398674 ("cam4"), ... Each camera's MLA is
// placed slightly differently (offset, rotation), as real units differ.
// Deterministic for a seed: the same parameters give the same bytes.

#include "config/error.h"
#include "config/frames.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"
#include "replay/synth/vicon_sim.h"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace lifmcr::synth {

inline constexpr std::string_view kPlateSubject = "plate";
inline constexpr int kSequenceCsvIndex = 1;

struct SynthCamera {
  std::string serial;
  std::string vicon_subject;  // "cam0", "cam2", ...
  SynthCameraParams params;
  MarkerCluster cluster;
  Pose marker_from_cam;
};

// The cameras of a rig, before any rendering (pure function of the params).
std::vector<SynthCamera> MakeSynthCameras(const SynthParams& params);

// Each camera's trajectory (trajectory.h) as WriteSyntheticDataset moves it
// through `scene`, and world_from_cam of each camera at each trigger
// ([camera][frame]): the poses GroundTruth/poses_<serial>.csv holds.
std::vector<CameraTrajectory> MakeTrajectories(const SynthParams& params, const Scene& scene);
std::vector<std::vector<Pose>> TriggerPoses(const SynthParams& params, const Scene& scene);

struct SynthSummary {
  std::filesystem::path sequence_dir;
  std::filesystem::path calibration_dir;
  int cameras = 0;
  int frames = 0;
  std::int64_t files = 0;
  double seconds = 0;
  std::string BriefReport() const;  // one line
};

using ProgressFn = std::function<void(std::string_view line)>;

// Writes everything under `out_dir` (created if needed). Errors name the file
// that could not be written. `progress` (may be empty) gets one line per
// rendered frame.
Expected<SynthSummary> WriteSyntheticDataset(const std::filesystem::path& out_dir,
                                             const SynthParams& params,
                                             const ProgressFn& progress = {});

// Writes the ground-truth CSV of world_from_cam per frame:
// frame,vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz.
std::string FormatPosesCsv(const std::vector<std::int64_t>& frames,
                           const std::vector<std::int64_t>& vicon_frames,
                           const std::vector<Pose>& world_from_cam);
// tx_mm,ty_mm,tz_mm,qw,qx,qy,qz and one row.
std::string FormatMarkerFromCamCsv(const Pose& marker_from_cam);

// GroundTruth/all_in_focus/<serial>_<frame, 6 digits>_all_in_focus.png (not in
// replay/layout.h: only the generator writes it).
std::filesystem::path AllInFocusPath(const std::filesystem::path& sequence_dir,
                                     std::string_view serial, std::int64_t frame);

}  // namespace lifmcr::synth
