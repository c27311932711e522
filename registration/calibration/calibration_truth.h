#pragma once
// The calibration's residuals evaluated at the ground truth of a synthetic
// sequence (`lifmcr calibrate --at-truth`): which observations the model
// does not explain with the true intrinsics and poses, frame by frame.
//
// The tracks are those the calibration builds (initialisation with the
// initial intrinsics, calibration.h step 2) and each observation is made as
// the bundle adjustment makes it (the max_lenses most central micro images,
// positions p_k = l_k + (x_v - l_k) / v with the frames' lambda). With the
// true intrinsics and the true poses held, each point is the one that fits
// its observations best (Huber loss as in the solve; an observation above
// max(outlier_px, 3 x the median RMS) is dropped and the point fitted
// again), so what remains is what the model cannot explain at the truth:
// a frame, a depth or an image region whose observations are biased
// against the others shows a residual with a mean.
//
// Each observation's micro-image residuals r_n = predicted - observed are
// summarised by the offset d = (dx, dy, dv) of the virtual point that
// explains them to first order: with the predicted virtual point (x, v) and
// the lens centres l_n, p_n = l_n + (x - l_n) / v moves by
//   dp_n = dx / v - (x - l_n) dv / v^2,
// and d is the least-squares fit of dp_n = -r_n (observed minus predicted):
// dx, dy in raw pixels of the virtual image (2 per TF pixel), dv / v.
// Plate corners (fixed points of the plate frame, inset 0) the same way.

#include "config/error.h"
#include "registration/calibration/calibration.h"

#include <Eigen/Core>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace lifmcr::registration {

struct TruthResiduals {
  // Summary of a set of observations.
  struct Stats {
    int observations = 0;  // kept (below the outlier threshold)
    int outliers = 0;
    double rmse_px = 0;                // micro-image residuals of the kept ones
    double mean_dx_px = 0, mean_dy_px = 0;  // virtual-image offset, observed - predicted
    double median_dv_rel = 0;          // dv / v
    double median_v = 0;               // predicted virtual depth
    double median_z_mm = 0;            // camera z of the point
  };
  struct Frame {
    std::int64_t frame = 0;
    Stats keypoints;
    Stats corners;  // plate corners (residuals in micro images where a depth was measured)
  };
  std::vector<Frame> frames;
  Stats all;
  // Keypoint observations of all frames by predicted virtual depth and by
  // position of the virtual point relative to the principal point (raw px).
  struct Bin {
    double lo = 0, hi = 0;
    Stats stats;
  };
  std::vector<Bin> by_v, by_x, by_y;
  // Every keypoint observation, kept or not (and plate corner: point -1).
  struct Row {
    std::int64_t frame = 0;
    int point = 0;          // index of the fitted point; -1 for a plate corner
    Eigen::Vector3d x_v = Eigen::Vector3d::Zero();     // predicted virtual point (raw px, v)
    double z_mm = 0;
    Eigen::Vector3d offset = Eigen::Vector3d::Zero();  // dx, dy (raw px), dv
    double rms_px = 0;              // of its micro-image residuals
    double unexplained_rms_px = 0;  // what the offset leaves
    int lenses = 0;
    double size_tf_px = 0;          // SIFT region diameter (0 for a corner)
    bool kept = true;               // below the outlier threshold
  };
  std::vector<Row> rows;
  std::string Csv() const;  // the rows, a header line first
  int points = 0;         // tracks fitted
  double outlier_px = 0;  // the threshold used
  std::string Report() const;  // markdown tables
};

// `world_from_cam` holds the true pose of each frame (w = the plate frame,
// as the calibration's w0); frames without one are left out.
Expected<TruthResiduals> EvaluateAtTruth(const CalibrationInput& input,
                                         const CalibrationOptions& options,
                                         const processing::CameraIntrinsics& truth,
                                         const std::map<std::int64_t, Pose>& world_from_cam,
                                         const ProgressFn& progress = {});

}  // namespace lifmcr::registration
