// `lifmcr evaluate SEQ_DIR --registration registration.csv [...] --out DIR`:
// registered extrinsics against Vicon, as the paper's tables, with the
// hand-eye correction the paper left out (evaluation/evaluation.h).
//
// Settings, each from the first place that has it: the flags, the rig file
// (--rig), the sequence's GroundTruth/cameras.yaml (synthetic rigs), the
// LiFMCR defaults (80 Hz, a trigger every 8 Vicon frames from Vicon frame 1,
// helical rotations in rad, left-handed with y mirrored, cameras 40398678 =
// cam0 (reference) and 40398673 = cam2, plate object "plate").

#include "apps/commands.h"
#include "evaluation/evaluation_plots.h"
#include "evaluation/evaluation_report.h"
#include "apps/revision.h"
#include "config/frames.h"
#include "config/rig_config.h"
#include "config/text_escape.h"
#include "registration/map/aruco_corners.h"
#include "evaluation/evaluation.h"
#include "evaluation/evaluation_inputs.h"
#include "registration/features/intrinsics_yaml.h"
#include "evaluation/plate_alignment.h"
#include "registration/map/poses_csv.h"
#include "evaluation/vicon_ground_truth.h"
#include "replay/csv_tokenizer.h"
#include "replay/layout.h"
#include "replay/sequence.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "replay/vsk.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace lifmcr::apps {
namespace {

namespace fs = std::filesystem;

constexpr int kExitOk = 0;
constexpr int kExitFailed = 1;
constexpr int kExitUsage = 2;
constexpr int kExitNoHandEye = 3;

struct EvaluateArgs {
  std::string sequence;
  std::vector<std::string> registration;
  std::string out;
  std::string hand_eye = "estimate";
  std::string split = "half";
  // --split sequence: the sequence and registration the offsets are estimated on.
  std::string hand_eye_from;
  std::vector<std::string> hand_eye_registration;
  bool print_table = true;
  std::string reference;
  std::vector<std::string> subjects;  // SERIAL=OBJECT
  std::string rig;
  std::optional<std::string> rotation, handedness;
  std::optional<int> trigger_divider;
  std::optional<std::int64_t> first_trigger_vicon_frame, first_frame;
  double vicon_frame_offset = 0;
  std::optional<double> vicon_rate;
  std::string vicon_csv, vsk, plate_subject, plate_aruco;
  std::string reference_poses;
  std::string map;  // lifmcr calibrate's output: ArUco corners, intrinsics, poses
  double min_rotation_spread_deg = 1.0;
  std::string plate_correction = "held";  // held | free: the joint map-frame hand-eye's Z
  bool no_plots = false;
  bool quiet = false;
  std::string command_line;
};

class Progress {
 public:
  explicit Progress(bool quiet) : quiet_(quiet) {}
  void operator()(const std::string& line) const {
    if (!quiet_) std::cerr << "evaluate: " << line << "\n";
  }

 private:
  bool quiet_;
};

std::string FormatMm(double mm) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f", mm);
  return text;
}

int Fail(const std::string& message, int code = kExitFailed) {
  std::cerr << "lifmcr evaluate: " << EscapeText(message) << "\n";
  return code;
}

Status WriteText(const fs::path& path, const std::string& text) {
  std::error_code ec;
  fs::create_directories(path.parent_path(), ec);
  std::ofstream out(path, std::ios::binary);
  out << text;
  out.close();
  if (!out) return MakeErrorAt(path.string(), "/", "cannot write the file");
  return Status::Ok();
}

// ArUco centres in the map frame: a CSV with a header "id,x_mm,y_mm,z_mm".
Expected<std::array<Eigen::Vector3d, 4>> ReadArucoCenters(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return MakeErrorAt(path.string(), "/", "cannot open the file");
  std::ostringstream text;
  text << in.rdbuf();
  Expected<CsvDocument> doc = TokenizeCsv(text.str(), path.string());
  if (!doc) return doc.error();
  std::array<Eigen::Vector3d, 4> centers;
  std::array<bool, 4> seen{};
  for (std::size_t r = 1; r < doc->rows.size(); ++r) {
    const CsvRow& row = doc->rows[r];
    if (row.IsBlank()) continue;
    if (row.fields.size() < 4)
      return MakeError(path.string(), row.line, 0, "expected id,x_mm,y_mm,z_mm");
    double v[4];
    for (int k = 0; k < 4; ++k) {
      const std::string& t = row.fields[k].text;
      const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v[k]);
      if (ec != std::errc() || p != t.data() + t.size())
        return MakeError(path.string(), row.line, row.fields[k].column,
                         "expected a number, got '" + t + "'");
    }
    const int id = static_cast<int>(v[0]);
    if (id < 0 || id > 3 || v[0] != id)
      return MakeError(path.string(), row.line, 1, "the plate's ArUco ids are 0..3");
    centers[id] = Eigen::Vector3d(v[1], v[2], v[3]);
    seen[id] = true;
  }
  for (int id = 0; id < 4; ++id)
    if (!seen[id])
      return MakeErrorAt(path.string(), "/", "no centre for ArUco id " + std::to_string(id));
  return centers;
}

