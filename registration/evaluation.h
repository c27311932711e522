#pragma once
// Evaluation of registered extrinsics c0_from_cx against Vicon, as the
// paper's tables, with and without the hand-eye correction.
//
// Ground truth. Vicon tracks each camera's marker cluster, not its optical
// centre: vicon_from_marker_k per frame. With the offsets
// marker_from_cam_k (X_k), the true extrinsics are
//   c0_from_cx = (vicon_from_marker0 · X_0)^-1 · vicon_from_markerX · X_X
//              = X_0^-1 · A · X_X,    A = marker0_from_markerX (Vicon).
// Without the correction (the paper's protocol) the marker frames stand in
// for the cameras: the ground truth is A itself, and the absolute error
// carries the offsets (supplementary: "Origin of a systematic offset").
//
// Hand-eye. With B = c0_from_cx registered, A X_X = X_0 B is the
// robot-world hand-eye problem A X = Z B (registration/hand_eye.h) with
// X = X_X and Z = X_0: both cameras' offsets come out of one solve, from
// the registered extrinsics and Vicon alone. It needs the two cameras to
// turn relative to each other about two axes; a rigidly mounted pair does
// not, and the solve says so.
//
// Split. So that the corrected figures are not fit to themselves, the
// offsets are estimated on the first half of the frames that have both an
// estimate and a ground truth, and the tables "with correction" are taken
// over the second half only (Split::kHalf); the uncorrected tables are given
// over all frames (the paper's protocol) and over that second half (to
// compare like with like). Split::kNone fits and evaluates on all frames
// (flagged in the result). Offsets given from elsewhere (another sequence's
// estimate, or the synthetic ground truth) are applied to all frames.

#include "config/error.h"
#include "config/frames.h"
#include "registration/hand_eye.h"
#include "registration/trajectory_metrics.h"

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

enum class HandEyeSplit { kHalf, kNone };

struct EvaluationOptions {
  HandEyeSplit split = HandEyeSplit::kHalf;
  HandEyeOptions hand_eye;
  Status Check() const;
};

struct MetricSet {
  PoseErrors ape, rpe;
  ErrorSummary ape_summary, rpe_summary;
  static MetricSet Of(const FramePoses& estimate, const FramePoses& truth);
};

struct CameraEvaluation {
  std::string method;
  std::string serial;            // camera X
  std::string reference_serial;  // camera 0
  std::size_t registered = 0;    // frames with an `ok` registration
  std::size_t failed = 0;        // rows with another status
  std::map<std::string, std::size_t> failure_reasons;
  std::size_t without_truth = 0;  // registered frames without a Vicon pose of either camera
  FramePoses estimate;            // c0_from_cx registered, with a ground truth
  FramePoses truth_uncorrected;   // marker0_from_markerX
  FramePoses truth_corrected;     // X_0^-1 · A · X_X (empty without offsets)

  // Frames of the two parts (inclusive); the estimation part is empty when
  // the offsets were given or the split is kNone.
  std::int64_t fit_first = 0, fit_last = -1;
  std::int64_t eval_first = 0, eval_last = -1;

  MetricSet uncorrected_all;   // the paper's protocol, every frame
  MetricSet uncorrected_eval;  // the evaluation part
  MetricSet corrected_eval;    // the evaluation part, with the offsets

  // Where the offsets come from: "estimated", "given", or "none" (with why).
  std::string correction_source = "none";
  std::string correction_note;
  std::optional<HandEyeResult> hand_eye;  // when estimated
  Pose marker_from_cam_reference = Pose::Identity();
  Pose marker_from_cam = Pose::Identity();
  bool corrected() const { return !truth_corrected.empty(); }
  bool fit_to_itself = false;  // Split::kNone
};

// One camera X and one method. `given` holds (X_0, X_X) when the offsets are
// known; otherwise they are estimated per `options`.
CameraEvaluation EvaluateCamera(const std::string& method, const std::string& serial,
                                const std::string& reference_serial,
                                const FramePoses& c0_from_cx,
                                const FramePoses& vicon_from_marker0,
                                const FramePoses& vicon_from_markerx,
                                const std::optional<std::pair<Pose, Pose>>& given,
                                const EvaluationOptions& options);

// Per-frame difference of two methods' c0_from_cx (supplementary
// "Evaluation of the difference between both benchmark methods"): E =
// a^-1 b on the frames both registered.
struct MethodDifference {
  std::string method_a, method_b, serial;
  PoseErrors errors;
  ErrorSummary summary;
};
MethodDifference CompareMethods(const std::string& method_a, const FramePoses& a,
                                const std::string& method_b, const FramePoses& b,
                                const std::string& serial);

}  // namespace lifmcr
