#include "registration/calibration/calibration_problem.h"

#include "processing/camera_model.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

namespace lifmcr::registration::internal {
namespace {

std::string Format(const char* fmt, auto... args) {
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer), fmt, args...);
  return buffer;
}

Pose PoseOfRvecTvec(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Mat r;
  cv::Rodrigues(rvec, r);
  Eigen::Matrix3d rotation;
  cv::cv2eigen(r, rotation);
  Pose c_from_w = Pose::Identity();
  c_from_w.linear() = rotation;
  c_from_w.translation() = Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1),
                                           tvec.at<double>(2));
  return c_from_w.inverse();
}

cv::Mat CameraMatrix(const processing::CameraModel& camera, double focal_px) {
  const Eigen::Vector2d c = camera.principal_point_px();
  return (cv::Mat_<double>(3, 3) << focal_px, 0, c.x(), 0, focal_px, c.y(), 0, 0, 1);
}

// Plate pose from the corners' virtual image points. The virtual image is a
// pinhole whose focal length b_L(Z) / s depends on depth: start from the
// frame's median virtual depth, then rescale each corner to the MLA-plane
// focal b_L0 / s with b_L of its depth under the current pose, twice.
bool PlatePose(const processing::CameraModel& camera, const CalibrationFrame& frame,
               Pose* w0_from_c) {
  const processing::CameraIntrinsics& k = camera.intrinsics();
  std::vector<float> vs;
  for (const float v : frame.virtual_depth)
    if (!std::isnan(v)) vs.push_back(v);
  if (vs.empty()) return false;
  std::nth_element(vs.begin(), vs.begin() + vs.size() / 2, vs.end());
  const double v_median = vs[vs.size() / 2];
  const Eigen::Vector2d c = camera.principal_point_px();
  std::vector<cv::Point3d> object;
  for (const PlateCorner& corner : frame.corners)
    object.emplace_back(corner.p_in_w_mm.x(), corner.p_in_w_mm.y(), corner.p_in_w_mm.z());
  std::vector<double> b_l(frame.corners.size(),
                          k.mla_to_main_lens_mm + v_median * k.mla_to_sensor_mm);
  const double focal = k.mla_to_main_lens_mm / k.pixel_size_mm;
  cv::Mat rvec, tvec;
  for (int round = 0; round < 3; ++round) {
    std::vector<cv::Point2d> image;
    for (std::size_t n = 0; n < frame.corners.size(); ++n) {
      const Eigen::Vector2d x_v = 2.0 * frame.corners[n].tf_px + Eigen::Vector2d(0.5, 0.5);
      const Eigen::Vector2d x = c + (x_v - c) * k.mla_to_main_lens_mm / b_l[n];
      image.emplace_back(x.x(), x.y());
    }
    if (!cv::solvePnP(object, image, CameraMatrix(camera, focal), cv::noArray(), rvec, tvec,
                      round > 0, round == 0 ? cv::SOLVEPNP_IPPE : cv::SOLVEPNP_ITERATIVE))
      return false;
    *w0_from_c = PoseOfRvecTvec(rvec, tvec);
    const Pose c_from_w = w0_from_c->inverse();
    for (std::size_t n = 0; n < frame.corners.size(); ++n) {
      const double z = (c_from_w * frame.corners[n].p_in_w_mm).z();
      if (!(z > k.main_focal_length_mm)) return false;
      b_l[n] = k.main_focal_length_mm * z / (z - k.main_focal_length_mm);
    }
  }
  return true;
}

}  // namespace

