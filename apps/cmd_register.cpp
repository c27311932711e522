// `lifmcr register SEQ_DIR --reference MAP_DIR --method pnp|ransac|both
// [--camera SERIAL...] --out DIR`: every camera X of a sequence registered to
// the reference camera 0 (the map's camera), per frame:
//   w0_from_c0 and w0_from_cx by the chosen method (registration/map/frame_registration.h),
//   c0_from_cx = c0_from_w0 * w0_from_cx      (registration/estimators/extrinsics.h).
// Matching against the map uses the map's kd-forest, built once
// (MapMatching(), registration/features/features.h); --matching exact is
// brute force, the reference.
// Writes DIR/registration.csv (the columns lifmcr evaluate reads, one row per
// frame, camera and method; status `ok` or the reason) and TUM trajectories
// DIR/trajectory_<serial>_<method>.tum of w0_from_cam (mm, frame number as
// the time stamp). Progress on stderr, a summary line per camera. When the
// sequence has GroundTruth/poses_<serial>.csv (lifmcr synth), the per-frame
// errors of c0_from_cx against it are printed, and with --method both the
// differences between the methods, as the paper's supplementary does, with
// each PnP row's squared Mahalanobis distance under its own covariance and
// what PnP's inliers show at the true pose (ResidualsAtTruth).
//
// --reference-from-ground-truth builds the map from the sequence's ground
// truth (registration/map/ground_truth_map.h) instead of reading one;
// --observations ground-truth takes keypoints and depth from the ground
// truth instead of processing the raw frames.

#include "apps/commands.h"
#include "config/text_escape.h"
#include "evaluation/evaluation_inputs.h"
#include "registration/estimators/extrinsics.h"
#include "registration/estimators/pose_checks.h"
#include "registration/estimators/tf_projection.h"
#include "registration/features/frame_observations.h"
#include "registration/map/frame_registration.h"
#include "registration/map/ground_truth_map.h"
#include "registration/map/map_extension.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/map/poses_csv.h"
#include "registration/map/reference_map.h"
#include "evaluation/trajectory_metrics.h"
#include "replay/layout.h"
#include "replay/sequence.h"

#include <CLI/CLI.hpp>

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;
namespace reg = registration;

struct RegisterOptions {
  std::string sequence;
  std::string reference;
  std::string method = "pnp";
  std::vector<std::string> cameras;
  std::string out;
  std::vector<std::string> intrinsics;  // each camera from the first file that has it
  std::string observations = "raw";
  bool reference_from_ground_truth = false;
  int map_frames = 3;
  int frames = 0;
  int max_features = 4000;
  std::string matching = "approximate";
  bool chain = false;
  int guided_rounds = 2;
};

int Fail(const std::string& message, int code = 1) {
  std::cerr << "lifmcr register: " << EscapeText(message) << "\n";
  return code;
}

// Per camera and method: w0_from_cam per frame (registered frames only).
using Trajectory = std::map<std::int64_t, reg::PoseWithCovariance>;

