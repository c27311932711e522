#include "registration/calibration/rig_calibration.h"

#include "processing/camera_model.h"
#include "registration/calibration/calibration_costs.h"
#include "registration/calibration/calibration_covariance.h"
#include "registration/calibration/calibration_problem.h"
#include "registration/estimators/plenoptic_point_noise.h"
#include "registration/estimators/pose_covariance.h"
#include "registration/features/frame_observations.h"
#include "registration/map/guided_matches.h"

#include <Eigen/Geometry>
#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <tuple>

namespace lifmcr::registration {
namespace {

using internal::MicroImageCost;
using internal::PlateCornerCost;
using internal::PrincipalPointPriorCost;

constexpr double kRigBound = 0.3;  // f_L, b_L0, B about their initial values (calibration.cpp)
constexpr double kRigMaxInsetTfPx = 2.0;  // the plate corners' inset (calibration.cpp)

std::string RigFormat(const char* fmt, auto... args) {
  char buffer[2048];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

// A pose a_from_b as Ceres blocks: unit quaternion (w, x, y, z), translation.
struct RigPoseBlock {
  std::array<double, 4> q{1, 0, 0, 0};
  std::array<double, 3> t{0, 0, 0};
};

RigPoseBlock BlockOf(const Pose& a_from_b) {
  const Eigen::Quaterniond q(a_from_b.linear());
  return {{q.w(), q.x(), q.y(), q.z()},
          {a_from_b.translation().x(), a_from_b.translation().y(), a_from_b.translation().z()}};
}

Pose PoseOf(const RigPoseBlock& b) {
  Pose a_from_b = Pose::Identity();
  a_from_b.linear() =
      Eigen::Quaterniond(b.q[0], b.q[1], b.q[2], b.q[3]).normalized().toRotationMatrix();
  a_from_b.translation() = Eigen::Vector3d(b.t[0], b.t[1], b.t[2]);
  return a_from_b;
}

// cx_from_w0 = cx_from_c0 c0_from_w0 from c0_from_w0 (q, t) and c0_from_cx
// (q_x, t_x): rotation conj(q_x) q, translation R_x^T (t - t_x).
template <typename T>
void ComposeCameraFromWorld(const T* q, const T* t, const T* q_x, const T* t_x, T* q_c, T* t_c) {
  const T q_x_inverse[4] = {q_x[0], -q_x[1], -q_x[2], -q_x[3]};
  ceres::QuaternionProduct(q_x_inverse, q, q_c);
  const T d[3] = {t[0] - t_x[0], t[1] - t_x[1], t[2] - t_x[2]};
  ceres::UnitQuaternionRotatePoint(q_x_inverse, d, t_c);
}

// A keypoint of camera X. Parameters: X's intrinsics, the rig pose
// c0_from_w0 (rotation, translation), c0_from_cx (rotation, translation),
// the point in w0.
struct RigMicroImageCost {
  MicroImageCost micro;
  template <typename T>
  bool operator()(const T* k, const T* q, const T* t, const T* q_x, const T* t_x, const T* p_in_w,
                  T* residuals) const {
    T q_c[4], t_c[3];
    ComposeCameraFromWorld(q, t, q_x, t_x, q_c, t_c);
    return micro(k, q_c, t_c, p_in_w, residuals);
  }
};

// A plate corner of camera X. Parameters: X's intrinsics, c0_from_w0,
// c0_from_cx, X's corner inset.
struct RigPlateCornerCost {
  PlateCornerCost corner;
  template <typename T>
  bool operator()(const T* k, const T* q, const T* t, const T* q_x, const T* t_x, const T* inset,
                  T* residuals) const {
    T q_c[4], t_c[3];
    ComposeCameraFromWorld(q, t, q_x, t_x, q_c, t_c);
    return corner(k, q_c, t_c, inset, residuals);
  }
};

struct LensObservation {
  int camera = 0;
  int trigger = 0;
  int point = 0;
  int frame = 0;  // index into the camera's frames
  int keypoint = 0;
  MicroImageCost cost;
};

struct CornerObservation {
  int camera = 0;
  int trigger = 0;
  PlateCornerCost cost;
};

const char* kRigParameterNames[kIntrinsicsSize] = {"f_L", "b_L0", "B",  "c_x", "c_y",
                                                   "k1",  "k2",   "p1", "p2"};

double Median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Robust mean of per-frame poses (rig_calibration.h, step 2).
Pose RobustMean(const std::vector<FramePose>& poses) {
  Eigen::Vector3d median;
  for (int a = 0; a < 3; ++a) {
    std::vector<double> c;
    for (const FramePose& p : poses) c.push_back(p.world_from_cam.translation()[a]);
    median[a] = Median(c);
  }
  std::vector<double> distance;
  for (const FramePose& p : poses)
    distance.push_back((p.world_from_cam.translation() - median).norm());
  const double limit = std::max(3 * Median(distance), 1.0);
  Eigen::Vector3d t_sum = Eigen::Vector3d::Zero();
  Eigen::Vector4d q_sum = Eigen::Vector4d::Zero();
  Eigen::Quaterniond reference(poses.front().world_from_cam.linear());
  int n = 0;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (distance[i] > limit) continue;
    const Eigen::Quaterniond q(poses[i].world_from_cam.linear());
    const double sign = q.dot(reference) < 0 ? -1 : 1;
    q_sum += sign * Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
    t_sum += poses[i].world_from_cam.translation();
    ++n;
  }
  Pose mean = Pose::Identity();
  mean.linear() =
      Eigen::Quaterniond(q_sum[0], q_sum[1], q_sum[2], q_sum[3]).normalized().toRotationMatrix();
  mean.translation() = t_sum / std::max(n, 1);
  return mean;
}

}  // namespace

Status RigCalibrationOptions::Check() const {
  if (Status s = calibration.Check(); !s) return s;
  if (Status s = registration.Check(); !s) return s;
  if (min_registered_frames < 1)
    return Error{"rig calibration options: min_registered_frames: expected >= 1"};
  return Status::Ok();
}

std::string RigCalibrationResult::BriefReport() const {
  long long observations = 0;
  for (const RigCameraResult& c : cameras) observations += c.observations;
  return RigFormat(
      "Rig calibration%s: %zu cameras, %zu triggers, %zu points (%d seen by several cameras, %d by "
      "one camera X alone), %lld observations, RMSE %.3f px; Ceres %d iterations %.1f s, cost %.4e "
      "-> %.4e, %s%s",
      non_rigid ? " (non-rigid)" : "", cameras.size(), trajectory.size(), map.points.size(),
      shared_points, own_points, observations, rmse_px, iterations, solver_seconds, initial_cost,
      final_cost, termination.c_str(), usable ? "" : ", NOT USABLE (see flags)");
}

std::string RigCalibrationResult::CameraReport() const {
  std::string text;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const RigCameraResult& r = cameras[c];
    const IntrinsicsVector k = ToVector(r.calibration.intrinsics);
    const Eigen::Vector3d t = r.c0_from_cx.translation();
    const Eigen::AngleAxisd aa(r.c0_from_cx.linear());
    const Eigen::Vector3d w = aa.angle() * aa.axis();
    text += RigFormat(
        "camera %zu (%s): f_L %.4f mm (sd %.2g), b_L0 %.4f mm (sd %.2g), B %.5f mm (sd %.2g), c "
        "(%.2f, %.2f) px (sd %.2g, %.2g); %lld observations, %d plate corners (position RMS "
        "%.3f px, weight %.2f), RMSE %.3f px",
        c, r.serial.c_str(), k[0], r.std_dev[0], k[1], r.std_dev[1], k[2], r.std_dev[2], k[3], k[4],
        r.std_dev[3], r.std_dev[4], r.observations, r.plate_corners, r.plate_corner_rms_px,
        r.plate_weight, r.rmse_px);
    if (c > 0 && non_rigid) {
      text += RigFormat(
          "; placed at %zu triggers (%zu passed the pose checks against the map "
          "of the cameras before it), robust mean of c0_from_cx t (%.3f, %.3f, "
          "%.3f) mm, rotation vector (%.5f, %.5f, %.5f) deg",
          r.per_trigger.size(), r.registered.size(), t.x(), t.y(), t.z(), w.x() * 180 / M_PI,
          w.y() * 180 / M_PI, w.z() * 180 / M_PI);
    } else if (c > 0) {
      const Eigen::Matrix<double, 6, 6>& s = r.c0_from_cx_covariance;
      text += RigFormat(
          "; c0_from_cx t (%.3f, %.3f, %.3f) mm (sd %.3f, %.3f, %.3f), rotation vector (%.5f, "
          "%.5f, %.5f) deg (sd %.5f, %.5f, %.5f); %zu frames registered",
          t.x(), t.y(), t.z(), std::sqrt(s(3, 3)), std::sqrt(s(4, 4)), std::sqrt(s(5, 5)),
          w.x() * 180 / M_PI, w.y() * 180 / M_PI, w.z() * 180 / M_PI,
          std::sqrt(s(0, 0)) * 180 / M_PI, std::sqrt(s(1, 1)) * 180 / M_PI,
          std::sqrt(s(2, 2)) * 180 / M_PI, r.registered.size());
    }
    text += "\n";
  }
  return text;
}

