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
// robot-world hand-eye problem A X = Z B (evaluation/hand_eye.h) with
// X = X_X and Z = X_0: both cameras' offsets come out of one solve, from
// the registered extrinsics and Vicon alone. It needs the two cameras to
// turn relative to each other about two axes; a rigidly mounted pair does
// not, and the solve says so.
//
// Split. So that the corrected figures are not fit to themselves,
// Split::kHalf cross-validates in two folds: the offsets estimated on the
// first half of the frames (those with an estimate and a ground truth)
// correct the second half, and the offsets estimated on the second half
// correct the first; the corrected tables cover every frame, each corrected
// by offsets fit without it. The offsets reported (and written to
// hand_eye.yaml) are estimated once more on all frames: the best estimate of
// the physical offset, with its uncertainty. Split::kNone corrects with the
// all-frames estimate (fit to itself, flagged). Offsets given from elsewhere
// (another sequence's estimate: a split by sequence; or the synthetic
// ground truth) correct every frame.

#include "config/error.h"
#include "config/frames.h"
#include "evaluation/hand_eye.h"
#include "evaluation/plate_alignment.h"
#include "evaluation/trajectory_metrics.h"

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

  // The last frame of the first half (kHalf): frames up to it are corrected
  // by the second fold's offsets, later ones by the first fold's.
  std::int64_t half_last = 0;

  MetricSet uncorrected;  // the paper's protocol
  MetricSet corrected;    // with the offsets (cross-validated for kHalf)

  // Where the offsets come from: "estimated", "given", "joint map frame"
  // (CorrectJointlyInTheMapFrame), or "none" (with why).
  std::string correction_source = "none";
  std::string correction_note;
  std::optional<HandEyeResult> hand_eye;  // on all frames, when estimated
  std::vector<HandEyeResult> folds;       // kHalf: fit on the first half, on the second half
  // The offsets reported: the all-frames estimate, or the given ones.
  Pose marker_from_cam_reference = Pose::Identity();
  Pose marker_from_cam = Pose::Identity();
  bool has_correction() const { return !truth_corrected.empty(); }
  // marker_from_cam(_reference) hold offsets (given, estimated on all
  // frames, or taken from the map-frame evaluations), not the identity.
  bool has_offsets() const {
    return correction_source == "given" || correction_source == "joint map frame" ||
           (hand_eye && hand_eye->success);
  }
  bool fit_to_itself = false;  // Split::kNone
};

// One camera X and one method. `given` holds (X_0, X_X) when the offsets are
// known; otherwise they are estimated per `options`.
//
// The same function evaluates a camera's poses in the map frame (the
// paper's absolute protocol): pass B = w0_from_cam as `c0_from_cx`, the
// plate alignment's vicon_from_map at every frame as `vicon_from_marker0`,
// and the camera's vicon_from_marker as
// `vicon_from_markerx`. The truth is then map_from_vicon · vicon_from_marker,
// and the hand-eye solves A X = Z B with Z a correction of the plate
// alignment (identity when the plate alignment is exact) and X = marker_from_cam.
CameraEvaluation EvaluateCamera(const std::string& method, const std::string& serial,
                                const std::string& reference_serial,
                                const FramePoses& c0_from_cx,
                                const FramePoses& vicon_from_marker0,
                                const FramePoses& vicon_from_markerx,
                                const std::optional<std::pair<Pose, Pose>>& given,
                                const EvaluationOptions& options);

// The joint map-frame hand-eye of a rig: the map-frame evaluations of
// camera 0 and of each camera X of one method (`in_map`, camera 0 first,
// each with B = w0_from_cam and A = map_from_vicon · vicon_from_marker)
// solved together, A_ki X_k = Z B_ki with every camera's X_k =
// marker_from_cam and ONE Z, the correction of the plate alignment
// (evaluation/hand_eye.h, SolveJointRobotWorldHandEye). One plate, so one
// Z: fitting a Z per camera lets each camera's Z absorb part of its own
// registration error and its X the rest, and c0_from_cx corrected with two
// such X carries the difference of the two Zs (the demo: 17.95 mm).
//
// Split::kHalf cross-validates as EvaluateCamera does, with the split at the
// middle of the frames any camera has: frame f is corrected by the fit on
// the half that does not hold f. Split::kNone fits all frames (flagged).
// On success every `in_map` evaluation is corrected with Z⁻¹ A X_k (source
// "joint map frame"; hand_eye and folds hold its camera's share of the
// joint fits, marker_from_cam_reference the shared Z), and every `pairs`
// evaluation of c0_from_cx (camera X = in_map[k]'s serial, k >= 1) with
// X_0⁻¹ A X_X. Returns false and leaves everything as it was, with `*why`
// set, when a fit is refused (a camera whose motions cannot determine its
// offset, too few frames in a half).
//
// What it cannot see: on a rigidly mounted pair, camera X's map pose is
// camera 0's times c0_from_cx, so a constant error of the registered
// c0_from_cx is indistinguishable from an error of X_X: the corrected
// absolute error of c0_from_cx shows how much the registration varies
// around its own mean, not its constant bias (docs/evaluation.md).
//
// `z_prior`: the plate alignment's own measure of Z (PlateCorrectionPrior);
// without it Z is free and, on a short sequence with rotations of a few
// degrees, the X_k come out several mm off (the demo: 5-7 mm).
bool CorrectJointlyInTheMapFrame(const std::vector<CameraEvaluation*>& in_map,
                                 const std::vector<CameraEvaluation*>& pairs,
                                 const EvaluationOptions& options,
                                 const std::optional<HandEyePrior>& z_prior, std::string* why);

// Z = identity as the plate alignment measured it: e = the RMS of its
// residuals (ArUco check P1, marker fit, plate motion), at least 0.3 mm;
// translation sd e, rotation sd e / d with d the shortest distance between
// the template's ArUco centres (the lever the map side's rotation rests on),
// at least 0.05 deg.
HandEyePrior PlateCorrectionPrior(const PlateAlignment& plate, const PlateTemplate& plate_template);

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
