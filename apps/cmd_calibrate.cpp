// `lifmcr calibrate SEQ_DIR --camera SERIAL --out DIR [--initial cameras.yaml]
// [--mla FILE] [--frames LIST] [--recalibrate FIXED.yaml] [--plate FILE]`:
// intrinsic calibration of one plenoptic camera and its reference map
// (registration/calibration/calibration.h). Writes into DIR intrinsics.yaml, the
// reference map (cameras.txt, images.txt, points3D.txt, points.ply,
// descriptors.bin), poses_<serial>.csv and calibration_report.md.

#include "apps/commands.h"
#include "apps/frame_list.h"
#include "config/text_escape.h"
#include "registration/map/aruco_corners.h"
#include "registration/calibration/calibration.h"
#include "registration/features/calibration_frames.h"
#include "registration/calibration/calibration_gates.h"
#include "registration/calibration/calibration_truth.h"
#include "registration/calibration/rig_calibration.h"
#include "registration/calibration/rig_output.h"
#include "registration/calibration/plate_plane_model.h"
#include "registration/calibration/rig_truth_per_frame.h"
#include "registration/calibration/truth_substitution.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/map/poses_csv.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/map/reference_map.h"
#include "replay/layout.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;

struct CalibrateOptions {
  std::string sequence;
  std::string camera;
  std::string out;
  std::string initial;
  std::string mla;
  std::string frames;
  std::string recalibrate;
  std::string plate;
  int max_features = 4000;
  bool quiet = false;
  bool ground_truth = false;
  bool at_truth = false;
  std::string substitute_truth;  // diagnostic (truth_substitution.h)
  int plate_model_passes = registration::PlateModelOptions{}.passes;
  std::string plate_model_corner_depth = "plane";
  std::string plate_model_edges = "whole";
  bool fix_principal_point = false;
  bool fix_distortion = false;
  bool tangential_distortion = false;
  int match_window = registration::CalibrationOptions{}.match_window;
  int min_map_observations = registration::CalibrationOptions{}.min_map_observations;
  double min_map_angle_deg = registration::CalibrationOptions{}.min_map_angle_deg;
  double map_sigma_v_rel = registration::CalibrationOptions{}.map_sigma_v_rel;
  double map_sigma_tf_px = registration::CalibrationOptions{}.map_sigma_tf_px;
  double max_keypoint_depth_range = registration::CalibrationOptions{}.max_keypoint_depth_range;
  double keypoint_depth_sigma_per_range =
      registration::CalibrationOptions{}.keypoint_depth_sigma_per_range;
  double keypoint_depth_robust = registration::CalibrationOptions{}.keypoint_depth_robust;
  double keypoint_sigma_size_tf_px = registration::CalibrationOptions{}.keypoint_sigma_size_tf_px;
  int keypoint_support_radius_tf_px = registration::KeypointDepthSupport{}.radius_tf_px;
  bool no_covariance = false;
  double plate_weight = registration::CalibrationOptions{}.plate_weight;
  double principal_point_prior_px = registration::CalibrationOptions{}.principal_point_prior_px;
  bool euclidean_points = false;
  bool fixed_corner_inset = false;
  bool keep_plate_corners = false;
  double plate_corner_threshold_tf_px =
      registration::PlateCornerCheckOptions{}.max_residual_tf_px;
  double plate_corner_ratio = registration::PlateCornerCheckOptions{}.max_residual_over_reference;
  std::string plate_frames;
  std::string cache;
  bool rig = false;
  bool non_rigid = false;
  bool rig_equal_plate_weight = false;
  std::string cameras;
  std::string camera0_calibration;
};

int Fail(const std::string& message, int code = 1) {
  std::cerr << "lifmcr calibrate: " << EscapeText(message) << "\n";
  return code;
}

// One camera's frames, processed with its initial intrinsics (or read from
// the cache where it has them processed so).
struct CameraFrames {
  registration::FrameLoaderOptions loader_options;
  std::unique_ptr<registration::CalibrationFrameLoader> loader;
  std::vector<registration::CalibrationFrame> frames;
};