CalibrationResult CalibrationResultOf(const CameraCalibration& calibration, ReferenceMap map) {
  CalibrationResult result;
  result.calibration = calibration;
  result.initial = ToVector(calibration.intrinsics);
  result.std_dev.fill(std::numeric_limits<double>::quiet_NaN());
  for (const MapImage& image : map.images)
    result.poses.push_back(FramePose{image.frame, image.vicon_frame, image.w0_from_c0});
  result.points = static_cast<int>(map.points.size());
  result.map = std::move(map);
  result.usable = true;
  result.termination = "given";
  return result;
}

Expected<RigCalibrationResult> CalibrateRig(const std::vector<CalibrationInput>& cameras,
                                            const RigCalibrationOptions& options,
                                            const CalibrationResult* camera0,
                                            const ProgressFn& progress) {
  const auto start = std::chrono::steady_clock::now();
  auto say = [&](const std::string& line) {
    if (progress) progress(line);
  };
  if (Status s = options.Check(); !s) return s.error();
  const int n_cameras = static_cast<int>(cameras.size());
  if (n_cameras < 2) return Error{"rig calibration: at least 2 cameras needed"};
  std::set<std::string> serials;
  for (const CalibrationInput& c : cameras) {
    if (!serials.insert(c.serial).second)
      return Error{"rig calibration: camera " + c.serial + " given twice"};
    if (c.micro_images == nullptr)
      return Error{"rig calibration: camera " + c.serial + ": no micro images"};
    if (Status s = c.initial.intrinsics.Check(); !s)
      return Error{"rig calibration: camera " + c.serial + ": " + s.error().message};
    if (c.frames.empty()) return Error{"rig calibration: camera " + c.serial + ": no frames"};
  }
  const CalibrationOptions& co = options.calibration;

  RigCalibrationResult result;
  // Step 1: camera 0 alone.
  if (camera0 != nullptr) {
    result.camera0 = *camera0;
  } else {
    say("rig calibration: camera 0 (" + cameras[0].serial + ") alone");
    Expected<CalibrationResult> c = Calibrate(cameras[0], co, progress);
    if (!c)
      return Error{"rig calibration: camera 0 (" + cameras[0].serial + "): " + c.error().message};
    result.camera0 = std::move(*c);
    say(result.camera0.BriefReport());
  }
  const CalibrationResult& cal0 = result.camera0;
  const ReferenceMap& map0 = cal0.map;

  std::vector<std::map<std::int64_t, int>> frame_index(n_cameras);
  for (int c = 0; c < n_cameras; ++c)
    for (std::size_t f = 0; f < cameras[c].frames.size(); ++f)
      frame_index[c][cameras[c].frames[f].frame] = static_cast<int>(f);

  // Triggers: the frames camera 0 placed; the rig pose c0_from_w0 per trigger.
  std::map<std::int64_t, int> trigger_of_frame;
  std::vector<std::int64_t> trigger_frame;
  std::vector<RigPoseBlock> rig;
  std::map<int, int> image_index_of_id;
  for (std::size_t i = 0; i < map0.images.size(); ++i) {
    const MapImage& image = map0.images[i];
    image_index_of_id[image.image_id] = static_cast<int>(i);
    const auto f = frame_index[0].find(image.frame);
    if (f == frame_index[0].end())
      return Error{
          RigFormat("rig calibration: camera 0's calibration has frame %lld, which is "
                    "not among camera 0's frames",
                    static_cast<long long>(image.frame))};
    if (static_cast<int>(image.keypoints.size()) != cameras[0].frames[f->second].features.size())
      return Error{RigFormat(
          "rig calibration: camera 0's calibration has %zu keypoints in frame %lld, the frame "
          "%d: it was processed otherwise (other initial values or --max-features)",
          image.keypoints.size(), static_cast<long long>(image.frame),
          cameras[0].frames[f->second].features.size())};
    trigger_of_frame[image.frame] = static_cast<int>(rig.size());
    trigger_frame.push_back(image.frame);
    rig.push_back(BlockOf(image.w0_from_c0.inverse()));
  }
  const int n_triggers = static_cast<int>(rig.size());
  if (n_triggers < 2) return Error{"rig calibration: camera 0 placed fewer than 2 frames"};

  // Per camera: intrinsics vector, the geometry its frames were processed in.
  std::vector<IntrinsicsVector> k(n_cameras);
  std::vector<double> lambda0(n_cameras);
  std::vector<Eigen::Vector2d> pp0(n_cameras);
  for (int c = 0; c < n_cameras; ++c) {
    k[c] = c == 0 ? ToVector(cal0.calibration.intrinsics) : ToVector(cameras[c].initial.intrinsics);
    lambda0[c] = cameras[c].frames_lambda > 0
                     ? cameras[c].frames_lambda
                     : processing::CameraModel(cameras[c].initial.intrinsics).lambda();
    pp0[c] = cameras[c].initial.intrinsics.PrincipalPointPx();
  }
  const std::vector<IntrinsicsVector> initial = k;
  // The bounds are about the nominal values (camera 0's too, as its own
  // calibration had them).
  std::vector<IntrinsicsVector> nominal(n_cameras);
  for (int c = 0; c < n_cameras; ++c) nominal[c] = ToVector(cameras[c].initial.intrinsics);

  // The shared points: camera 0's map.
  const int n_points = static_cast<int>(map0.points.size());
  std::vector<Eigen::Vector3d> points(n_points);
  for (int j = 0; j < n_points; ++j) points[j] = map0.points[j].p_in_w0_mm;
  std::vector<LensObservation> lens;
  std::vector<int> lenses_seen;
  auto add_observation = [&](int c, int trigger, int point, int frame, int keypoint) {
    LensObservation lo;
    lo.camera = c;
    lo.trigger = trigger;
    lo.point = point;
    lo.frame = frame;
    lo.keypoint = keypoint;
    const Eigen::Vector3d x_v = internal::VirtualPoint(cameras[c].frames[frame], keypoint);
    if (!internal::MakeMicroImageCost(
            x_v, *cameras[c].micro_images, pp0[c], lambda0[c], co.max_lenses,
            cameras[c].initial.intrinsics.pixel_size_mm, &lenses_seen, &lo.cost,
            internal::KeypointDepthRange(cameras[c].frames[frame], keypoint) >
                co.max_keypoint_depth_range))
      return;
    lens.push_back(std::move(lo));
  };
  for (int j = 0; j < n_points; ++j)
    for (const TrackElement& e : map0.points[j].track) {
      const auto image = image_index_of_id.find(e.image_id);
      if (image == image_index_of_id.end()) continue;
      const std::int64_t frame = map0.images[image->second].frame;
      add_observation(0, trigger_of_frame.at(frame), j, frame_index[0].at(frame), e.keypoint);
    }

  // Step 2: every camera X against camera 0's map (non-rigid: the map grown
  // by the cameras X before it).
  const bool per_trigger = options.non_rigid;
  result.non_rigid = per_trigger;
  MapIndex index;
  std::vector<int> point_of_index;  // MapIndex order -> index into `points`
  auto build_index = [&](const ReferenceMap& map) {
    index = MapIndex::Of(map);
    point_of_index.clear();
    for (int j = 0; j < static_cast<int>(map.points.size()); ++j)
      if (map.points[j].descriptor.size() == static_cast<std::size_t>(kDescriptorSize))
        point_of_index.push_back(j);
  };
  build_index(map0);
  // Non-rigid: camera 0's map and, in the order of `points`, the points of
  // the cameras X registered so far (descriptor and start position).
  ReferenceMap grown;
  if (per_trigger) grown = map0;
  result.cameras.resize(n_cameras);
  // c0_from_cx: one block per camera (rigid) or one per camera and trigger
  // (non-rigid); placed[c][t]: camera c has a pose at trigger t.
  std::vector<std::vector<RigPoseBlock>> extrinsics(
      n_cameras, std::vector<RigPoseBlock>(per_trigger ? n_triggers : 1));
  auto block = [&](int c, int t) -> RigPoseBlock& { return extrinsics[c][per_trigger ? t : 0]; };
  std::vector<std::vector<bool>> placed(n_cameras, std::vector<bool>(n_triggers, !per_trigger));
  placed[0].assign(n_triggers, true);
  // Points of one camera X alone (after camera 0's): which keypoint made each.
  struct OwnPoint {
    int camera = 0, frame = 0, keypoint = 0;
  };
  std::vector<OwnPoint> own_point;
  for (int c = 1; c < n_cameras; ++c) {
    RigCameraResult& rc = result.cameras[c];
    const processing::CameraModel model(cameras[c].initial.intrinsics);
    if (per_trigger && c > 1) build_index(grown);
    std::map<std::pair<int, int>, int> matched;  // (frame index, keypoint) -> point
    std::vector<FramePose> estimated;            // every pose PnP returned
    for (std::size_t f = 0; f < cameras[c].frames.size(); ++f) {
      const CalibrationFrame& frame = cameras[c].frames[f];
      const auto trigger = trigger_of_frame.find(frame.frame);
      if (trigger == trigger_of_frame.end()) continue;
      FrameObservations obs;
      obs.frame = frame.frame;
      obs.features = frame.features;
      obs.virtual_depth.assign(frame.virtual_depth.begin(), frame.virtual_depth.end());
      CompleteObservations(model, &obs);
      const FrameRegistration r =
          RegisterFrame(index, model, obs, RegistrationMethod::kPnp, options.registration);
      say(RigFormat("camera %d (%s) frame %lld: %s", c, cameras[c].serial.c_str(),
                    static_cast<long long>(frame.frame),
                    r.BriefReport(RegistrationMethod::kPnp).c_str()));
      // A pose the checks refused (too little of the image, too uncertain
      // alone) still has inliers under it: they observe the map points.
      if (!r.estimated) continue;
      for (std::size_t i = 0; i < r.inlier_points.size(); ++i)
        matched[{static_cast<int>(f), r.inlier_queries[i]}] = point_of_index[r.inlier_points[i]];
      const Pose c0_from_cx = PoseOf(rig[trigger->second]) * r.w0_from_cam.pose;
      estimated.push_back(FramePose{frame.frame, -1, c0_from_cx});
      if (per_trigger) {
        placed[c][trigger->second] = true;
        extrinsics[c][trigger->second] = BlockOf(c0_from_cx);
        rc.per_trigger_initial.push_back(FramePose{frame.frame, -1, c0_from_cx});
      }
      if (!r.success) continue;
      rc.registered.push_back(FramePose{frame.frame, -1, c0_from_cx});
    }
    const bool enough_passed =
        static_cast<int>(rc.registered.size()) >= options.min_registered_frames;
    if (!per_trigger && !enough_passed)
      say(RigFormat("camera %s: %zu of its frames passed the pose checks against camera 0's map: "
                    "c0_from_cx starts from the %zu poses PnP estimated",
                    cameras[c].serial.c_str(), rc.registered.size(), estimated.size()));
    const std::vector<FramePose>& starts =
        per_trigger ? rc.per_trigger_initial : (enough_passed ? rc.registered : estimated);
    if (static_cast<int>(starts.size()) < options.min_registered_frames)
      return Error{RigFormat("rig calibration: camera %s: %zu of its frames %s, at least %d needed",
                             cameras[c].serial.c_str(), starts.size(),
                             per_trigger ? "placed by PnP against the map of the cameras before it"
                                         : "given a pose by PnP against camera 0's map",
                             options.min_registered_frames)};
    if (!per_trigger) rc.start = starts;
    rc.c0_from_cx_initial = RobustMean(starts);
    if (!per_trigger) extrinsics[c][0] = BlockOf(rc.c0_from_cx_initial);

    // X's own tracks across time (camera 0's initialisation, calibration.h
    // step 2, on X's frames): a track with a keypoint matched to a map point
    // joins that point (all its keypoints observe it), one whose keypoints
    // match none becomes a point of X alone, back-projected at its first
    // observation through the rig; a track matched to several map points
    // adds nothing beyond its matches.
    Expected<internal::InitialMap> own =
        internal::Initialise(cameras[c], cameras[c].initial.intrinsics, co, progress);
    if (!own) {
      say("camera " + cameras[c].serial + ": no tracks of its own (" + own.error().message +
          "): its matches to camera 0's map alone");
      own = internal::InitialMap{};
    }
    int joined = 0, added = 0, conflicting = 0;
    for (const internal::Track& track : own->tracks) {
      std::set<int> targets;
      std::vector<const internal::Observation*> usable;
      std::set<int> frames_seen;
      for (const internal::Observation& ob : track.observations) {
        const auto trigger = trigger_of_frame.find(cameras[c].frames[ob.frame].frame);
        if (trigger == trigger_of_frame.end() || !placed[c][trigger->second]) continue;
        if (!frames_seen.insert(ob.frame).second) continue;
        usable.push_back(&ob);
        if (const auto m = matched.find({ob.frame, ob.keypoint}); m != matched.end())
          targets.insert(m->second);
      }
      if (targets.size() > 1) {
        ++conflicting;
        continue;
      }
      if (usable.size() < 2) continue;
      int point = -1;
      if (targets.size() == 1) {
        point = *targets.begin();
        ++joined;
      } else {
        const internal::Observation& first = *usable.front();
        const CalibrationFrame& frame = cameras[c].frames[first.frame];
        const Eigen::Vector3d x_v = internal::VirtualPoint(frame, first.keypoint);
        if (!(x_v.z() > 1)) continue;
        const int t = trigger_of_frame.at(frame.frame);
        const Pose w0_from_cx = PoseOf(rig[t]).inverse() * PoseOf(block(c, t));
        points.push_back(w0_from_cx * model.BackProject(x_v));
        point = static_cast<int>(points.size()) - 1;
        own_point.push_back({c, first.frame, first.keypoint});
        if (per_trigger) {
          // The next cameras match it by this keypoint's descriptor.
          MapPoint grown_point;
          grown_point.id = point + 1;
          grown_point.p_in_w0_mm = points.back();
          const float* d = frame.features.Descriptor(first.keypoint);
          grown_point.descriptor.assign(d, d + kDescriptorSize);
          grown.points.push_back(std::move(grown_point));
        }
        ++added;
      }
      for (const internal::Observation* ob : usable)
        if (!matched.count({ob->frame, ob->keypoint})) matched[{ob->frame, ob->keypoint}] = point;
    }
    for (const auto& [at, point] : matched)
      add_observation(c, trigger_of_frame.at(cameras[c].frames[at.first].frame), point, at.first,
                      at.second);
    say(
        RigFormat("camera %s: %d tracks of its own joined camera 0's points, %d became points "
                  "of its own, %d matched several points (left out)",
                  cameras[c].serial.c_str(), joined, added, conflicting));
  }

  // Plate corners of every camera (calibration.cpp: the planar check first).
  std::vector<CornerObservation> corners;
  for (int c = 0; c < n_cameras; ++c) {
    std::vector<std::vector<PlateCorner>> all;
    for (const CalibrationFrame& frame : cameras[c].frames) all.push_back(frame.corners);
    const double reference = MedianPlateCornerResidual(all, co.plate_corner_check);
    const double s = cameras[c].initial.intrinsics.pixel_size_mm;
    for (const CalibrationFrame& frame : cameras[c].frames) {
      const auto trigger = trigger_of_frame.find(frame.frame);
      if (trigger == trigger_of_frame.end() || !placed[c][trigger->second]) continue;
      const PlateCornerCheck check =
          CheckPlateCorners(frame.corners, reference, co.plate_corner_check);
      for (std::size_t n = 0; n < frame.corners.size(); ++n) {
        if (co.reject_plate_corners && std::find(check.rejected.begin(), check.rejected.end(),
                                                 static_cast<int>(n)) != check.rejected.end())
          continue;
        CornerObservation ob;
        ob.camera = c;
        ob.trigger = trigger->second;
        ob.cost = internal::MakePlateCornerCost(frame, n, *cameras[c].micro_images, pp0[c],
                                                lambda0[c], co.max_lenses, s, &lenses_seen);
        corners.push_back(std::move(ob));
        ++result.cameras[c].plate_corners;
      }
    }
  }

  std::vector<int> constant;
  if (!co.estimate_principal_point) constant.insert(constant.end(), {3, 4});
  if (!co.estimate_distortion)
    constant.insert(constant.end(), {5, 6, 7, 8});
  else if (!co.estimate_tangential_distortion)
    constant.insert(constant.end(), {7, 8});
  if (co.recalibrate) constant.insert(constant.end(), {0, 2});
  // The plate corners' inset (calibration.h): one for every camera
  // (`shared_corner_inset`: camera 0's block, from its calibration), else
  // one per camera X from 0.
  const bool shared_inset = options.shared_corner_inset;
  std::vector<double> inset(n_cameras, cal0.corner_inset_tf_px);
  if (!shared_inset)
    for (int c = 1; c < n_cameras; ++c) inset[c] = 0;
  auto inset_of = [&](int c) { return shared_inset ? &inset[0] : &inset[c]; };

  // Residuals of one observation at the current parameters.
  auto evaluate = [&](const LensObservation& lo, std::vector<double>* r) {
    r->resize(2 * lo.cost.centres_px.size());
    const RigPoseBlock& p = rig[lo.trigger];
    if (lo.camera == 0)
      return lo.cost(k[0].data(), p.q.data(), p.t.data(), points[lo.point].data(), r->data());
    const RigPoseBlock& e = block(lo.camera, lo.trigger);
    return RigMicroImageCost{lo.cost}(k[lo.camera].data(), p.q.data(), p.t.data(), e.q.data(),
                                      e.t.data(), points[lo.point].data(), r->data());
  };

  // Residuals of one plate corner at the current parameters.
  auto evaluate_corner = [&](const CornerObservation& ob, std::vector<double>* r) {
    r->resize(ob.cost.residuals());
    const RigPoseBlock& p = rig[ob.trigger];
    if (ob.camera == 0) return ob.cost(k[0].data(), p.q.data(), p.t.data(), &inset[0], r->data());
    const RigPoseBlock& e = block(ob.camera, ob.trigger);
    return RigPlateCornerCost{ob.cost}(k[ob.camera].data(), p.q.data(), p.t.data(), e.q.data(),
                                       e.t.data(), inset_of(ob.camera), r->data());
  };
  // The plate corners' weight per camera (rig_calibration.h, step 3).
  std::vector<double> plate_weight(n_cameras, co.plate_weight);

  // Each camera's plate corners: the RMS of their position residuals (the
  // mean of a corner's micro-image residuals) at the current parameters;
  // camera X's weight plate_weight x min(1, sqrt(s_0 / s_X)) from then on.
  auto reweigh_plate_corners = [&]() {
    std::vector<double> corner_ss(n_cameras, 0), r;
    std::vector<int> corner_n(n_cameras, 0);
    for (const CornerObservation& ob : corners) {
      if (!evaluate_corner(ob, &r)) continue;
      const int n = static_cast<int>(r.size()) / 2;
      Eigen::Vector2d mean = Eigen::Vector2d::Zero();
      for (int i = 0; i < n; ++i) mean += Eigen::Vector2d(r[2 * i], r[2 * i + 1]) / n;
      corner_ss[ob.camera] += mean.squaredNorm();
      ++corner_n[ob.camera];
    }
    for (int c = 0; c < n_cameras; ++c)
      if (corner_n[c] > 0)
        result.cameras[c].plate_corner_rms_px = std::sqrt(corner_ss[c] / corner_n[c]);
    const double s0 = result.cameras[0].plate_corner_rms_px;
    for (int c = 1; c < n_cameras; ++c) {
      const double sc = result.cameras[c].plate_corner_rms_px;
      plate_weight[c] = options.reweigh_plate_corners && s0 > 0 && sc > s0
                            ? co.plate_weight * std::sqrt(s0 / sc)
                            : co.plate_weight;
    }
    std::string weights;
    for (int c = 0; c < n_cameras; ++c)
      weights += RigFormat("%s camera %d %.2f (RMS %.3f px, inset %+.3f TF px)", c == 0 ? "" : ",",
                           c, plate_weight[c], result.cameras[c].plate_corner_rms_px, *inset_of(c));
    say("plate corner weights:" + weights);
  };

  std::vector<bool> inlier(lens.size(), true);
  // The joint solve's covariance of each c0_from_cx block (step 4).
  std::vector<std::vector<Eigen::Matrix<double, 6, 6>>> extrinsics_covariance(n_cameras);
  for (int c = 0; c < n_cameras; ++c)
    extrinsics_covariance[c].assign(extrinsics[c].size(), Eigen::Matrix<double, 6, 6>::Zero());
  ceres::Solver::Summary summary;
  constexpr int kRounds = 3;
  double first_cost = -1;
  for (int round = 0; round < kRounds; ++round) {
    // Round 0: the cameras X alone against camera 0's trajectory and map.
    const bool x_only = round == 0;
    ceres::Problem problem;
    std::vector<bool> camera_used(n_cameras, false), trigger_used(n_triggers, false);
    for (std::size_t n = 0; n < lens.size(); ++n) {
      if (!inlier[n]) continue;
      LensObservation& lo = lens[n];
      if (x_only && lo.camera == 0) continue;
      const int residuals = 2 * static_cast<int>(lo.cost.centres_px.size());
      ceres::LossFunction* loss = new ceres::HuberLoss(co.huber_px * std::sqrt(residuals / 2.0));
      RigPoseBlock& p = rig[lo.trigger];
      if (lo.camera == 0) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<MicroImageCost, ceres::DYNAMIC, kIntrinsicsSize, 4, 3,
                                            3>(new MicroImageCost(lo.cost), residuals),
            loss, k[0].data(), p.q.data(), p.t.data(), points[lo.point].data());
      } else {
        RigPoseBlock& e = block(lo.camera, lo.trigger);
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<RigMicroImageCost, ceres::DYNAMIC, kIntrinsicsSize, 4,
                                            3, 4, 3, 3>(new RigMicroImageCost{lo.cost}, residuals),
            loss, k[lo.camera].data(), p.q.data(), p.t.data(), e.q.data(), e.t.data(),
            points[lo.point].data());
      }
      camera_used[lo.camera] = true;
      trigger_used[lo.trigger] = true;
    }
    for (CornerObservation& ob : corners) {
      if (x_only && ob.camera == 0) continue;
      const int residuals = ob.cost.residuals();
      ceres::LossFunction* loss =
          new ceres::ScaledLoss(new ceres::HuberLoss(co.huber_px * std::sqrt(residuals / 2.0)),
                                plate_weight[ob.camera] * plate_weight[ob.camera],
                                ceres::TAKE_OWNERSHIP);
      RigPoseBlock& p = rig[ob.trigger];
      if (ob.camera == 0) {
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<PlateCornerCost, ceres::DYNAMIC, kIntrinsicsSize, 4, 3,
                                            1>(new PlateCornerCost(ob.cost), residuals),
            loss, k[0].data(), p.q.data(), p.t.data(), &inset[0]);
      } else {
        RigPoseBlock& e = block(ob.camera, ob.trigger);
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<RigPlateCornerCost, ceres::DYNAMIC, kIntrinsicsSize, 4,
                                            3, 4, 3, 1>(new RigPlateCornerCost{ob.cost}, residuals),
            loss, k[ob.camera].data(), p.q.data(), p.t.data(), e.q.data(), e.t.data(),
            inset_of(ob.camera));
      }
      camera_used[ob.camera] = true;
      trigger_used[ob.trigger] = true;
    }
    for (int t = 0; t < n_triggers; ++t) {
      if (!trigger_used[t]) continue;
      problem.SetManifold(rig[t].q.data(), new ceres::QuaternionManifold());
      if (x_only) {
        problem.SetParameterBlockConstant(rig[t].q.data());
        problem.SetParameterBlockConstant(rig[t].t.data());
      }
    }
    if (x_only)  // camera 0's points held; those of a camera X alone move with it
      for (int j = 0; j < n_points; ++j)
        if (problem.HasParameterBlock(points[j].data()))
          problem.SetParameterBlockConstant(points[j].data());
    for (int c = 0; c < n_cameras; ++c) {
      if (!camera_used[c]) continue;
      if (c > 0)
        for (RigPoseBlock& e : extrinsics[c])
          if (problem.HasParameterBlock(e.q.data()))
            problem.SetManifold(e.q.data(), new ceres::QuaternionManifold());
      if (problem.HasParameterBlock(&inset[c])) {
        // Solve (a) holds a shared inset with the rest of camera 0.
        if (co.estimate_corner_inset && !(x_only && c == 0)) {
          problem.SetParameterLowerBound(&inset[c], 0, -kRigMaxInsetTfPx);
          problem.SetParameterUpperBound(&inset[c], 0, kRigMaxInsetTfPx);
        } else {
          problem.SetParameterBlockConstant(&inset[c]);
        }
      }
      if (static_cast<int>(constant.size()) == kIntrinsicsSize) {
        problem.SetParameterBlockConstant(k[c].data());
        continue;
      }
      if (co.estimate_principal_point && co.principal_point_prior_px > 0)
        problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<PrincipalPointPriorCost, 2, kIntrinsicsSize>(
                new PrincipalPointPriorCost{pp0[c], co.principal_point_prior_px}),
            nullptr, k[c].data());
      if (!constant.empty())
        problem.SetManifold(k[c].data(), new ceres::SubsetManifold(kIntrinsicsSize, constant));
      for (int i = 0; i < 3; ++i) {
        problem.SetParameterLowerBound(k[c].data(), i, (1 - kRigBound) * nominal[c][i]);
        problem.SetParameterUpperBound(k[c].data(), i, (1 + kRigBound) * nominal[c][i]);
      }
      const double size[2] = {static_cast<double>(cameras[c].initial.intrinsics.width_px),
                              static_cast<double>(cameras[c].initial.intrinsics.height_px)};
      for (int a = 0; a < 2; ++a) {
        problem.SetParameterLowerBound(k[c].data(), 3 + a, nominal[c][3 + a] - 0.1 * size[a]);
        problem.SetParameterUpperBound(k[c].data(), 3 + a, nominal[c][3 + a] + 0.1 * size[a]);
      }
    }

    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::SPARSE_SCHUR;
    const bool last = round == kRounds - 1;
    solver_options.max_num_iterations = last ? 2 * co.max_iterations : co.max_iterations;
    solver_options.num_threads = co.threads;
    // The last solve stops at a relative cost change of 1e-7: on the
    // `medium` rig (200 000 residual blocks) at 1e-9 it crept on for 40
    // iterations with steps of 1e-3 and the cost unchanged in 7 digits.
    solver_options.function_tolerance = last ? 1e-7 : 1e-6;
    solver_options.parameter_tolerance = last ? 1e-10 : 1e-8;
    const std::string stage =
        RigFormat("rig BA %d/%d%s", round + 1, kRounds,
                  x_only ? " (cameras X; camera 0, trajectory, map held)" : "");
    say(RigFormat("%s: %d residual blocks, %d parameter blocks", stage.c_str(),
                  problem.NumResidualBlocks(), problem.NumParameterBlocks()));
    struct Callback : ceres::IterationCallback {
      const ProgressFn* progress;
      std::string stage;
      ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
        if (*progress)
          (*progress)(RigFormat("%s iteration %3d  cost %.6e  |step| %.3e%s", stage.c_str(),
                                s.iteration, s.cost, s.step_norm,
                                s.step_is_successful ? "" : "  (rejected step)"));
        return ceres::SOLVER_CONTINUE;
      }
    } callback;
    callback.progress = &progress;
    callback.stage = stage;
    solver_options.callbacks.push_back(&callback);
    ceres::Solve(solver_options, &problem, &summary);
    say(summary.BriefReport());
    result.solver_seconds += summary.total_time_in_seconds;
    result.iterations += static_cast<int>(summary.iterations.size()) - 1;
    if (first_cost < 0 && !x_only) first_cost = summary.initial_cost;
    if (!summary.IsSolutionUsable())
      return Error{"rig calibration: " + stage + ": " + summary.message};

    if (per_trigger && round < 2) {
      // Non-rigid: the map points found again in every placed image by its
      // solved pose (guided_matches.h: within guided_radius_px of the
      // projection, the ratio test among those, the virtual depth within
      // 10 % of the predicted): the cross-camera observations that PnP's
      // inliers against the grown map missed, and the far camera's links to
      // points placed by its neighbours.
      for (std::size_t j = 0; j < points.size(); ++j) grown.points[j].p_in_w0_mm = points[j];
      const MapIndex solved = MapIndex::Of(grown);
      std::vector<int> solved_point;  // MapIndex order -> index into `points`
      for (int j = 0; j < static_cast<int>(grown.points.size()); ++j)
        if (grown.points[j].descriptor.size() == static_cast<std::size_t>(kDescriptorSize))
          solved_point.push_back(j);
      std::set<std::tuple<int, int, int>> seen_keypoint, seen_point;  // (camera, frame, kp / point)
      for (const LensObservation& lo : lens) {
        seen_keypoint.insert({lo.camera, lo.frame, lo.keypoint});
        seen_point.insert({lo.camera, lo.frame, lo.point});
      }
      const std::size_t before = lens.size();
      const float ratio2 =
          static_cast<float>(options.registration.guided_ratio * options.registration.guided_ratio);
      for (int c = 0; c < n_cameras; ++c) {
        const processing::CameraModel model(FromVector(k[c], cameras[c].initial.intrinsics));
        for (std::size_t f = 0; f < cameras[c].frames.size(); ++f) {
          const CalibrationFrame& frame = cameras[c].frames[f];
          const auto trigger = trigger_of_frame.find(frame.frame);
          if (trigger == trigger_of_frame.end() || !placed[c][trigger->second]) continue;
          const int t = trigger->second;
          const Pose c0_from_cx = c == 0 ? Pose::Identity() : PoseOf(block(c, t));
          const Pose cx_from_w0 = c0_from_cx.inverse() * PoseOf(rig[t]);
          const ProjectedMapGrid grid(
              solved, model, cx_from_w0, cameras[c].initial.intrinsics.width_px / 2,
              cameras[c].initial.intrinsics.height_px / 2, options.registration.guided_radius_px);
          FrameObservations obs;
          obs.frame = frame.frame;
          obs.features = frame.features;
          obs.virtual_depth.assign(frame.virtual_depth.begin(), frame.virtual_depth.end());
          CompleteObservations(model, &obs);
          std::map<int, std::pair<float, int>> best_of_point;  // point -> (distance^2, keypoint)
          for (int kp = 0; kp < obs.features.size(); ++kp) {
            if (seen_keypoint.count({c, static_cast<int>(f), kp})) continue;
            float d1 = 0;
            const int nearest =
                grid.Nearest(obs.tf_px[kp], obs.features.Descriptor(kp), ratio2, &d1);
            if (nearest < 0) continue;
            const double v =
                kp < static_cast<int>(obs.virtual_depth.size()) ? obs.virtual_depth[kp] : NAN;
            if (!(std::abs(v / grid.virtual_depth(nearest) - 1) < 0.1)) continue;
            const auto [it, added] = best_of_point.try_emplace(nearest, d1, kp);
            if (!added && d1 < it->second.first) it->second = {d1, kp};
          }
          for (const auto& [point, best] : best_of_point) {
            const int j = solved_point[point];
            if (!seen_point.insert({c, static_cast<int>(f), j}).second) continue;
            add_observation(c, t, j, static_cast<int>(f), best.second);
          }
        }
      }
      inlier.resize(lens.size(), true);
      say(
          RigFormat("guided re-association: %zu observations added (map points found again "
                    "in the images by their solved poses)",
                    lens.size() - before));
    }
    if (round == 0) reweigh_plate_corners();
    if (round == 1) {
      // Observations above max(outlier_px, 3 x the median RMS) out.
      std::vector<double> rms(lens.size(), std::numeric_limits<double>::infinity());
      std::vector<double> r;
      for (std::size_t n = 0; n < lens.size(); ++n) {
        if (!evaluate(lens[n], &r)) continue;
        double ss = 0;
        for (const double x : r) ss += x * x;
        rms[n] = std::sqrt(ss / lens[n].cost.centres_px.size());
      }
      const double threshold = std::max(co.outlier_px, 3 * Median(rms));
      for (std::size_t n = 0; n < lens.size(); ++n)
        if (!(rms[n] <= threshold)) {
          inlier[n] = false;
          ++result.rejected_observations;
        }
      say(RigFormat("outliers: %lld of %zu observations above %.2f px RMS dropped",
                    result.rejected_observations, lens.size(), threshold));
      reweigh_plate_corners();
    }
    if (!last) continue;

    // Covariance (rig_calibration.h, step 4).
    for (RigCameraResult& rc : result.cameras)
      rc.std_dev.fill(std::numeric_limits<double>::quiet_NaN());
    if (!co.covariance) continue;
    std::vector<internal::KeptBlock> kept;
    std::vector<std::vector<int>> free(n_cameras);
    for (int c = 0; c < n_cameras; ++c) {
      internal::KeptBlock block{k[c].data(), {}};
      for (int i = 0; i < kIntrinsicsSize; ++i)
        if (std::find(constant.begin(), constant.end(), i) == constant.end()) {
          free[c].push_back(i);
          block.names.push_back(RigFormat("camera %d %s", c, kRigParameterNames[i]));
        }
      kept.push_back(block);
    }
    struct KeptExtrinsics {
      int camera = 0, block = 0, kept = 0;  // kept: its rotation's index in `kept`
    };
    std::vector<KeptExtrinsics> kept_extrinsics;
    for (int c = 1; c < n_cameras; ++c)
      for (std::size_t b = 0; b < extrinsics[c].size(); ++b) {
        RigPoseBlock& e = extrinsics[c][b];
        if (!problem.HasParameterBlock(e.q.data())) continue;
        const std::string name = per_trigger ? RigFormat("c0_from_c%d trigger %lld", c,
                                                         static_cast<long long>(trigger_frame[b]))
                                             : RigFormat("c0_from_c%d", c);
        kept_extrinsics.push_back({c, static_cast<int>(b), static_cast<int>(kept.size())});
        kept.push_back({e.q.data(), {name + " rot x", name + " rot y", name + " rot z"}});
        kept.push_back({e.t.data(), {name + " t x", name + " t y", name + " t z"}});
      }
    for (int c = 0; c < n_cameras; ++c)
      if (problem.HasParameterBlock(&inset[c]))
        kept.push_back({&inset[c], {RigFormat("camera %d inset", c)}});
    for (int t = 0; t < n_triggers; ++t) {
      const std::string name = RigFormat("trigger %lld", static_cast<long long>(trigger_frame[t]));
      kept.push_back({rig[t].q.data(), {name + " rot x", name + " rot y", name + " rot z"}});
      kept.push_back({rig[t].t.data(), {name + " t x", name + " t y", name + " t z"}});
    }
    std::vector<double*> point_blocks;
    for (Eigen::Vector3d& p : points)
      if (problem.HasParameterBlock(p.data())) point_blocks.push_back(p.data());
    Expected<internal::ReducedCovariance> reduced =
        internal::ComputeReducedCovariance(&problem, kept, point_blocks);
    if (!reduced) {
      result.flags.push_back("covariance: " + reduced.error().message);
      continue;
    }
    if (reduced->rank_deficiency > 0 || reduced->singular_points > 0) {
      result.flags.push_back(RigFormat(
          "covariance: rank-deficient by %d, %d points not determined: the frames do not "
          "determine %s",
          reduced->rank_deficiency, reduced->singular_points,
          reduced->null_directions.empty() ? "some points" : reduced->null_directions.c_str()));
      continue;
    }
    double ss = 0;
    long long m = 0;
    std::vector<double> r;
    for (std::size_t n = 0; n < lens.size(); ++n) {
      if (!inlier[n] || !evaluate(lens[n], &r)) continue;
      for (const double x : r) ss += x * x;
      m += static_cast<long long>(r.size());
    }
    const long long dof = m - problem.NumParameters();
    const double variance = dof > 0 ? ss / dof : std::numeric_limits<double>::quiet_NaN();
    int coordinate = 0;
    for (int c = 0; c < n_cameras; ++c)
      for (const int i : free[c])
        result.cameras[c].std_dev[i] = reduced->std_dev[coordinate++] * std::sqrt(variance);
    for (const KeptExtrinsics& ke : kept_extrinsics) {
      const int fq = reduced->first_coordinate[ke.kept];
      const int ft = reduced->first_coordinate[ke.kept + 1];
      if (fq < 0 || ft < 0) continue;
      const int at[6] = {fq, fq + 1, fq + 2, ft, ft + 1, ft + 2};
      // Ceres' QuaternionManifold: x + d = [cos|d|, sin|d| d/|d|] x, a
      // rotation by 2|d|: the rotation vector is 2 d.
      const double scale[6] = {2, 2, 2, 1, 1, 1};
      Eigen::Matrix<double, 6, 6>& s = extrinsics_covariance[ke.camera][ke.block];
      for (int a = 0; a < 6; ++a)
        for (int b = 0; b < 6; ++b)
          s(a, b) = reduced->covariance(at[a], at[b]) * scale[a] * scale[b] * variance;
    }
    result.covariance_computed = true;
    result.weakest_direction = reduced->weakest_direction;
  }

  // Results.
  for (int c = 0; c < n_cameras; ++c) result.cameras[c].corner_inset_tf_px = *inset_of(c);
  result.initial_cost = first_cost;
  result.final_cost = summary.final_cost;
  result.termination = ceres::TerminationTypeToString(summary.termination_type);
  result.usable = summary.IsSolutionUsable();
  std::vector<double> camera_ss(n_cameras, 0);
  std::vector<long long> camera_m(n_cameras, 0);
  double ss = 0;
  long long m = 0;
  std::vector<std::vector<RigCalibrationResult::Observer>> observers(points.size());
  std::vector<double> point_ss(points.size(), 0);
  std::vector<long long> point_m(points.size(), 0);
  std::vector<double> r;
  for (std::size_t n = 0; n < lens.size(); ++n) {
    if (!inlier[n] || !evaluate(lens[n], &r)) continue;
    const LensObservation& lo = lens[n];
    for (const double x : r) camera_ss[lo.camera] += x * x;
    camera_m[lo.camera] += static_cast<long long>(r.size());
    ++result.cameras[lo.camera].observations;
    for (const double x : r) point_ss[lo.point] += x * x;
    point_m[lo.point] += static_cast<long long>(r.size());
    observers[lo.point].push_back(
        {lo.camera, cameras[lo.camera].frames[lo.frame].frame, lo.keypoint});
  }
  for (int c = 0; c < n_cameras; ++c) {
    ss += camera_ss[c];
    m += camera_m[c];
    RigCameraResult& rc = result.cameras[c];
    rc.serial = cameras[c].serial;
    rc.calibration = cameras[c].initial;
    rc.calibration.intrinsics = FromVector(k[c], cameras[c].initial.intrinsics);
    rc.initial = initial[c];
    rc.frames = static_cast<int>(cameras[c].frames.size());
    if (c == 0) {
      rc.c0_from_cx = Pose::Identity();
      rc.c0_from_cx_initial = Pose::Identity();
    } else if (!per_trigger) {
      rc.c0_from_cx = PoseOf(extrinsics[c][0]);
      rc.c0_from_cx_covariance = extrinsics_covariance[c][0];
    } else {
      for (int t = 0; t < n_triggers; ++t) {
        if (!placed[c][t]) continue;
        rc.per_trigger.push_back(FramePose{trigger_frame[t], -1, PoseOf(extrinsics[c][t])});
        rc.per_trigger_covariance.push_back(extrinsics_covariance[c][t]);
      }
      rc.c0_from_cx = RobustMean(rc.per_trigger);
    }
    rc.rmse_px = camera_m[c] > 0 ? std::sqrt(camera_ss[c] / camera_m[c]) : 0;
    rc.plate_weight = plate_weight[c];
    if (!rc.calibration.intrinsics.Check())
      result.flags.push_back("camera " + rc.serial +
                             ": diverged: its intrinsics left their valid range");
    for (int i = 0; i < 3; ++i)
      if (std::abs(k[c][i] / nominal[c][i] - 1) > kRigBound - 1e-3)
        result.flags.push_back(RigFormat("camera %s: diverged: %s reached its bound",
                                         rc.serial.c_str(), kRigParameterNames[i]));
  }
  result.rmse_px = m > 0 ? std::sqrt(ss / m) : 0;
  if (result.rmse_px > 1.0)
    result.flags.push_back(RigFormat("reprojection RMSE %.2f px is high (> 1 px)", result.rmse_px));
  for (int t = 0; t < n_triggers; ++t)
    result.trajectory.push_back(FramePose{trigger_frame[t], -1, PoseOf(rig[t]).inverse()});

  // The shared map: camera 0's, at the joint solution.
  ReferenceMap& out = result.map;
  out = map0;
  const double s0 = cameras[0].initial.intrinsics.pixel_size_mm;
  out.camera.focal_px = (k[0][1] + 2 * k[0][2]) / (2 * s0);
  out.camera.principal_point_px =
      (Eigen::Vector2d(k[0][3], k[0][4]) - Eigen::Vector2d(0.5, 0.5)) / 2.0;
  const processing::CameraModel model0(result.cameras[0].calibration.intrinsics);
  for (MapImage& image : out.images) {
    const int t = trigger_of_frame.at(image.frame);
    image.w0_from_c0 = result.trajectory[t].world_from_cam;
    const CalibrationFrame& frame = cameras[0].frames[frame_index[0].at(image.frame)];
    for (int kp = 0; kp < static_cast<int>(image.keypoints.size()); ++kp) {
      Eigen::Vector3d x_v = internal::VirtualPoint(frame, kp);
      if (std::isnan(x_v.z())) x_v.z() = 2.0;
      image.keypoints[kp].pinhole_px = internal::TfPinholePx(k[0], model0, x_v);
    }
  }
  // Camera 0's points, then those of a camera X alone that kept two
  // observations: no track (the map's images are camera 0's), the
  // descriptor and colour of the keypoint that made them, sigma_mm the
  // plenoptic covariances of their observations fused
  // (plenoptic_point_noise.h, CalibrationOptions' map_sigma_v_rel and
  // map_sigma_tf_px).
  std::int64_t next_id = 1;
  for (const MapPoint& p : out.points) next_id = std::max(next_id, p.id + 1);
  for (int j = 0; j < n_points; ++j) {
    out.points[j].p_in_w0_mm = points[j];
    result.observers.push_back(observers[j]);
  }
  std::vector<processing::CameraModel> final_models;
  for (int c = 0; c < n_cameras; ++c)
    final_models.emplace_back(result.cameras[c].calibration.intrinsics);
  for (std::size_t j = n_points; j < points.size(); ++j) {
    if (observers[j].size() < 2) continue;
    const OwnPoint& made = own_point[j - n_points];
    const CalibrationFrame& frame = cameras[made.camera].frames[made.frame];
    Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
    for (const RigCalibrationResult::Observer& o : observers[j]) {
      const CalibrationFrame& seen = cameras[o.camera].frames[frame_index[o.camera].at(o.frame)];
      const Eigen::Vector3d x_v = internal::VirtualPoint(seen, o.keypoint);
      const int t = trigger_of_frame.at(o.frame);
      const Pose w0_from_cam = result.trajectory[t].world_from_cam *
                               (o.camera == 0 ? Pose::Identity() : PoseOf(block(o.camera, t)));
      const processing::CameraModel& model = final_models[o.camera];
      const Eigen::Matrix3d cov =
          PlenopticPointCovariance(model, w0_from_cam.inverse() * points[j],
                                   co.map_sigma_v_rel * x_v.z(), co.map_sigma_tf_px);
      const Eigen::Matrix3d rot = w0_from_cam.linear();
      const Eigen::Matrix3d info = (rot * cov * rot.transpose()).inverse();
      if (info.allFinite()) information += info;
    }
    const Eigen::Matrix3d fused = information.inverse();
    if (!fused.allFinite()) continue;
    MapPoint point;
    point.id = next_id++;
    point.p_in_w0_mm = points[j];
    point.rgb = frame.rgb[made.keypoint];
    point.sigma_mm = fused.diagonal().cwiseSqrt().cast<float>();
    point.error_px = point_m[j] > 0 ? std::sqrt(point_ss[j] / point_m[j]) : 0;
    const float* d = frame.features.Descriptor(made.keypoint);
    point.descriptor.assign(d, d + kDescriptorSize);
    out.points.push_back(std::move(point));
    result.observers.push_back(observers[j]);
    ++result.own_points;
  }
  for (const auto& seen : result.observers) {
    std::set<int> seen_by;
    for (const RigCalibrationResult::Observer& o : seen) seen_by.insert(o.camera);
    if (seen_by.size() > 1) ++result.shared_points;
  }
  if (!result.flags.empty()) result.usable = false;
  result.total_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::string RigTruthComparison::Report() const {
  std::string text;
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const Camera& k = cameras[c];
    text += RigFormat(
        "camera %zu (%s) vs truth: f_L %+.3f %%, b_L0 %+.3f %%, B %+.3f %%, "
        "principal point %.2f px",
        c, k.serial.c_str(), 100 * k.f_l_rel, 100 * k.b_l0_rel, 100 * k.b_rel,
        k.principal_point_px);
    if (c > 0) {
      text += RigFormat(
          "; c0_from_cx joint %.3f mm / %.4f deg | registered alone, nominal "
          "intrinsics (%d frames, %d of them passing the pose checks): robust mean %.3f mm / "
          "%.4f deg, per-frame median %.3f mm / %.4f deg",
          k.joint_mm, k.joint_deg, k.start_frames, k.registered, k.mean_mm, k.mean_deg,
          k.median_mm, k.median_deg);
      if (k.true_registered > 0)
        text += RigFormat(
            " | registered alone, true intrinsics (%d frames): robust mean %.3f mm "
            "/ %.4f deg, per-frame median %.3f mm / %.4f deg",
            k.true_registered, k.true_mean_mm, k.true_mean_deg, k.true_median_mm,
            k.true_median_deg);
    }
    text += "\n";
  }
  text += RigFormat(
      "gates (f_L, b_L0, B within 0.3 %%, principal point 0.5 px, c0_from_cx 0.2 mm "
      "/ 0.01 deg and better than registered alone): %s\n",
      GatesMet() ? "met" : "NOT met");
  return text;
}