Expected<double> MlaDistanceFromPlate(const CalibrationInput& input,
                                      const processing::CameraIntrinsics& nominal,
                                      const CalibrationOptions& options) {
  const processing::CameraModel camera(nominal);
  const double f = nominal.main_focal_length_mm;
  std::vector<double> b_l0;
  for (const CalibrationFrame& frame : input.frames) {
    if (static_cast<int>(frame.corners.size()) < options.min_plate_corners) continue;
    Pose w0_from_c;
    if (!PlatePose(camera, frame, &w0_from_c)) continue;
    const Pose c_from_w = w0_from_c.inverse();
    for (std::size_t n = 0; n < frame.corners.size() && n < frame.corner_virtual_depth.size(); ++n) {
      const double v = frame.corner_virtual_depth[n];
      const double z = (c_from_w * frame.corners[n].p_in_w_mm).z();
      if (std::isnan(v) || !(z > f)) continue;
      b_l0.push_back(f * z / (z - f) - v * nominal.mla_to_sensor_mm);
    }
  }
  if (b_l0.empty())
    return Error{"recalibration: no plate corner with a virtual depth to start b_L0 from"};
  std::nth_element(b_l0.begin(), b_l0.begin() + b_l0.size() / 2, b_l0.end());
  return b_l0[b_l0.size() / 2];
}