Expected<CameraFrames> LoadCameraFrames(const CalibrateOptions& o, const std::string& serial,
                                        const registration::CameraCalibration& initial,
                                        const registration::PlateLayout& plate,
                                        const registration::ProgressFn& progress) {
  CameraFrames out;
  registration::FrameLoaderOptions& loader_options = out.loader_options;
  loader_options.lambda = processing::CameraModel(initial.intrinsics).lambda();
  loader_options.principal_point_px = initial.intrinsics.principal_point_px;
  loader_options.features.max_features = o.max_features;
  loader_options.keypoint_support.radius_tf_px = o.keypoint_support_radius_tf_px;
  auto loader = registration::CalibrationFrameLoader::Open(o.sequence, serial, o.mla, plate,
                                                           loader_options);
  if (!loader) return loader.error();
  if ((*loader)->width() != initial.intrinsics.width_px ||
      (*loader)->height() != initial.intrinsics.height_px)
    return Error{"camera " + serial + ": the raw frames are " + std::to_string((*loader)->width()) +
                 "x" + std::to_string((*loader)->height()) + ", the initial intrinsics " +
                 std::to_string(initial.intrinsics.width_px) + "x" +
                 std::to_string(initial.intrinsics.height_px)};
  std::vector<std::int64_t> frames = (*loader)->frames();
  if (!o.frames.empty()) {
    Expected<std::set<std::int64_t>> wanted = ParseFrameList(o.frames, "--frames");
    if (!wanted) return wanted.error();
    std::vector<std::int64_t> kept;
    for (const std::int64_t f : *wanted) {
      if (std::find(frames.begin(), frames.end(), f) == frames.end())
        return Error{"--frames: camera " + serial + " has no frame " + std::to_string(f)};
      kept.push_back(f);
    }
    frames = kept;
  }
  std::error_code ec;
  for (const std::int64_t f : frames) {
    const fs::path cached =
        o.cache.empty() ? fs::path()
                        : fs::path(o.cache) / (serial + "_" + std::to_string(f) + ".frame");
    Expected<registration::CalibrationFrame> frame = Error{""};
    if (!cached.empty() && fs::exists(cached))
      frame = registration::LoadCalibrationFrame(cached, loader_options);
    const bool from_cache = frame.ok();
    if (!frame) frame = (*loader)->Load(f);
    if (!frame) return frame.error();
    // A cached file processed otherwise (lambda, principal point, keypoint
    // limit) or of an older version is replaced.
    if (!cached.empty() && !from_cache) {
      fs::create_directories(o.cache, ec);
      if (Status s = registration::SaveCalibrationFrame(cached, *frame, loader_options); !s)
        return s.error();
    }
    char line[256];
    std::snprintf(line, sizeof(line),
                  "%sframe %lld: %d SIFT keypoints, TF depth %.0f %%, %zu plate corners, %.2f s",
                  o.rig ? ("camera " + serial + " ").c_str() : "", static_cast<long long>(f), frame->features.size(),
                  100 * frame->tf_depth_coverage, frame->corners.size(), frame->seconds);
    progress(line);
    out.frames.push_back(std::move(*frame));
  }
  out.loader = std::move(*loader);
  return out;
}

// The calibration options of the command line.
Expected<registration::CalibrationOptions> MakeCalibrationOptions(const CalibrateOptions& o) {
  registration::CalibrationOptions options;
  options.recalibrate = !o.recalibrate.empty();
  options.estimate_principal_point = !o.fix_principal_point;
  options.estimate_distortion = !o.fix_distortion;
  options.estimate_tangential_distortion = o.tangential_distortion;
  options.match_window = o.match_window;
  options.min_map_observations = o.min_map_observations;
  options.min_map_angle_deg = o.min_map_angle_deg;
  options.map_sigma_v_rel = o.map_sigma_v_rel;
  options.map_sigma_tf_px = o.map_sigma_tf_px;
  options.max_keypoint_depth_range = o.max_keypoint_depth_range;
  options.keypoint_depth_sigma_per_range = o.keypoint_depth_sigma_per_range;
  options.keypoint_depth_robust = o.keypoint_depth_robust;
  options.keypoint_sigma_size_tf_px = o.keypoint_sigma_size_tf_px;
  options.covariance = !o.no_covariance;
  options.plate_weight = o.plate_weight;
  if (!o.plate_frames.empty()) {
    Expected<std::set<std::int64_t>> list = ParseFrameList(o.plate_frames, "--plate-frames");
    if (!list) return list.error();
    options.plate_frames.assign(list->begin(), list->end());
  }
  options.principal_point_prior_px = o.principal_point_prior_px;
  options.inverse_depth = !o.euclidean_points;
  options.estimate_corner_inset = !o.fixed_corner_inset;
  options.reject_plate_corners = !o.keep_plate_corners;
  options.plate_corner_check.max_residual_tf_px = o.plate_corner_threshold_tf_px;
  options.plate_corner_check.max_residual_over_reference = o.plate_corner_ratio;
  return options;
}

// The options of the plate corners placed again at the predicted plate
// plane (plate_plane_model.h).
Expected<registration::PlateModelOptions> MakePlateModelOptions(const CalibrateOptions& o) {
  registration::PlateModelOptions options;
  options.passes = o.plate_model_passes;
  if (o.plate_model_corner_depth != "plane" && o.plate_model_corner_depth != "measured")
    return Error{"--plate-model-corner-depth: expected plane or measured, got '" +
                 o.plate_model_corner_depth + "'"};
  options.corner_depth_from_plane = o.plate_model_corner_depth == "plane";
  if (o.plate_model_edges != "whole" && o.plate_model_edges != "half")
    return Error{"--plate-model-edges: expected whole or half, got '" + o.plate_model_edges + "'"};
  options.edges.whole_edges = o.plate_model_edges == "whole";
  if (Status s = options.Check(); !s) return s.error();
  return options;
}

int RunCalibrateRig(const CalibrateOptions& o);

