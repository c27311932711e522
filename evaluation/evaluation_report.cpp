#include "evaluation/evaluation_report.h"

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

namespace lifmcr {
namespace {

constexpr double kDeg = M_PI / 180.0;

std::string F(double v, int digits = 2) {
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", digits, v);
  return text;
}

nlohmann::json StatsJson(const ErrorStats& s) {
  return {{"count", s.count}, {"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median},
          {"sd", s.sd},       {"min", s.min},   {"max", s.max}};
}

nlohmann::json SummaryJson(const ErrorSummary& s) {
  nlohmann::json j;
  j["translation_mm"] = StatsJson(s.translation_mm);
  j["rotation_deg"] = StatsJson(s.rotation_deg);
  const char* axes[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    j["translation_axis_mm"][axes[k]] = StatsJson(s.translation_axis_mm[k]);
    j["rotation_axis_deg"][axes[k]] = StatsJson(s.rotation_axis_deg[k]);
  }
  return j;
}

nlohmann::json MetricJson(const MetricSet& m) {
  return {{"ape", SummaryJson(m.ape_summary)}, {"rpe", SummaryJson(m.rpe_summary)}};
}

nlohmann::json PoseJson(const Pose& p) {
  const Eigen::Quaterniond q(p.linear());
  const Eigen::Vector3d w = RotationLog(p.linear()) / kDeg;
  return {{"tx_mm", p.translation().x()},
          {"ty_mm", p.translation().y()},
          {"tz_mm", p.translation().z()},
          {"qw", q.w()},
          {"qx", q.x()},
          {"qy", q.y()},
          {"qz", q.z()},
          {"rotation_vector_deg", {w.x(), w.y(), w.z()}}};
}

nlohmann::json VecJson(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json HandEyeJson(const HandEyeResult& h) {
  return {{"success", h.success},
          {"message", h.message},
          {"observations", h.observations},
          {"inliers", h.inliers},
          {"translation_rms_mm", h.translation_rms_mm},
          {"rotation_rms_deg", h.rotation_rms_deg},
          {"translation_sigma_mm", h.translation_sigma_mm},
          {"rotation_sigma_deg", h.rotation_sigma_deg},
          {"rotation_spread_deg", VecJson(h.rotation_spread_deg)},
          {"iterations", h.iterations},
          {"x", PoseJson(h.x)},
          {"z", PoseJson(h.z)},
          {"x_closed_form", PoseJson(h.x_closed_form)},
          {"z_closed_form", PoseJson(h.z_closed_form)},
          {"x_translation_sd_mm", VecJson(h.x_translation_sd_mm)},
          {"x_rotation_sd_deg", VecJson(h.x_rotation_sd_deg)},
          {"z_translation_sd_mm", VecJson(h.z_translation_sd_mm)},
          {"z_rotation_sd_deg", VecJson(h.z_rotation_sd_deg)}};
}

// "12.34 ± 0.56"
std::string PlusMinus(double v, double sd, int digits) { return F(v, digits) + " ± " + F(sd, digits); }

std::string Label(const CameraEvaluation& e) { return e.method + " " + e.serial; }

// Rows of the paper's tables 2 and 3 (T RMSE, T SD, R RMSE, R SD) per
// method, for one camera and one state.
struct TableRow {
  std::string name;
  std::map<std::string, const ErrorSummary*> by_method;
};

std::string PaperTable(const std::string& title, const std::vector<std::string>& methods,
                       const std::vector<TableRow>& rows) {
  std::ostringstream md;
  md << "### " << title << "\n\n| |";
  for (const std::string& m : methods) md << " " << m << " T RMSE [mm] | T SD | R RMSE [°] | R SD |";
  md << "\n|---|";
  for (std::size_t k = 0; k < methods.size(); ++k) md << "---|---|---|---|";
  md << "\n";
  for (const TableRow& row : rows) {
    md << "| " << row.name << " |";
    for (const std::string& m : methods) {
      const auto it = row.by_method.find(m);
      if (it == row.by_method.end() || it->second->translation_mm.count == 0) {
        md << " – | – | – | – |";
        continue;
      }
      const ErrorSummary& s = *it->second;
      md << " " << F(s.translation_mm.rmse) << " | " << F(s.translation_mm.sd) << " | "
         << F(s.rotation_deg.rmse) << " | " << F(s.rotation_deg.sd) << " |";
    }
    md << "\n";
  }
  md << "\n";
  return md.str();
}

void OffsetsSection(std::ostringstream& md, const EvaluationRun& run,
                    const std::vector<CameraEvaluation>& evaluations) {
  md << "| method | camera | source | tx [mm] | ty [mm] | tz [mm] | rx [°] | ry [°] | rz [°] | "
        "centre in camera frame [mm] | residual | vs truth |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const CameraEvaluation& e : evaluations) {
    const bool estimated = e.hand_eye && e.hand_eye->success;
    if (!e.has_offsets()) {
      md << "| " << e.method << " | " << e.serial << " | none | " << e.correction_note
         << " | | | | | | | | |\n";
      continue;
    }
    const std::string source = e.correction_source == "joint map frame" && estimated
                                   ? "joint map frame, all frames"
                                   : estimated ? "estimated, all frames" : e.correction_source;
    struct Item {
      std::string serial;
      Pose x;
      Eigen::Vector3d sd_t, sd_r;
    };
    std::vector<Item> items;
    items.push_back({e.serial, e.marker_from_cam,
                     estimated ? e.hand_eye->x_translation_sd_mm : Eigen::Vector3d::Zero(),
                     estimated ? e.hand_eye->x_rotation_sd_deg : Eigen::Vector3d::Zero()});
    items.push_back({e.reference_serial, e.marker_from_cam_reference,
                     estimated ? e.hand_eye->z_translation_sd_mm : Eigen::Vector3d::Zero(),
                     estimated ? e.hand_eye->z_rotation_sd_deg : Eigen::Vector3d::Zero()});
    // Offsets given, or taken from another evaluation, have no uncertainty here.
    auto pm = [&](double v, double sd, int digits) {
      return estimated ? PlusMinus(v, sd, digits) : F(v, digits);
    };
    for (const Item& it : items) {
      const Eigen::Vector3d t = it.x.translation();
      const Eigen::Vector3d w = RotationLog(it.x.linear()) / kDeg;
      const Eigen::Vector3d centre = -(it.x.linear().transpose() * t);
      md << "| " << e.method << " | " << it.serial << " | " << source << " | "
         << pm(t.x(), it.sd_t.x(), 2) << " | " << pm(t.y(), it.sd_t.y(), 2) << " | "
         << pm(t.z(), it.sd_t.z(), 2) << " | " << pm(w.x(), it.sd_r.x(), 3) << " | "
         << pm(w.y(), it.sd_r.y(), 3) << " | " << pm(w.z(), it.sd_r.z(), 3)
         << " | (" << F(centre.x(), 1) << ", " << F(centre.y(), 1) << ", " << F(centre.z(), 1)
         << ") | ";
      if (estimated)
        md << F(e.hand_eye->translation_rms_mm) << " mm / " << F(e.hand_eye->rotation_rms_deg, 3)
           << "°, " << e.hand_eye->inliers << "/" << e.hand_eye->observations << " inliers";
      md << " | ";
      const CameraTruth* truth = run.Camera(it.serial);
      if (truth && truth->true_marker_from_cam) {
        const Pose d = truth->true_marker_from_cam->inverse() * it.x;
        md << F((it.x.translation() - truth->true_marker_from_cam->translation()).norm()) << " mm / "
           << F(RotationAngleDeg(d.linear()), 3) << "°";
      }
      md << " |\n";
    }
  }
  md << "\n";
  for (const CameraEvaluation& e : evaluations) {
    if (e.hand_eye) md << "- " << Label(e) << ", all frames: " << e.hand_eye->BriefReport() << "\n";
    for (std::size_t k = 0; k < e.folds.size(); ++k)
      md << "- " << Label(e) << ", " << (k == 0 ? "first" : "second")
         << " half (corrects the other): " << e.folds[k].BriefReport() << "\n";
    if (!e.correction_note.empty() && e.correction_source != "none")
      md << "- " << Label(e) << ": " << e.correction_note << "\n";
  }
  md << "\n";

}

void TablesSection(std::ostringstream& md, const EvaluationRun& run,
                   const std::vector<CameraEvaluation>& evaluations, const std::string& suffix) {
  std::vector<std::string> methods;
  std::set<std::string> serials;
  for (const CameraEvaluation& e : evaluations) {
    if (std::find(methods.begin(), methods.end(), e.method) == methods.end())
      methods.push_back(e.method);
    serials.insert(e.serial);
  }
  for (const bool relative : {true, false}) {
    std::vector<TableRow> rows;
    for (const std::string& serial : serials) {
      TableRow plain{serial + ", no correction (the paper's protocol)", {}};
      TableRow corrected{serial + ", hand-eye corrected", {}};
      for (const CameraEvaluation& e : evaluations) {
        if (e.serial != serial) continue;
        plain.by_method[e.method] =
            relative ? &e.uncorrected.rpe_summary : &e.uncorrected.ape_summary;
        if (e.has_correction())
          corrected.by_method[e.method] =
              relative ? &e.corrected.rpe_summary : &e.corrected.ape_summary;
      }
      rows.push_back(plain);
      rows.push_back(corrected);
    }
    md << "## " << (relative ? "Relative errors (consecutive frames; the paper's Table 2)"
                             : "Absolute errors (the paper's Table 3)")
       << suffix << "\n\n";
    md << PaperTable(run.sequence_name, methods, rows);
  }

  md << "## Absolute errors per camera axis (the supplementary's table)" << suffix << "\n\n"
        "Signed components of t(E) and of the rotation vector of R(E), in the camera frame "
        "(x right, y down, z along the optical axis): RMSE, mean, SD.\n\n";
  for (const CameraEvaluation& e : evaluations) {
    md << "### " << Label(e) << "\n\n| axis | no correction RMSE | mean | SD | hand-eye RMSE | "
                                 "mean | SD |\n|---|---|---|---|---|---|---|\n";
    const char* names[3] = {"x", "y", "z"};
    for (int rot = 0; rot < 2; ++rot) {
      for (int k = 0; k < 3; ++k) {
        const ErrorStats& u = rot ? e.uncorrected.ape_summary.rotation_axis_deg[k]
                                  : e.uncorrected.ape_summary.translation_axis_mm[k];
        md << "| " << names[k] << (rot ? " [°]" : " [mm]") << " | " << F(u.rmse, rot ? 3 : 2)
           << " | " << F(u.mean, rot ? 3 : 2) << " | " << F(u.sd, rot ? 3 : 2) << " |";
        if (e.has_correction()) {
          const ErrorStats& c = rot ? e.corrected.ape_summary.rotation_axis_deg[k]
                                    : e.corrected.ape_summary.translation_axis_mm[k];
          md << " " << F(c.rmse, rot ? 3 : 2) << " | " << F(c.mean, rot ? 3 : 2) << " | "
             << F(c.sd, rot ? 3 : 2) << " |\n";
        } else {
          md << " – | – | – |\n";
        }
      }
    }
    md << "\n";
  }

}

}  // namespace

const CameraTruth* EvaluationRun::Camera(const std::string& serial) const {
  for (const CameraTruth& c : cameras)
    if (c.serial == serial) return &c;
  return nullptr;
}

std::string FormatTum(const EvaluationRun& run, const FramePoses& poses) {
  std::string text;
  for (const auto& [frame, p] : poses) {
    const Eigen::Quaterniond q(p.linear());
    const Eigen::Vector3d t = p.translation();
    char line[256];
    std::snprintf(line, sizeof(line), "%.6f %.6f %.6f %.6f %.12f %.12f %.12f %.12f\n",
                  run.TimestampOf(frame), t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    text += line;
  }
  return text;
}

std::string FormatSummaryTable(const EvaluationRun& run) {
  std::ostringstream out;
  char line[400];
  std::snprintf(line, sizeof(line), "%-22s %-26s %9s %8s %9s %8s\n", "method camera", "errors",
                "T RMSE mm", "T SD", "R RMSE deg", "R SD");
  out << line;
  auto row = [&](const CameraEvaluation& e, const char* what, const ErrorSummary& s) {
    if (s.translation_mm.count == 0) return;
    std::snprintf(line, sizeof(line), "%-22s %-26s %9.2f %8.2f %9.3f %8.3f\n", Label(e).c_str(),
                  what, s.translation_mm.rmse, s.translation_mm.sd, s.rotation_deg.rmse,
                  s.rotation_deg.sd);
    out << line;
  };
  for (const CameraEvaluation& e : run.map_evaluations) {
    row(e, "map frame, uncorrected", e.uncorrected.ape_summary);
    if (e.has_correction()) row(e, "map frame, hand-eye", e.corrected.ape_summary);
  }
  for (const CameraEvaluation& e : run.evaluations) {
    row(e, "relative, uncorrected", e.uncorrected.rpe_summary);
    row(e, "absolute, uncorrected", e.uncorrected.ape_summary);
    if (e.has_correction()) {
      row(e, "relative, hand-eye", e.corrected.rpe_summary);
      row(e, "absolute, hand-eye", e.corrected.ape_summary);
    } else {
      out << Label(e) << ": no hand-eye correction: " << e.correction_note << "\n";
    }
  }
  return out.str();
}

std::string FormatEvaluationMarkdown(const EvaluationRun& run,
                                     const std::vector<std::string>& files) {
  std::ostringstream md;
  md << "# Evaluation of " << run.sequence_name << " against Vicon\n\n";
  md << "lifmcr " << run.git_revision << ". Registration files:";
  for (const auto& f : run.registration_files) md << " `" << f.string() << "`";
  md << ". Vicon: `" << run.vicon_csv.string() << "` (" << run.rotation << ", " << run.handedness
     << "), " << run.rate_hz << " Hz, a camera trigger every " << run.association.trigger_divider
     << " Vicon frames from Vicon frame " << run.association.vicon_frame_of_first_trigger
     << " (image frame " << run.association.first_frame << ")";
  if (run.association.vicon_frame_offset != 0)
    md << ", offset " << run.association.vicon_frame_offset << " Vicon frames (interpolated)";
  md << ".\n\n";
  md << "Metrics follow evo / TUM RGB-D: absolute error E = P⁻¹Q (estimate P, Vicon Q) per "
        "frame, relative error E = (Q_i⁻¹Q_{i+1})⁻¹(P_i⁻¹P_{i+1}) between consecutive frames "
        "(Δ = 1 frame); translation |t(E)| in mm, rotation angle of R(E) in degrees; RMSE, mean, "
        "SD (population) and median over frames. The pose evaluated is each camera's extrinsics "
        "`c0_from_cx`; its Vicon truth is `(vicon_from_marker0 · X0)⁻¹ · vicon_from_markerX · "
        "XX` with the hand-eye offsets X = `marker_from_cam`, or X = I without correction (the "
        "paper's protocol).\n\n";
  for (const std::string& w : run.warnings) md << "**Warning:** " << w << "\n\n";

  md << "## Ground truth\n\n| camera | Vicon object | frames | tracked | untracked (left out) |\n"
        "|---|---|---|---|---|\n";
  for (const CameraTruth& c : run.cameras) {
    md << "| " << c.serial << (c.serial == run.reference_serial ? " (reference)" : "") << " | "
       << c.subject << " | " << c.asked << " | " << c.asked - c.untracked.size() << " | "
       << c.untracked.size();
    if (!c.untracked.empty()) {
      md << ":";
      for (std::size_t k = 0; k < c.untracked.size() && k < 12; ++k) md << " " << c.untracked[k];
      if (c.untracked.size() > 12) md << " …";
    }
    md << " |\n";
  }
  md << "\n";
  if (run.plate) {
    const Eigen::Vector3d t = run.plate->vicon_from_world.translation();
    md << "Plate alignment (supplementary, \"Data Alignment\"): " << run.plate->BriefReport()
       << ". `vicon_from_world` t = (" << F(t.x()) << ", " << F(t.y()) << ", " << F(t.z())
       << ") mm, rotation " << F(RotationAngleDeg(run.plate->vicon_from_world.linear()), 3)
       << "°. Trajectories in the plots are in the plate (world) frame.";
    if (!run.aruco_source.empty()) md << " ArUco centres in the map: " << run.aruco_source << ".";
    md << "\n\n";
  } else {
    md << "Plate alignment: not done (" << run.plate_note
       << "); trajectories in the plots are in the Vicon frame.\n\n";
  }

  md << "## Registration\n\n| method | camera | registered | failed | without Vicon truth | "
        "evaluated |\n|---|---|---|---|---|---|\n";
  for (const CameraEvaluation& e : run.evaluations) {
    md << "| " << e.method << " | " << e.serial << " | " << e.registered << " | " << e.failed;
    if (!e.failure_reasons.empty()) {
      md << " (";
      bool first = true;
      for (const auto& [why, n] : e.failure_reasons) {
        md << (first ? "" : ", ") << why << ": " << n;
        first = false;
      }
      md << ")";
    }
    md << " | " << e.without_truth << " | " << e.estimate.size() << " |\n";
  }
  md << "\n";

  md << "## Hand-eye offsets `marker_from_cam`\n\n";
  md << "Mode: " << run.hand_eye_mode;
  if (run.split == "sequence")
    md << ", split sequence (the offsets were estimated on all frames of " << run.hand_eye_from
       << ", another sequence of the rig, and correct every frame of this one: no corrected "
          "figure is fit to itself)";
  else if (run.hand_eye_mode == "estimate")
    md << ", split " << run.split
       << (run.split == "half"
               ? " (two folds: the offsets fit on the first half of each camera's frames correct "
                 "the second half and vice versa, so no corrected figure is fit to itself; the "
                 "offsets below are fit on all frames)"
               : " (fit and corrected on the same frames: the corrected figures are fit to "
                 "themselves)");
  md << ". Per axis of the marker (Vicon object) frame, ± one standard deviation (Ceres "
        "covariance); the camera centre seen from the markers is t, the offset the paper's "
        "supplementary reads from its per-axis errors is −Rᵀt (in the camera frame).\n\n";
  OffsetsSection(md, run, run.evaluations);
  TablesSection(md, run, run.evaluations, "");
  if (!run.map_evaluations.empty()) {
    md << "## Camera poses in the map (plate) frame: the paper's absolute protocol\n\n"
          "Each camera's pose in the map, `w0_from_c0` from the reference poses and "
          "`w0_from_c0 · c0_from_cx` for camera X, against `map_from_vicon · vicon_from_marker` "
          "through the plate alignment. The hand-eye solves A X = Z B with Z a correction of the "
          "plate alignment (shown as camera `map`; identity when the alignment is exact). "
          "Camera 0 and the cameras X of a method are solved together with one Z (one plate)";
    if (!run.z_prior_note.empty()) md << "; " << run.z_prior_note;
    md << ".\n\n";
    OffsetsSection(md, run, run.map_evaluations);
    TablesSection(md, run, run.map_evaluations, " (map frame)");
  }
  if (!run.differences.empty()) {
    md << "## Differences between the methods (the supplementary's comparison)\n\n"
          "| camera | methods | frames | T RMSE [mm] | T mean | T SD | R RMSE [°] | R mean | R SD "
          "|\n|---|---|---|---|---|---|---|---|---|\n";
    for (const MethodDifference& d : run.differences) {
      const ErrorSummary& s = d.summary;
      md << "| " << d.serial << " | " << d.method_a << " vs " << d.method_b << " | "
         << s.translation_mm.count << " | " << F(s.translation_mm.rmse) << " | "
         << F(s.translation_mm.mean) << " | " << F(s.translation_mm.sd) << " | "
         << F(s.rotation_deg.rmse, 3) << " | " << F(s.rotation_deg.mean, 3) << " | "
         << F(s.rotation_deg.sd, 3) << " |\n";
    }
    md << "\n";
  }

  md << "## Files\n\n";
  for (const std::string& f : files) {
    if (f.size() > 4 && f.substr(f.size() - 4) == ".png")
      md << "- `" << f << "`\n\n  ![" << f << "](" << f << ")\n";
    else
      md << "- `" << f << "`\n";
  }
  md << "\nTUM files hold `timestamp tx ty tz qx qy qz qw` with the timestamp = the trigger's "
        "Vicon frame / Vicon rate (s) and translations in mm, so `evo_ape tum "
        "tum/<serial>_c0_from_cx_vicon.txt tum/<method>_<serial>_c0_from_cx.txt` reproduces the "
        "uncorrected absolute figures (read its metres as mm) and `evo_rpe ... --delta 1 "
        "--delta_unit f` the relative ones.\n";
  return md.str();
}

static nlohmann::json EvaluationsJson(const EvaluationRun& run,
                                      const std::vector<CameraEvaluation>& evaluations) {
  nlohmann::json out = nlohmann::json::array();
  for (const CameraEvaluation& e : evaluations) {
    nlohmann::json ej = {{"method", e.method},
                         {"camera", e.serial},
                         {"reference", e.reference_serial},
                         {"registered", e.registered},
                         {"failed", e.failed},
                         {"failure_reasons", e.failure_reasons},
                         {"without_truth", e.without_truth},
                         {"evaluated", e.estimate.size()},
                         {"first_half_last_frame", e.half_last},
                         {"fit_to_itself", e.fit_to_itself},
                         {"uncorrected", MetricJson(e.uncorrected)},
                         {"correction", {{"source", e.correction_source}, {"note", e.correction_note}}}};
    if (e.has_correction()) ej["corrected"] = MetricJson(e.corrected);
    if (e.has_offsets()) {
      ej["correction"]["marker_from_cam"] = PoseJson(e.marker_from_cam);
      ej["correction"]["marker_from_cam_reference"] = PoseJson(e.marker_from_cam_reference);
    }
    if (e.hand_eye) ej["hand_eye"] = HandEyeJson(*e.hand_eye);
    for (const HandEyeResult& fold : e.folds) ej["hand_eye_folds"].push_back(HandEyeJson(fold));
    for (const CameraTruth* truth : {run.Camera(e.serial), run.Camera(e.reference_serial)}) {
      if (!e.has_offsets() || !truth || !truth->true_marker_from_cam) continue;
      const Pose& x = truth->serial == e.serial ? e.marker_from_cam : e.marker_from_cam_reference;
      const Pose d = truth->true_marker_from_cam->inverse() * x;
      ej["correction"]["error_vs_truth"][truth->serial] = {
          {"translation_mm", (x.translation() - truth->true_marker_from_cam->translation()).norm()},
          {"rotation_deg", RotationAngleDeg(d.linear())}};
    }
    out.push_back(ej);
  }
  return out;
}

std::string FormatEvaluationJson(const EvaluationRun& run, const std::vector<std::string>& files) {
  nlohmann::json j;
  j["generator"] = "lifmcr evaluate";
  j["git_revision"] = run.git_revision;
  j["command_line"] = run.command_line;
  j["sequence_dir"] = run.sequence_dir.string();
  j["sequence"] = run.sequence_name;
  for (const auto& f : run.registration_files) j["inputs"]["registration"].push_back(f.string());
  j["inputs"]["vicon_csv"] = run.vicon_csv.string();
  j["inputs"]["vsk"] = run.vsk.string();
  j["settings"] = {{"rotation", run.rotation},
                   {"handedness", run.handedness},
                   {"vicon_rate_hz", run.rate_hz},
                   {"trigger_divider", run.association.trigger_divider},
                   {"vicon_frame_of_first_trigger", run.association.vicon_frame_of_first_trigger},
                   {"first_frame", run.association.first_frame},
                   {"vicon_frame_offset", run.association.vicon_frame_offset},
                   {"max_gap_frames", run.association.max_gap_frames},
                   {"hand_eye", run.hand_eye_mode},
                   {"split", run.split},
                   {"hand_eye_from", run.hand_eye_from},
                   {"reference", run.reference_serial},
                   {"metrics",
                    "evo/TUM: APE E=P^-1 Q, RPE delta=1 frame E=(Qi^-1 Qi+1)^-1 (Pi^-1 Pi+1); "
                    "translation mm, rotation deg; per axis in the camera frame"}};
  j["warnings"] = run.warnings;
  for (const CameraTruth& c : run.cameras) {
    nlohmann::json cj = {{"serial", c.serial},
                         {"vicon_object", c.subject},
                         {"frames", c.asked},
                         {"tracked", c.asked - c.untracked.size()},
                         {"untracked_frames", c.untracked}};
    if (c.true_marker_from_cam) cj["true_marker_from_cam"] = PoseJson(*c.true_marker_from_cam);
    j["cameras"].push_back(cj);
  }
  if (run.plate) {
    j["plate_alignment"] = {{"vicon_from_world", PoseJson(run.plate->vicon_from_world)},
                            {"world_from_map", PoseJson(run.plate->world_from_map)},
                            {"map_is_plate_frame", run.plate->map_is_plate_frame},
                            {"aruco_source", run.aruco_source},
                            {"z_prior", run.z_prior_note},
                            {"aruco_check_mm", run.plate->aruco_check_mm},
                            {"marker_fit_rms_mm", run.plate->marker_fit_rms_mm},
                            {"plate_motion_rms_mm", run.plate->plate_motion_rms_mm},
                            {"plate_motion_rms_deg", run.plate->plate_motion_rms_deg},
                            {"plate_motion_max_mm", run.plate->plate_motion_max_mm},
                            {"plate_motion_max_deg", run.plate->plate_motion_max_deg},
                            {"plate_moved", run.plate->plate_moved()},
                            {"plate_samples", run.plate->plate_samples}};
  } else {
    j["plate_alignment"] = {{"done", false}, {"why", run.plate_note}};
  }
  j["evaluations"] = EvaluationsJson(run, run.evaluations);
  if (!run.map_evaluations.empty())
    j["map_frame_evaluations"] = EvaluationsJson(run, run.map_evaluations);
  for (const MethodDifference& d : run.differences)
    j["method_differences"].push_back({{"camera", d.serial},
                                       {"method_a", d.method_a},
                                       {"method_b", d.method_b},
                                       {"difference", SummaryJson(d.summary)}});
  j["files"] = files;
  return j.dump(2) + "\n";
}

}  // namespace lifmcr
