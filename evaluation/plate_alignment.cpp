#include "evaluation/plate_alignment.h"

#include "evaluation/trajectory_metrics.h"
#include "replay/synth/marker_plate.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace lifmcr {

PlateTemplate DefaultPlateTemplate() {
  const synth::MarkerPlateLayout layout;
  PlateTemplate plate;
  for (int k = 0; k < 4; ++k) {
    plate.aruco_centers_mm[k] = Eigen::Vector3d(layout.aruco_centers_mm[k].x(),
                                                layout.aruco_centers_mm[k].y(), 0.0);
    plate.vicon_markers_mm[k] = layout.ViconMarkers()[k];
  }
  return plate;
}

std::string PlateAlignment::BriefReport() const {
  char check[64];
  std::snprintf(check, sizeof(check), "ArUco check (P1) %.3f mm", aruco_check_mm);
  char line[400];
  std::snprintf(line, sizeof(line),
                "plate alignment: Vicon markers fit the template to %.3f mm RMS, %s, plate %s "
                "(RMS deviation %.3f mm / %.4f deg, largest %.3f mm / %.4f deg over %zu samples)",
                marker_fit_rms_mm,
                map_is_plate_frame ? "map frame taken as the plate frame (no ArUco detections)"
                                   : check,
                plate_moved() ? "MOVED" : "still", plate_motion_rms_mm, plate_motion_rms_deg,
                plate_motion_max_mm, plate_motion_max_deg, plate_samples);
  return line;
}

Expected<ArucoPlateFrame> ArucoFrameOf(const std::array<Eigen::Vector3d, 4>& p,
                                       const PlateTemplate& plate) {
  auto frame = [](const std::array<Eigen::Vector3d, 4>& c) -> std::optional<Pose> {
    const Eigen::Vector3d x_raw = c[3] - c[2], y_raw = c[0] - c[2];
    if (x_raw.norm() < 1e-6 || y_raw.norm() < 1e-6) return std::nullopt;
    const Eigen::Vector3d x = x_raw.normalized();
    const Eigen::Vector3d z_raw = x.cross(y_raw.normalized());
    if (z_raw.norm() < 1e-3) return std::nullopt;
    const Eigen::Vector3d z = z_raw.normalized();
    Pose pose = Pose::Identity();
    pose.linear().col(0) = x;
    pose.linear().col(1) = z.cross(x);
    pose.linear().col(2) = z;
    pose.translation() = c[2];
    return pose;
  };
  const std::optional<Pose> seen = frame(p);
  const std::optional<Pose> model = frame(plate.aruco_centers_mm);
  if (!seen || !model)
    return Error{"plate alignment: ArUco centres 2, 3 and 0 are (nearly) collinear or coincide"};
  ArucoPlateFrame result;
  result.frame_from_aruco = *seen;
  const Eigen::Vector3d p1_seen = seen->inverse() * p[1];
  const Eigen::Vector3d p1_model = model->inverse() * plate.aruco_centers_mm[1];
  result.check_mm = (p1_seen - p1_model).norm();
  return result;
}

Expected<PlateAlignment> AlignPlate(std::span<const ViconPoseSample> plate_samples,
                                    std::span<const Eigen::Vector3d> plate_markers_mm,
                                    const PlateTemplate& plate,
                                    const std::optional<std::array<Eigen::Vector3d, 4>>& aruco) {
  PlateAlignment result;
  if (plate_markers_mm.size() != 4)
    return Error{"plate alignment: the plate's VSK object has " +
                 std::to_string(plate_markers_mm.size()) + " markers, 4 expected"};
  // world_from_plate: the VSK markers in file order against the template's
  // order; another ordering only when it fits clearly better (a plate made
  // symmetric, such as a rectangle, fits several orderings equally: then the
  // file order decides).
  Eigen::Matrix<double, 3, 4> model, target;
  for (int k = 0; k < 4; ++k) target.col(k) = plate.vicon_markers_mm[k];
  auto fit_order = [&](const std::array<int, 4>& order, Pose* fit) {
    for (int k = 0; k < 4; ++k) model.col(k) = plate_markers_mm[order[k]];
    fit->matrix() = Eigen::umeyama(model, target, false);
    const Eigen::Matrix<double, 3, 4> moved =
        (fit->linear() * model).colwise() + fit->translation();
    return std::sqrt((moved - target).colwise().squaredNorm().mean());
  };
  std::array<int, 4> order{0, 1, 2, 3};
  Pose world_from_plate = Pose::Identity();
  double best = fit_order(order, &world_from_plate);
  constexpr double kClearlyBetterMm = 0.5;
  while (std::next_permutation(order.begin(), order.end())) {
    Pose fit = Pose::Identity();
    const double rms = fit_order(order, &fit);
    if (rms + kClearlyBetterMm < best) {
      best = rms;
      world_from_plate = fit;
    }
  }
  result.marker_fit_rms_mm = best;

  // The plate at rest: mean pose and its spread.
  Eigen::Matrix3d rotation_sum = Eigen::Matrix3d::Zero();
  Eigen::Vector3d translation_sum = Eigen::Vector3d::Zero();
  for (const ViconPoseSample& s : plate_samples) {
    if (!s.vicon_from_marker) continue;
    rotation_sum += s.vicon_from_marker->linear();
    translation_sum += s.vicon_from_marker->translation();
    ++result.plate_samples;
  }
  if (result.plate_samples == 0)
    return Error{"plate alignment: the plate object is never tracked in the Vicon export"};
  Pose vicon_from_plate = Pose::Identity();
  vicon_from_plate.linear() = NearestRotation(rotation_sum);
  vicon_from_plate.translation() = translation_sum / static_cast<double>(result.plate_samples);
  // Motion of the plate's extent (its markers), not only of its centroid.
  double sum_sq_mm = 0, sum_sq_deg = 0;
  for (const ViconPoseSample& s : plate_samples) {
    if (!s.vicon_from_marker) continue;
    const Pose d = vicon_from_plate.inverse() * *s.vicon_from_marker;
    for (const Eigen::Vector3d& m : plate_markers_mm) {
      const double moved = (d * m - m).norm();
      sum_sq_mm += moved * moved;
      result.plate_motion_max_mm = std::max(result.plate_motion_max_mm, moved);
    }
    const double angle = RotationAngleDeg(d.linear());
    sum_sq_deg += angle * angle;
    result.plate_motion_max_deg = std::max(result.plate_motion_max_deg, angle);
  }
  const double n = static_cast<double>(result.plate_samples);
  result.plate_motion_rms_mm =
      std::sqrt(sum_sq_mm / (n * static_cast<double>(plate_markers_mm.size())));
  result.plate_motion_rms_deg = std::sqrt(sum_sq_deg / n);
  result.vicon_from_world = vicon_from_plate * world_from_plate.inverse();

  if (aruco) {
    Expected<ArucoPlateFrame> seen = ArucoFrameOf(*aruco, plate);
    if (!seen) return seen.error();
    Expected<ArucoPlateFrame> model = ArucoFrameOf(plate.aruco_centers_mm, plate);
    if (!model) return model.error();
    result.world_from_map = model->frame_from_aruco * seen->frame_from_aruco.inverse();
    result.aruco_check_mm = seen->check_mm;
    result.map_is_plate_frame = false;
  }
  return result;
}

}  // namespace lifmcr