void WriteTum(const fs::path& path, const Trajectory& trajectory) {
  std::ofstream out(path);
  out << "# TUM trajectory of w0_from_cam: frame tx_mm ty_mm tz_mm qx qy qz qw\n";
  char line[256];
  for (const auto& [frame, pose] : trajectory) {
    const Eigen::Quaterniond q(pose.pose.linear());
    const Eigen::Vector3d t = pose.pose.translation();
    std::snprintf(line, sizeof line, "%lld %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n",
                  static_cast<long long>(frame), t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    out << line;
  }
}

// A camera's registered w0_from_cam against the truth, averaged over its
// frames in its own frame (x right, y down, z forward): the position error
// true_from_estimated's translation, the rotation error its rotation vector.
// c0_from_cx's error is camera X's less camera 0's, so these say which
// camera carries it (with a calibrated camera 0 its rotation error is the
// one its principal point's error trades against, docs/calibration.md).
void PrintOwnFrameError(const std::string& label, const Trajectory& trajectory,
                        const std::map<std::int64_t, Pose>& truth) {
  Eigen::Vector3d t_mm = Eigen::Vector3d::Zero(), r_deg = Eigen::Vector3d::Zero();
  int n = 0;
  for (const auto& [frame, estimated] : trajectory) {
    const auto it = truth.find(frame);
    if (it == truth.end()) continue;
    const Pose true_from_estimated = it->second.inverse() * estimated.pose;
    const Eigen::AngleAxisd r(true_from_estimated.linear());
    t_mm += true_from_estimated.translation();
    r_deg += r.angle() * 180.0 / M_PI * r.axis();
    ++n;
  }
  if (n == 0) return;
  t_mm /= n;
  r_deg /= n;
  std::printf("  %-34s mean in its own frame: position x %+.3f y %+.3f z %+.3f mm, rotation x "
              "%+.4f y %+.4f z %+.4f deg (n=%d)\n",
              label.c_str(), t_mm.x(), t_mm.y(), t_mm.z(), r_deg.x(), r_deg.y(), r_deg.z(), n);
}

// The 95 % quantile of chi-square with 6 degrees of freedom.
constexpr double kChiSquare6At95 = 12.5916;

struct Errors {
  std::vector<double> t_mm, r_deg;
};

// PnP's inliers at the true pose (a sequence with a ground truth): their
// residuals against the noise the covariance assumes (registration/estimators/pnp.h,
// "Covariance"), per component, and the part common to a frame's keypoints.
struct ResidualsAtTruth {
  double x2 = 0, y2 = 0;  // sum of r^2 / s^2 per component (s^2: the pose's own)
  std::size_t n = 0;
  double z2 = 0;  // sum of the depth z-scores squared (pose_checks.h)
  std::size_t n_depth = 0;
  double shift_x2 = 0, shift_y2 = 0;  // per frame: mean residual^2 less s^2 / n
  int frames = 0;
};

void AddResidualsAtTruth(const fs::path& seq, const std::string& serial, std::int64_t frame,
                         const processing::CameraModel& camera, const reg::MapIndex& index,
                         const reg::FrameObservations& obs, const reg::FrameRegistration& r,
                         double sigma_v_relative,
                         std::map<std::string, std::map<std::int64_t, Pose>>* truth_of,
                         ResidualsAtTruth* out) {
  if (!truth_of->count(serial)) {
    auto& poses = (*truth_of)[serial];
    if (Expected<std::vector<reg::FramePose>> gt = reg::ReadPosesCsv(layout::PosesCsvPath(seq, serial)))
      for (const reg::FramePose& p : *gt) poses[p.frame] = p.world_from_cam;
  }
  const auto truth = (*truth_of)[serial].find(frame);
  const std::size_t n = r.inlier_points.size();
  if (truth == (*truth_of)[serial].end() || n < 4 || r.inlier_queries.size() != n) return;
  const Pose cam_from_w0 = truth->second.inverse();
  // s^2 of the estimate: sum |r_i|^2 / (2 n - 6) = rmse^2 n / (2 n - 6).
  const double s2 = r.rmse_px * r.rmse_px * static_cast<double>(n) / static_cast<double>(2 * n - 6);
  if (!(s2 > 0)) return;
  const reg::TfProjection projection = reg::TfProjection::Of(camera);
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector3d> points;
  std::vector<double> v;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d x = index.points_in_w0[r.inlier_points[k]];
    Eigen::Vector2d tf;
    Eigen::Matrix<double, 2, 3> jacobian;
    if (!projection.WithJacobian(cam_from_w0 * x, &tf, &jacobian)) continue;
    const Eigen::Vector2d residual = tf - r.inlier_tf_px[k];
    out->x2 += residual.x() * residual.x() / s2;
    out->y2 += residual.y() * residual.y() / s2;
    ++out->n;
    sum += residual;
    points.push_back(x);
    v.push_back(obs.virtual_depth[r.inlier_queries[k]]);
  }
  std::vector<double> z, depth_mm;
  reg::InlierDepths(camera, cam_from_w0, points, v, sigma_v_relative, &z, &depth_mm);
  for (const double zi : z)
    if (std::isfinite(zi)) {
      out->z2 += zi * zi;
      ++out->n_depth;
    }
  const Eigen::Vector2d mean = sum / static_cast<double>(n);
  out->shift_x2 += mean.x() * mean.x() - s2 / static_cast<double>(n);
  out->shift_y2 += mean.y() * mean.y() - s2 / static_cast<double>(n);
  ++out->frames;
}