bool RigTruthComparison::GatesMet() const {
  for (std::size_t c = 0; c < cameras.size(); ++c) {
    const Camera& k = cameras[c];
    if (std::abs(k.f_l_rel) > 0.003 || std::abs(k.b_l0_rel) > 0.003 || std::abs(k.b_rel) > 0.003 ||
        k.principal_point_px > 0.5)
      return false;
    // Better than registered alone: than the better of the two baselines.
    const double alone_mm =
        std::isnan(k.true_median_mm) ? k.median_mm : std::min(k.median_mm, k.true_median_mm);
    const double alone_deg =
        std::isnan(k.true_median_deg) ? k.median_deg : std::min(k.median_deg, k.true_median_deg);
    if (c > 0 && (k.joint_mm > 0.2 || k.joint_deg > 0.01 || k.joint_mm >= alone_mm ||
                  k.joint_deg >= alone_deg))
      return false;
  }
  return true;
}

std::vector<FramePose> RegisterAgainstCamera0(const CalibrationResult& camera0,
                                              const CalibrationInput& camera,
                                              const processing::CameraIntrinsics& intrinsics,
                                              const FrameRegistrationOptions& options) {
  const MapIndex index = MapIndex::Of(camera0.map);
  const processing::CameraModel model(intrinsics);
  std::map<std::int64_t, Pose> w0_from_c0;
  for (const FramePose& p : camera0.poses) w0_from_c0[p.frame] = p.world_from_cam;
  std::vector<FramePose> out;
  for (const CalibrationFrame& frame : camera.frames) {
    const auto c0 = w0_from_c0.find(frame.frame);
    if (c0 == w0_from_c0.end()) continue;
    FrameObservations obs;
    obs.frame = frame.frame;
    obs.features = frame.features;
    obs.virtual_depth.assign(frame.virtual_depth.begin(), frame.virtual_depth.end());
    CompleteObservations(model, &obs);
    const FrameRegistration r = RegisterFrame(index, model, obs, RegistrationMethod::kPnp, options);
    if (r.success)
      out.push_back(FramePose{frame.frame, -1, c0->second.inverse() * r.w0_from_cam.pose});
  }
  return out;
}

