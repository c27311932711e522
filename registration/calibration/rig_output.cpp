#include "registration/calibration/rig_output.h"

#include "processing/camera_model.h"
#include "registration/calibration/calibration_problem.h"

#include <Eigen/Geometry>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>

namespace lifmcr::registration {
namespace {

namespace fs = std::filesystem;

std::string RigOutputFormat(const char* fmt, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

// "QW QX QY QZ TX TY TZ" of a pose a_from_b (COLMAP's order).
std::string ColmapPose(const Pose& a_from_b) {
  const Eigen::Quaterniond q(a_from_b.linear());
  const Eigen::Vector3d t = a_from_b.translation();
  return RigOutputFormat("%.17g %.17g %.17g %.17g %.17g %.17g %.17g", q.w(), q.x(), q.y(), q.z(),
                         t.x(), t.y(), t.z());
}

Status WriteText(const fs::path& path, const std::string& text) {
  std::ofstream file(path, std::ios::binary);
  file << text;
  if (!file) return Error{path.string() + ": could not write"};
  return Status::Ok();
}

// A pose as rig.yaml's `translation_mm`, `rotation_wxyz`, `covariance_rad_mm`
// lines, indented by `indent`.
std::string PoseYaml(const Pose& c0_from_cx, const Eigen::Matrix<double, 6, 6>& covariance,
                     const std::string& indent) {
  const Eigen::Quaterniond q(c0_from_cx.linear());
  const Eigen::Vector3d t = c0_from_cx.translation();
  std::string text =
      indent + RigOutputFormat("translation_mm: [%.6f, %.6f, %.6f]\n", t.x(), t.y(), t.z());
  text += indent + RigOutputFormat("rotation_wxyz: [%.12f, %.12f, %.12f, %.12f]\n", q.w(), q.x(),
                                   q.y(), q.z());
  text += indent + "covariance_rad_mm: [";
  for (int a = 0; a < 6; ++a)
    for (int b = 0; b < 6; ++b)
      text += RigOutputFormat("%s%.6e", a + b > 0 ? ", " : "", covariance(a, b));
  return text + "]\n";
}

std::string RigYaml(const RigCalibrationResult& result) {
  std::string text =
      "# Each camera's pose in the rig, c0_from_cx (maps camera X into camera 0), from\n"
      "# `lifmcr calibrate --rig`: " + result.BriefReport() + "\n"
      "# covariance_rad_mm: row-major 6 x 6 over [rotation vector (rad, left perturbation in\n"
      "# c0), translation (mm, in c0)], scaled by the residual variance (optimistic: the\n"
      "# micro-image residuals of a keypoint are taken as independent).\n"
      "# mount: rigid (one c0_from_cx per camera) or non_rigid (the cameras move\n"
      "# independently: c0_from_cx per frame, c0_from_cx_per_frame; c0_from_cx is then\n"
      "# their robust mean, a summary without covariance).\n";
  text += result.non_rigid ? "mount: non_rigid\n" : "mount: rigid\n";
  text += "cameras:\n";
  for (std::size_t c = 0; c < result.cameras.size(); ++c) {
    const RigCameraResult& rc = result.cameras[c];
    text += "  - serial: \"" + rc.serial + "\"\n";
    text += c == 0 ? "    role: reference\n" : "    role: registered\n";
    if (c == 0) continue;
    text += "    c0_from_cx:\n" + PoseYaml(rc.c0_from_cx, rc.c0_from_cx_covariance, "      ");
    text += RigOutputFormat("      frames_registered: %zu\n", rc.registered.size());
    if (!result.non_rigid) continue;
    text += "    c0_from_cx_per_frame:\n";
    for (std::size_t i = 0; i < rc.per_trigger.size(); ++i) {
      text += RigOutputFormat("      - frame: %lld\n", static_cast<long long>(rc.per_trigger[i].frame));
      text += PoseYaml(rc.per_trigger[i].world_from_cam, rc.per_trigger_covariance[i], "        ");
    }
  }
  return text;
}

}  // namespace

Status WriteRigCalibration(const fs::path& dir, const RigCalibrationResult& result,
                           const std::vector<CalibrationInput>& cameras) {
  if (cameras.size() != result.cameras.size())
    return Error{"rig output: the inputs are not the result's cameras"};
  std::error_code ec;
  fs::create_directories(dir / "colmap", ec);
  if (ec) return Error{(dir / "colmap").string() + ": " + ec.message()};
  if (Status s = WriteText(dir / "rig.yaml", RigYaml(result)); !s) return s;

  const int n_cameras = static_cast<int>(cameras.size());
  const int n_triggers = static_cast<int>(result.trajectory.size());
  // Image ids: camera c, trigger t -> c * n_triggers + t + 1, where camera c
  // has that frame.
  std::map<std::int64_t, int> trigger_of_frame;
  for (int t = 0; t < n_triggers; ++t) trigger_of_frame[result.trajectory[t].frame] = t;
  // c0_from_cx of camera c at trigger t: its one pose (rigid), else the
  // triggers it was placed at.
  std::vector<std::map<int, Pose>> c0_from_cx(n_cameras);
  for (int c = 0; c < n_cameras; ++c) {
    const RigCameraResult& rc = result.cameras[c];
    for (int t = 0; t < n_triggers; ++t)
      if (!result.non_rigid || c == 0) c0_from_cx[c][t] = rc.c0_from_cx;
    if (result.non_rigid)
      for (const FramePose& p : rc.per_trigger)
        if (const auto t = trigger_of_frame.find(p.frame); t != trigger_of_frame.end())
          c0_from_cx[c][t->second] = p.world_from_cam;
  }
  std::vector<std::map<int, int>> frame_of_trigger(n_cameras);  // trigger -> frame index
  for (int c = 0; c < n_cameras; ++c)
    for (std::size_t f = 0; f < cameras[c].frames.size(); ++f)
      if (const auto t = trigger_of_frame.find(cameras[c].frames[f].frame);
          t != trigger_of_frame.end() && c0_from_cx[c].count(t->second))
        frame_of_trigger[c][t->second] = static_cast<int>(f);
  auto image_id = [&](int c, int t) { return c * n_triggers + t + 1; };
  // Point ids of the keypoints, per image.
  std::map<int, std::map<int, std::int64_t>> point_of_keypoint;  // image id -> keypoint -> point
  std::string points = RigOutputFormat(
      "# 3D point list with one line of data per point:\n"
      "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      "# Number of points: %zu\n",
      result.map.points.size());
  for (std::size_t j = 0; j < result.map.points.size(); ++j) {
    const MapPoint& p = result.map.points[j];
    points += RigOutputFormat("%lld %.6f %.6f %.6f %d %d %d %.6f", static_cast<long long>(p.id),
                              p.p_in_w0_mm.x(), p.p_in_w0_mm.y(), p.p_in_w0_mm.z(), p.rgb[0],
                              p.rgb[1], p.rgb[2], p.error_px);
    for (const RigCalibrationResult::Observer& o : result.observers[j]) {
      const auto t = trigger_of_frame.find(o.frame);
      if (t == trigger_of_frame.end()) continue;
      const int id = image_id(o.camera, t->second);
      point_of_keypoint[id][o.keypoint] = p.id;
      points += RigOutputFormat(" %d %d", id, o.keypoint);
    }
    points += "\n";
  }

  std::string cameras_txt = RigOutputFormat(
      "# Camera list with one line of data per camera:\n"
      "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: %d\n",
      n_cameras);
  // Rigid: one rig, camera 0 its reference sensor. Non-rigid: as COLMAP
  // models cameras without a rig, one rig of one sensor per camera (and
  // below, one frame per image).
  std::string rigs = RigOutputFormat(
      "# Rig calib list with one line of data per calib:\n"
      "#   RIG_ID, NUM_SENSORS, REF_SENSOR_TYPE, REF_SENSOR_ID, SENSORS[] as (SENSOR_TYPE, "
      "SENSOR_ID, HAS_POSE, [QW, QX, QY, QZ, TX, TY, TZ])\n# Number of rigs: %d\n",
      result.non_rigid ? n_cameras : 1);
  if (result.non_rigid)
    for (int c = 0; c < n_cameras; ++c) rigs += RigOutputFormat("%d 1 CAMERA %d\n", c + 1, c + 1);
  else
    rigs += RigOutputFormat("1 %d CAMERA 1", n_cameras);
  std::string images =
      "# Image list with two lines of data per image:\n"
      "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
      "#   POINTS2D[] as (X, Y, POINT3D_ID)\n";
  for (int c = 0; c < n_cameras; ++c) {
    const RigCameraResult& rc = result.cameras[c];
    const IntrinsicsVector k = ToVector(rc.calibration.intrinsics);
    const double s = rc.calibration.intrinsics.pixel_size_mm;
    const double focal = (k[1] + 2 * k[2]) / (2 * s);
    cameras_txt += RigOutputFormat("%d PINHOLE %d %d %.9f %.9f %.9f %.9f\n", c + 1,
                                   rc.calibration.intrinsics.width_px / 2,
                                   rc.calibration.intrinsics.height_px / 2, focal, focal,
                                   (k[3] - 0.5) / 2, (k[4] - 0.5) / 2);
    if (c > 0 && !result.non_rigid) rigs += RigOutputFormat(" CAMERA %d 1 ", c + 1) + ColmapPose(rc.c0_from_cx.inverse());
    const processing::CameraModel model(rc.calibration.intrinsics);
    for (const auto& [t, f] : frame_of_trigger[c]) {
      const CalibrationFrame& frame = cameras[c].frames[f];
      const int id = image_id(c, t);
      const Pose cx_from_w0 =
          c0_from_cx[c].at(t).inverse() * result.trajectory[t].world_from_cam.inverse();
      images += std::to_string(id) + " " + ColmapPose(cx_from_w0) + " " + std::to_string(c + 1) +
                " " + (frame.name.empty() ? rc.serial + "_" + std::to_string(frame.frame) : frame.name) +
                "\n";
      const auto& points_of_image = point_of_keypoint[id];
      for (int kp = 0; kp < frame.features.size(); ++kp) {
        Eigen::Vector3d x_v = internal::VirtualPoint(frame, kp);
        if (std::isnan(x_v.z())) x_v.z() = 2.0;
        const Eigen::Vector2d px = internal::TfPinholePx(k, model, x_v);
        const auto point = points_of_image.find(kp);
        images += RigOutputFormat("%s%.4f %.4f %lld", kp > 0 ? " " : "", px.x(), px.y(),
                                  point == points_of_image.end()
                                      ? -1LL
                                      : static_cast<long long>(point->second));
      }
      images += "\n";
    }
  }
  if (!result.non_rigid) rigs += "\n";
  int n_images = 0;
  for (int c = 0; c < n_cameras; ++c) n_images += static_cast<int>(frame_of_trigger[c].size());
  std::string frames = RigOutputFormat(
      "# Frame list with one line of data per frame:\n"
      "#   FRAME_ID, RIG_ID, RIG_FROM_WORLD[QW, QX, QY, QZ, TX, TY, TZ], NUM_DATA_IDS, DATA_IDS[] "
      "as (SENSOR_TYPE, SENSOR_ID, DATA_ID)\n# Number of frames: %d\n",
      result.non_rigid ? n_images : n_triggers);
  if (result.non_rigid)  // one frame per image, its camera's rig, rig_from_world = cx_from_w0
    for (int c = 0; c < n_cameras; ++c)
      for (const auto& [t, f] : frame_of_trigger[c])
        frames += RigOutputFormat("%d %d ", image_id(c, t), c + 1) +
                  ColmapPose(c0_from_cx[c].at(t).inverse() *
                             result.trajectory[t].world_from_cam.inverse()) +
                  RigOutputFormat(" 1 CAMERA %d %d\n", c + 1, image_id(c, t));
  for (int t = 0; t < n_triggers && !result.non_rigid; ++t) {
    int n = 0;
    std::string data;
    for (int c = 0; c < n_cameras; ++c)
      if (frame_of_trigger[c].count(t)) {
        data += RigOutputFormat(" CAMERA %d %d", c + 1, image_id(c, t));
        ++n;
      }
    frames += RigOutputFormat("%d 1 ", t + 1) +
              ColmapPose(result.trajectory[t].world_from_cam.inverse()) +
              RigOutputFormat(" %d", n) + data + "\n";
  }
  const fs::path colmap = dir / "colmap";
  if (Status st = WriteText(colmap / "cameras.txt", cameras_txt); !st) return st;
  if (Status st = WriteText(colmap / "rigs.txt", rigs); !st) return st;
  if (Status st = WriteText(colmap / "frames.txt", frames); !st) return st;
  if (Status st = WriteText(colmap / "images.txt", images); !st) return st;
  return WriteText(colmap / "points3D.txt", points);
}

}  // namespace lifmcr::registration