void PrintStats(const std::string& label, const Errors& e) {
  const ErrorStats t = ErrorStats::Of(e.t_mm), r = ErrorStats::Of(e.r_deg);
  std::printf("  %-34s translation %s | rotation %s\n", label.c_str(), t.BriefReport("mm").c_str(),
              r.BriefReport("deg").c_str());
}

int RunRegister(const RegisterOptions& o) {
  const fs::path seq = o.sequence;
  std::vector<reg::RegistrationMethod> methods;
  if (o.method == "both") {
    methods = {reg::RegistrationMethod::kPnp, reg::RegistrationMethod::kRansac3d};
  } else if (const auto m = reg::ParseRegistrationMethod(o.method)) {
    methods = {*m};
  } else {
    return Fail("--method " + o.method + ": expected pnp, ransac or both", 2);
  }
  reg::ObservationSource source;
  if (o.observations == "raw") source = reg::ObservationSource::kRaw;
  else if (o.observations == "ground-truth") source = reg::ObservationSource::kGroundTruth;
  else return Fail("--observations " + o.observations + ": expected raw or ground-truth", 2);
  reg::FrameRegistrationOptions options;
  if (o.matching == "exact") options.match = reg::ExactMatching();
  else if (o.matching != "approximate")
    return Fail("--matching " + o.matching + ": expected approximate or exact", 2);
  if (o.reference.empty() == !o.reference_from_ground_truth)
    return Fail("give either --reference MAP_DIR or --reference-from-ground-truth", 2);
  std::vector<fs::path> intrinsics_paths(o.intrinsics.begin(), o.intrinsics.end());
  if (intrinsics_paths.empty()) intrinsics_paths.push_back(layout::CamerasYamlPath(seq));

  Expected<SequenceLayout> layout_or = DiscoverSequence(seq);
  if (!layout_or) return Fail(layout_or.error().message);
  std::vector<std::string> serials = o.cameras;
  if (serials.empty())
    for (const CameraFolder& c : layout_or->cameras) serials.push_back(c.serial);

  std::map<std::string, processing::CameraModel> cameras;
  auto camera_of = [&](const std::string& serial) -> Expected<processing::CameraModel> {
    if (const auto it = cameras.find(serial); it != cameras.end()) return it->second;
    // The first file that has the camera; the last file's error otherwise.
    Expected<reg::CameraCalibration> k = Error{""};
    for (const fs::path& path : intrinsics_paths)
      if ((k = reg::ReadCameraCalibration(path, serial))) break;
    if (!k) return k.error();
    return cameras.emplace(serial, processing::CameraModel(k->intrinsics)).first->second;
  };

  // The reference map and camera 0.
  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": " + ec.message());
  reg::FeatureOptions features;
  features.max_features = o.max_features;
  reg::ReferenceMap map;
  if (o.reference_from_ground_truth) {
    // Camera 0: the sequence's first camera (the ground truth lists it first).
    Expected<SynthGroundTruthInfo> info = ReadCamerasYaml(layout::CamerasYamlPath(seq));
    if (!info) return Fail(info.error().message);
    if (info->serials.empty()) return Fail(layout::CamerasYamlPath(seq).string() + ": no cameras");
    const std::string reference = info->serials.front();
    Expected<processing::CameraModel> camera = camera_of(reference);
    if (!camera) return Fail(camera.error().message);
    std::vector<std::int64_t> frames;
    for (int f = 0; f < o.map_frames; ++f) frames.push_back(f);
    reg::GroundTruthMapOptions map_options;
    map_options.features = features;
    // Each frame against the map so far, by the same matcher (kd-forests
    // rebuilt per frame: the map grows; brute force grows with it).
    map_options.match = options.match;
    Expected<reg::ReferenceMap> built =
        reg::BuildGroundTruthMap(seq, reference, frames, *camera, map_options);
    if (!built) return Fail(built.error().message);
    map = std::move(*built);
    if (Status s = reg::WriteReferenceMap(fs::path(o.out) / "reference", map); !s)
      return Fail(s.error().message);
    std::cerr << "reference map from ground truth: camera " << reference << ", "
              << map.points.size() << " points from frames 0-" << o.map_frames - 1 << " -> "
              << (fs::path(o.out) / "reference").string() << "\n";
  } else {
    Expected<reg::ReferenceMap> read = reg::ReadReferenceMap(o.reference);
    if (!read) return Fail(read.error().message);
    map = std::move(*read);
  }
  const std::string reference_serial = map.camera.serial;
  reg::MapIndex index = reg::MapIndex::Of(map);
  if (index.size() < 10)
    return Fail("the reference map has " + std::to_string(index.size()) +
                " points with descriptors; at least 10 are needed");
  // Camera 0 is registered too: its w0_from_c0 per frame composes every c0_from_cx.
  if (std::find(serials.begin(), serials.end(), reference_serial) == serials.end())
    serials.insert(serials.begin(), reference_serial);
  else
    std::stable_partition(serials.begin(), serials.end(),
                          [&](const std::string& s) { return s == reference_serial; });

  // The map's kd-forest, once per map, before its first frame (features.h).
  const auto prepare_index = [&] {
    if (options.match.kd_tree_checks <= 0) return;
    const auto start = std::chrono::steady_clock::now();
    index.descriptors->Prepare(options.match.kd_trees);
    std::fprintf(stderr, "map index: kd-forest of %d trees over %d points, %.0f ms\n",
                 options.match.kd_trees, index.size(),
                 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - start)
                           .count());
  };
  prepare_index();
  // --chain: the keypoints of every registered frame that are not in the map
  // yet join it, where seen twice, before the next camera
  // (registration/map/map_extension.h).
  reg::MapExtensionOptions extension_options;
  extension_options.map_match = options.match;
  extension_options.sigma_v_relative = options.sigma_v_relative;
  extension_options.sigma_tf_px = options.sigma_tf_px;
  if (Status s = extension_options.Check(); !s) return Fail(s.error().message, 2);
  reg::SharedMapBuilder shared_map(extension_options);
  int camera_order = 0;
  // An `ok` row promises c0_from_cx within 5 mm / 0.25 deg of the truth
  // (registration/estimators/pose_checks.h, ForErrorBound).
  options.checks = reg::PoseCheckOptions::ForErrorBound(5.0, 0.25);
  // Each PnP pose's map points matched again around their projections
  // (registration/map/frame_registration.h, guided_rounds).
  options.guided_rounds = o.guided_rounds;
  // The methods' trajectories: [method][serial] -> w0_from_cam.
  std::map<reg::RegistrationMethod, std::map<std::string, Trajectory>> trajectories;
  std::map<reg::RegistrationMethod, std::map<std::string, std::map<std::int64_t, std::string>>>
      failures;
  // Poses the pose checks refused (reported against a ground truth only).
  std::map<reg::RegistrationMethod, std::map<std::string, Trajectory>> refused;
  std::map<std::string, std::vector<std::int64_t>> frames_of;
  std::map<std::string, std::map<std::int64_t, Pose>> truth_of;
  std::map<std::string, ResidualsAtTruth> residuals_at_truth;
  std::map<std::pair<reg::RegistrationMethod, std::string>, std::map<std::int64_t, std::size_t>>
      inliers_of;
  std::map<std::pair<reg::RegistrationMethod, std::string>, std::map<std::int64_t, double>> rmse_of;
  for (const std::string& serial : serials) {
    Expected<processing::CameraModel> camera = camera_of(serial);
    if (!camera) return Fail(camera.error().message);
    Expected<std::unique_ptr<reg::FrameObserver>> observer = reg::FrameObserver::Open(
        source, seq, serial, *camera, layout::CamerasYamlPath(seq), features);
    if (!observer) return Fail(observer.error().message);
    std::vector<std::int64_t> frames = (*observer)->frames();
    if (o.frames > 0 && frames.size() > static_cast<std::size_t>(o.frames))
      frames.resize(static_cast<std::size_t>(o.frames));
    frames_of[serial] = frames;
    for (const std::int64_t frame : frames) {
      Expected<reg::FrameObservations> obs = (*observer)->Observe(frame);
      for (const reg::RegistrationMethod method : methods) {
        if (!obs) {
          failures[method][serial][frame] = obs.error().message;
          continue;
        }
        const reg::FrameRegistration r = reg::RegisterFrame(index, *camera, *obs, method, options);
        inliers_of[{method, serial}][frame] = r.inliers;
        rmse_of[{method, serial}][frame] = r.rmse_px;
        if (r.success)
          trajectories[method][serial][frame] = r.w0_from_cam;
        else
          failures[method][serial][frame] = r.status;
        if (r.estimated && !r.success) refused[method][serial][frame] = r.w0_from_cam;
        if (r.estimated && method == reg::RegistrationMethod::kPnp)
          AddResidualsAtTruth(seq, serial, frame, *camera, index, *obs, r,
                              options.sigma_v_relative, &truth_of, &residuals_at_truth[serial]);
        std::cerr << "camera " << serial << " frame " << frame << ": "
                  << obs->features.size() << " keypoints (" << static_cast<int>(1e3 * obs->seconds)
                  << " ms), " << r.BriefReport(method) << "\n";
        // The first method's poses place the frame in the map.
        if (o.chain && r.success && method == methods.front())
          if (Status s =
                  shared_map.AddFrame(camera_order, *camera, *obs, r.w0_from_cam.pose, index);
              !s)
            return Fail(s.error().message);
      }
    }
    if (o.chain && serial != serials.back()) {
      const reg::MapExtension e = shared_map.AddTracksTo(&map);
      std::cerr << "chained map after camera " << serial << ": " << e.BriefReport() << "; "
                << map.points.size() << " points\n";
      index = reg::MapIndex::Of(map);
      prepare_index();
    }
    ++camera_order;
  }

  // c0_from_cx per frame, the CSV rows and the TUM files.
  std::vector<RegistrationRow> rows;
  std::map<std::pair<reg::RegistrationMethod, std::string>, std::map<std::int64_t, Pose>> c0_from;
  std::map<std::pair<reg::RegistrationMethod, std::string>,
           std::map<std::int64_t, reg::PoseWithCovariance>>
      c0_from_with_covariance;
  for (const reg::RegistrationMethod method : methods) {
    const std::string name(reg::ToString(method));
    const Trajectory& reference_trajectory = trajectories[method][reference_serial];
    for (const std::string& serial : serials) {
      WriteTum(fs::path(o.out) / ("trajectory_" + serial + "_" + name + ".tum"),
               trajectories[method][serial]);
      if (serial == reference_serial) continue;
      int ok = 0;
      for (const std::int64_t frame : frames_of[serial]) {
        RegistrationRow row;
        row.frame = frame;
        row.camera = serial;
        row.method = name;
        row.inliers = static_cast<std::int64_t>(inliers_of[{method, serial}][frame]);
        row.rmse_px = rmse_of[{method, serial}][frame];
        const auto x = trajectories[method][serial].find(frame);
        const auto zero = reference_trajectory.find(frame);
        if (x == trajectories[method][serial].end()) {
          row.status = failures[method][serial][frame];
        } else if (zero == reference_trajectory.end()) {
          const auto why = failures[method][reference_serial].find(frame);
          row.status = "reference camera " + reference_serial + ": " +
                       (why != failures[method][reference_serial].end() ? why->second
                                                                         : "frame missing");
        } else {
          const reg::PoseWithCovariance c0_from_cx = reg::C0FromCxByPnp(zero->second, x->second);
          row.c0_from_cx = c0_from_cx.pose;
          c0_from_with_covariance[{method, serial}][frame] = c0_from_cx;
          row.status = "ok";
          c0_from[{method, serial}][frame] = row.c0_from_cx;
          ++ok;
        }
        rows.push_back(row);
      }
      std::fprintf(stderr, "%s: camera %s -> %s: %d of %zu frames registered\n", name.c_str(),
                   serial.c_str(), reference_serial.c_str(), ok, frames_of[serial].size());
    }
  }
  {
    std::ofstream csv(fs::path(o.out) / "registration.csv");
    csv << FormatRegistrationCsv(rows);
    if (!csv) return Fail((fs::path(o.out) / "registration.csv").string() + ": cannot write");
  }

  // Against the ground truth, when the sequence has it.
  std::map<std::string, std::map<std::int64_t, Pose>> world_from;
  for (const std::string& serial : serials) {
    Expected<std::vector<reg::FramePose>> gt = reg::ReadPosesCsv(layout::PosesCsvPath(seq, serial));
    if (!gt) break;
    for (const reg::FramePose& p : *gt) world_from[serial][p.frame] = p.world_from_cam;
  }
  if (world_from.size() == serials.size()) {
    std::printf("c0_from_cx against GroundTruth (per frame; c0_from_cx_true = world_from_c0^-1 "
                "world_from_cx):\n");
    // With a ground-truth map w0 is the world: each camera's own error.
    if (o.reference_from_ground_truth) {
      for (const reg::RegistrationMethod method : methods)
        for (const std::string& serial : serials) {
          Errors e;
          for (const auto& [frame, pose] : trajectories[method][serial]) {
            const auto truth = world_from[serial].find(frame);
            if (truth == world_from[serial].end()) continue;
            e.t_mm.push_back(reg::TranslationDifference(pose.pose, truth->second));
            e.r_deg.push_back(reg::RotationDifferenceDeg(pose.pose, truth->second));
          }
          PrintStats(std::string(reg::ToString(method)) + " w0_from_cam " + serial, e);
        }
    }
    for (const auto& [serial, a] : residuals_at_truth) {
      if (a.n == 0) continue;
      const auto sd = [](double sum2, double count) { return std::sqrt(std::max(0.0, sum2 / count)); };
      std::printf("  pnp inliers of %s at the true pose: residual variance / the pose's s^2 x %.2f, "
                  "y %.2f (n=%zu), depth z-score variance %.2f (n=%zu); common shift (frame mean "
                  "less noise) RMS x %.3f, y %.3f px over %d frames\n",
                  serial.c_str(), a.x2 / static_cast<double>(a.n), a.y2 / static_cast<double>(a.n),
                  a.n, a.n_depth ? a.z2 / static_cast<double>(a.n_depth) : 0.0, a.n_depth,
                  sd(a.shift_x2, a.frames), sd(a.shift_y2, a.frames), a.frames);
    }
    // Each camera against the truth on its own (w0 is the ground truth's
    // world: a calibration's map frame is the plate frame).
    if (!o.reference_from_ground_truth)
      for (const reg::RegistrationMethod method : methods)
        for (const std::string& serial : serials)
          PrintOwnFrameError(std::string(reg::ToString(method)) + " w0_from_cam " + serial,
                             trajectories[method][serial], world_from[serial]);
    for (const std::string& serial : serials) {
      if (serial == reference_serial) continue;
      std::printf("camera %s -> %s\n  frame", serial.c_str(), reference_serial.c_str());
      for (const reg::RegistrationMethod method : methods)
        std::printf("   %6s t_mm  r_deg", std::string(reg::ToString(method)).c_str());
      if (methods.size() == 2) std::printf("   diff t_mm  r_deg");
      std::printf("\n");
      std::map<reg::RegistrationMethod, Errors> errors;
      std::map<reg::RegistrationMethod, int> beyond, within_chi2;
      Errors differences;
      for (const std::int64_t frame : frames_of[serial]) {
        const auto zero = world_from[reference_serial].find(frame);
        const auto x = world_from[serial].find(frame);
        if (zero == world_from[reference_serial].end() || x == world_from[serial].end()) continue;
        const Pose truth = zero->second.inverse() * x->second;
        std::printf("  %5lld", static_cast<long long>(frame));
        std::vector<const Pose*> estimates;
        for (const reg::RegistrationMethod method : methods) {
          const auto& by_frame = c0_from[{method, serial}];
          const auto e = by_frame.find(frame);
          if (e == by_frame.end()) {
            // A pose the checks refused: its error, to show what they caught.
            const auto pose_of = [&](const std::string& s) -> const reg::PoseWithCovariance* {
              if (const auto it = trajectories[method][s].find(frame);
                  it != trajectories[method][s].end())
                return &it->second;
              if (const auto it = refused[method][s].find(frame); it != refused[method][s].end())
                return &it->second;
              return nullptr;
            };
            const reg::PoseWithCovariance* z = pose_of(reference_serial);
            const reg::PoseWithCovariance* xp = pose_of(serial);
            if (z && xp) {
              const Pose c = reg::C0FromCxByPnp(*z, *xp).pose;
              std::printf("   %6s %6.1f %6.3f refused", "",
                          reg::TranslationDifference(c, truth), reg::RotationDifferenceDeg(c, truth));
            } else {
              std::printf("   %6s %6s %6s", "", "failed", "");
            }
            estimates.push_back(nullptr);
            continue;
          }
          const double t = reg::TranslationDifference(e->second, truth);
          const double r = reg::RotationDifferenceDeg(e->second, truth);
          errors[method].t_mm.push_back(t);
          errors[method].r_deg.push_back(r);
          if (t > 5 || r > 0.25) ++beyond[method];
          const reg::PoseWithCovariance& with_covariance =
              c0_from_with_covariance[{method, serial}][frame];
          const double d2 = reg::SquaredMahalanobis(with_covariance, truth);
          if (d2 <= kChiSquare6At95) ++within_chi2[method];
          std::printf("   %6s %6.3f %6.4f chi2 %6.2f", "", t, r, d2);
          estimates.push_back(&e->second);
        }
        if (estimates.size() == 2 && estimates[0] && estimates[1]) {
          const double t = reg::TranslationDifference(*estimates[0], *estimates[1]);
          const double r = reg::RotationDifferenceDeg(*estimates[0], *estimates[1]);
          differences.t_mm.push_back(t);
          differences.r_deg.push_back(r);
          std::printf("   %9.3f %6.4f", t, r);
        }
        std::printf("\n");
      }
      for (const reg::RegistrationMethod method : methods) {
        std::vector<double> t = errors[method].t_mm, r = errors[method].r_deg;
        const double median_t = ErrorStats::Of(t).median, median_r = ErrorStats::Of(r).median;
        PrintStats(std::string(reg::ToString(method)) + " error vs ground truth", errors[method]);
        std::printf("  %-34s median %.3f mm / %.4f deg (gate <= 2 mm / 0.1 deg), registered "
                    "%zu/%zu (gate >= 95 %%)\n",
                    (std::string(reg::ToString(method)) + " gate").c_str(), median_t, median_r,
                    t.size(), frames_of[serial].size());
        std::printf("  %-34s %d ok rows beyond 5 mm / 0.25 deg; %d of %zu (%.1f %%) within the "
                    "95 %% chi-square(6) bound of their covariance (%.3f)\n",
                    (std::string(reg::ToString(method)) + " checks").c_str(), beyond[method],
                    within_chi2[method], t.size(),
                    t.empty() ? 0.0 : 100.0 * within_chi2[method] / static_cast<double>(t.size()),
                    kChiSquare6At95);
      }
      if (methods.size() == 2) PrintStats("difference pnp - ransac", differences);
    }
  }
  if (o.chain) {
    // The extended map, for `replay --reference` and a later `register --reference`.
    const fs::path chained = fs::path(o.out) / "chained_reference";
    if (Status s = reg::WriteReferenceMap(chained, map); !s) return Fail(s.error().message);
    std::printf("wrote %s (%zu points)\n", chained.string().c_str(), map.points.size());
  }
  std::printf("wrote %s (%zu rows)\n", (fs::path(o.out) / "registration.csv").string().c_str(),
              rows.size());
  return 0;
}

}  // namespace

