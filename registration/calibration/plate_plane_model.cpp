#include "registration/calibration/plate_plane_model.h"

#include "registration/calibration/calibration_gates.h"

#include <Eigen/Dense>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>

namespace lifmcr::registration {

Status PlateModelOptions::Check() const {
  if (!(passes >= 0 && passes <= 5)) return Error{"plate model: passes: expected in [0, 5]"};
  return edges.Check();
}

Expected<PlatePlane> PredictPlatePlane(const IntrinsicsVector& k, double pixel_size_mm,
                                       const Pose& cam_from_w,
                                       const std::vector<Eigen::Vector3d>& p_in_w_mm,
                                       double lambda0, const Eigen::Vector2d& c0) {
  if (p_in_w_mm.size() < 3) return Error{"plate plane: fewer than 3 plate points"};
  const double lambda = k[1] / (k[1] + k[2]);
  const ProcessedGeometry geometry{lambda, lambda0, Eigen::Vector2d(k[3], k[4]), c0};
  Eigen::MatrixXd a(p_in_w_mm.size(), 3);
  Eigen::VectorXd b(p_in_w_mm.size());
  for (std::size_t i = 0; i < p_in_w_mm.size(); ++i) {
    const Eigen::Vector3d p_in_cam = cam_from_w * p_in_w_mm[i];
    std::array<double, 3> virtual_px{};
    if (!ProjectToVirtual(k.data(), pixel_size_mm, p_in_cam.data(), virtual_px.data()) ||
        !(virtual_px[2] > 1))
      return Error{"plate plane: a plate point is not imaged (within the main lens' focal length)"};
    const double v = virtual_px[2];
    const Eigen::Vector2d tf =
        TfOfVirtual(geometry.ProcessedOfTrue(Eigen::Vector2d(virtual_px[0], virtual_px[1]), v));
    a.row(static_cast<Eigen::Index>(i)) << 1.0, tf.x(), tf.y();
    b[static_cast<Eigen::Index>(i)] = geometry.ProcessedDepth(v);
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
  if (qr.rank() < 3) return Error{"plate plane: the plate points do not span a plane"};
  const Eigen::Vector3d x = qr.solve(b);
  PlatePlane plane;
  plane.a = x[0];
  plane.b = x[1];
  plane.c = x[2];
  plane.samples = static_cast<int>(p_in_w_mm.size());
  const Eigen::VectorXd r = (a * x - b).cwiseQuotient(b);
  plane.rms_rel = std::sqrt(r.squaredNorm() / static_cast<double>(r.size()));
  return plane;
}

std::string PlateModelPass::Summary() const {
  char line[256];
  std::snprintf(line, sizeof(line),
                "plate corners placed again at the predicted plate plane: %d frames, %d corners "
                "(%d lost), mean move %.3f TF px (y %+.3f), corner depth %+.3f %%",
                frames, corners, corners_lost, mean_shift_tf_px, mean_dy_tf_px,
                100 * mean_depth_change_rel);
  return line;
}

Expected<PlateModelPass> PlaceCornersAtModelPlane(const CalibrationResult& result,
                                                  const PlateModelOptions& options,
                                                  CalibrationFrameLoader* loader,
                                                  std::vector<CalibrationFrame>* frames) {
  if (Status s = options.Check(); !s) return s.error();
  std::map<std::int64_t, Pose> cam_from_w;
  for (const FramePose& p : result.poses) cam_from_w[p.frame] = p.world_from_cam.inverse();
  const IntrinsicsVector k = ToVector(result.calibration.intrinsics);
  const double pixel_size_mm = result.calibration.intrinsics.pixel_size_mm;
  PlateModelPass pass;
  double depth_change_sum = 0;
  int depth_changes = 0;
  for (CalibrationFrame& frame : *frames) {
    const auto pose = cam_from_w.find(frame.frame);
    if (pose == cam_from_w.end() || frame.corners.empty()) continue;
    // The frame's markers with all four corners, and what was measured at them.
    std::map<int, PlateMarker> markers;
    std::map<int, int> seen;
    std::map<std::pair<int, int>, float> measured_depth;
    std::vector<Eigen::Vector3d> p_in_w;
    for (std::size_t n = 0; n < frame.corners.size(); ++n) {
      const PlateCorner& c = frame.corners[n];
      if (c.corner < 0 || c.corner > 3) continue;
      markers[c.marker_id].marker_id = c.marker_id;
      markers[c.marker_id].quad[c.corner] = c.tf_px;
      ++seen[c.marker_id];
      measured_depth[{c.marker_id, c.corner}] =
          n < frame.corner_virtual_depth.size() ? frame.corner_virtual_depth[n] : std::nanf("");
      p_in_w.push_back(c.p_in_w_mm);
    }
    std::vector<PlateMarker> complete;
    for (const auto& [id, m] : markers)
      if (seen[id] == 4) complete.push_back(m);
    if (complete.empty()) continue;
    Expected<PlatePlane> plane = PredictPlatePlane(k, pixel_size_mm, pose->second, p_in_w,
                                                   result.frames_lambda,
                                                   result.frames_principal_point_px);
    if (!plane) return Error{"frame " + std::to_string(frame.frame) + ": " + plane.error().message};
    Expected<std::vector<PlateCorner>> placed =
        loader->PlaceCornersAtPlane(frame.frame, complete, *plane, options.edges);
    if (!placed) return Error{"frame " + std::to_string(frame.frame) + ": " + placed.error().message};
    std::map<std::pair<int, int>, Eigen::Vector2d> before;
    for (const PlateCorner& c : frame.corners) before[{c.marker_id, c.corner}] = c.tf_px;
    std::vector<float> depths;
    for (const PlateCorner& c : *placed) {
      const float measured = measured_depth[{c.marker_id, c.corner}];
      const float v = options.corner_depth_from_plane
                          ? static_cast<float>(plane->At(c.tf_px.x(), c.tf_px.y()))
                          : measured;
      if (std::isfinite(measured) && std::isfinite(v)) {
        depth_change_sum += v / measured - 1.0;
        ++depth_changes;
      }
      depths.push_back(v);
      const Eigen::Vector2d move = c.tf_px - before[{c.marker_id, c.corner}];
      pass.mean_shift_tf_px += move.norm();
      pass.mean_dy_tf_px += move.y();
    }
    pass.corners += static_cast<int>(placed->size());
    pass.corners_lost += static_cast<int>(frame.corners.size() - placed->size());
    ++pass.frames;
    frame.corners = std::move(*placed);
    frame.corner_virtual_depth = std::move(depths);
  }
  if (pass.corners > 0) {
    pass.mean_shift_tf_px /= pass.corners;
    pass.mean_dy_tf_px /= pass.corners;
  }
  if (depth_changes > 0) pass.mean_depth_change_rel = depth_change_sum / depth_changes;
  return pass;
}

}  // namespace lifmcr::registration
