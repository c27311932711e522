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
  std::vector<std::int64_t> frames;
  for (const auto& [frame, pose] : e.estimate) frames.push_back(frame);
  e.eval_first = frames.front();
  e.eval_last = frames.back();
  e.uncorrected_all = MetricSet::Of(e.estimate, e.truth_uncorrected);

  if (given) {
    e.correction_source = "given";
    e.marker_from_cam_reference = given->first;
    e.marker_from_cam = given->second;
  } else {
    std::vector<Pose> a, b;
    if (options.split == HandEyeSplit::kHalf) {
      const std::size_t half = frames.size() / 2;
      if (half < 1 || half >= frames.size()) {
        e.correction_note = "too few frames to split";
      } else {
        e.fit_first = frames.front();
        e.fit_last = frames[half - 1];
        e.eval_first = frames[half];
      }
    } else {
      e.fit_first = frames.front();
      e.fit_last = frames.back();
      e.fit_to_itself = true;
    }
    for (const auto& [frame, pose] : FramesBetween(e.estimate, e.fit_first, e.fit_last)) {
      b.push_back(pose);
      a.push_back(e.truth_uncorrected.at(frame));
    }
    if (!a.empty()) {
      HandEyeResult result = SolveRobotWorldHandEye(a, b, options.hand_eye);
      if (result.success) {
        e.correction_source = "estimated";
        e.marker_from_cam = result.x;
        e.marker_from_cam_reference = result.z;
      } else {
        e.correction_note = result.message;
      }
      e.hand_eye = std::move(result);
    }
  }
  const FramePoses estimate_eval = FramesBetween(e.estimate, e.eval_first, e.eval_last);
  const FramePoses truth_eval = FramesBetween(e.truth_uncorrected, e.eval_first, e.eval_last);
  e.uncorrected_eval = MetricSet::Of(estimate_eval, truth_eval);
  if (e.correction_source != "none") {
    const Pose reference_inverse = e.marker_from_cam_reference.inverse();
    for (const auto& [frame, a] : e.truth_uncorrected)
      e.truth_corrected.emplace(frame, Pose(reference_inverse * a * e.marker_from_cam));
    e.corrected_eval =
        MetricSet::Of(estimate_eval, FramesBetween(e.truth_corrected, e.eval_first, e.eval_last));
  }
  return e;
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