int RunCalibrate(const CalibrateOptions& o) {
  if (o.rig && !o.substitute_truth.empty())
    return Fail("--substitute-truth calibrates one camera (not with --rig)", 2);
  if (o.rig && o.plate_model_passes > 0)
    return Fail("--plate-model-passes calibrates one camera (not with --rig)", 2);
  if (o.rig) return RunCalibrateRig(o);
  if (o.camera.empty()) return Fail("--camera SERIAL is needed (or --rig)", 2);
  const fs::path seq = o.sequence;
  const fs::path gt_yaml = layout::CamerasYamlPath(seq);
  const fs::path plate_path = o.plate.empty() ? gt_yaml : fs::path(o.plate);
  if (o.initial.empty() && o.recalibrate.empty())
    return Fail("--initial cameras.yaml is needed: the nominal pixel size, f_L, b_L0 and B "
                "(or --recalibrate FIXED.yaml)",
                2);
  Expected<registration::CameraCalibration> initial = registration::ReadCameraCalibration(
      o.initial.empty() ? o.recalibrate : o.initial, o.camera);
  if (!initial) return Fail(initial.error().message);
  if (!o.recalibrate.empty()) {
    Expected<registration::CameraCalibration> fixed =
        registration::ReadCameraCalibration(o.recalibrate, o.camera);
    if (!fixed) return Fail(fixed.error().message);
    initial->intrinsics.main_focal_length_mm = fixed->intrinsics.main_focal_length_mm;
    initial->intrinsics.mla_to_sensor_mm = fixed->intrinsics.mla_to_sensor_mm;
  }
  if (!fs::exists(plate_path))
    return Fail(plate_path.string() +
                ": no marker plate layout (--plate names a file with a plate: section)");
  Expected<registration::PlateLayout> plate = registration::ReadPlateLayout(plate_path);
  if (!plate) return Fail(plate.error().message);

  if (!o.frames.empty())
    if (Expected<std::set<std::int64_t>> wanted = ParseFrameList(o.frames, "--frames"); !wanted)
      return Fail(wanted.error().message, 2);
  registration::TruthSubstitution substitution;
  if (!o.substitute_truth.empty()) {
    Expected<registration::TruthSubstitution> parsed =
        registration::ParseTruthSubstitution(o.substitute_truth);
    if (!parsed) return Fail(parsed.error().message, 2);
    substitution = *parsed;
  }
  // The options are checked before the frames are processed (minutes of
  // CPU), so a bad value fails at once.
  Expected<registration::CalibrationOptions> calibration_options = MakeCalibrationOptions(o);
  if (!calibration_options) return Fail(calibration_options.error().message, 2);
  if (Status s = calibration_options->Check(); !s) return Fail(s.error().message, 2);
  const registration::CalibrationOptions& options = *calibration_options;
  Expected<registration::PlateModelOptions> plate_model = MakePlateModelOptions(o);
  if (!plate_model) return Fail(plate_model.error().message, 2);
  if (plate_model->passes > 0 && o.at_truth)
    return Fail("--plate-model-passes: not with --at-truth (no calibration to predict from)", 2);
  const registration::ProgressFn progress = [&](std::string_view line) {
    if (!o.quiet) std::cerr << line << "\n";
  };
  Expected<CameraFrames> camera_frames = LoadCameraFrames(o, o.camera, *initial, *plate, progress);
  if (!camera_frames) return Fail(camera_frames.error().message);
  const registration::FrameLoaderOptions& loader_options = camera_frames->loader_options;
  if (substitution.any()) {
    // A diagnostic: one group of observations made exact (truth_substitution.h).
    Expected<std::string> line = registration::SubstituteTruth(
        substitution, seq, o.camera, loader_options.lambda,
        initial->intrinsics.PrincipalPointPx(), loader_options.features, &camera_frames->frames);
    if (!line) return Fail(line.error().message);
    progress(*line);
  }
  std::error_code ec;
  registration::CalibrationInput input;
  input.serial = o.camera;
  input.initial = *initial;
  input.micro_images = &camera_frames->loader->micro_images();
  input.frames = std::move(camera_frames->frames);
  if (o.at_truth) {
    // The bundle adjustment's residuals with the true intrinsics and poses
    // (registration/calibration/calibration_truth.h); no calibration.
    Expected<registration::CameraCalibration> truth =
        registration::ReadCameraCalibration(gt_yaml, o.camera);
    if (!truth) return Fail(truth.error().message);
    Expected<std::vector<registration::FramePose>> poses =
        registration::ReadPosesCsv(layout::PosesCsvPath(seq, o.camera));
    if (!poses) return Fail(poses.error().message);
    std::map<std::int64_t, Pose> world_from_cam;
    for (const registration::FramePose& p : *poses) world_from_cam[p.frame] = p.world_from_cam;
    Expected<registration::TruthResiduals> at_truth = registration::EvaluateAtTruth(
        input, options, truth->intrinsics, world_from_cam, progress);
    if (!at_truth) return Fail(at_truth.error().message);
    const std::string text = at_truth->Report();
    std::cout << text;
    fs::create_directories(o.out, ec);
    if (ec) return Fail(o.out + ": " + ec.message());
    std::ofstream file(fs::path(o.out) / "residuals_at_truth.md", std::ios::binary);
    file << "# Calibration residuals at the ground truth, camera " << o.camera << "\n\n" << text;
    if (!file) return Fail((fs::path(o.out) / "residuals_at_truth.md").string() + ": could not write");
    std::ofstream csv(fs::path(o.out) / "residuals_at_truth.csv", std::ios::binary);
    csv << at_truth->Csv();
    if (!csv) return Fail((fs::path(o.out) / "residuals_at_truth.csv").string() + ": could not write");
    return 0;
  }
  Expected<registration::CalibrationResult> result =
      registration::Calibrate(input, options, progress);
  if (!result) return Fail(result.error().message);
  for (int pass = 1; pass <= plate_model->passes; ++pass) {
    progress("plate model pass " + std::to_string(pass) + ": " + result->BriefReport());
    if (o.ground_truth) {
      // The figures before the pass, beside the final ones printed below.
      Expected<registration::GroundTruthComparison> before =
          registration::CompareWithGroundTruth(*result, seq, o.camera);
      if (!before) return Fail(before.error().message);
      progress("plate model pass " + std::to_string(pass) + ", before: " + before->BriefReport());
    }
    Expected<registration::PlateModelPass> placed = registration::PlaceCornersAtModelPlane(
        *result, *plate_model, camera_frames->loader.get(), &input.frames);
    if (!placed) return Fail(placed.error().message);
    progress("plate model pass " + std::to_string(pass) + ": " + placed->Summary());
    result = registration::Calibrate(input, options, progress);
    if (!result) return Fail(result.error().message);
  }

  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": " + ec.message());
  const fs::path out = o.out;
  registration::CalibrationAnnotation annotation;
  annotation.summary = result->BriefReport();
  const char* keys[registration::kIntrinsicsSize] = {
      "main_focal_length_mm", "mla_to_main_lens_mm", "mla_to_sensor_mm", "principal_point_x_px",
      "principal_point_y_px", "k1", "k2", "p1", "p2"};
  for (int i = 0; i < registration::kIntrinsicsSize; ++i)
    if (!std::isnan(result->std_dev[i])) annotation.std_dev[keys[i]] = result->std_dev[i];
  if (Status s = registration::WriteIntrinsicsYaml(out / "intrinsics.yaml", o.camera,
                                                   result->calibration, annotation);
      !s)
    return Fail(s.error().message);
  if (Status s = registration::WriteReferenceMap(out, result->map); !s)
    return Fail(s.error().message);
  // The plate corners of the placed frames, for the plate alignment of
  // `lifmcr evaluate --map` (registration/map/aruco_corners.h).
  {
    std::set<std::int64_t> placed;
    for (const registration::FramePose& p : result->poses) placed.insert(p.frame);
    std::vector<registration::ArucoCornerObservation> corners;
    for (const registration::CalibrationFrame& frame : input.frames) {
      if (!placed.count(frame.frame)) continue;
      for (std::size_t n = 0; n < frame.corners.size(); ++n) {
        const registration::PlateCorner& c = frame.corners[n];
        corners.push_back({frame.frame, c.marker_id, c.corner, c.tf_px,
                           n < frame.corner_virtual_depth.size() ? frame.corner_virtual_depth[n]
                                                                 : std::nan("")});
      }
    }
    std::ofstream csv(out / "aruco_corners.csv", std::ios::binary);
    csv << registration::FormatArucoCornersCsv(corners);
    if (!csv) return Fail((out / "aruco_corners.csv").string() + ": could not write");
  }
  std::ofstream report(out / "calibration_report.md", std::ios::binary);
  report << registration::FormatCalibrationReport(*result, o.camera);
  if (!report) return Fail((out / "calibration_report.md").string() + ": could not write");
  std::cout << result->BriefReport() << "\n";
  if (o.ground_truth) {
    Expected<registration::GroundTruthComparison> c =
        registration::CompareWithGroundTruth(*result, seq, o.camera);
    if (!c) return Fail(c.error().message);
    std::cout << c->BriefReport() << "\n";
    report << "\n## Against the ground truth\n\n" << c->BriefReport() << "\n";
    Expected<registration::PlateCornerBias> bias =
        registration::MeasurePlateCornerBias(input.frames, loader_options.lambda, seq,
                                             o.camera);
    if (!bias) return Fail(bias.error().message);
    std::cout << bias->BriefReport() << "\n" << bias->PerFrameReport();
    report << "\n" << bias->BriefReport() << "\n\n" << bias->PerFrameReport();
  }
  for (const std::string& flag : result->flags) std::cerr << "flag: " << flag << "\n";
  return result->usable ? 0 : 3;
}


