#include "registration/calibration/calibration.h"

#include "processing/camera_model.h"
#include "registration/estimators/plenoptic_point_noise.h"
#include "registration/calibration/calibration_covariance.h"
#include "registration/calibration/calibration_costs.h"
#include "registration/calibration/calibration_problem.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>

namespace lifmcr::registration {
namespace {

using internal::InitialMap;
using internal::MakeMicroImageCost;
using internal::MakePlateCornerCost;
using internal::PrincipalPointPriorCost;
using internal::MicroImageCost;
using internal::PlateCornerCost;
using internal::Observation;
using internal::TfPinholePx;
using internal::Track;

constexpr double kBound = 0.3;  // relative bound of f_L, b_L0, B about their initial values
constexpr double kMaxInsetTfPx = 2.0;  // bound of the plate corners' inset (PlateCornerCost)

std::string Format(const char* fmt, auto... args) {
  char buffer[1024];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}


// Points by inverse depth in the frame of their first observation (the
// anchor a): (alpha, beta, rho) with p_in_a = (alpha, beta, 1) / rho, rho
// bounded to (0, 1 / (2.6 f_L)], so no step of the solve can move a point
// onto or behind the main lens' focal plane in its anchor frame (where the
// thin lens has no image and the residual cannot be evaluated).
template <typename T>
void PointInAnchor(const T* inverse, T* p_in_a) {
  p_in_a[0] = inverse[0] / inverse[2];
  p_in_a[1] = inverse[1] / inverse[2];
  p_in_a[2] = T(1) / inverse[2];
}

// An observation in the anchor frame itself. Parameters: intrinsics, point.
struct AnchorFrameCost {
  MicroImageCost micro;
  template <typename T>
  bool operator()(const T* k, const T* inverse, T* residuals) const {
    T p_in_c[3];
    PointInAnchor(inverse, p_in_c);
    return micro.Residuals(k, p_in_c, residuals);
  }
};

// An observation in another frame. Parameters: intrinsics, cam_from_world of
// the observing frame (rotation, translation), of the anchor frame, point.
struct AnchoredCost {
  MicroImageCost micro;
  template <typename T>
  bool operator()(const T* k, const T* q, const T* t, const T* q_a, const T* t_a,
                  const T* inverse, T* residuals) const {
    T p_in_a[3], p_in_w[3], p_in_c[3];
    PointInAnchor(inverse, p_in_a);
    for (int a = 0; a < 3; ++a) p_in_a[a] -= t_a[a];
    const T q_a_inverse[4] = {q_a[0], -q_a[1], -q_a[2], -q_a[3]};
    ceres::UnitQuaternionRotatePoint(q_a_inverse, p_in_a, p_in_w);
    ceres::UnitQuaternionRotatePoint(q, p_in_w, p_in_c);
    for (int a = 0; a < 3; ++a) p_in_c[a] += t[a];
    return micro.Residuals(k, p_in_c, residuals);
  }
};

// One micro-image observation set of a keypoint (what the cost holds, kept
// to evaluate residuals after the solve).
struct LensObservation {
  int track = 0;
  int observation = 0;  // index into the track's observations
  MicroImageCost cost;
  double sigma = 1;  // of its residuals (CalibrationOptions::keypoint_sigma_size_tf_px)
};

struct PoseBlock {
  std::array<double, 4> q{1, 0, 0, 0};  // cam_from_world (w, x, y, z)
  std::array<double, 3> t{0, 0, 0};
};

PoseBlock ToBlock(const Pose& w0_from_c) {
  const Pose c_from_w = w0_from_c.inverse();
  const Eigen::Quaterniond q(c_from_w.linear());
  PoseBlock b;
  b.q = {q.w(), q.x(), q.y(), q.z()};
  b.t = {c_from_w.translation().x(), c_from_w.translation().y(), c_from_w.translation().z()};
  return b;
}

Pose FromBlock(const PoseBlock& b) {
  Pose c_from_w = Pose::Identity();
  c_from_w.linear() = Eigen::Quaterniond(b.q[0], b.q[1], b.q[2], b.q[3]).normalized().toRotationMatrix();
  c_from_w.translation() = Eigen::Vector3d(b.t[0], b.t[1], b.t[2]);
  return c_from_w.inverse();
}

class ProgressCallback : public ceres::IterationCallback {
 public:
  ProgressCallback(const ProgressFn& progress, std::string stage)
      : progress_(progress), stage_(std::move(stage)) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (progress_)
      progress_(Format("%s iteration %3d  cost %.6e  |step| %.3e  %s", stage_.c_str(), s.iteration,
                       s.cost, s.step_norm, s.step_is_successful ? "" : "(rejected step)"));
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const ProgressFn& progress_;
  std::string stage_;
};

const char* kParameterNames[kIntrinsicsSize] = {"main_focal_length_mm", "mla_to_main_lens_mm",
                                                "mla_to_sensor_mm",     "principal_point_x_px",
                                                "principal_point_y_px", "k1",
                                                "k2",                   "p1",
                                                "p2"};

// The largest angle (degrees) at the point between the rays from the
// centres of the frames whose observations of the track were kept.
double TriangulationAngleDeg(const Track& track, const std::vector<int>& kept,
                             const std::vector<PoseBlock>& poses) {
  std::vector<Eigen::Vector3d> rays;
  for (const int o : kept)
    rays.push_back((FromBlock(poses[track.observations[o].frame]).translation() - track.p_in_w_mm)
                       .normalized());
  double min_cos = 1;
  for (std::size_t a = 0; a < rays.size(); ++a)
    for (std::size_t b = a + 1; b < rays.size(); ++b) min_cos = std::min(min_cos, rays[a].dot(rays[b]));
  return std::acos(std::clamp(min_cos, -1.0, 1.0)) * 180 / M_PI;
}

}  // namespace

namespace internal {

// TF pinhole pixel of a virtual point under the intrinsics vector
// (reference_map.h: distortion corrected, eqs. projX/projY, TF grid):
// calibration_problem.h.
Eigen::Vector2d TfPinholePx(const IntrinsicsVector& k, const processing::CameraModel& model,
                            const Eigen::Vector3d& virtual_px) {
  const double s = model.intrinsics().pixel_size_mm;
  const Eigen::Vector2d c(k[3], k[4]);
  const double b_l = k[1] + virtual_px.z() * k[2];
  const Eigen::Vector2d x_mla = model.Undistort((virtual_px.head<2>() - c) * s * k[1] / b_l);
  const Eigen::Vector2d raw = c + x_mla * (k[1] + 2 * k[2]) / (k[1] * s);
  return (raw - Eigen::Vector2d(0.5, 0.5)) / 2.0;
}

}  // namespace internal

Status CalibrationOptions::Check() const {
  auto fail = [](const std::string& what) { return Error{"calibration options: " + what}; };
  if (min_frames < 2) return fail("min_frames: expected >= 2");
  if (min_features < 6) return fail("min_features: expected >= 6");
  if (min_plate_corners < 4) return fail("min_plate_corners: expected >= 4");
  if (Status s = match.Check(); !s) return s;
  if (match_window < 1) return fail("match_window: expected >= 1");
  if (!(pnp_threshold_px > 0)) return fail("pnp_threshold_px: expected > 0");
  if (pnp_iterations < 10) return fail("pnp_iterations: expected >= 10");
  if (min_pnp_inliers < 6) return fail("min_pnp_inliers: expected >= 6");
  if (!(huber_px > 0)) return fail("huber_px: expected > 0");
  if (!(outlier_px > 0)) return fail("outlier_px: expected > 0");
  if (!(plate_weight > 0)) return fail("plate_weight: expected > 0");
  if (Status s = plate_corner_check.Check(); !s) return s;
  if (!(principal_point_prior_px >= 0))
    return fail("principal_point_prior_px: expected >= 0 (0: no prior)");
  if (max_lenses < 2) return fail("max_lenses: expected >= 2");
  if (min_map_observations < 2) return fail("min_map_observations: expected >= 2");
  if (!(min_map_angle_deg >= 0 && min_map_angle_deg < 90))
    return fail("min_map_angle_deg: expected in [0, 90)");
  if (!(map_sigma_v_rel > 0 && map_sigma_v_rel < 1))
    return fail("map_sigma_v_rel: expected in (0, 1)");
  if (!(map_sigma_tf_px > 0 && map_sigma_tf_px < 100))
    return fail("map_sigma_tf_px: expected in (0, 100)");
  if (!(max_keypoint_depth_range > 0))
    return fail("max_keypoint_depth_range: expected > 0 (a share of v; large: every depth kept)");
  if (!(keypoint_depth_sigma_rel > 0 && keypoint_depth_sigma_rel < 1))
    return fail("keypoint_depth_sigma_rel: expected in (0, 1) (a share of v)");
  if (!(keypoint_depth_sigma_per_range >= 0 && keypoint_depth_sigma_per_range < 100))
    return fail("keypoint_depth_sigma_per_range: expected in [0, 100) (0: every depth at full "
                "weight)");
  if (!(keypoint_sigma_size_tf_px >= 0 && keypoint_sigma_size_tf_px < 1000))
    return fail("keypoint_sigma_size_tf_px: expected in [0, 1000) (TF px; 0: every keypoint at "
                "unit sigma)");
  if (!(keypoint_depth_robust >= 0 && keypoint_depth_robust < 100))
    return fail("keypoint_depth_robust: expected in [0, 100) (times the disagreements' robust "
                "sigma; 0: no reweighting)");
  if (max_iterations < 1) return fail("max_iterations: expected >= 1");
  if (threads < 1) return fail("threads: expected >= 1");
  return Status::Ok();
}

std::string CalibrationResult::BriefReport() const {
  const IntrinsicsVector k = ToVector(calibration.intrinsics);
  int placed = 0;
  for (const FrameReport& f : frames) placed += f.placed ? 1 : 0;
  return Format(
      "Calibration: %d/%zu frames, %d points, %lld observations (%lld micro-image), RMSE %.3f px "
      "(plate %.3f px, corner inset %+.3f TF px); f_L %.4f mm, b_L0 %.4f mm, B %.5f mm, c (%.2f, %.2f) px; Ceres %d "
      "iterations %.2f s, cost %.4e -> %.4e, %s%s",
      placed, frames.size(), points, observations, micro_observations, rmse_px, plate_rmse_px,
      corner_inset_tf_px, k[0], k[1], k[2], k[3], k[4], iterations, solver_seconds, initial_cost, final_cost,
      termination.c_str(), usable ? "" : ", NOT USABLE (see flags)");
}

Expected<CalibrationResult> Calibrate(const CalibrationInput& input,
                                      const CalibrationOptions& options,
                                      const ProgressFn& progress) {
  const auto start = std::chrono::steady_clock::now();
  if (Status s = options.Check(); !s) return s.error();
  if (Status s = input.initial.intrinsics.Check(); !s) return s.error();
  if (input.micro_images == nullptr) return Error{"calibration: no micro images"};
  if (!(input.frames_lambda >= 0 && input.frames_lambda <= 1))
    return Error{Format("calibration: frames_lambda %g: expected 0 (the initial intrinsics') or "
                        "in (0, 1]",
                        input.frames_lambda)};
  if (static_cast<int>(input.frames.size()) < options.min_frames)
    return Error{Format("calibration: %zu frames given, at least %d needed", input.frames.size(),
                        options.min_frames)};
  // Recalibration starts b_L0 from the plate (f_L and B are known): from
  // 10 % off, the thin lens puts the whole map at the wrong depth and the
  // solve does not come back (it ran into the 30 % bound).
  processing::CameraIntrinsics initial = input.initial.intrinsics;
  const double frames_lambda =
      input.frames_lambda > 0 ? input.frames_lambda : processing::CameraModel(initial).lambda();
  if (options.recalibrate) {
    Expected<double> b_l0 = internal::MlaDistanceFromPlate(input, initial, options);
    if (!b_l0) return b_l0.error();
    if (progress)
      progress(Format("recalibration: b_L0 %.4f mm from the plate (given %.4f mm)", *b_l0,
                      initial.mla_to_main_lens_mm));
    initial.mla_to_main_lens_mm = *b_l0;
    if (Status s = initial.Check(); !s) return s.error();
  }
  Expected<InitialMap> init = internal::Initialise(input, initial, options, progress);
  if (!init) return init.error();
  InitialMap& map = *init;
  const int n_frames = static_cast<int>(input.frames.size());
  int placed = 0;
  for (const internal::FrameState& f : map.frames) placed += f.placed ? 1 : 0;
  if (placed < options.min_frames)
    return Error{Format("calibration: %d of %d frames could be placed, at least %d needed "
                        "(see the progress lines for why)",
                        placed, n_frames, options.min_frames)};

  CalibrationResult result;
  result.initial = ToVector(initial);
  IntrinsicsVector k = result.initial;
  const double s = input.initial.intrinsics.pixel_size_mm;
  const Eigen::Vector2d c0 = input.initial.intrinsics.PrincipalPointPx();
  // The micro-lens centres the frames were processed with (their TF images
  // and virtual depths): the observations in the micro images undo them.
  const double lambda0 = frames_lambda;
  std::vector<PoseBlock> poses(n_frames);
  for (int f = 0; f < n_frames; ++f)
    if (map.frames[f].placed) poses[f] = ToBlock(map.frames[f].w0_from_c);

  // Observations in micro images (fixed for the whole solve).
  std::vector<LensObservation> lens_observations;
  std::vector<int> lenses;
  std::vector<double> depth_weights;  // of the keypoints that keep their depth
  for (int t = 0; t < static_cast<int>(map.tracks.size()); ++t) {
    const Track& track = map.tracks[t];
    if (track.observations.size() < 2) continue;
    for (int o = 0; o < static_cast<int>(track.observations.size()); ++o) {
      const Observation& ob = track.observations[o];
      const Eigen::Vector3d x_v = internal::VirtualPoint(input.frames[ob.frame], ob.keypoint);
      LensObservation lo;
      lo.track = t;
      lo.observation = o;
      const double range = internal::KeypointDepthRange(input.frames[ob.frame], ob.keypoint);
      const bool position_only = range > options.max_keypoint_depth_range;
      const double depth_weight = internal::KeypointDepthWeight(
          range, options.keypoint_depth_sigma_rel, options.keypoint_depth_sigma_per_range);
      if (!MakeMicroImageCost(x_v, *input.micro_images, c0, lambda0, options.max_lenses, s,
                              &lenses, &lo.cost, position_only, depth_weight))
        continue;
      if (options.keypoint_sigma_size_tf_px > 0)
        lo.sigma = std::max(1.0, input.frames[ob.frame].features.keypoints[ob.keypoint].size /
                                     options.keypoint_sigma_size_tf_px);
      result.position_only_observations += position_only ? 1 : 0;
      if (!position_only) depth_weights.push_back(depth_weight);
      lens_observations.push_back(std::move(lo));
    }
  }
  if (progress) {
    progress(Format("keypoints: %lld of %zu observations by their position only (virtual depth "
                    "range over the support above %.1f %%)",
                    result.position_only_observations, lens_observations.size(),
                    100 * options.max_keypoint_depth_range));
    const std::size_t below = static_cast<std::size_t>(
        std::count_if(depth_weights.begin(), depth_weights.end(), [](double w) { return w < 0.5; }));
    double sum = 0;
    for (const double w : depth_weights) sum += w;
    progress(Format("keypoints: depth weight (sigma %.2f %% of v, + %.2f x the support's range) "
                    "mean %.3f, %zu of %zu below 0.5",
                    100 * options.keypoint_depth_sigma_rel, options.keypoint_depth_sigma_per_range,
                    depth_weights.empty() ? 1.0 : sum / depth_weights.size(), below,
                    depth_weights.size()));
  }
  std::vector<bool> inlier(lens_observations.size(), true);
  // Plate corners: fixed points; in the micro images where the TF depth map
  // has a virtual depth at the corner, else in the virtual image.
  struct CornerObservation {
    int frame = 0;
    PlateCornerCost cost;
  };
  std::vector<CornerObservation> corner_observations;
  // Each frame's corners against the plate's planar geometry (before any
  // solve, so without the pose or the intrinsics): the ones that fail stay
  // out of the plate terms.
  std::vector<PlateCornerCheck> corner_checks(n_frames);
  std::vector<std::vector<PlateCorner>> all_corners;
  for (const CalibrationFrame& frame : input.frames) all_corners.push_back(frame.corners);
  const double reference_tf_px = MedianPlateCornerResidual(all_corners, options.plate_corner_check);
  if (progress)
    progress(Format("plate corner check: median leave-one-out residual %.3f TF px, threshold "
                    "%.3f TF px",
                    reference_tf_px,
                    std::max(options.plate_corner_check.max_residual_tf_px,
                             options.plate_corner_check.max_residual_over_reference *
                                 reference_tf_px)));
  for (int f = 0; f < n_frames; ++f) {
    const CalibrationFrame& frame = input.frames[f];
    corner_checks[f] = CheckPlateCorners(frame.corners, reference_tf_px, options.plate_corner_check);
    if (!options.reject_plate_corners || !map.frames[f].placed) continue;
    const PlateCornerCheck& check = corner_checks[f];
    for (std::size_t r = 0; r < check.rejected.size(); ++r) {
      const PlateCorner& corner = frame.corners[check.rejected[r]];
      result.rejected_corners.push_back(RejectedPlateCorner{
          frame.frame, corner.marker_id, corner.corner, corner.tf_px,
          check.rejected_residual_tf_px[r], check.threshold_tf_px});
      if (progress)
        progress(Format("plate corner check: frame %lld marker %d corner %d left out "
                        "(leave-one-out homography residual %.2f TF px > %.2f)",
                        static_cast<long long>(frame.frame), corner.marker_id, corner.corner,
                        check.rejected_residual_tf_px[r], check.threshold_tf_px));
    }
  }
  for (int f = 0; f < n_frames; ++f) {
    if (!map.frames[f].placed) continue;
    const CalibrationFrame& frame = input.frames[f];
    if (!options.plate_frames.empty() &&
        std::find(options.plate_frames.begin(), options.plate_frames.end(), frame.frame) ==
            options.plate_frames.end())
      continue;
    for (std::size_t n = 0; n < frame.corners.size(); ++n) {
      if (options.reject_plate_corners &&
          std::find(corner_checks[f].rejected.begin(), corner_checks[f].rejected.end(),
                    static_cast<int>(n)) != corner_checks[f].rejected.end())
        continue;
      CornerObservation co;
      co.frame = f;
      co.cost = MakePlateCornerCost(frame, n, *input.micro_images, c0, lambda0,
                                    options.max_lenses, s, &lenses);
      corner_observations.push_back(std::move(co));
    }
  }

  std::vector<int> constant;
  if (!options.estimate_principal_point) constant.insert(constant.end(), {3, 4});
  if (!options.estimate_distortion) constant.insert(constant.end(), {5, 6, 7, 8});
  else if (!options.estimate_tangential_distortion) constant.insert(constant.end(), {7, 8});
  if (options.recalibrate) constant.insert(constant.end(), {0, 2});

  ceres::Solver::Summary summary;
  double solver_seconds = 0;
  int iterations = 0;
  double first_initial_cost = -1;
  // Round 0: poses and points under the initial intrinsics (a consistent
  // structure first); round 1: everything; outliers dropped; round 2.
  constexpr int kRounds = 3;
  double corner_inset_tf_px = 0;  // PlateCornerCost
  // Inverse-depth points (AnchoredCost): anchor frame and (alpha, beta, rho).
  std::vector<int> anchor(map.tracks.size(), -1);
  std::vector<std::array<double, 3>> inverse(map.tracks.size());
  const double max_rho = 1 / (2 * (1 + kBound) * result.initial[0]);
  for (std::size_t t = 0; t < map.tracks.size(); ++t) {
    anchor[t] = map.tracks[t].observations.front().frame;
    const Eigen::Vector3d p = FromBlock(poses[anchor[t]]).inverse() * map.tracks[t].p_in_w_mm;
    inverse[t] = {p.x() / p.z(), p.y() / p.z(), std::clamp(1 / p.z(), 1e-9, max_rho)};
  }
  // The world position of every point from its inverse depth.
  auto update_points = [&] {
    if (!options.inverse_depth) return;
    for (std::size_t t = 0; t < map.tracks.size(); ++t) {
      double p_in_a[3];
      PointInAnchor(inverse[t].data(), p_in_a);
      map.tracks[t].p_in_w_mm = FromBlock(poses[anchor[t]]) * Eigen::Vector3d(p_in_a[0], p_in_a[1], p_in_a[2]);
    }
  };
  for (int round = 0; round < kRounds; ++round) {
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    std::vector<bool> pose_used(n_frames, false);
    for (std::size_t n = 0; n < lens_observations.size(); ++n) {
      if (!inlier[n]) continue;
      LensObservation& lo = lens_observations[n];
      Track& track = map.tracks[lo.track];
      const int f = track.observations[lo.observation].frame;
      const int residuals = 2 * static_cast<int>(lo.cost.centres_px.size());
      // Residuals r / sigma under Huber's loss at huber: sigma^-2 rho_{huber sigma}(r^2).
      ceres::LossFunction* loss =
          new ceres::HuberLoss(options.huber_px * std::sqrt(residuals / 2.0) * lo.sigma);
      if (lo.sigma != 1)
        loss = new ceres::ScaledLoss(loss, 1 / (lo.sigma * lo.sigma), ceres::TAKE_OWNERSHIP);
      if (!options.inverse_depth) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<MicroImageCost, ceres::DYNAMIC, kIntrinsicsSize, 4, 3,
                                            3>(new MicroImageCost(lo.cost), residuals),
            loss, k.data(), poses[f].q.data(), poses[f].t.data(), track.p_in_w_mm.data());
      } else if (f == anchor[lo.track]) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<AnchorFrameCost, ceres::DYNAMIC, kIntrinsicsSize, 3>(
                new AnchorFrameCost{lo.cost}, residuals),
            loss, k.data(), inverse[lo.track].data());
      } else {
        const int a = anchor[lo.track];
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<AnchoredCost, ceres::DYNAMIC, kIntrinsicsSize, 4, 3, 4,
                                            3, 3>(new AnchoredCost{lo.cost}, residuals),
            loss, k.data(), poses[f].q.data(), poses[f].t.data(), poses[a].q.data(),
            poses[a].t.data(), inverse[lo.track].data());
        pose_used[a] = true;
      }
      if (options.inverse_depth) {
        problem.SetParameterLowerBound(inverse[lo.track].data(), 2, 1e-9);
        problem.SetParameterUpperBound(inverse[lo.track].data(), 2, max_rho);
      }
      pose_used[f] = true;
    }
    for (CornerObservation& co : corner_observations) {
      const int f = co.frame;
      const int residuals = co.cost.residuals();
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<PlateCornerCost, ceres::DYNAMIC, kIntrinsicsSize, 4, 3,
                                          1>(new PlateCornerCost(co.cost), residuals),
          new ceres::ScaledLoss(new ceres::HuberLoss(options.huber_px * std::sqrt(residuals / 2.0)),
                                options.plate_weight * options.plate_weight,
                                ceres::TAKE_OWNERSHIP),
          k.data(), poses[f].q.data(), poses[f].t.data(), &corner_inset_tf_px);
      pose_used[f] = true;
    }
    for (int f = 0; f < n_frames; ++f)
      if (pose_used[f]) problem.SetManifold(poses[f].q.data(), new ceres::QuaternionManifold());
    if (problem.HasParameterBlock(&corner_inset_tf_px)) {
      if (options.estimate_corner_inset) {
        problem.SetParameterLowerBound(&corner_inset_tf_px, 0, -kMaxInsetTfPx);
        problem.SetParameterUpperBound(&corner_inset_tf_px, 0, kMaxInsetTfPx);
      } else {
        problem.SetParameterBlockConstant(&corner_inset_tf_px);
      }
    }
    if (round == 0 || static_cast<int>(constant.size()) == kIntrinsicsSize) {
      problem.SetParameterBlockConstant(k.data());
    } else {
      if (options.estimate_principal_point && options.principal_point_prior_px > 0)
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<PrincipalPointPriorCost, 2, kIntrinsicsSize>(
                new PrincipalPointPriorCost{c0, options.principal_point_prior_px}),
            nullptr, k.data());
      if (!constant.empty())
        problem.SetManifold(k.data(), new ceres::SubsetManifold(kIntrinsicsSize, constant));
      // Keep the solve among cameras: f_L, b_L0, B within 30 % of their
      // initial values, the principal point within 10 % of the image size
      // (a bound reached is flagged below).
      for (int i = 0; i < 3; ++i) {
        problem.SetParameterLowerBound(k.data(), i, (1 - kBound) * result.initial[i]);
        problem.SetParameterUpperBound(k.data(), i, (1 + kBound) * result.initial[i]);
      }
      const double size[2] = {static_cast<double>(input.initial.intrinsics.width_px),
                              static_cast<double>(input.initial.intrinsics.height_px)};
      for (int a = 0; a < 2; ++a) {
        problem.SetParameterLowerBound(k.data(), 3 + a, result.initial[3 + a] - 0.1 * size[a]);
        problem.SetParameterUpperBound(k.data(), 3 + a, result.initial[3 + a] + 0.1 * size[a]);
      }
    }

    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    solver_options.max_num_iterations =
        round == kRounds - 1 ? 2 * options.max_iterations : options.max_iterations;
    solver_options.num_threads = options.threads;
    // The first two solves only bring the structure near the minimum (the
    // last one refines it): Ceres' default tolerance there; at 1e-9 they
    // spent half their iterations on relative cost changes below 1e-7.
    const bool last = round == kRounds - 1;
    solver_options.function_tolerance = last ? 1e-9 : 1e-6;
    solver_options.parameter_tolerance = last ? 1e-10 : 1e-8;
    const std::string stage = "BA " + std::to_string(round + 1) + "/" + std::to_string(kRounds);
    ProgressCallback callback(progress, stage);
    solver_options.callbacks.push_back(&callback);
    solver_options.update_state_every_iteration = false;
    if (progress)
      progress(Format("%s%s: %d residual blocks, %d parameter blocks", stage.c_str(),
                      round == 0 ? " (intrinsics held)" : "", problem.NumResidualBlocks(),
                      problem.NumParameterBlocks()));
    ceres::Solve(solver_options, &problem, &summary);
    update_points();
    solver_seconds += summary.total_time_in_seconds;
    iterations += static_cast<int>(summary.iterations.size()) - 1;
    if (first_initial_cost < 0) first_initial_cost = summary.initial_cost;
    if (progress) progress(summary.BriefReport());

    if (round == 0) continue;
    if (round == 1) {
      // Drop observations whose RMS micro-image residual exceeds
      // max(outlier_px, 3 x the median RMS): a solve that has not yet
      // reached the noise level keeps its bulk.
      std::vector<double> rms(lens_observations.size(), std::numeric_limits<double>::infinity());
      for (std::size_t n = 0; n < lens_observations.size(); ++n) {
        LensObservation& lo = lens_observations[n];
        const Track& track = map.tracks[lo.track];
        const int f = track.observations[lo.observation].frame;
        std::vector<double> r(lo.cost.centres_px.size() * 2);
        if (!lo.cost(k.data(), poses[f].q.data(), poses[f].t.data(), track.p_in_w_mm.data(),
                     r.data()))
          continue;
        double ss = 0;
        for (const double x : r) ss += x * x;
        rms[n] = std::sqrt(ss / lo.cost.centres_px.size());
      }
      std::vector<double> sorted = rms;
      std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
      const double threshold =
          sorted.empty() ? options.outlier_px
                         : std::max(options.outlier_px, 3 * sorted[sorted.size() / 2]);
      long long dropped = 0;
      for (std::size_t n = 0; n < lens_observations.size(); ++n)
        if (!(rms[n] <= threshold)) {
          inlier[n] = false;
          ++dropped;
        }
      result.rejected_observations = dropped;
      if (progress)
        progress(Format("outliers: %lld of %zu observations above %.2f px RMS dropped", dropped,
                        lens_observations.size(), threshold));
      // Each kept keypoint's depth reweighed by its disagreement e with its
      // point after this solve (one step of iteratively reweighted least
      // squares, weights fixed for the last solve, so the depths as a whole
      // still determine B): w / sqrt(1 + (e / s)^2) (Cauchy) scales the depth
      // part of its residuals (calibration_costs.h), s = factor x 1.4826 x
      // the median |e| (the disagreements' robust sigma: where the views
      // leave the intrinsics further off, every depth disagrees more, and
      // the weights stay even). A depth 2-30 % off next to a depth edge
      // stops pulling B; one within the noise keeps its weight.
      if (options.keypoint_depth_robust > 0) {
        std::vector<double> e(lens_observations.size(), std::nan(""));
        std::vector<double> magnitude;
        for (std::size_t n = 0; n < lens_observations.size(); ++n) {
          LensObservation& lo = lens_observations[n];
          if (!inlier[n] || lo.cost.depth_from_estimate) continue;
          const Track& track = map.tracks[lo.track];
          const int f = track.observations[lo.observation].frame;
          e[n] = lo.cost.DepthDisagreement(k.data(), poses[f].q.data(), poses[f].t.data(),
                                           track.p_in_w_mm.data());
          if (!std::isnan(e[n])) magnitude.push_back(std::abs(e[n]));
        }
        if (!magnitude.empty()) {
          std::nth_element(magnitude.begin(), magnitude.begin() + magnitude.size() / 2,
                           magnitude.end());
          const double scale =
              options.keypoint_depth_robust * 1.4826 * magnitude[magnitude.size() / 2];
          long long below = 0;
          for (std::size_t n = 0; n < lens_observations.size(); ++n) {
            if (std::isnan(e[n]) || !(scale > 0)) continue;
            MicroImageCost& cost = lens_observations[n].cost;
            cost.depth_weight /= std::sqrt(1 + (e[n] / scale) * (e[n] / scale));
            below += cost.depth_weight < 0.5 ? 1 : 0;
          }
          if (progress)
            progress(Format("keypoints: depths reweighed by their disagreement with their point "
                            "(Cauchy, scale %.3f %% of v): %lld of %zu below 0.5",
                            100 * scale, below, magnitude.size()));
        }
      }
      continue;
    }

    // Standard deviations of the intrinsics: the covariance of the camera
    // parameters by the Schur complement of the points, scaled to unit
    // diagonal (calibration_covariance.h). Ceres' own (ceres::Covariance,
    // SPARSE_QR) judges rank against a threshold relative to the largest
    // column norm in the parameters' units and cannot be told otherwise in
    // Ceres 2.1: on 40 `medium` frames it called the problem rank-deficient
    // by 1 (k2's column, mm^-4, 6e8 against 25 for a translation along the
    // axis) where the scaled system is full rank (smallest eigenvalue 1e-6
    // of the largest: principal point against the frames' translations).
    result.std_dev.fill(std::numeric_limits<double>::quiet_NaN());
    if (options.covariance && !problem.IsParameterBlockConstant(k.data())) {
      std::vector<internal::KeptBlock> kept;
      std::vector<int> free;
      internal::KeptBlock intrinsics{k.data(), {}};
      for (int i = 0; i < kIntrinsicsSize; ++i)
        if (std::find(constant.begin(), constant.end(), i) == constant.end()) {
          free.push_back(i);
          intrinsics.names.push_back(kParameterNames[i]);
        }
      kept.push_back(intrinsics);
      kept.push_back({&corner_inset_tf_px, {"corner inset"}});
      for (int f = 0; f < n_frames; ++f) {
        const std::string frame = "frame " + std::to_string(input.frames[f].frame);
        kept.push_back({poses[f].q.data(), {frame + " rot x", frame + " rot y", frame + " rot z"}});
        kept.push_back({poses[f].t.data(), {frame + " t x", frame + " t y", frame + " t z"}});
      }
      std::vector<double*> point_blocks;
      for (std::size_t t = 0; t < map.tracks.size(); ++t)
        point_blocks.push_back(options.inverse_depth ? inverse[t].data()
                                                     : map.tracks[t].p_in_w_mm.data());
      Expected<internal::ReducedCovariance> reduced =
          internal::ComputeReducedCovariance(&problem, kept, point_blocks);
      if (!reduced) {
        result.flags.push_back("covariance: " + reduced.error().message);
      } else if (reduced->rank_deficiency > 0 || reduced->singular_points > 0) {
        result.flags.push_back(Format(
            "covariance: rank-deficient by %d, %d points not determined: these frames do not "
            "determine %s",
            reduced->rank_deficiency, reduced->singular_points,
            reduced->null_directions.empty() ? "some points" : reduced->null_directions.c_str()));
      } else {
        // Unit-variance covariance scaled by the residual variance.
        double ss = 0;
        long long m = 0;
        for (std::size_t n = 0; n < lens_observations.size(); ++n) {
          if (!inlier[n]) continue;
          const LensObservation& lo = lens_observations[n];
          const Track& track = map.tracks[lo.track];
          const int f = track.observations[lo.observation].frame;
          std::vector<double> r(lo.cost.centres_px.size() * 2);
          if (!lo.cost(k.data(), poses[f].q.data(), poses[f].t.data(), track.p_in_w_mm.data(),
                       r.data()))
            continue;
          for (const double x : r) ss += x * x;
          m += static_cast<long long>(r.size());
        }
        const long long dof = m - problem.NumParameters();
        const double variance = dof > 0 ? ss / dof : std::numeric_limits<double>::quiet_NaN();
        for (std::size_t j = 0; j < free.size(); ++j)
          result.std_dev[free[j]] = reduced->std_dev[j] * std::sqrt(variance);
        result.weakest_direction = reduced->weakest_direction;
      }
    }
  }

  // Results: intrinsics, poses, residuals per frame.
  result.calibration.intrinsics = FromVector(k, input.initial.intrinsics);
  result.corner_inset_tf_px = corner_inset_tf_px;
  if (options.estimate_corner_inset && std::abs(corner_inset_tf_px) > kMaxInsetTfPx - 1e-3)
    result.flags.push_back(Format("plate corners: their inset reached its bound (%.2f TF px): "
                                  "check the marker layout",
                                  corner_inset_tf_px));
  result.initial_cost = first_initial_cost;
  result.frames_lambda = lambda0;
  result.frames_principal_point_px = c0;
  result.final_cost = summary.final_cost;
  result.iterations = iterations;
  result.solver_seconds = solver_seconds;
  result.termination = ceres::TerminationTypeToString(summary.termination_type);
  result.usable = summary.IsSolutionUsable();
  if (!result.calibration.intrinsics.Check())
    result.flags.push_back("diverged: the intrinsics left their valid range");
  for (int i = 0; i < 3; ++i)
    if (std::abs(k[i] / result.initial[i] - 1) > kBound - 1e-3)
      result.flags.push_back(Format("diverged: %s reached its bound (%.0f %% from its initial "
                                    "value)",
                                    kParameterNames[i], 100 * (k[i] / result.initial[i] - 1)));

  std::vector<double> frame_ss(n_frames, 0);
  std::vector<long long> frame_m(n_frames, 0), frame_obs(n_frames, 0);
  std::vector<double> track_ss(map.tracks.size(), 0);
  std::vector<long long> track_m(map.tracks.size(), 0);
  double ss = 0;
  long long m = 0;
  for (std::size_t n = 0; n < lens_observations.size(); ++n) {
    if (!inlier[n]) continue;
    const LensObservation& lo = lens_observations[n];
    const Track& track = map.tracks[lo.track];
    const int f = track.observations[lo.observation].frame;
    std::vector<double> r(lo.cost.centres_px.size() * 2);
    if (!lo.cost(k.data(), poses[f].q.data(), poses[f].t.data(), track.p_in_w_mm.data(),
                 r.data()))
      continue;
    for (const double x : r) {
      frame_ss[f] += x * x;
      track_ss[lo.track] += x * x;
      ss += x * x;
    }
    track_m[lo.track] += static_cast<long long>(r.size());
    frame_m[f] += static_cast<long long>(r.size());
    m += static_cast<long long>(r.size());
    ++frame_obs[f];
  }
  result.rmse_px = m > 0 ? std::sqrt(ss / m) : 0;
  result.micro_observations = m / 2;
  double plate_ss = 0;
  long long plate_m = 0;
  for (const CornerObservation& co : corner_observations) {
    const int f = co.frame;
    std::vector<double> r(co.cost.residuals());
    const bool ok = co.cost(k.data(), poses[f].q.data(), poses[f].t.data(), &corner_inset_tf_px,
                            r.data());
    if (!ok) continue;
    for (const double x : r) plate_ss += x * x;
    plate_m += static_cast<long long>(r.size());
  }
  result.plate_rmse_px = plate_m > 0 ? std::sqrt(plate_ss / plate_m) : 0;
  for (int f = 0; f < n_frames; ++f) {
    const CalibrationFrame& frame = input.frames[f];
    FrameReport report;
    report.frame = frame.frame;
    report.placed = map.frames[f].placed;
    report.how = map.frames[f].how;
    for (const float v : frame.virtual_depth) report.keypoints += std::isnan(v) ? 0 : 1;
    report.plate_corners = static_cast<int>(frame.corners.size());
    report.observations = static_cast<int>(frame_obs[f]);
    report.rmse_px = frame_m[f] > 0 ? std::sqrt(frame_ss[f] / frame_m[f]) : 0;
    report.plate_corner_residual_max_tf_px = std::nan("");
    if (corner_checks[f].checked) {
      report.plate_corner_residual_max_tf_px = 0;
      for (const double x : corner_checks[f].residual_tf_px)
        if (!std::isnan(x))
          report.plate_corner_residual_max_tf_px = std::max(report.plate_corner_residual_max_tf_px, x);
    }
    if (options.reject_plate_corners && report.placed)
      report.plate_corners_rejected = static_cast<int>(corner_checks[f].rejected.size());
    if (report.placed && frame_obs[f] == 0 && frame.corners.empty()) {
      result.flags.push_back(Format("frame %lld: placed at initialisation but no observation "
                                    "survived; its pose is not refined",
                                    static_cast<long long>(frame.frame)));
    }
    result.frames.push_back(report);
    if (report.placed) {
      const Pose w0_from_c0 = FromBlock(poses[f]);
      result.poses.push_back(FramePose{frame.frame, -1, w0_from_c0});
    }
  }

  // The reference map: the placed frames, every keypoint; the points that
  // kept at least two observations.
  const processing::CameraModel final_model(result.calibration.intrinsics);
  ReferenceMap& out = result.map;
  out.camera.serial = input.serial;
  out.camera.width_px = input.initial.intrinsics.width_px / 2;
  out.camera.height_px = input.initial.intrinsics.height_px / 2;
  out.camera.focal_px = (k[1] + 2 * k[2]) / (2 * s);
  out.camera.principal_point_px = (Eigen::Vector2d(k[3], k[4]) - Eigen::Vector2d(0.5, 0.5)) / 2.0;
  std::vector<int> image_of_frame(n_frames, -1);
  for (int f = 0; f < n_frames; ++f) {
    if (!map.frames[f].placed) continue;
    const CalibrationFrame& frame = input.frames[f];
    MapImage image;
    image.image_id = static_cast<int>(out.images.size()) + 1;
    image.frame = frame.frame;
    image.name = frame.name;
    image.w0_from_c0 = FromBlock(poses[f]);
    for (int kp = 0; kp < frame.features.size(); ++kp) {
      MapKeypoint mk;
      mk.tf_px = frame.features.keypoints[kp].xy_px;
      mk.virtual_depth = frame.virtual_depth[kp];
      const Eigen::Vector3d x_v = internal::VirtualPoint(frame, kp);
      mk.pinhole_px = std::isnan(x_v.z()) ? TfPinholePx(k, final_model,
                                                        Eigen::Vector3d(x_v.x(), x_v.y(), 2.0))
                                          : TfPinholePx(k, final_model, x_v);
      image.keypoints.push_back(mk);
    }
    image_of_frame[f] = static_cast<int>(out.images.size());
    out.images.push_back(std::move(image));
  }
  // Which observations survived, per track.
  std::vector<std::vector<int>> kept(map.tracks.size());
  for (std::size_t n = 0; n < lens_observations.size(); ++n)
    if (inlier[n]) kept[lens_observations[n].track].push_back(lens_observations[n].observation);
  // 99 % point of chi-square with 3 degrees of freedom.
  constexpr double kChi2Dof3P99 = 11.345;
  std::vector<int> agreeing;
  for (int t = 0; t < static_cast<int>(map.tracks.size()); ++t) {
    if (static_cast<int>(kept[t].size()) < options.min_map_observations) continue;
    const Track& track = map.tracks[t];
    // The observations that agree with the point (CalibrationOptions), and
    // the information they carry about it.
    agreeing.clear();
    Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
    Eigen::Vector3d sum_sq = Eigen::Vector3d::Zero();
    for (const int o : kept[t]) {
      const Observation& ob = track.observations[o];
      const CalibrationFrame& frame = input.frames[ob.frame];
      const Eigen::Vector3d x_v = internal::VirtualPoint(frame, ob.keypoint);
      if (!(x_v.z() > 1)) continue;
      const Eigen::Isometry3d w0_from_cam = FromBlock(poses[ob.frame]);
      const Eigen::Vector3d p_in_cam = final_model.BackProject(x_v);
      const Eigen::Matrix3d cov_in_cam = PlenopticPointCovariance(
          final_model, p_in_cam, options.map_sigma_v_rel * x_v.z(), options.map_sigma_tf_px);
      const Eigen::Matrix3d r = w0_from_cam.linear();
      const Eigen::Matrix3d info = (r * cov_in_cam * r.transpose()).inverse();
      const Eigen::Vector3d d = w0_from_cam * p_in_cam - track.p_in_w_mm;
      if (!info.allFinite() || d.dot(info * d) > kChi2Dof3P99) continue;
      agreeing.push_back(o);
      information += info;
      sum_sq += d.cwiseAbs2();
    }
    if (static_cast<int>(agreeing.size()) < options.min_map_observations) continue;
    if (options.min_map_angle_deg > 0 &&
        TriangulationAngleDeg(track, agreeing, poses) < options.min_map_angle_deg)
      continue;
    const Eigen::Matrix3d fused = information.inverse();
    if (!fused.allFinite()) continue;
    MapPoint point;
    point.id = static_cast<std::int64_t>(out.points.size()) + 1;
    point.p_in_w0_mm = track.p_in_w_mm;
    Eigen::Vector3i rgb = Eigen::Vector3i::Zero();
    for (const int o : agreeing) {
      const Observation& ob = track.observations[o];
      const CalibrationFrame& frame = input.frames[ob.frame];
      for (int a = 0; a < 3; ++a) rgb[a] += frame.rgb[ob.keypoint][a];
      MapImage& image = out.images[image_of_frame[ob.frame]];
      image.keypoints[ob.keypoint].point_id = point.id;
      point.track.push_back({image.image_id, ob.keypoint});
    }
    const double count = static_cast<double>(agreeing.size());
    // Fused, or the back-projections' spread about the point over sqrt(n)
    // where larger (the model's sigma_v too small for these frames).
    const Eigen::Vector3d spread = (sum_sq / (count * count)).cwiseSqrt();
    point.sigma_mm = fused.diagonal().cwiseSqrt().cwiseMax(spread).cast<float>();
    for (int a = 0; a < 3; ++a) point.rgb[a] = static_cast<std::uint8_t>(rgb[a] / count);
    point.error_px = track_m[t] > 0 ? std::sqrt(track_ss[t] / track_m[t]) : 0;
    const Observation& first = track.observations[agreeing.front()];
    const float* d = input.frames[first.frame].features.Descriptor(first.keypoint);
    point.descriptor.assign(d, d + kDescriptorSize);
    out.points.push_back(std::move(point));
  }
  result.points = static_cast<int>(out.points.size());
  result.observations = 0;
  for (const MapPoint& p : out.points) result.observations += static_cast<long long>(p.track.size());
  if (result.rmse_px > 1.0)
    result.flags.push_back(Format("reprojection RMSE %.2f px is high (> 1 px): check the initial "
                                  "values and the MLA file",
                                  result.rmse_px));
  if (!result.flags.empty()) result.usable = false;
  result.total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string FormatCalibrationReport(const CalibrationResult& r, const std::string& serial) {
  const IntrinsicsVector k = ToVector(r.calibration.intrinsics);
  std::string text = "# Calibration of camera " + serial + "\n\n";
  text += r.BriefReport() + "\n\n";
  text += r.flags.empty() ? "No flags.\n\n" : "## Flags\n\n";
  for (const std::string& f : r.flags) text += "- " + f + "\n";
  if (!r.flags.empty()) text += "\n";
  text += "## Intrinsics\n\n| parameter | initial | estimate | std dev |\n|---|---|---|---|\n";
  for (int i = 0; i < kIntrinsicsSize; ++i)
    text += Format("| %s | %.9g | %.9g | %s |\n", kParameterNames[i], r.initial[i], k[i],
                   std::isnan(r.std_dev[i]) ? "fixed / n.a." : Format("%.3g", r.std_dev[i]).c_str());
  if (!r.weakest_direction.empty())
    text += "\nStandard deviations: covariance of the camera parameters by the Schur complement "
            "of the points, scaled by the residual variance. Its least determined direction "
            "(eigenvalue relative to the largest of the unit-diagonal system: largest "
            "components): " + r.weakest_direction + "\n";
  text += Format(
      "\nReprojection RMSE over all micro-image residuals: %.4f px (%lld micro-image "
      "observations); plate corners in the virtual image: %.4f px.\n"
      "Observations dropped as outliers after the first solve: %lld.\n"
      "Ceres: %d iterations, %.2f s, cost %.6e -> %.6e, %s. Total %.1f s.\n\n",
      r.rmse_px, r.micro_observations, r.plate_rmse_px, r.rejected_observations, r.iterations,
      r.solver_seconds, r.initial_cost, r.final_cost, r.termination.c_str(), r.total_seconds);
  text += "## Frames\n\n| frame | placed | how | keypoints with v | plate corners (left out) | "
          "plate corners' largest leave-one-out residual TF px | observations | RMSE px |\n"
          "|---|---|---|---|---|---|---|---|\n";
  for (const FrameReport& f : r.frames)
    text += Format("| %lld | %s | %s | %d | %d (%d) | %s | %d | %.4f |\n",
                   static_cast<long long>(f.frame), f.placed ? "yes" : "no", f.how.c_str(),
                   f.keypoints, f.plate_corners, f.plate_corners_rejected,
                   std::isnan(f.plate_corner_residual_max_tf_px)
                       ? "not checked"
                       : Format("%.3f", f.plate_corner_residual_max_tf_px).c_str(),
                   f.observations, f.rmse_px);
  text += "\n## Rejected plate corners\n\n";
  if (r.rejected_corners.empty()) {
    text += "None: every plate corner of a placed frame fits its frame's plate homography "
            "(or the check is off).\n";
  } else {
    text += "Left out of the bundle adjustment: their leave-one-out residual to the homography "
            "from the plate to the TF image fitted to the frame's other corners is above "
            "the threshold (registration/features/plate_corner_check.h).\n\n"
            "| frame | marker | corner | TF x px | TF y px | residual TF px | threshold TF px |\n"
            "|---|---|---|---|---|---|---|\n";
    for (const RejectedPlateCorner& c : r.rejected_corners)
      text += Format("| %lld | %d | %d | %.2f | %.2f | %.3f | %.3f |\n",
                     static_cast<long long>(c.frame), c.marker_id, c.corner, c.tf_px.x(),
                     c.tf_px.y(), c.residual_tf_px, c.threshold_tf_px);
  }
  return text;
}

}  // namespace lifmcr::registration