CommandRun AddRegisterCommand(CLI::App& app) {
  auto o = std::make_shared<RegisterOptions>();
  app.footer(
      "Reads: SEQ_DIR (raw frames, or with --observations ground-truth its GroundTruth/),\n"
      "the reference map (--reference MAP_DIR, lifmcr calibrate's output) and --intrinsics.\n"
      "Writes: into --out, registration.csv (frame, camera, method, c0_from_cx, inliers,\n"
      "rmse_px, status) and trajectory_<serial>_<method>.tum; with --chain the extended map\n"
      "in chained_reference/ (a --reference MAP_DIR); progress on stderr.\n"
      "Exit codes: 0 written; 1 an input could not be read or written; 2 usage error.");
  app.add_option("SEQ_DIR", o->sequence, "Sequence folder (SCENE/SEQ)")->required();
  app.add_option("--reference", o->reference, "Reference map folder (lifmcr calibrate's output)");
  app.add_flag("--reference-from-ground-truth", o->reference_from_ground_truth,
               "Build the map from the sequence's ground truth (camera 0, --map-frames frames)");
  app.add_option("--map-frames", o->map_frames, "Frames of camera 0 in a ground-truth map")
      ->check(CLI::PositiveNumber);
  app.add_option("--method", o->method, "pnp, ransac or both");
  app.add_option("--camera", o->cameras, "Cameras to register (default: all)");
  app.add_option("--out", o->out, "Output folder")->required();
  app.add_option("--intrinsics", o->intrinsics,
                 "cameras.yaml / intrinsics.yaml (default: SEQ/GroundTruth/cameras.yaml); repeat it "
                 "to take each camera from the first file that has it (camera 0 from lifmcr "
                 "calibrate's intrinsics.yaml, the others from their own)");
  app.add_option("--observations", o->observations,
                 "Keypoints and depth from: raw (processing) or ground-truth");
  app.add_option("--frames", o->frames, "Only the first N frames of each camera (0: all)");
  app.add_option("--max-features", o->max_features, "SIFT keypoints per frame (0: all)");
  app.add_option("--matching", o->matching,
                 "Frame-to-map matching: approximate (the map's kd-forest, built once) or exact "
                 "(brute force, the reference; its time grows with the map)");
  app.add_option("--guided-rounds", o->guided_rounds,
                 "PnP: for a pose its checks refuse, rounds of matching the map points again "
                 "around that pose's projections, each followed by PnP and the checks (0: none)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--chain", o->chain,
               "Register the cameras in order, each against the map extended by the frames of "
               "the cameras registered before it (a far camera through its neighbours' views)");
  return [o] { return RunRegister(*o); };
}

}  // namespace lifmcr::apps