int RunEvaluate(const EvaluateArgs& args);

// The ArUco centres in the map of `lifmcr calibrate` (its output folder):
// the corners it detected, triangulated with its poses and intrinsics.
Expected<registration::ArucoCentersInMap> ArucoCentersOfMap(const fs::path& map,
                                                            const std::string& reference) {
  Expected<std::vector<registration::ArucoCornerObservation>> corners =
      registration::ReadArucoCornersCsv(map / "aruco_corners.csv");
  if (!corners) return corners.error();
  Expected<registration::CameraCalibration> k =
      registration::ReadCameraCalibration(map / "intrinsics.yaml", reference);
  if (!k) return k.error();
  const fs::path poses_path = map / ("poses_" + reference + ".csv");
  Expected<std::vector<registration::FramePose>> poses = registration::ReadPosesCsv(poses_path);
  if (!poses) return poses.error();
  std::map<std::int64_t, Pose> w0_from_c0;
  for (const registration::FramePose& p : *poses) w0_from_c0[p.frame] = p.world_from_cam;
  Expected<registration::ArucoCentersInMap> centers = registration::TriangulateArucoCenters(
      *corners, w0_from_c0, processing::CameraModel(k->intrinsics));
  if (!centers) return Error{(map / "aruco_corners.csv").string() + ": " + centers.error().message};
  return centers;
}

// --split sequence: the offsets estimated on another sequence of the same rig
// (all its frames, its own evaluation written into OUT/hand_eye_source/),
// then this sequence evaluated with them, so no corrected figure is fit to
// the frames it corrects.
int RunSplitBySequence(const EvaluateArgs& args) {
  const Progress progress(args.quiet);
  if (args.hand_eye_from.empty() || args.hand_eye_registration.empty())
    return Fail("--split sequence needs --hand-eye-from SEQ_DIR (another sequence of the rig) and "
                "--hand-eye-registration FILE (its registration.csv)",
                kExitUsage);
  if (args.hand_eye != "estimate")
    return Fail("--split sequence estimates the offsets on --hand-eye-from; --hand-eye " +
                    args.hand_eye + " is another source of them",
                kExitUsage);
  if (fs::weakly_canonical(args.hand_eye_from) == fs::weakly_canonical(args.sequence))
    return Fail("--hand-eye-from names the evaluated sequence itself: the split would fit the "
                "offsets to the frames they correct",
                kExitUsage);
  // Settings of the rig carry over; those of one sequence do not.
  EvaluateArgs source = args;
  source.sequence = args.hand_eye_from;
  source.registration = args.hand_eye_registration;
  source.out = (fs::path(args.out) / "hand_eye_source").string();
  source.split = "none";
  source.hand_eye_from.clear();
  source.hand_eye_registration.clear();
  source.vicon_csv.clear();
  source.first_frame.reset();
  source.vicon_frame_offset = 0;
  source.reference_poses.clear();
  source.plate_aruco.clear();
  source.print_table = false;
  source.command_line = args.command_line + " (offsets estimated on " + args.hand_eye_from + ")";
  progress("split sequence: estimating the hand-eye offsets on " + args.hand_eye_from +
           " (all its frames; its evaluation goes into " + source.out + ")");
  const int code = RunEvaluate(source);
  const fs::path offsets = fs::path(source.out) / "hand_eye.yaml";
  if (code != kExitOk || !fs::exists(offsets))
    return Fail("--hand-eye-from " + args.hand_eye_from +
                    ": the offsets could not be estimated there (exit " + std::to_string(code) +
                    "; " + (fs::path(source.out) / "evaluation.md").string() + " says why)",
                code == kExitNoHandEye ? kExitNoHandEye : kExitFailed);
  EvaluateArgs target = args;
  target.hand_eye = offsets.string();
  progress("split sequence: evaluating " + args.sequence + " with the offsets of " + offsets.string());
  return RunEvaluate(target);
}

