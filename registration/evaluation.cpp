#include "registration/evaluation.h"

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

// The offset marker_from_cam a map-frame evaluation applies at `frame`:
// the fold that did not see the frame, or the all-frames fit without folds.
Pose MapFrameOffsetAt(const CameraEvaluation& m, std::int64_t frame) {
  if (m.folds.size() == 2) return frame <= m.half_last ? m.folds[1].x : m.folds[0].x;
  return m.marker_from_cam;
}

}  // namespace

bool CorrectWithMapFrameOffsets(CameraEvaluation* e, const CameraEvaluation& reference_in_map,
                                const CameraEvaluation& camera_in_map) {
  for (const CameraEvaluation* m : {&reference_in_map, &camera_in_map}) {
    if (m->correction_source != "estimated") {
      e->correction_note += "; nor from the map-frame offsets: camera " + m->serial +
                            " has none (" + m->correction_note + ")";
      return false;
    }
  }
  e->truth_corrected.clear();
  for (const auto& [frame, a] : e->truth_uncorrected)
    e->truth_corrected.emplace(frame, Corrected(a, MapFrameOffsetAt(reference_in_map, frame),
                                                MapFrameOffsetAt(camera_in_map, frame)));
  e->corrected = MetricSet::Of(e->estimate, e->truth_corrected);
  e->correction_source = "map frame";
  e->correction_note = "its own hand-eye refused (" + e->correction_note +
                       "); corrected with each camera's offset from its map-frame hand-eye" +
                       (camera_in_map.folds.size() == 2 ? ", each frame by the fold that did not see it"
                                                        : ", fit on the same frames");
  e->fit_to_itself = camera_in_map.fit_to_itself || reference_in_map.fit_to_itself;
  e->marker_from_cam_reference = reference_in_map.marker_from_cam;
  e->marker_from_cam = camera_in_map.marker_from_cam;
  return true;
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