// `lifmcr calibrate SEQ --rig`: the cameras of --cameras (camera 0 first)
// calibrated as one rig (registration/calibration/rig_calibration.h).
int RunCalibrateRig(const CalibrateOptions& o) {
  const fs::path seq = o.sequence;
  const fs::path gt_yaml = layout::CamerasYamlPath(seq);
  const fs::path plate_path = o.plate.empty() ? gt_yaml : fs::path(o.plate);
  if (o.initial.empty()) return Fail("--rig: --initial cameras.yaml with every camera is needed", 2);
  if (o.non_rigid && !o.rig) return Fail("--non-rigid needs --rig", 2);
  if (o.at_truth) return Fail("--rig: --at-truth is for one camera", 2);
  if (o.keypoint_sigma_size_tf_px > 0)
    return Fail("--rig: --keypoint-sigma-size is for one camera (the rig's solve weighs every "
                "keypoint alike)", 2);
  if (!o.frames.empty())
    if (Expected<std::set<std::int64_t>> wanted = ParseFrameList(o.frames, "--frames"); !wanted)
      return Fail(wanted.error().message, 2);
  // The cameras: --cameras, else --camera and every other camera of SEQ.
  std::vector<std::string> serials;
  if (!o.cameras.empty()) {
    std::stringstream list(o.cameras);
    for (std::string serial; std::getline(list, serial, ',');)
      if (!serial.empty()) serials.push_back(serial);
  } else {
    if (o.camera.empty()) return Fail("--rig: --cameras S0,S1,... or --camera S0 is needed", 2);
    serials.push_back(o.camera);
    std::vector<std::string> others;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(seq, ec))
      if (auto serial = layout::ParseCameraFolderName(e.path().filename().string()))
        if (*serial != o.camera) others.push_back(*serial);
    if (ec) return Fail(seq.string() + ": " + ec.message());
    std::sort(others.begin(), others.end());
    serials.insert(serials.end(), others.begin(), others.end());
  }
  if (!o.camera.empty() && serials.front() != o.camera)
    return Fail("--rig: --camera " + o.camera + " is not the first of --cameras", 2);
  if (serials.size() < 2) return Fail("--rig: at least two cameras are needed", 2);
  // A synthetic sequence's truth says whether the mount is rigid: camera X's
  // c0_from_cx over the frames both cameras have (0.1 mm / 0.01 deg: the
  // rigid rigs' are equal to rounding).
  std::map<std::string, std::map<std::int64_t, Pose>> truth_c0_from_cx;
  {
    std::map<std::int64_t, Pose> world_from_c0;
    for (const std::string& serial : serials) {
      const fs::path csv = layout::PosesCsvPath(seq, serial);
      if (!fs::exists(csv)) {
        truth_c0_from_cx.clear();
        break;
      }
      Expected<std::vector<registration::FramePose>> poses = registration::ReadPosesCsv(csv);
      if (!poses) return Fail(poses.error().message);
      if (world_from_c0.empty())
        for (const registration::FramePose& p : *poses) world_from_c0[p.frame] = p.world_from_cam;
      for (const registration::FramePose& p : *poses)
        if (const auto c0 = world_from_c0.find(p.frame); c0 != world_from_c0.end())
          truth_c0_from_cx[serial][p.frame] = c0->second.inverse() * p.world_from_cam;
    }
    for (const auto& [serial, poses] : truth_c0_from_cx) {
      if (poses.empty() || o.non_rigid) continue;
      double mm = 0, deg = 0;
      for (const auto& [frame, pose] : poses) {
        mm = std::max(mm, registration::TranslationDifference(pose, poses.begin()->second));
        deg = std::max(deg, registration::RotationDifferenceDeg(pose, poses.begin()->second));
      }
      if (mm > 0.1 || deg > 0.01) {
        char line[512];
        std::snprintf(line, sizeof(line),
                      "--rig: %s says camera %s moves against camera 0 (its c0_from_cx varies by "
                      "up to %.1f mm / %.3f deg over the sequence): the mount is not rigid; "
                      "calibrate it with --rig --non-rigid",
                      layout::PosesCsvPath(seq, serial).parent_path().string().c_str(),
                      serial.c_str(), mm, deg);
        return Fail(line, 2);
      }
    }
  }
  if (!fs::exists(plate_path))
    return Fail(plate_path.string() +
                ": no marker plate layout (--plate names a file with a plate: section)");
  Expected<registration::PlateLayout> plate = registration::ReadPlateLayout(plate_path);
  if (!plate) return Fail(plate.error().message);
  const registration::ProgressFn progress = [&](std::string_view line) {
    if (!o.quiet) std::cerr << line << "\n";
  };
  registration::RigCalibrationOptions options;
  Expected<registration::CalibrationOptions> calibration_options = MakeCalibrationOptions(o);
  if (!calibration_options) return Fail(calibration_options.error().message, 2);
  options.calibration = *calibration_options;
  options.non_rigid = o.non_rigid;
  options.reweigh_plate_corners = !o.rig_equal_plate_weight;
  if (Status s = options.Check(); !s) return Fail(s.error().message, 2);  // before the frames
  std::vector<CameraFrames> frames;
  std::vector<registration::CalibrationInput> inputs;
  for (const std::string& serial : serials) {
    Expected<registration::CameraCalibration> initial =
        registration::ReadCameraCalibration(o.initial, serial);
    if (!initial) return Fail(initial.error().message);
    if (!o.recalibrate.empty()) {  // every camera's f_L and B known (held)
      Expected<registration::CameraCalibration> fixed =
          registration::ReadCameraCalibration(o.recalibrate, serial);
      if (!fixed) return Fail(fixed.error().message);
      initial->intrinsics.main_focal_length_mm = fixed->intrinsics.main_focal_length_mm;
      initial->intrinsics.mla_to_sensor_mm = fixed->intrinsics.mla_to_sensor_mm;
    }
    Expected<CameraFrames> loaded = LoadCameraFrames(o, serial, *initial, *plate, progress);
    if (!loaded) return Fail(loaded.error().message);
    registration::CalibrationInput input;
    input.serial = serial;
    input.initial = *initial;
    input.micro_images = &loaded->loader->micro_images();
    input.frames = std::move(loaded->frames);
    inputs.push_back(std::move(input));
    frames.push_back(std::move(*loaded));
  }
  std::optional<registration::CalibrationResult> camera0;
  if (!o.camera0_calibration.empty()) {
    Expected<registration::ReferenceMap> map = registration::ReadReferenceMap(o.camera0_calibration);
    if (!map) return Fail(map.error().message);
    Expected<registration::CameraCalibration> intrinsics = registration::ReadCameraCalibration(
        fs::path(o.camera0_calibration) / "intrinsics.yaml", serials.front());
    if (!intrinsics) return Fail(intrinsics.error().message);
    camera0 = registration::CalibrationResultOf(*intrinsics, std::move(*map));
  }
  Expected<registration::RigCalibrationResult> result = registration::CalibrateRig(
      inputs, options, camera0 ? &*camera0 : nullptr, progress);
  if (!result) return Fail(result.error().message);

  std::error_code ec;
  fs::create_directories(o.out, ec);
  if (ec) return Fail(o.out + ": " + ec.message());
  const fs::path out = o.out;
  const char* keys[registration::kIntrinsicsSize] = {
      "main_focal_length_mm", "mla_to_main_lens_mm", "mla_to_sensor_mm", "principal_point_x_px",
      "principal_point_y_px", "k1", "k2", "p1", "p2"};
  for (std::size_t c = 0; c < result->cameras.size(); ++c) {
    const registration::RigCameraResult& rc = result->cameras[c];
    registration::CalibrationAnnotation annotation;
    annotation.summary = result->BriefReport();
    for (int i = 0; i < registration::kIntrinsicsSize; ++i)
      if (!std::isnan(rc.std_dev[i])) annotation.std_dev[keys[i]] = rc.std_dev[i];
    // Camera 0's as `lifmcr calibrate` names it (register --intrinsics
    // DIR/intrinsics.yaml), every camera's as intrinsics_<serial>.yaml.
    const fs::path own = out / ("intrinsics_" + rc.serial + ".yaml");
    if (Status s = registration::WriteIntrinsicsYaml(own, rc.serial, rc.calibration, annotation); !s)
      return Fail(s.error().message);
    if (c == 0)
      if (Status s = registration::WriteIntrinsicsYaml(out / "intrinsics.yaml", rc.serial,
                                                       rc.calibration, annotation);
          !s)
        return Fail(s.error().message);
  }
  if (Status s = registration::WriteReferenceMap(out, result->map); !s)
    return Fail(s.error().message);
  if (Status s = registration::WriteRigCalibration(out, *result, inputs); !s)
    return Fail(s.error().message);
  std::ofstream report(out / "calibration_report.md", std::ios::binary);
  report << "# Rig calibration\n\n" << result->BriefReport() << "\n\n```\n"
         << result->CameraReport() << "```\n";
  report << "\n## Camera 0 alone (the start)\n\n" << result->camera0.BriefReport() << "\n";
  std::cout << result->BriefReport() << "\n" << result->CameraReport();
  if (o.ground_truth && o.non_rigid) {
    // Per frame: the joint c0_from_cx(t), where it started, and each camera
    // X's frame registered alone against camera 0's map (its nominal
    // intrinsics, the frames as processed here).
    std::vector<registration::CameraCalibration> truth;
    std::vector<std::map<std::int64_t, Pose>> c0_from_cx;
    std::vector<std::vector<registration::FramePose>> alone(serials.size());
    for (std::size_t c = 0; c < serials.size(); ++c) {
      Expected<registration::CameraCalibration> t =
          registration::ReadCameraCalibration(gt_yaml, serials[c]);
      if (!t) return Fail(t.error().message);
      truth.push_back(*t);
      if (!truth_c0_from_cx.count(serials[c]))
        return Fail("--ground-truth: no " + layout::PosesCsvPath(seq, serials[c]).string());
      c0_from_cx.push_back(truth_c0_from_cx.at(serials[c]));
      if (c == 0) {  // camera 0's rows: w0_from_c0 against the plate frame's truth
        Expected<std::vector<registration::FramePose>> poses =
            registration::ReadPosesCsv(layout::PosesCsvPath(seq, serials[0]));
        if (!poses) return Fail(poses.error().message);
        c0_from_cx[0].clear();
        for (const registration::FramePose& p : *poses) c0_from_cx[0][p.frame] = p.world_from_cam;
      }
      if (c > 0)
        alone[c] = registration::RegisterAgainstCamera0(result->camera0, inputs[c],
                                                        inputs[c].initial.intrinsics,
                                                        options.registration);
    }
    Expected<registration::RigPerFrameTruth> c =
        registration::CompareNonRigidWithTruth(*result, truth, c0_from_cx, alone);
    if (!c) return Fail(c.error().message);
    std::cout << c->Report();
    report << "\n## Against the ground truth\n\n" << c->Report() << "\n";
  } else if (o.ground_truth) {
    std::vector<registration::CameraCalibration> truth;
    std::vector<Pose> c0_from_cx;
    std::map<std::int64_t, Pose> world_from_c0;
    for (const std::string& serial : serials) {
      Expected<registration::CameraCalibration> t = registration::ReadCameraCalibration(gt_yaml, serial);
      if (!t) return Fail(t.error().message);
      truth.push_back(*t);
      Expected<std::vector<registration::FramePose>> poses =
          registration::ReadPosesCsv(layout::PosesCsvPath(seq, serial));
      if (!poses) return Fail(poses.error().message);
      if (world_from_c0.empty())
        for (const registration::FramePose& p : *poses) world_from_c0[p.frame] = p.world_from_cam;
      // A rigid mount: c0_from_cx at the first frame both cameras have.
      bool found = false;
      for (const registration::FramePose& p : *poses)
        if (const auto c0 = world_from_c0.find(p.frame); c0 != world_from_c0.end()) {
          c0_from_cx.push_back(c0->second.inverse() * p.world_from_cam);
          found = true;
          break;
        }
      if (!found) return Fail("ground truth: camera " + serial + " shares no frame with camera 0");
    }
    // Beside the joint figures: each camera X registered alone against
    // camera 0's map (the start, its nominal intrinsics). Registered with its
    // true intrinsics it needs its frames processed with them (`lifmcr
    // register`, docs/calibration.md): these frames were processed with the
    // nominal ones.
    Expected<registration::RigTruthComparison> c =
        registration::CompareRigWithTruth(*result, truth, c0_from_cx);
    if (!c) return Fail(c.error().message);
    std::cout << c->Report();
    report << "\n## Against the ground truth\n\n```\n" << c->Report() << "```\n";
  }
  if (!report) return Fail((out / "calibration_report.md").string() + ": could not write");
  for (const std::string& flag : result->flags) std::cerr << "flag: " << flag << "\n";
  return result->usable ? 0 : 3;
}

}  // namespace