int RunEvaluate(const EvaluateArgs& args) {
  if (args.split == "sequence" && args.hand_eye == "estimate") return RunSplitBySequence(args);
  if (args.split != "sequence" && (!args.hand_eye_from.empty() || !args.hand_eye_registration.empty()))
    return Fail("--hand-eye-from and --hand-eye-registration go with --split sequence", kExitUsage);
  const Progress progress(args.quiet);
  if (!args.map.empty() && !args.plate_aruco.empty())
    return Fail("--map and --plate-aruco both give the ArUco centres in the map: give one",
                kExitUsage);
  EvaluationRun run;
  run.sequence_dir = args.sequence;
  run.git_revision = GitRevision();
  run.command_line = args.command_line;
  run.hand_eye_mode = args.hand_eye;
  run.split = args.split;
  if (args.split == "sequence") run.hand_eye_from = args.hand_eye_from;

  Expected<SequenceLayout> layout = DiscoverSequence(args.sequence);
  if (!layout) return Fail(layout.error().message);
  run.sequence_name = layout->scene + "/" + layout->name;

  // Defaults, then cameras.yaml, then the rig file, then the flags.
  std::map<std::string, std::string> subject{{"40398678", "cam0"}, {"40398673", "cam2"}};
  std::string reference = "40398678";
  std::string rotation = "helical_rad", handedness = "left_flip_y", plate_subject = "plate";
  FrameAssociationOptions association;
  double rate_hz = 80;
  fs::path vsk_path;
  const fs::path cameras_yaml = layout::CamerasYamlPath(args.sequence);
  if (fs::exists(cameras_yaml)) {
    Expected<SynthGroundTruthInfo> info = ReadCamerasYaml(cameras_yaml);
    if (!info) return Fail(info.error().message);
    if (!info->vicon_subject.empty()) subject = info->vicon_subject;
    if (!info->serials.empty()) reference = info->serials.front();
    if (info->rotation) rotation = *info->rotation;
    if (info->handedness) handedness = *info->handedness;
    if (info->trigger_divider) association.trigger_divider = *info->trigger_divider;
    if (info->first_trigger_frame)
      association.vicon_frame_of_first_trigger = *info->first_trigger_frame;
    if (info->rate_hz) rate_hz = *info->rate_hz;
    if (info->plate_subject) plate_subject = *info->plate_subject;
    progress("settings from " + cameras_yaml.string());
  }
  PlateTemplate plate_template = DefaultPlateTemplate();
  if (fs::exists(cameras_yaml)) {
    Expected<SynthGroundTruthInfo> info = ReadCamerasYaml(cameras_yaml);
    if (info && info->plate) plate_template = *info->plate;
  }
  if (!args.rig.empty()) {
    Expected<RigConfig> rig = LoadRigConfig(args.rig);
    if (!rig) return Fail(rig.error().message);
    subject.clear();
    for (const CameraConfig& c : rig->cameras)
      if (!c.vicon_object.empty()) subject[c.serial] = c.vicon_object;
    if (rig->ReferenceIndex() >= 0) reference = rig->cameras[rig->ReferenceIndex()].serial;
    rotation = std::string(ToString(rig->vicon.rotation));
    handedness = std::string(ToString(rig->vicon.handedness));
    association.trigger_divider = rig->vicon.trigger_divider;
    rate_hz = rig->vicon.rate_hz;
    plate_subject = rig->vicon.plate_object;
    if (!rig->vicon.vsk.empty()) vsk_path = rig->vicon.vsk;
  }
  for (const std::string& pair : args.subjects) {
    const auto eq = pair.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == pair.size())
      return Fail("--subject: expected SERIAL=OBJECT, got '" + pair + "'", kExitUsage);
    subject[pair.substr(0, eq)] = pair.substr(eq + 1);
  }
  if (!args.reference.empty()) reference = args.reference;
  if (args.rotation) rotation = *args.rotation;
  if (args.handedness) handedness = *args.handedness;
  if (args.trigger_divider) association.trigger_divider = *args.trigger_divider;
  if (args.first_trigger_vicon_frame)
    association.vicon_frame_of_first_trigger = *args.first_trigger_vicon_frame;
  if (args.vicon_rate) rate_hz = *args.vicon_rate;
  if (!args.plate_subject.empty()) plate_subject = args.plate_subject;
  association.vicon_frame_offset = args.vicon_frame_offset;
  // Image frames are numbered from the first frame any camera kept
  // (replay/sequence.h); 0 when the sequence holds no frames (poses only).
  association.first_frame = 0;
  if (!layout->cameras.empty()) {
    association.first_frame = std::numeric_limits<std::int64_t>::max();
    for (const CameraFolder& c : layout->cameras)
      if (!c.frames.empty()) association.first_frame = std::min(association.first_frame, c.frames.front());
    if (association.first_frame == std::numeric_limits<std::int64_t>::max()) association.first_frame = 0;
  }
  if (args.first_frame) association.first_frame = *args.first_frame;
  if (Status s = association.Check(); !s) return Fail(s.error().message, kExitUsage);
  if (!(rate_hz > 0)) return Fail("--vicon-rate must be > 0", kExitUsage);
  ViconPoseOptions pose_options;
  // Both names were checked (flags by CLI11, files by their loaders).
  if (auto r = ParseRotationRepresentation(rotation)) pose_options.rotation = *r;
  else return Fail("unknown rotation representation '" + rotation + "'", kExitUsage);
  if (auto h = ParseHandedness(handedness)) pose_options.handedness = *h;
  else return Fail("unknown handedness '" + handedness + "'", kExitUsage);
  run.rotation = rotation;
  run.handedness = handedness;
  run.rate_hz = rate_hz;
  run.association = association;
  run.reference_serial = reference;

  // Registration tables: (method, camera) -> c0_from_cx, and the failures.
  struct Registered {
    FramePoses poses;
    std::size_t failed = 0;
    std::map<std::string, std::size_t> reasons;
  };
  std::map<std::pair<std::string, std::string>, Registered> registered;
  std::vector<std::string> method_order;
  for (const std::string& file : args.registration) {
    progress("reading " + file);
    Expected<RegistrationTable> table = ReadRegistrationCsv(file);
    if (!table) return Fail(table.error().message);
    run.registration_files.push_back(file);
    for (const RegistrationRow& row : table->rows) {
      if (row.camera == reference) continue;  // c0_from_c0 is the identity
      Registered& r = registered[{row.method, row.camera}];
      if (std::find(method_order.begin(), method_order.end(), row.method) == method_order.end())
        method_order.push_back(row.method);
      if (row.status == "ok") {
        if (!r.poses.emplace(row.frame, row.c0_from_cx).second)
          return Fail(file + ":" + std::to_string(row.line) + ": frame " +
                      std::to_string(row.frame) + " of camera " + row.camera + " (" + row.method +
                      ") registered twice");
      } else {
        ++r.failed;
        ++r.reasons[row.status];
      }
    }
  }
  if (registered.empty())
    return Fail("no registration of a camera other than the reference " + reference +
                " in the registration files");

  // Camera 0's poses in the map (lifmcr calibrate's poses_<serial>.csv).
  FramePoses w0_from_c0;
  if (!args.reference_poses.empty()) {
    progress("reading " + args.reference_poses);
    if (fs::path(args.reference_poses).extension() == ".tum") {
      Expected<FramePoses> poses = ReadFrameTum(args.reference_poses);
      if (!poses) return Fail(poses.error().message);
      w0_from_c0 = std::move(*poses);
    } else {
      auto poses = registration::ReadPosesCsv(args.reference_poses);
      if (!poses) return Fail(poses.error().message);
      for (const registration::FramePose& p : *poses) w0_from_c0[p.frame] = p.world_from_cam;
    }
  }

  // Vicon export and ground truth per camera.
  fs::path vicon_csv = args.vicon_csv;
  if (vicon_csv.empty()) {
    if (layout->vicon_csvs.empty())
      return Fail(args.sequence + ": no Vicon/sequence_XX.csv (give --vicon-csv)");
    vicon_csv = layout->vicon_csvs.front();
    if (layout->vicon_csvs.size() > 1)
      run.warnings.push_back("several Vicon CSVs; used " + vicon_csv.string());
  }
  run.vicon_csv = vicon_csv;
  progress("reading " + vicon_csv.string());
  Expected<ViconCsv> csv = ReadViconCsv(vicon_csv);
  if (!csv) return Fail(csv.error().message);

  std::set<std::string> serials{reference};
  for (const auto& [key, r] : registered) serials.insert(key.second);
  std::vector<std::string> ordered{reference};
  for (const std::string& s : serials)
    if (s != reference) ordered.push_back(s);
  std::map<std::string, std::vector<ViconPoseSample>> samples;
  for (const std::string& serial : ordered) {
    const auto it = subject.find(serial);
    if (it == subject.end())
      return Fail("camera " + serial + " has no Vicon object: give --subject " + serial +
                  "=OBJECT (or a rig file, or GroundTruth/cameras.yaml)");
    Expected<std::vector<ViconPoseSample>> s = ExtractSubjectPoses(*csv, it->second, pose_options);
    if (!s) return Fail(s.error().message);
    samples[serial] = std::move(*s);
    CameraTruth truth;
    truth.serial = serial;
    truth.subject = it->second;
    std::set<std::int64_t> frames;
    for (const auto& [key, r] : registered) {
      if (serial != reference && key.second != serial) continue;
      for (const auto& [f, p] : r.poses) frames.insert(f);
    }
    if (serial == reference)
      for (const auto& [f, p] : w0_from_c0) frames.insert(f);
    const std::vector<std::int64_t> frame_list(frames.begin(), frames.end());
    AssociatedPoses associated = AssociateFrames(samples[serial], frame_list, association);
    truth.asked = frame_list.size();
    truth.untracked = associated.untracked;
    truth.vicon_from_marker = std::move(associated.vicon_from_marker);
    const fs::path true_offset = layout::MarkerFromCamCsvPath(args.sequence, serial);
    if (fs::exists(true_offset)) {
      Expected<Pose> x = ReadMarkerFromCamCsv(true_offset);
      if (!x) return Fail(x.error().message);
      truth.true_marker_from_cam = *x;
    }
    // Vicon's tracking of the frames this camera has a pose for; a camera
    // with none (nothing registered) says so instead of "0/0".
    progress("camera " + serial + " (Vicon " + truth.subject + "): " +
             (truth.asked == 0
                  ? std::string("no registered frame to evaluate")
                  : std::to_string(truth.asked - truth.untracked.size()) + "/" +
                        std::to_string(truth.asked) + " of its registered frames tracked by Vicon"));
    run.cameras.push_back(std::move(truth));
  }

  // The plate alignment.
  if (vsk_path.empty()) vsk_path = args.vsk;
  if (vsk_path.empty()) {
    if (const auto calibration = FindCalibrationFor(args.sequence))
      vsk_path = layout::VskPath(*calibration);
  }
  run.vsk = vsk_path;
  {
    std::vector<std::string> subjects = PoseSubjects(*csv);
    const bool has_plate =
        std::any_of(subjects.begin(), subjects.end(), [&](const std::string& s) {
          return s == plate_subject || SubjectOf(s) == plate_subject;
        });
    if (!has_plate) {
      run.plate_note = "no Vicon object '" + plate_subject + "' in the export";
    } else if (vsk_path.empty() || !fs::exists(vsk_path)) {
      run.plate_note = "no VSK with the plate's markers (give --vsk)";
    } else {
      Expected<Vsk> vsk = ReadVsk(vsk_path);
      Expected<std::vector<ViconPoseSample>> plate_samples =
          ExtractSubjectPoses(*csv, plate_subject, pose_options);
      if (!vsk) return Fail(vsk.error().message);
      if (!plate_samples) return Fail(plate_samples.error().message);
      std::vector<Eigen::Vector3d> markers;
      for (const VskMarker& m : VskMarkersOfSubject(*vsk, plate_subject))
        markers.push_back(m.position_mm);
      std::optional<std::array<Eigen::Vector3d, 4>> aruco;
      if (!args.map.empty()) {
        Expected<registration::ArucoCentersInMap> centers = ArucoCentersOfMap(args.map, reference);
        if (!centers) return Fail(centers.error().message);
        aruco = centers->centers_mm;
        run.aruco_source = centers->BriefReport() + ", triangulated from " +
                           (fs::path(args.map) / "aruco_corners.csv").string();
        progress(run.aruco_source);
      } else if (!args.plate_aruco.empty()) {
        Expected<std::array<Eigen::Vector3d, 4>> centers = ReadArucoCenters(args.plate_aruco);
        if (!centers) return Fail(centers.error().message);
        aruco = *centers;
      }
      Expected<PlateAlignment> plate = AlignPlate(*plate_samples, markers, plate_template, aruco);
      if (plate) {
        run.plate = *plate;
        progress(plate->BriefReport());
        if (plate->plate_moved())
          run.warnings.push_back("the plate moved during the sequence: its markers deviate by " +
                                 FormatMm(plate->plate_motion_rms_mm) + " mm RMS (largest " +
                                 FormatMm(plate->plate_motion_max_mm) +
                                 " mm) from its mean pose, which is the plate frame used");
      } else {
        run.plate_note = plate.error().message;
      }
    }
  }

  // Hand-eye offsets given from elsewhere.
  std::optional<HandEyeOffsets> given;
  if (args.hand_eye == "truth") {
    HandEyeOffsets offsets;
    for (const CameraTruth& c : run.cameras) {
      if (!c.true_marker_from_cam)
        return Fail("--hand-eye truth: no " +
                    layout::MarkerFromCamCsvPath(args.sequence, c.serial).string());
      offsets[c.serial] = *c.true_marker_from_cam;
    }
    given = offsets;
  } else if (args.hand_eye != "estimate") {
    Expected<HandEyeOffsets> offsets = ReadHandEyeYaml(args.hand_eye);
    if (!offsets) return Fail(offsets.error().message);
    for (const std::string& serial : ordered)
      if (!offsets->count(serial))
        return Fail(args.hand_eye + ": no marker_from_cam for camera " + serial);
    given = *offsets;
  }

  EvaluationOptions options;
  options.split = args.split == "none" ? HandEyeSplit::kNone : HandEyeSplit::kHalf;
  options.hand_eye.min_rotation_spread_deg = args.min_rotation_spread_deg;
  if (Status s = options.Check(); !s) return Fail(s.error().message, kExitUsage);
  const CameraTruth* reference_truth = run.Camera(reference);
  bool hand_eye_refused = false;
  for (const std::string& method : method_order) {
    for (const std::string& serial : ordered) {
      const auto it = registered.find({method, serial});
      if (it == registered.end()) continue;
      std::optional<std::pair<Pose, Pose>> offsets;
      if (given) offsets = std::pair{given->at(reference), given->at(serial)};
      progress(method + " " + serial + ": " + std::to_string(it->second.poses.size()) +
               " registered frames" + (given ? "" : ", estimating the hand-eye offsets"));
      CameraEvaluation e = EvaluateCamera(method, serial, reference, it->second.poses,
                                          reference_truth->vicon_from_marker,
                                          run.Camera(serial)->vicon_from_marker, offsets, options);
      e.failed = it->second.failed;
      e.failure_reasons = it->second.reasons;
      if (e.hand_eye) progress(method + " " + serial + ": " + e.hand_eye->BriefReport());
      run.evaluations.push_back(std::move(e));
    }
  }
  // Poses in the map frame through the plate alignment: camera 0 from the
  // reference poses, camera X as w0_from_c0 · c0_from_cx.
  if (!w0_from_c0.empty()) {
    if (!run.plate)
      return Fail("--reference-poses needs the plate alignment, which was not done: " +
                  run.plate_note);
    FramePoses vicon_from_map;
    for (const CameraTruth& c : run.cameras)
      for (const auto& [f, p] : c.vicon_from_marker) vicon_from_map[f] = run.plate->vicon_from_map();
    auto evaluate_in_map = [&](const std::string& method, const std::string& serial,
                               const FramePoses& w0_from_cam) {
      std::optional<std::pair<Pose, Pose>> offsets;
      if (given) offsets = std::pair{Pose(Pose::Identity()), given->at(serial)};
      progress("map frame: " + method + " " + serial + ": " + std::to_string(w0_from_cam.size()) +
               " poses");
      CameraEvaluation e = EvaluateCamera(method, serial, "map", w0_from_cam, vicon_from_map,
                                          run.Camera(serial)->vicon_from_marker, offsets, options);
      if (e.hand_eye) progress("map frame: " + method + " " + serial + ": " + e.hand_eye->BriefReport());
      run.map_evaluations.push_back(std::move(e));
    };
    evaluate_in_map("reference", reference, w0_from_c0);
    for (const std::string& method : method_order)
      for (const std::string& serial : ordered) {
        const auto it = registered.find({method, serial});
        if (it == registered.end()) continue;
        FramePoses w0_from_cx;
        for (const auto& [f, b] : it->second.poses) {
          const auto c0 = w0_from_c0.find(f);
          if (c0 != w0_from_c0.end()) w0_from_cx.emplace(f, Pose(c0->second * b));
        }
        evaluate_in_map(method, serial, w0_from_cx);
      }
  }

  // The joint map-frame hand-eye per method: camera 0 and the method's
  // cameras X with one plate correction Z (evaluation/evaluation.h). It
  // corrects the map-frame evaluations, and the pairs whose c0_from_cx
  // could not determine its own offsets (the cameras turn together). The
  // reference's map-frame evaluation keeps the first method's joint fit.
  // Offsets given (--hand-eye truth|FILE) are used as given.
  if (!run.map_evaluations.empty() && !given) {
    CameraEvaluation* reference_in_map = nullptr;
    for (CameraEvaluation& m : run.map_evaluations)
      if (m.method == "reference") reference_in_map = &m;
    // The map-frame evaluations exist only with a plate alignment.
    std::optional<HandEyePrior> z_prior;
    if (args.plate_correction == "held") {
      z_prior = PlateCorrectionPrior(*run.plate, plate_template);
      char line[160];
      std::snprintf(line, sizeof(line),
                    "the plate correction Z held at identity within %.2f mm / %.3f deg (the plate "
                    "alignment's residuals)",
                    z_prior->translation_sd_mm, z_prior->rotation_sd_deg);
      run.z_prior_note = line;
    } else {
      run.z_prior_note = "the plate correction Z free (--plate-correction free)";
    }
    progress("map frame: " + run.z_prior_note);
    for (std::size_t mi = 0; mi < method_order.size() && reference_in_map; ++mi) {
      const std::string& method = method_order[mi];
      CameraEvaluation reference_copy = *reference_in_map;
      std::vector<CameraEvaluation*> in_map{mi == 0 ? reference_in_map : &reference_copy};
      std::vector<CameraEvaluation*> pairs;
      for (CameraEvaluation& m : run.map_evaluations)
        if (m.method == method) in_map.push_back(&m);
      for (CameraEvaluation& e : run.evaluations)
        if (e.method == method && !e.has_correction()) pairs.push_back(&e);
      std::string why;
      if (CorrectJointlyInTheMapFrame(in_map, pairs, options, z_prior, &why)) {
        progress("map frame: " + method + ": " + in_map.front()->correction_note);
        for (CameraEvaluation* m : in_map)
          if (m->hand_eye)
            progress("map frame: " + m->method + " " + m->serial + ": " + m->hand_eye->BriefReport());
      } else {
        progress("map frame: " + method + ": " + why);
        for (CameraEvaluation* e : pairs) e->correction_note += "; nor jointly in the map frame: " + why;
      }
    }
  }
  for (const CameraEvaluation& e : run.evaluations) {
    if (e.has_correction()) continue;
    hand_eye_refused = true;
    std::cerr << "lifmcr evaluate: " << e.method << " " << e.serial
              << ": no hand-eye correction: " << e.correction_note << "\n";
  }

  for (std::size_t a = 0; a < method_order.size(); ++a)
    for (std::size_t b = a + 1; b < method_order.size(); ++b)
      for (const std::string& serial : ordered) {
        const auto pa = registered.find({method_order[a], serial});
        const auto pb = registered.find({method_order[b], serial});
        if (pa == registered.end() || pb == registered.end()) continue;
        run.differences.push_back(CompareMethods(method_order[a], pa->second.poses, method_order[b],
                                                 pb->second.poses, serial));
      }

  // Outputs.
  const fs::path out = args.out;
  std::vector<std::string> files;
  auto write = [&](const std::string& name, const std::string& text) -> Status {
    files.push_back(name);
    return WriteText(out / name, text);
  };
  HandEyeOffsets estimated;
  for (const CameraEvaluation& e : run.evaluations) {
    if (e.correction_source != "estimated") continue;
    // The first method's estimate of each camera; the others are in the report.
    estimated.emplace(e.serial, e.marker_from_cam);
    estimated.emplace(e.reference_serial, e.marker_from_cam_reference);
  }
  // Cameras whose pair could not determine them (a rigid rig): their
  // map-frame estimate, so that `--hand-eye FILE` and `--split sequence`
  // can use them on another sequence.
  for (const CameraEvaluation& e : run.map_evaluations)
    if (e.correction_source == "estimated" || e.correction_source == "joint map frame")
      estimated.emplace(e.serial, e.marker_from_cam);
  if (!estimated.empty())
    if (Status s = write("hand_eye.yaml",
                         FormatHandEyeYaml(estimated, "hand-eye offsets estimated by lifmcr "
                                                      "evaluate on " +
                                                          run.sequence_name + " (" +
                                                          method_order.front() + ")"));
        !s)
      return Fail(s.error().message);
  for (const CameraTruth& c : run.cameras) {
    if (c.serial == reference) continue;
    FramePoses truth;
    const CameraTruth& r = *reference_truth;
    for (const auto& [f, m] : c.vicon_from_marker) {
      const auto m0 = r.vicon_from_marker.find(f);
      if (m0 != r.vicon_from_marker.end()) truth.emplace(f, Pose(m0->second.inverse() * m));
    }
    if (Status s = write("tum/" + c.serial + "_c0_from_cx_vicon.txt", FormatTum(run, truth)); !s)
      return Fail(s.error().message);
  }
  for (const CameraEvaluation& e : run.evaluations) {
    const std::string stem = "tum/" + e.method + "_" + e.serial + "_c0_from_cx";
    if (Status s = write(stem + ".txt", FormatTum(run, e.estimate)); !s) return Fail(s.error().message);
    if (e.has_correction())
      if (Status s = write(stem + "_vicon_corrected.txt", FormatTum(run, e.truth_corrected)); !s)
        return Fail(s.error().message);
  }
  if (!args.no_plots) {
    progress("drawing plots");
    std::error_code ec;
    fs::create_directories(out / "plots", ec);
    files.push_back("plots/trajectories_top.png");
    if (Status s = PlotTrajectoriesTop(run, out / files.back()); !s) return Fail(s.error().message);
    for (const CameraEvaluation& e : run.map_evaluations) {
      files.push_back("plots/map_" + e.method + "_" + e.serial + "_errors.png");
      if (Status s = PlotErrorsOverFrames(e, out / files.back()); !s) return Fail(s.error().message);
      files.push_back("plots/map_" + e.method + "_" + e.serial + "_axis_histograms.png");
      if (Status s = PlotAxisHistograms(e, out / files.back()); !s) return Fail(s.error().message);
    }
    for (const CameraEvaluation& e : run.evaluations) {
      files.push_back("plots/" + e.method + "_" + e.serial + "_errors.png");
      if (Status s = PlotErrorsOverFrames(e, out / files.back()); !s) return Fail(s.error().message);
      files.push_back("plots/" + e.method + "_" + e.serial + "_axis_histograms.png");
      if (Status s = PlotAxisHistograms(e, out / files.back()); !s) return Fail(s.error().message);
    }
  }
  std::vector<std::string> listed = files;
  listed.push_back("evaluation.json");
  if (Status s = WriteText(out / "evaluation.md", FormatEvaluationMarkdown(run, listed)); !s)
    return Fail(s.error().message);
  listed.back() = "evaluation.md";
  if (Status s = WriteText(out / "evaluation.json", FormatEvaluationJson(run, listed)); !s)
    return Fail(s.error().message);
  if (args.print_table) {
    std::cout << FormatSummaryTable(run);
    std::cout << "evaluation: " << (out / "evaluation.md").string() << ", plots in "
              << (out / "plots").string() << "\n";
  }
  return hand_eye_refused && args.hand_eye == "estimate" ? kExitNoHandEye : kExitOk;
}

}  // namespace