Expected<InitialMap> Initialise(const CalibrationInput& input,
                                const processing::CameraIntrinsics& nominal,
                                const CalibrationOptions& options, const ProgressFn& progress) {
  const processing::CameraModel camera(nominal);
  const int n = static_cast<int>(input.frames.size());
  InitialMap map;
  map.frames.resize(n);
  std::vector<int> usable;
  for (int f = 0; f < n; ++f) {
    const CalibrationFrame& frame = input.frames[f];
    map.frames[f].track_of_keypoint.assign(frame.features.size(), -1);
    int with_depth = 0;
    for (const float v : frame.virtual_depth) with_depth += std::isnan(v) ? 0 : 1;
    if (with_depth < options.min_features) {
      map.frames[f].how = Format("rejected: %d keypoints with a virtual depth (at least %d)",
                                 with_depth, options.min_features);
      continue;
    }
    usable.push_back(f);
  }
  if (usable.empty())
    return Error{Format("features too few: no frame has %d keypoints with a virtual depth "
                        "(textured scene needed)",
                        options.min_features)};
  // The first frame that sees the plate starts; then the later frames in
  // order, then the earlier ones backwards, so each frame follows a
  // neighbour in time.
  int start = -1;
  for (const int f : usable)
    if (static_cast<int>(input.frames[f].corners.size()) >= options.min_plate_corners) {
      start = f;
      break;
    }
  if (start < 0)
    return Error{"no frame sees the marker plate (at least " +
                 std::to_string(options.min_plate_corners) +
                 " ArUco corners): the plate fixes the metric scale and the world frame"};
  std::vector<int> order;
  for (const int f : usable)
    if (f >= start) order.push_back(f);
  for (auto it = usable.rbegin(); it != usable.rend(); ++it)
    if (*it < start) order.push_back(*it);

  const double pinhole_focal = camera.FeatureFocalPx();
  const cv::Mat k_pinhole = CameraMatrix(camera, pinhole_focal);
  std::vector<int> placed_order;
  for (const int f : order) {
    const CalibrationFrame& frame = input.frames[f];
    FrameState& state = map.frames[f];
    // Candidate points: those seen by the last placed frames.
    std::vector<int> candidates;
    for (int back = static_cast<int>(placed_order.size()) - 1, used = 0;
         back >= 0 && used < options.match_window; --back, ++used)
      for (const int t : map.frames[placed_order[back]].track_of_keypoint)
        if (t >= 0) candidates.push_back(t);
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    std::vector<float> train;
    train.reserve(candidates.size() * kDescriptorSize);
    for (const int t : candidates) {
      const Observation& first = map.tracks[t].observations.front();
      const float* d = input.frames[first.frame].features.Descriptor(first.keypoint);
      train.insert(train.end(), d, d + kDescriptorSize);
    }
    // Only keypoints with a virtual depth take part.
    std::vector<int> query_keypoints;
    std::vector<float> query;
    for (int k = 0; k < frame.features.size(); ++k) {
      if (std::isnan(frame.virtual_depth[k])) continue;
      query_keypoints.push_back(k);
      const float* d = frame.features.Descriptor(k);
      query.insert(query.end(), d, d + kDescriptorSize);
    }
    const std::vector<Match> matches =
        candidates.empty()
            ? std::vector<Match>{}
            : MatchDescriptors(query.data(), static_cast<int>(query_keypoints.size()),
                               train.data(), static_cast<int>(candidates.size()), options.match);
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (const Match& m : matches) {
      const Eigen::Vector3d& p = map.tracks[candidates[m.train]].p_in_w_mm;
      object.emplace_back(p.x(), p.y(), p.z());
      const Eigen::Vector2d x =
          camera.FeatureImagePoint(VirtualPoint(frame, query_keypoints[m.query]));
      image.emplace_back(x.x(), x.y());
    }
    std::vector<int> inliers;
    bool placed = false;
    if (object.size() >= 6) {
      cv::Mat rvec, tvec;
      if (cv::solvePnPRansac(object, image, k_pinhole, cv::noArray(), rvec, tvec, false,
                             options.pnp_iterations, options.pnp_threshold_px, 0.999, inliers,
                             cv::SOLVEPNP_EPNP) &&
          static_cast<int>(inliers.size()) >= options.min_pnp_inliers) {
        // Refine on the inliers (Levenberg-Marquardt on the pinhole).
        std::vector<cv::Point3d> o_in;
        std::vector<cv::Point2d> i_in;
        for (const int i : inliers) {
          o_in.push_back(object[i]);
          i_in.push_back(image[i]);
        }
        cv::solvePnPRefineLM(o_in, i_in, k_pinhole, cv::noArray(), rvec, tvec);
        state.w0_from_c = PoseOfRvecTvec(rvec, tvec);
        state.how = Format("pnp: %zu of %zu matches", inliers.size(), matches.size());
        placed = true;
      }
    }
    if (!placed && static_cast<int>(frame.corners.size()) >= options.min_plate_corners) {
      placed = PlatePose(camera, frame, &state.w0_from_c);
      if (placed) {
        state.how = Format("plate: %zu corners", frame.corners.size());
        inliers.clear();
      }
    }
    if (!placed) {
      state.how = Format("rejected: placed neither by PnP (%zu matches, %zu inliers, need %d) "
                         "nor by the plate (%zu corners)",
                         matches.size(), inliers.size(), options.min_pnp_inliers,
                         frame.corners.size());
      if (progress) progress("init  frame " + std::to_string(frame.frame) + " " + state.how);
      continue;
    }
    state.placed = true;
    placed_order.push_back(f);
    for (const int i : inliers) {
      const Match& m = matches[i];
      const int t = candidates[m.train];
      const int k = query_keypoints[m.query];
      // A track takes one keypoint per frame.
      bool seen = false;
      for (const Observation& o : map.tracks[t].observations) seen |= o.frame == f;
      if (seen) continue;
      map.tracks[t].observations.push_back({f, k, true});
      state.track_of_keypoint[k] = t;
    }
    int added = 0;
    for (const int k : query_keypoints) {
      if (state.track_of_keypoint[k] >= 0) continue;
      const Eigen::Vector3d p_in_c = camera.BackProject(VirtualPoint(frame, k));
      if (!(p_in_c.z() > 0) || !p_in_c.allFinite()) continue;
      Track track;
      track.p_in_w_mm = state.w0_from_c * p_in_c;
      track.observations.push_back({f, k, true});
      state.track_of_keypoint[k] = static_cast<int>(map.tracks.size());
      map.tracks.push_back(std::move(track));
      ++added;
    }
    if (progress)
      progress(Format("init  frame %lld %s, %d new points, %zu points",
                      static_cast<long long>(frame.frame), state.how.c_str(), added,
                      map.tracks.size()));
  }
  return map;
}

}  // namespace lifmcr::registration::internal
