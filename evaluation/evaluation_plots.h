#pragma once
// PNG plots of `lifmcr evaluate`, drawn with OpenCV imgproc and written with
// imgcodecs (no Python): trajectories seen from above, errors over frames
// with RMSE and median lines, per-axis error histograms.

#include "evaluation/evaluation_report.h"
#include "config/error.h"

#include <filesystem>

namespace lifmcr {

// Every camera's Vicon trajectory (camera centres when offsets are known,
// else marker centroids) and each method's registered camera X placed by
// camera 0's Vicon pose, in the plate frame (or the Vicon frame), x-y plane.
Status PlotTrajectoriesTop(const EvaluationRun& run, const std::filesystem::path& path);
// Absolute translation and rotation error over frames, without and with the
// correction, with each curve's RMSE (solid) and median (dashed).
Status PlotErrorsOverFrames(const CameraEvaluation& e, const std::filesystem::path& path);
// Histograms of the signed per-axis absolute errors (camera frame), without
// and with the correction.
Status PlotAxisHistograms(const CameraEvaluation& e, const std::filesystem::path& path);

}  // namespace lifmcr