CommandRun AddCalibrateCommand(CLI::App& app) {
  auto o = std::make_shared<CalibrateOptions>();
  app.footer(
      "Reads: SEQ_DIR's raw frames of --camera, the MLA XML (--mla, else the dataset's\n"
      "Calibration/), --initial cameras.yaml (nominal model), --recalibrate and --plate when\n"
      "given. Writes: into --out, intrinsics.yaml, the reference map (cameras.txt, images.txt,\n"
      "points3D.txt, points.ply, descriptors.bin), poses_<serial>.csv, aruco_corners.csv (the\n"
      "plate corners seen, for lifmcr evaluate --map), calibration_report.md.\n"
      "With --rig (the cameras of --cameras as one rigid rig): intrinsics.yaml (camera 0)\n"
      "and intrinsics_<serial>.yaml (every camera), the shared map as above (camera 0's\n"
      "images), rig.yaml (each camera's c0_from_cx and its covariance), colmap/ (the rig as a\n"
      "COLMAP text model: cameras, rigs, frames, images, points3D), calibration_report.md.\n"
      "With --rig --non-rigid (cameras moving independently): the same, c0_from_cx per frame\n"
      "in rig.yaml (c0_from_cx_per_frame), in colmap/ one rig per camera and one frame per\n"
      "image.\n"
      "Progress on stderr unless --quiet.\n"
      "Exit codes: 0 calibrated; 1 an input could not be read or written; 2 usage error;\n"
      "3 the calibration ran but is not usable (the report says why).");
  app.add_option("SEQ_DIR", o->sequence, "Sequence folder (SCENE/SEQ)")->required();
  app.add_option("--camera", o->camera,
                 "Serial of the camera to calibrate (with --rig: camera 0, the reference)");
  app.add_flag("--rig", o->rig,
               "Calibrate the cameras of --cameras as one rig: every camera's intrinsics, each "
               "camera's c0_from_cx (rig.yaml; rigid: one per camera, --non-rigid: one per "
               "frame), camera 0's trajectory and one shared map");
  app.add_flag("--non-rigid", o->non_rigid,
               "With --rig: the cameras move independently (not one mount): a pose per camera "
               "and frame over the shared map, each camera registered through the map grown by "
               "the cameras before it (--cameras order: neighbours should follow each other). "
               "--rig refuses a sequence whose ground truth says the mount is not rigid "
               "without it");
  app.add_flag("--rig-equal-plate-weight", o->rig_equal_plate_weight,
               "--rig: every camera's plate corners weigh --plate-weight to the end (default: "
               "after the first solve a camera X's weigh --plate-weight x sqrt(camera 0's corner "
               "RMS / its own) where its own is larger)");
  app.add_option("--cameras", o->cameras,
                 "With --rig: the cameras, camera 0 first, e.g. 40398678,40398673 (default: "
                 "--camera, then the sequence's other cameras in ascending order)");
  app.add_option("--camera0-calibration", o->camera0_calibration,
                 "With --rig: camera 0's calibration of the same frames (a `lifmcr calibrate` "
                 "--out folder) to start from instead of calibrating camera 0 alone first");
  app.add_option("--out", o->out, "Output folder (created if needed)")->required();
  app.add_option("--initial", o->initial,
                 "cameras.yaml with nominal values (pixel size, f_L, b_L0, B)");
  app.add_option("--mla", o->mla, "MLA XML (default: the dataset's Calibration folder)");
  app.add_option("--frames", o->frames, "Frames to use, e.g. 0-39 or 0,4,8 (default: all)");
  app.add_option("--recalibrate", o->recalibrate,
                 "cameras.yaml whose f_L and B are held fixed (LiFCal recalib; with --rig: "
                 "every camera's)");
  app.add_option("--plate", o->plate,
                 "File with the marker plate's `plate:` section (default: "
                 "SEQ/GroundTruth/cameras.yaml)");
  app.add_option("--max-features", o->max_features, "SIFT keypoints per TF image (0 = all)");
  app.add_flag("--quiet", o->quiet, "No progress lines on stderr");
  app.add_option("--cache", o->cache,
                 "Folder keeping the processed frames (depth, TF, SIFT, ArUco) for later runs "
                 "with the same initial values");
  app.add_flag("--fix-principal-point", o->fix_principal_point,
               "Hold the principal point at its initial value");
  app.add_flag("--fix-distortion", o->fix_distortion, "Hold k1, k2, p1, p2 at their initial values");
  app.add_option("--min-map-observations", o->min_map_observations,
                 "Frames that must see a point for it to enter the reference map")
      ->check(CLI::Range(2, 1000));
  app.add_option("--min-map-angle", o->min_map_angle_deg,
                 "Degrees at which the rays of the frames that see a point must also meet for it "
                 "to enter the reference map (default 0: any baseline; a point enters where its "
                 "frames' plenoptic observations agree, --map-sigma-v)")
      ->check(CLI::Range(0.0, 89.9));
  app.add_option("--map-sigma-v", o->map_sigma_v_rel,
                 "Sigma of a keypoint's virtual depth as a share of v (default 0.015): frames' "
                 "observations of a point agree within the 99 % bound of it")
      ->check(CLI::Range(0.0001, 0.5));
  app.add_option("--map-sigma-tf", o->map_sigma_tf_px,
                 "Sigma of a keypoint's TF position in TF pixels (default 1): the lateral part "
                 "of that agreement")
      ->check(CLI::Range(0.01, 20.0));
  app.add_option("--keypoint-depth-range", o->max_keypoint_depth_range,
                 "A keypoint whose measured virtual depth ranges more than this share of v over "
                 "its support (--keypoint-support) enters by its position only (default: none, "
                 "every keypoint's depth enters; 0.01 leaves out the depths next to depth "
                 "edges: docs/calibration.md)")
      ->check(CLI::Range(1e-4, 1e9));
  app.add_option("--keypoint-depth-sigma-per-range", o->keypoint_depth_sigma_per_range,
                 "A keypoint's depth enters with sigma sqrt(0.28 %^2 + (S x range)^2) of v, "
                 "range its support's (--keypoint-support), its position at full weight "
                 "(default 0: every depth at full weight; 0.44 measured: docs/calibration.md)")
      ->check(CLI::Range(0.0, 99.0));
  app.add_option("--keypoint-sigma-size", o->keypoint_sigma_size_tf_px,
                 "Each keypoint's residuals weighed by its scale: sigma = max(1, SIFT size / this) "
                 "(TF px; 0: every keypoint at unit sigma; docs/calibration.md)")
      ->check(CLI::Range(0.0, 999.0));
  app.add_option("--keypoint-depth-robust", o->keypoint_depth_robust,
                 "After the first solve each keypoint's depth is reweighed by its disagreement e "
                 "with its point, 1 / sqrt(1 + (e / s)^2), s this times the robust sigma of every "
                 "e (default 0: none; 2.385 measured: docs/calibration.md)")
      ->check(CLI::Range(0.0, 99.0));
  app.add_option("--keypoint-support", o->keypoint_support_radius_tf_px,
                 "Radius of a keypoint's support in TF pixels, over which the range of its "
                 "virtual depth is measured (default 8; part of what --cache holds)")
      ->check(CLI::Range(1, 32));
  app.add_option("--match-window", o->match_window,
                 "Match each frame against the points of this many placed frames before it")
      ->check(CLI::PositiveNumber);
  app.add_flag("--tangential-distortion", o->tangential_distortion,
               "Estimate p1, p2 too (default: held at their initial values; they trade with the "
               "principal point)");
  app.add_flag("--no-covariance", o->no_covariance,
               "Skip the standard deviations of the intrinsics (Ceres covariance: about a "
               "quarter of the solve's time)");
  app.add_option("--plate-weight", o->plate_weight,
                 "Weight of the plate corners' residuals against the features' (default 5)");
  app.add_option("--principal-point-prior", o->principal_point_prior_px,
                 "Sigma (raw px) of the principal point's Gaussian prior about its initial "
                 "value (default 20; 0: none)");
  app.add_flag("--euclidean-points", o->euclidean_points,
               "Points as 3D positions in the plate frame instead of inverse depth in their "
               "first frame");
  app.add_option("--plate-frames", o->plate_frames,
                 "Frames whose plate corners enter the bundle adjustment, e.g. 0-19,28-39 "
                 "(default: all; every frame can still be placed on the plate)");
  app.add_flag("--no-corner-inset", o->fixed_corner_inset,
               "Take the ArUco corners as detected (no estimated inset towards the marker centre)");
  app.add_flag("--keep-plate-corners", o->keep_plate_corners,
               "Every detected plate corner enters the bundle adjustment (default: a corner "
               "off its frame's plate homography is left out and reported)");
  app.add_option("--plate-corner-threshold", o->plate_corner_threshold_tf_px,
                 "Leave-one-out homography residual (TF px) above which a plate corner is left "
                 "out (and above --plate-corner-ratio x the median over every frame's corners)");
  app.add_option("--plate-corner-ratio", o->plate_corner_ratio,
                 "A plate corner is left out above this many times the median leave-one-out "
                 "residual over every frame's corners (and above --plate-corner-threshold; "
                 "default 5)");
  app.add_flag("--at-truth", o->at_truth,
               "Synthetic sequences: no calibration; the bundle adjustment's residuals with the "
               "true intrinsics and poses of SEQ/GroundTruth, per frame, by virtual depth and by "
               "image position (printed and written to residuals_at_truth.md)");
  app.add_option("--substitute-truth", o->substitute_truth,
                 "Synthetic sequences, a diagnostic: replace one group of observations by the "
                 "renderer's truth before the calibration (keypoint-depth, keypoints, corners, "
                 "corner-depth, no-corner-depth; comma-separated; "
                 "registration/calibration/truth_substitution.h)");
  app.add_option("--plate-model-passes", o->plate_model_passes,
                 "After the calibration, place the plate corners again on the plate rendered at "
                 "the plate plane the calibration predicts (instead of the plane fitted to the "
                 "measured depths) and calibrate again, this many times (default 0; "
                 "registration/calibration/plate_plane_model.h)")
      ->check(CLI::Range(0, 5));
  app.add_option("--plate-model-corner-depth", o->plate_model_corner_depth,
                 "With --plate-model-passes: each corner's virtual depth from the predicted "
                 "plane (plane, default) or as measured at the corner pixel (measured)");
  app.add_option("--plate-model-edges", o->plate_model_edges,
                 "With --plate-model-passes: the corner lines fitted to the whole of each "
                 "marker edge (whole, default) or to the half nearest the corner (half)");
  app.add_flag("--ground-truth", o->ground_truth,
               "Synthetic sequences: compare with SEQ/GroundTruth and print the figures");
  return [o] { return RunCalibrate(*o); };
}

}  // namespace lifmcr::apps
