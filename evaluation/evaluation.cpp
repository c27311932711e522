#include "evaluation/evaluation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <vector>

namespace lifmcr {

Status EvaluationOptions::Check() const { return hand_eye.Check(); }

MetricSet MetricSet::Of(const FramePoses& estimate, const FramePoses& truth) {
  MetricSet m;
  m.ape = AbsolutePoseErrors(estimate, truth);
  m.rpe = RelativePoseErrors(estimate, truth);
  m.ape_summary = SummarizeErrors(m.ape);
  m.rpe_summary = SummarizeErrors(m.rpe);
  return m;
}

namespace {

// marker0_from_markerX corrected by (X_0, X_X): X_0^-1 A X_X.
Pose Corrected(const Pose& a, const Pose& x0, const Pose& xx) { return x0.inverse() * a * xx; }

HandEyeResult Fit(const FramePoses& estimate, const FramePoses& truth, std::int64_t first,
                  std::int64_t last, const HandEyeOptions& options) {
  std::vector<Pose> a, b;
  for (const auto& [frame, pose] : FramesBetween(estimate, first, last)) {
    b.push_back(pose);
    a.push_back(truth.at(frame));
  }
  return SolveRobotWorldHandEye(a, b, options);
}

}  // namespace

CameraEvaluation EvaluateCamera(const std::string& method, const std::string& serial,
                                const std::string& reference_serial,
                                const FramePoses& c0_from_cx,
                                const FramePoses& vicon_from_marker0,
                                const FramePoses& vicon_from_markerx,
                                const std::optional<std::pair<Pose, Pose>>& given,
                                const EvaluationOptions& options) {
  CameraEvaluation e;
  e.method = method;
  e.serial = serial;
  e.reference_serial = reference_serial;
  e.registered = c0_from_cx.size();
  for (const auto& [frame, b] : c0_from_cx) {
    const auto m0 = vicon_from_marker0.find(frame);
    const auto mx = vicon_from_markerx.find(frame);
    if (m0 == vicon_from_marker0.end() || mx == vicon_from_markerx.end()) {
      ++e.without_truth;
      continue;
    }
    e.estimate.emplace(frame, b);
    e.truth_uncorrected.emplace(frame, Pose(m0->second.inverse() * mx->second));
  }
  if (e.estimate.empty()) {
    e.correction_note = "no registered frame has a Vicon pose of both cameras";
    return e;
  }
  e.uncorrected = MetricSet::Of(e.estimate, e.truth_uncorrected);
  std::vector<std::int64_t> frames;
  for (const auto& [frame, pose] : e.estimate) frames.push_back(frame);

  if (given) {
    e.correction_source = "given";
    e.marker_from_cam_reference = given->first;
    e.marker_from_cam = given->second;
    for (const auto& [frame, a] : e.truth_uncorrected)
      e.truth_corrected.emplace(frame, Corrected(a, given->first, given->second));
  } else {
    HandEyeResult all = Fit(e.estimate, e.truth_uncorrected, frames.front(), frames.back(),
                            options.hand_eye);
    if (!all.success) {
      e.correction_note = all.message;
    } else if (options.split == HandEyeSplit::kNone) {
      e.correction_source = "estimated";
      e.fit_to_itself = true;
      for (const auto& [frame, a] : e.truth_uncorrected)
        e.truth_corrected.emplace(frame, Corrected(a, all.z, all.x));
    } else {
      const std::size_t half = frames.size() / 2;
      e.half_last = frames[half - 1];
      e.folds.push_back(
          Fit(e.estimate, e.truth_uncorrected, frames.front(), e.half_last, options.hand_eye));
      e.folds.push_back(
          Fit(e.estimate, e.truth_uncorrected, frames[half], frames.back(), options.hand_eye));
      if (!e.folds[0].success || !e.folds[1].success) {
        e.correction_note = "a half of the frames cannot determine the offsets: " +
                            (e.folds[0].success ? e.folds[1].message : e.folds[0].message);
      } else {
        e.correction_source = "estimated";
        for (const auto& [frame, a] : e.truth_uncorrected) {
          // Each frame corrected by the fold that did not see it.
          const HandEyeResult& fold = frame <= e.half_last ? e.folds[1] : e.folds[0];
          e.truth_corrected.emplace(frame, Corrected(a, fold.z, fold.x));
        }
      }
    }
    if (all.success) {
      e.marker_from_cam = all.x;
      e.marker_from_cam_reference = all.z;
    }
    e.hand_eye = std::move(all);
  }
  if (!e.truth_corrected.empty()) e.corrected = MetricSet::Of(e.estimate, e.truth_corrected);
  return e;
}

namespace {

// The joint fit on the frames of each `in_map` evaluation within [first, last].
JointHandEyeResult FitJointly(const std::vector<CameraEvaluation*>& in_map, std::int64_t first,
                              std::int64_t last, const HandEyeOptions& options,
                              const std::optional<HandEyePrior>& z_prior) {
  std::vector<HandEyeObservations> cams;
  for (const CameraEvaluation* m : in_map) {
    HandEyeObservations& c = cams.emplace_back();
    c.name = m->serial;
    for (const auto& [frame, b] : FramesBetween(m->estimate, first, last)) {
      c.b.push_back(b);
      c.a.push_back(m->truth_uncorrected.at(frame));
    }
  }
  return SolveJointRobotWorldHandEye(cams, options, z_prior);
}

}  // namespace

bool CorrectJointlyInTheMapFrame(const std::vector<CameraEvaluation*>& in_map,
                                 const std::vector<CameraEvaluation*>& pairs,
                                 const EvaluationOptions& options,
                                 const std::optional<HandEyePrior>& z_prior, std::string* why) {
  std::set<std::int64_t> union_frames;
  for (const CameraEvaluation* m : in_map)
    for (const auto& [frame, pose] : m->estimate) union_frames.insert(frame);
  if (in_map.size() < 2 || union_frames.empty()) {
    *why = "the joint map-frame hand-eye needs camera 0 and a camera X with poses in the map";
    return false;
  }
  const std::vector<std::int64_t> frames(union_frames.begin(), union_frames.end());
  const JointHandEyeResult all =
      FitJointly(in_map, frames.front(), frames.back(), options.hand_eye, z_prior);
  if (!all.success) {
    *why = "joint map-frame hand-eye: " + all.message;
    return false;
  }
  std::vector<JointHandEyeResult> folds;
  std::int64_t half_last = frames.back();
  if (options.split == HandEyeSplit::kHalf) {
    half_last = frames[frames.size() / 2 - (frames.size() > 1 ? 1 : 0)];
    folds.push_back(FitJointly(in_map, frames.front(), half_last, options.hand_eye, z_prior));
    folds.push_back(FitJointly(in_map, half_last + 1, frames.back(), options.hand_eye, z_prior));
    for (std::size_t k = 0; k < 2; ++k)
      if (!folds[k].success) {
        *why = std::string("joint map-frame hand-eye: the ") + (k == 0 ? "first" : "second") +
               " half of the frames cannot determine the offsets: " + folds[k].message;
        return false;
      }
  }
  // The fit that did not see `frame`.
  auto fit_for = [&](std::int64_t frame) -> const JointHandEyeResult& {
    if (folds.empty()) return all;
    return frame <= half_last ? folds[1] : folds[0];
  };
  const bool fit_to_itself = folds.empty();
  const std::string how = fit_to_itself ? "fit on the same frames"
                                        : "each frame by the fit on the half that did not see it";
  for (std::size_t k = 0; k < in_map.size(); ++k) {
    CameraEvaluation& m = *in_map[k];
    m.truth_corrected.clear();
    for (const auto& [frame, a] : m.truth_uncorrected) {
      const JointHandEyeResult& fit = fit_for(frame);
      m.truth_corrected.emplace(frame, Corrected(a, fit.z, fit.cameras[k].x));
    }
    m.corrected = MetricSet::Of(m.estimate, m.truth_corrected);
    m.correction_source = "joint map frame";
    m.correction_note = "joint map-frame hand-eye of " + std::to_string(in_map.size()) +
                        " cameras with one plate correction Z" +
                        (z_prior ? " (held near the plate alignment's)" : "") + ", " + how;
    m.fit_to_itself = fit_to_itself;
    m.hand_eye = all.cameras[k];
    m.folds.clear();
    for (const JointHandEyeResult& fold : folds) m.folds.push_back(fold.cameras[k]);
    m.half_last = half_last;
    m.marker_from_cam = all.cameras[k].x;
    m.marker_from_cam_reference = all.z;
  }
  for (CameraEvaluation* e : pairs) {
    std::size_t k = 1;
    while (k < in_map.size() && in_map[k]->serial != e->serial) ++k;
    if (k == in_map.size() || e->estimate.empty()) continue;
    e->truth_corrected.clear();
    for (const auto& [frame, a] : e->truth_uncorrected) {
      const JointHandEyeResult& fit = fit_for(frame);
      e->truth_corrected.emplace(frame, Corrected(a, fit.cameras[0].x, fit.cameras[k].x));
    }
    e->corrected = MetricSet::Of(e->estimate, e->truth_corrected);
    e->correction_source = "joint map frame";
    e->correction_note = (e->correction_note.empty() ? "" : "its own hand-eye refused (" +
                                                                e->correction_note + "); ") +
                         "corrected with camera 0's and camera " + e->serial +
                         "'s offsets from the joint map-frame hand-eye, " + how;
    e->fit_to_itself = fit_to_itself;
    e->half_last = half_last;
    e->marker_from_cam_reference = all.cameras[0].x;
    e->marker_from_cam = all.cameras[k].x;
  }
  return true;
}

HandEyePrior PlateCorrectionPrior(const PlateAlignment& plate, const PlateTemplate& plate_template) {
  const double e = std::max(0.3, std::sqrt(plate.aruco_check_mm * plate.aruco_check_mm +
                                           plate.marker_fit_rms_mm * plate.marker_fit_rms_mm +
                                           plate.plate_motion_rms_mm * plate.plate_motion_rms_mm));
  double d = std::numeric_limits<double>::max();
  for (std::size_t i = 0; i < 4; ++i)
    for (std::size_t j = i + 1; j < 4; ++j)
      d = std::min(d, (plate_template.aruco_centers_mm[i] - plate_template.aruco_centers_mm[j]).norm());
  HandEyePrior prior;
  prior.translation_sd_mm = e;
  prior.rotation_sd_deg = std::max(0.05, e / std::max(d, 1.0) * 180.0 / M_PI);
  return prior;
}

MethodDifference CompareMethods(const std::string& method_a, const FramePoses& a,
                                const std::string& method_b, const FramePoses& b,
                                const std::string& serial) {
  MethodDifference d;
  d.method_a = method_a;
  d.method_b = method_b;
  d.serial = serial;
  d.errors = AbsolutePoseErrors(a, b);
  d.summary = SummarizeErrors(d.errors);
  return d;
}

}  // namespace lifmcr