Expected<RigTruthComparison> CompareRigWithTruth(
    const RigCalibrationResult& result, const std::vector<CameraCalibration>& truth,
    const std::vector<Pose>& c0_from_cx_truth,
    const std::vector<std::vector<FramePose>>& registered_with_truth) {
  if (truth.size() != result.cameras.size() || c0_from_cx_truth.size() != result.cameras.size())
    return Error{
        RigFormat("rig truth comparison: %zu cameras calibrated, %zu true intrinsics, "
                  "%zu true c0_from_cx",
                  result.cameras.size(), truth.size(), c0_from_cx_truth.size())};
  RigTruthComparison out;
  for (std::size_t c = 0; c < result.cameras.size(); ++c) {
    const RigCameraResult& rc = result.cameras[c];
    const IntrinsicsVector e = ToVector(rc.calibration.intrinsics);
    const IntrinsicsVector t = ToVector(truth[c].intrinsics);
    RigTruthComparison::Camera k;
    k.serial = rc.serial;
    k.f_l_rel = e[0] / t[0] - 1;
    k.b_l0_rel = e[1] / t[1] - 1;
    k.b_rel = e[2] / t[2] - 1;
    k.principal_point_px = std::hypot(e[3] - t[3], e[4] - t[4]);
    const Pose& truth_pose = c0_from_cx_truth[c];
    k.joint_mm = TranslationDifference(rc.c0_from_cx, truth_pose);
    k.joint_deg = RotationDifferenceDeg(rc.c0_from_cx, truth_pose);
    if (c > 0) {
      k.mean_mm = TranslationDifference(rc.c0_from_cx_initial, truth_pose);
      k.mean_deg = RotationDifferenceDeg(rc.c0_from_cx_initial, truth_pose);
      std::vector<double> mm, deg;
      for (const FramePose& p : rc.start) {
        mm.push_back(TranslationDifference(p.world_from_cam, truth_pose));
        deg.push_back(RotationDifferenceDeg(p.world_from_cam, truth_pose));
      }
      k.median_mm = Median(mm);
      k.median_deg = Median(deg);
      k.start_frames = static_cast<int>(rc.start.size());
      k.registered = static_cast<int>(rc.registered.size());
      if (c < registered_with_truth.size() && !registered_with_truth[c].empty()) {
        const std::vector<FramePose>& alone = registered_with_truth[c];
        const Pose mean = RobustMean(alone);
        k.true_mean_mm = TranslationDifference(mean, truth_pose);
        k.true_mean_deg = RotationDifferenceDeg(mean, truth_pose);
        mm.clear();
        deg.clear();
        for (const FramePose& p : alone) {
          mm.push_back(TranslationDifference(p.world_from_cam, truth_pose));
          deg.push_back(RotationDifferenceDeg(p.world_from_cam, truth_pose));
        }
        k.true_median_mm = Median(mm);
        k.true_median_deg = Median(deg);
        k.true_registered = static_cast<int>(alone.size());
      }
    }
    out.cameras.push_back(k);
  }
  return out;
}

}  // namespace lifmcr::registration
