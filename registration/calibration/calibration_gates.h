#pragma once
// A calibration measured against the ground truth of a synthetic sequence
// (`lifmcr synth`: SEQ/GroundTruth/cameras.yaml, poses_<serial>.csv,
// depth/<serial>_<frame>_depth_mm.tiff), with the figures of the issue's
// gates: relative errors of f_L, b_L0 and B, principal point error,
// reprojection RMSE, map point error, pose error, scale error.
//
// Map points: the true position of a point is that of its first
// observation: the keypoint's TF pixel with the true depth there (the
// ground-truth depth map, bilinear within one surface), back-projected with the true
// intrinsics and placed with the true pose. The keypoint's pixel and virtual
// depth are in the geometry of the frame's processing (the calibration's
// frames_lambda and principal point, see PlateCornerBias below): they are
// taken back to the true virtual image first, and the keypoints' virtual
// depths are compared with the true one as that processing reads it. World frames: both are the plate
// frame (the calibration's w0 is fixed by the plate corners). Scale: the
// scale of the least-squares similarity (Umeyama) from the estimated to the
// true points, over the points within 3 median errors.

#include "config/error.h"
#include "registration/calibration/calibration.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace lifmcr::processing {
class CameraModel;
}  // namespace lifmcr::processing

namespace lifmcr::registration {

struct GroundTruthComparison {
  double f_l_rel = 0, b_l0_rel = 0, b_rel = 0;  // estimate / truth - 1
  double principal_point_px = 0;                // |c - c_true|
  double rmse_px = 0;                           // of the calibration
  double map_median_mm = 0;                     // median |p - p_true|
  int map_points = 0;                           // compared
  double map_median_by_track_mm[3] = {0, 0, 0};  // points seen in 2, 3, >= 4 frames
  int map_points_by_track[3] = {0, 0, 0};
  double pose_median_mm = 0, pose_median_deg = 0;  // median per frame
  double scale_error = 0;                          // |s - 1|
  double keypoint_v_median_rel = 0;                // median |v - v_true| / v_true of observations
  double keypoint_v_bias_rel = 0;                  // median (v - v_true) / v_true
  std::string BriefReport() const;                 // one line
};

struct GateThresholds {
  double intrinsic_rel = 0.005;  // f_L, b_L0, B
  double principal_point_px = 1.0;
  double rmse_px = 0.3;
  double map_median_mm = 1.0;
  double pose_mm = 1.0, pose_deg = 0.05;
  double scale = 0.002;
};
// Each gate missed, as "name value > threshold"; empty when all are met.
std::vector<std::string> MissedGates(const GroundTruthComparison& c, const GateThresholds& t,
                                     bool intrinsics_fixed_fl_b = false);

// ArUco plate corners of processed frames against their true TF positions
// (true intrinsics and poses, plenoptic_projection.h): the mean offset in
// x and y, the mean component towards the marker's centre (inset: positive
// when the detected corner lies inside the true square), and the RMS.
// A TF image processed with micro-lens centres of another lambda (lambda0,
// the initial intrinsics') than the true one is the true TF image scaled
// about the principal point c by v'/v: a lens centre l'_k = c + (c_k - c)
// lambda0 makes the disparity of a point at virtual depth v read as v' with
//   1 - 1/v' = (lambda / lambda0) (1 - 1/v),
// and its position x_v' - c = (x_v - c) v' / v (the same for every micro
// image). The true positions are compared in that image, not in the true one
// (the calibration's observations, raw micro-image positions, are free of it).
struct PlateCornerBias {
  int corners = 0;
  double mean_x_tf_px = 0, mean_y_tf_px = 0, mean_inset_tf_px = 0, rms_tf_px = 0;
  int corners_with_v = 0;  // with a measured virtual depth
  double v_bias_rel = 0;   // median (v - v_true) / v_true, v_true as the processing reads it
  // The same per frame (frames with corners), to find the views whose corners are off.
  struct Frame {
    std::int64_t frame = 0;
    int corners = 0;
    double mean_x_tf_px = 0, mean_y_tf_px = 0, rms_tf_px = 0;
    double v_bias_rel = 0;  // median, NaN without a corner virtual depth
    // The corner farthest from its true position: marker id, corner 0..3,
    // its offset (TF px).
    int worst_marker = -1, worst_corner = -1;
    Eigen::Vector2d worst_offset_tf_px = Eigen::Vector2d::Zero();
  };
  std::vector<Frame> frames;
  std::string BriefReport() const;  // one line
  std::string PerFrameReport() const;  // a line per frame
};
// A synthetic sequence's true intrinsics of `serial` and its poses
// (cam_from_world, w the plate frame), by frame.
struct SequenceTruth {
  CameraCalibration camera;
  std::map<std::int64_t, Pose> cam_from_world;
};
Expected<SequenceTruth> ReadSequenceTruth(const std::filesystem::path& sequence_dir,
                                          const std::string& serial);

Expected<PlateCornerBias> MeasurePlateCornerBias(const std::vector<CalibrationFrame>& frames,
                                                 double frames_lambda,
                                                 const std::filesystem::path& sequence_dir,
                                                 const std::string& serial);

// The true depth (mm) at TF position tf of a ground-truth depth map (w x h,
// row-major): bilinear between the four nearest pixels when they lie on one
// surface (within 1 % of each other), else the nearest pixel's. The nearest
// pixel alone is up to half a TF pixel off, which on a surface seen
// obliquely is tenths of a mm.
double SurfaceDepthMm(const std::vector<float>& depth, int w, int h, const Eigen::Vector2d& tf);

// A virtual point of a frame processed with lambda0 and principal point c0
// (the initial intrinsics) and the true virtual point whose micro images the
// processing read as it: equal micro-image positions for every lens,
//   lambda (1 - 1/v) = lambda0 (1 - 1/v'),
//   x / v = x' / v' - c (1 - lambda)(1 - 1/v) + c0 (1 - lambda0)(1 - 1/v').
struct ProcessedGeometry {
  double lambda = 1, lambda0 = 1;  // true, processed
  Eigen::Vector2d c = Eigen::Vector2d::Zero(), c0 = Eigen::Vector2d::Zero();  // raw px
  double ProcessedDepth(double v) const { return 1.0 / (1.0 - lambda / lambda0 * (1.0 - 1.0 / v)); }
  // x' (raw px) of the true x at depth v.
  Eigen::Vector2d ProcessedOfTrue(const Eigen::Vector2d& x, double v) const;
  // x (raw px) of the processed x' at the true depth v.
  Eigen::Vector2d TrueOfProcessed(const Eigen::Vector2d& x_processed, double v) const;
};

// A TF pixel's virtual point in raw px (x_v = 2 tf + 0.5), and back.
inline Eigen::Vector2d VirtualOfTf(const Eigen::Vector2d& tf) {
  return 2.0 * tf + Eigen::Vector2d(0.5, 0.5);
}
inline Eigen::Vector2d TfOfVirtual(const Eigen::Vector2d& x) {
  return (x - Eigen::Vector2d(0.5, 0.5)) / 2.0;
}

// The true virtual point behind the processed x' (raw px) of a frame whose
// ground-truth depth map (w x h, the TF grid) is `depth`: x at the true
// depth v the map has there, by a few fixed-point steps from x = x'
// (TrueOfProcessed at SurfaceDepthMm's depth at x). v is NaN where the map
// has no surface beyond the main lens's focal length.
struct TrueVirtualPoint {
  Eigen::Vector2d x = Eigen::Vector2d::Zero();  // raw px
  double v = 0;
};
TrueVirtualPoint TrueOfProcessedOnSurface(const ProcessedGeometry& geometry,
                                          const processing::CameraModel& true_model,
                                          const std::vector<float>& depth, int w, int h,
                                          const Eigen::Vector2d& x_processed);

Expected<GroundTruthComparison> CompareWithGroundTruth(const CalibrationResult& result,
                                                       const std::filesystem::path& sequence_dir,
                                                       const std::string& serial);

}  // namespace lifmcr::registration