CommandRun AddEvaluateCommand(CLI::App& app) {
  auto a = std::make_shared<EvaluateArgs>();
  app.description(
      "Evaluate registered extrinsics c0_from_cx against Vicon, as the paper's tables, with the "
      "hand-eye correction.");
  // What it reads, writes and returns comes last, after the options, as in
  // every subcommand's --help.
  app.footer(
      "Reads: SEQ_DIR/Vicon/sequence_XX.csv, Calibration/03_Vicon/Object.vsk (plate alignment), "
      "SEQ_DIR/GroundTruth/ when present (synthetic rigs: settings, true offsets), the "
      "registration CSVs (lifmcr register, or lifmcr replay --extrinsics-csv), with --map "
      "CAL_DIR its aruco_corners.csv, intrinsics.yaml and poses_<serial>.csv (lifmcr calibrate), "
      "with --split sequence the other sequence and its registration CSVs.\n"
      "Writes: into --out, evaluation.md, evaluation.json, hand_eye.yaml (estimated offsets), "
      "hand_eye_source/ (--split sequence: the other sequence's evaluation), "
      "tum/*.txt (TUM trajectories: timestamp tx ty tz qx qy qz qw, mm), plots/*.png.\n"
      "Metrics: evo/TUM APE and RPE (delta = 1 frame), translation mm, rotation deg, per axis in "
      "the camera frame.\n"
      "Exit codes: 0 written; 1 an input could not be read or nothing could be evaluated; 2 usage "
      "error; 3 written, but the hand-eye offsets could not be estimated for some camera (the "
      "report says why, e.g. rotations about one axis only).");
  app.add_option("SEQ_DIR", a->sequence, "Sequence folder (SCENE/SEQ)")->required();
  app.add_option("--registration", a->registration,
                 "registration.csv of lifmcr register; repeat for several methods")
      ->required();
  app.add_option("--out", a->out, "Folder to write the evaluation into (created)")->required();
  app.add_option("--hand-eye", a->hand_eye,
                 "estimate (default): from the registered poses and Vicon; truth: "
                 "GroundTruth/marker_from_cam_*.csv; or a hand_eye.yaml written by an earlier "
                 "evaluation (e.g. of another sequence: a split by sequence)");
  app.add_option("--split", a->split,
                 "half (default): estimate the offsets on the first half of the frames, evaluate "
                 "on the second, and the other way round; sequence: estimate them on another "
                 "sequence of the rig (--hand-eye-from, --hand-eye-registration), evaluate on "
                 "this one; none: both on all frames (fit to themselves)")
      ->check(CLI::IsMember({"half", "sequence", "none"}));
  app.add_option("--hand-eye-from", a->hand_eye_from,
                 "With --split sequence: the sequence folder the offsets are estimated on")
      ->check(CLI::ExistingDirectory);
  app.add_option("--hand-eye-registration", a->hand_eye_registration,
                 "With --split sequence: that sequence's registration.csv (repeat per method)")
      ->check(CLI::ExistingFile);
  app.add_option("--reference", a->reference, "Serial of camera 0 (default: from the rig)");
  app.add_option("--subject", a->subjects, "SERIAL=OBJECT: the Vicon object of a camera");
  app.add_option("--rig", a->rig, "Rig file: Vicon objects, reference, Vicon settings")
      ->check(CLI::ExistingFile);
  app.add_option("--rotation", a->rotation, "Vicon RX RY RZ: " + RotationRepresentationNames())
      ->check([](const std::string& v) {
        return ParseRotationRepresentation(v) ? std::string() : "expected " + RotationRepresentationNames();
      });
  app.add_option("--handedness", a->handedness, "Vicon frame: right|left_flip_x|left_flip_y|left_flip_z")
      ->check([](const std::string& v) {
        return ParseHandedness(v) ? std::string() : std::string("expected right|left_flip_x|left_flip_y|left_flip_z");
      });
  app.add_option("--trigger-divider", a->trigger_divider, "Vicon frames per camera trigger (8)");
  app.add_option("--first-trigger-vicon-frame", a->first_trigger_vicon_frame,
                 "Vicon frame of the first trigger (1)");
  app.add_option("--first-frame", a->first_frame,
                 "Image frame number of the first trigger (default: the first frame on disk, else 0)");
  app.add_option("--vicon-frame-offset", a->vicon_frame_offset,
                 "Added to each trigger's Vicon frame (fractional: SE(3) interpolation)");
  app.add_option("--vicon-rate", a->vicon_rate, "Vicon frame rate in Hz (80)");
  app.add_option("--vicon-csv", a->vicon_csv, "Vicon export (default: SEQ_DIR/Vicon/sequence_XX.csv)");
  app.add_option("--vsk", a->vsk, "Vicon object model with the plate's markers");
  app.add_option("--plate-subject", a->plate_subject, "Vicon object of the marker plate (plate)");
  app.add_option("--map", a->map,
                 "lifmcr calibrate's output folder: the plate's ArUco corners it detected "
                 "(aruco_corners.csv), triangulated with its poses and intrinsics, give the plate "
                 "alignment's map side (instead of --plate-aruco)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--plate-aruco", a->plate_aruco,
                 "CSV id,x_mm,y_mm,z_mm: the plate's ArUco centres in the map frame (default: the "
                 "map frame is the plate frame)")
      ->check(CLI::ExistingFile);
  app.add_option("--reference-poses", a->reference_poses,
                 "Camera 0's poses in the map (w0_from_c0: lifmcr calibrate's poses_<serial>.csv, "
                 "or lifmcr register's trajectory_<serial>_<method>.tum): "
                 "adds every camera's poses in the map frame against Vicon through the plate "
                 "alignment (the paper's absolute protocol)")
      ->check(CLI::ExistingFile);
  app.add_option("--plate-correction", a->plate_correction,
                 "held (default): the joint map-frame hand-eye holds its plate correction Z at "
                 "the plate alignment's, within its residuals; free: Z from the motions alone "
                 "(long sequences turning tens of degrees; a short one trades Z against the "
                 "offsets by several mm)")
      ->check(CLI::IsMember({"held", "free"}))
      ->capture_default_str();
  app.add_option("--min-rotation-spread", a->min_rotation_spread_deg,
                 "Refuse the hand-eye below this rotation spread about a second axis, deg (1)");
  app.add_flag("--no-plots", a->no_plots, "Write no PNG plots");
  app.add_flag("--quiet", a->quiet, "No progress on stderr");
  return [a, &app] {
    a->command_line = "lifmcr evaluate";
    for (const std::string& r : a->registration) a->command_line += " --registration " + r;
    a->command_line += " " + a->sequence + " --out " + a->out + " --hand-eye " + a->hand_eye +
                       " --split " + a->split;
    if (!a->hand_eye_from.empty()) a->command_line += " --hand-eye-from " + a->hand_eye_from;
    for (const std::string& r : a->hand_eye_registration)
      a->command_line += " --hand-eye-registration " + r;
    (void)app;
    return RunEvaluate(*a);
  };
}

}  // namespace lifmcr::apps
