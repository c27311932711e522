#include "registration/calibration/calibration_gates.h"

#include "processing/camera_model.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/map/poses_csv.h"
#include "replay/layout.h"
#include "replay/synth/gt_images.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

namespace lifmcr::registration {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

std::string Format(const char* fmt, auto... args) {
  char buffer[1024];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

}  // namespace

std::string GroundTruthComparison::BriefReport() const {
  return Format(
      "vs ground truth: f_L %+.3f %%, b_L0 %+.3f %%, B %+.3f %%, principal point %.2f px, RMSE "
      "%.3f px, map median %.3f mm (%d points; seen in 2 / 3 / >= 4 frames: %d / %d / %d points, "
      "%.3f / %.3f / %.3f mm), pose median %.3f mm / %.4f deg, scale %.3f %%, "
      "keypoint v median |error| %.2f %% (signed %+.2f %%)",
      100 * f_l_rel, 100 * b_l0_rel, 100 * b_rel, principal_point_px, rmse_px, map_median_mm,
      map_points, map_points_by_track[0], map_points_by_track[1], map_points_by_track[2],
      map_median_by_track_mm[0], map_median_by_track_mm[1], map_median_by_track_mm[2],
      pose_median_mm, pose_median_deg, 100 * scale_error,
      100 * keypoint_v_median_rel, 100 * keypoint_v_bias_rel);
}

std::vector<std::string> MissedGates(const GroundTruthComparison& c, const GateThresholds& t,
                                     bool fixed) {
  std::vector<std::string> missed;
  auto check = [&](const char* name, double value, double limit) {
    if (!(std::abs(value) <= limit)) missed.push_back(Format("%s %.4g > %.4g", name, value, limit));
  };
  if (!fixed) {
    check("f_L rel", c.f_l_rel, t.intrinsic_rel);
    check("B rel", c.b_rel, t.intrinsic_rel);
  }
  check("b_L0 rel", c.b_l0_rel, t.intrinsic_rel);
  check("principal point px", c.principal_point_px, t.principal_point_px);
  check("RMSE px", c.rmse_px, t.rmse_px);
  check("map median mm", c.map_median_mm, t.map_median_mm);
  check("pose median mm", c.pose_median_mm, t.pose_mm);
  check("pose median deg", c.pose_median_deg, t.pose_deg);
  check("scale", c.scale_error, t.scale);
  return missed;
}

std::string PlateCornerBias::BriefReport() const {
  return Format("plate corners vs truth (%d): mean offset (%+.3f, %+.3f) TF px, inset %+.3f TF px, "
                "RMS %.3f TF px; virtual depth (%d corners) median %+.2f %%",
                corners, mean_x_tf_px, mean_y_tf_px, mean_inset_tf_px, rms_tf_px, corners_with_v,
                100 * v_bias_rel);
}

std::string PlateCornerBias::PerFrameReport() const {
  std::string text;
  for (const Frame& f : frames)
    text += Format("  frame %lld: %d corners, mean offset (%+.3f, %+.3f) TF px, RMS %.3f TF px, "
                   "virtual depth median %+.2f %%; farthest: marker %d corner %d (%+.3f, %+.3f) "
                   "TF px\n",
                   static_cast<long long>(f.frame), f.corners, f.mean_x_tf_px, f.mean_y_tf_px,
                   f.rms_tf_px, 100 * f.v_bias_rel, f.worst_marker, f.worst_corner,
                   f.worst_offset_tf_px.x(), f.worst_offset_tf_px.y());
  return text;
}

Expected<SequenceTruth> ReadSequenceTruth(const std::filesystem::path& seq,
                                          const std::string& serial) {
  Expected<CameraCalibration> camera = ReadCameraCalibration(layout::CamerasYamlPath(seq), serial);
  if (!camera) return camera.error();
  Expected<std::vector<FramePose>> poses = ReadPosesCsv(layout::PosesCsvPath(seq, serial));
  if (!poses) return poses.error();
  SequenceTruth truth;
  truth.camera = *camera;
  for (const FramePose& p : *poses) truth.cam_from_world[p.frame] = p.world_from_cam.inverse();
  return truth;
}

Expected<PlateCornerBias> MeasurePlateCornerBias(const std::vector<CalibrationFrame>& frames,
                                                 double frames_lambda,
                                                 const std::filesystem::path& seq,
                                                 const std::string& serial) {
  Expected<SequenceTruth> sequence_truth = ReadSequenceTruth(seq, serial);
  if (!sequence_truth) return sequence_truth.error();
  const CameraCalibration* truth = &sequence_truth->camera;
  const std::map<std::int64_t, Pose>& cam_from_world = sequence_truth->cam_from_world;
  const IntrinsicsVector k = ToVector(truth->intrinsics);
  const double s = truth->intrinsics.pixel_size_mm;
  const double lambda_ratio = processing::CameraModel(truth->intrinsics).lambda() / frames_lambda;
  const Eigen::Vector2d c = truth->intrinsics.PrincipalPointPx();
  // TF pixel of a plate point in the TF image processed with frames_lambda
  // (x_v = 2 tf + 0.5).
  double last_v_processed = 0;  // of the last tf_of
  auto tf_of = [&](const Pose& c_from_w, const Eigen::Vector3d& p_in_w, Eigen::Vector2d* tf) {
    const Eigen::Vector3d p = c_from_w * p_in_w;
    double x_v[3];
    if (!ProjectToVirtual(k.data(), s, p.data(), x_v)) return false;
    const double v_processed = 1.0 / (1.0 - lambda_ratio * (1.0 - 1.0 / x_v[2]));
    const Eigen::Vector2d x = c + (Eigen::Vector2d(x_v[0], x_v[1]) - c) * (v_processed / x_v[2]);
    *tf = TfOfVirtual(x);
    last_v_processed = v_processed;
    return true;
  };
  std::vector<double> v_signed;
  PlateCornerBias b;
  double ss = 0;
  for (const CalibrationFrame& f : frames) {
    const auto it = cam_from_world.find(f.frame);
    if (it == cam_from_world.end()) continue;
    PlateCornerBias::Frame pf;
    pf.frame = f.frame;
    double pf_ss = 0;
    std::vector<double> pf_v;
    for (const PlateCorner& corner : f.corners) {
      // The marker centre: the mean of its four corners in the plate frame.
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (const PlateCorner& other : f.corners)
        if (other.marker_id == corner.marker_id) centre += 0.25 * other.p_in_w_mm;
      Eigen::Vector2d tf_true, tf_centre;
      if (!tf_of(it->second, corner.p_in_w_mm, &tf_true)) continue;
      const std::size_t n = static_cast<std::size_t>(&corner - f.corners.data());
      if (n < f.corner_virtual_depth.size() && !std::isnan(f.corner_virtual_depth[n])) {
        v_signed.push_back(f.corner_virtual_depth[n] / last_v_processed - 1);
        pf_v.push_back(v_signed.back());
      }
      if (!tf_of(it->second, centre, &tf_centre)) continue;
      const Eigen::Vector2d d = corner.tf_px - tf_true;
      b.mean_x_tf_px += d.x();
      b.mean_y_tf_px += d.y();
      b.mean_inset_tf_px += d.dot((tf_centre - tf_true).normalized());
      ss += d.squaredNorm();
      ++b.corners;
      pf.mean_x_tf_px += d.x();
      pf.mean_y_tf_px += d.y();
      pf_ss += d.squaredNorm();
      ++pf.corners;
      if (pf.worst_marker < 0 || d.norm() > pf.worst_offset_tf_px.norm()) {
        pf.worst_marker = corner.marker_id;
        pf.worst_corner = corner.corner;
        pf.worst_offset_tf_px = d;
      }
    }
    if (pf.corners > 0) {
      pf.mean_x_tf_px /= pf.corners;
      pf.mean_y_tf_px /= pf.corners;
      pf.rms_tf_px = std::sqrt(pf_ss / pf.corners);
      pf.v_bias_rel = pf_v.empty() ? std::nan("") : Median(pf_v);
      b.frames.push_back(pf);
    }
  }
  if (b.corners > 0) {
    b.mean_x_tf_px /= b.corners;
    b.mean_y_tf_px /= b.corners;
    b.mean_inset_tf_px /= b.corners;
    b.rms_tf_px = std::sqrt(ss / b.corners);
  }
  b.corners_with_v = static_cast<int>(v_signed.size());
  b.v_bias_rel = v_signed.empty() ? std::nan("") : Median(v_signed);
  return b;
}

double SurfaceDepthMm(const std::vector<float>& depth, int w, int h, const Eigen::Vector2d& tf) {
  const auto at = [&](int x, int y) {
    return static_cast<double>(depth[static_cast<std::size_t>(std::clamp(y, 0, h - 1)) * w +
                                     std::clamp(x, 0, w - 1)]);
  };
  const double nearest = at(static_cast<int>(std::lround(tf.x())), static_cast<int>(std::lround(tf.y())));
  const int x0 = static_cast<int>(std::floor(tf.x())), y0 = static_cast<int>(std::floor(tf.y()));
  const double fx = tf.x() - x0, fy = tf.y() - y0;
  const double z00 = at(x0, y0), z10 = at(x0 + 1, y0), z01 = at(x0, y0 + 1), z11 = at(x0 + 1, y0 + 1);
  const double lo = std::min({z00, z10, z01, z11}), hi = std::max({z00, z10, z01, z11});
  if (!(hi <= 1.01 * lo)) return nearest;  // NaN or an edge between surfaces
  return (1 - fy) * ((1 - fx) * z00 + fx * z10) + fy * ((1 - fx) * z01 + fx * z11);
}

Eigen::Vector2d ProcessedGeometry::ProcessedOfTrue(const Eigen::Vector2d& x, double v) const {
  const double v_processed = ProcessedDepth(v);
  return v_processed * (x / v + c * (1 - lambda) * (1 - 1 / v) -
                        c0 * (1 - lambda0) * (1 - 1 / v_processed));
}

Eigen::Vector2d ProcessedGeometry::TrueOfProcessed(const Eigen::Vector2d& x_processed,
                                                   double v) const {
  const double v_processed = ProcessedDepth(v);
  return v * (x_processed / v_processed - c * (1 - lambda) * (1 - 1 / v) +
              c0 * (1 - lambda0) * (1 - 1 / v_processed));
}

TrueVirtualPoint TrueOfProcessedOnSurface(const ProcessedGeometry& geometry,
                                          const processing::CameraModel& true_model,
                                          const std::vector<float>& depth, int w, int h,
                                          const Eigen::Vector2d& x_processed) {
  const double f_l = true_model.intrinsics().main_focal_length_mm;
  TrueVirtualPoint p{x_processed, std::nan("")};
  for (int step = 0; step < 4; ++step) {
    const double z = SurfaceDepthMm(depth, w, h, TfOfVirtual(p.x));
    if (!(z > f_l)) return {p.x, std::nan("")};
    p.v = true_model.VirtualDepthOfDepth(z);
    p.x = geometry.TrueOfProcessed(x_processed, p.v);
  }
  return p;
}

Expected<GroundTruthComparison> CompareWithGroundTruth(const CalibrationResult& result,
                                                       const std::filesystem::path& seq,
                                                       const std::string& serial) {
  Expected<CameraCalibration> truth = ReadCameraCalibration(layout::CamerasYamlPath(seq), serial);
  if (!truth) return truth.error();
  Expected<std::vector<FramePose>> true_poses = ReadPosesCsv(layout::PosesCsvPath(seq, serial));
  if (!true_poses) return true_poses.error();
  std::map<std::int64_t, Pose> world_from_cam;
  for (const FramePose& p : *true_poses) world_from_cam[p.frame] = p.world_from_cam;

  GroundTruthComparison c;
  const processing::CameraIntrinsics& e = result.calibration.intrinsics;
  const processing::CameraIntrinsics& t = truth->intrinsics;
  c.f_l_rel = e.main_focal_length_mm / t.main_focal_length_mm - 1;
  c.b_l0_rel = e.mla_to_main_lens_mm / t.mla_to_main_lens_mm - 1;
  c.b_rel = e.mla_to_sensor_mm / t.mla_to_sensor_mm - 1;
  c.principal_point_px =
      (result.calibration.intrinsics.PrincipalPointPx() - truth->intrinsics.PrincipalPointPx()).norm();
  c.rmse_px = result.rmse_px;

  std::vector<double> d_mm, d_deg;
  for (const FramePose& p : result.poses) {
    const auto it = world_from_cam.find(p.frame);
    if (it == world_from_cam.end()) return Error{"ground truth has no pose of frame " +
                                                 std::to_string(p.frame)};
    const Pose delta = it->second.inverse() * p.world_from_cam;
    d_mm.push_back((p.world_from_cam.translation() - it->second.translation()).norm());
    d_deg.push_back(Eigen::AngleAxisd(delta.linear()).angle() * 180 / M_PI);
  }
  c.pose_median_mm = Median(d_mm);
  c.pose_median_deg = Median(d_deg);

  // Map points against the true surface.
  const processing::CameraModel true_model(t);
  std::map<int, const MapImage*> images;
  for (const MapImage& image : result.map.images) images[image.image_id] = &image;
  std::map<std::int64_t, std::vector<float>> depth_of_frame;
  int depth_w = 0, depth_h = 0;
  std::vector<double> errors, v_errors, v_signed;
  std::vector<double> by_track[3];  // track length 2, 3, >= 4
  const ProcessedGeometry geometry{true_model.lambda(), result.frames_lambda, t.PrincipalPointPx(),
                                   result.frames_principal_point_px};
  std::vector<Eigen::Vector3d> estimated, expected;
  for (const MapPoint& point : result.map.points) {
    const TrackElement& first = point.track.front();
    const MapImage& image = *images.at(first.image_id);
    auto it = depth_of_frame.find(image.frame);
    if (it == depth_of_frame.end()) {
      Expected<std::vector<float>> depth =
          synth::ReadFloatTiff(layout::DepthMmPath(seq, serial, image.frame), &depth_w, &depth_h);
      if (!depth) return depth.error();
      it = depth_of_frame.emplace(image.frame, std::move(*depth)).first;
    }
    const MapKeypoint& kp = image.keypoints[first.keypoint];
    // The keypoint is in the geometry of its processed frame (lambda0, c0):
    // the true virtual point x (depth v) whose micro images the processing
    // read as it (ProcessedGeometry), with the true depth at x.
    const TrueVirtualPoint on_surface = TrueOfProcessedOnSurface(
        geometry, true_model, it->second, depth_w, depth_h, VirtualOfTf(kp.tf_px.cast<double>()));
    const Eigen::Vector2d x_true = on_surface.x;
    const double v = on_surface.v;
    if (std::isnan(v)) continue;
    const double v_processed = geometry.ProcessedDepth(v);
    const Eigen::Vector3d p_in_c =
        true_model.BackProject(Eigen::Vector3d(x_true.x(), x_true.y(), v));
    const Eigen::Vector3d p_true = world_from_cam.at(image.frame) * p_in_c;
    errors.push_back((point.p_in_w0_mm - p_true).norm());
    by_track[std::min<std::size_t>(point.track.size(), 4) - 2].push_back(errors.back());
    estimated.push_back(point.p_in_w0_mm);
    expected.push_back(p_true);
    if (!std::isnan(kp.virtual_depth)) {
      v_errors.push_back(std::abs(kp.virtual_depth / v_processed - 1));
      v_signed.push_back(kp.virtual_depth / v_processed - 1);
    }
  }
  c.map_points = static_cast<int>(errors.size());
  c.map_median_mm = Median(errors);
  for (int n = 0; n < 3; ++n) c.map_points_by_track[n] = static_cast<int>(by_track[n].size());
  for (int n = 0; n < 3; ++n)
    c.map_median_by_track_mm[n] = by_track[n].empty() ? std::nan("") : Median(by_track[n]);
  c.keypoint_v_median_rel = Median(v_errors);
  c.keypoint_v_bias_rel = Median(v_signed);
  std::vector<int> kept;
  for (std::size_t n = 0; n < errors.size(); ++n)
    if (errors[n] <= 3 * c.map_median_mm) kept.push_back(static_cast<int>(n));
  if (kept.size() >= 3) {
    Eigen::Matrix3Xd a(3, kept.size()), b(3, kept.size());
    for (std::size_t n = 0; n < kept.size(); ++n) {
      a.col(n) = estimated[kept[n]];
      b.col(n) = expected[kept[n]];
    }
    const Eigen::Matrix4d sim = Eigen::umeyama(a, b, true);
    c.scale_error = std::abs(std::cbrt(sim.topLeftCorner<3, 3>().determinant()) - 1);
  } else {
    c.scale_error = std::nan("");
  }
  return c;
}

}  // namespace lifmcr::registration
