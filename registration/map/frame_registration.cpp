#include "registration/map/frame_registration.h"

#include "registration/estimators/tf_projection.h"
#include "registration/map/guided_matches.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

namespace lifmcr::registration {

std::string_view ToString(RegistrationMethod method) {
  return method == RegistrationMethod::kPnp ? "pnp" : "ransac";
}

std::optional<RegistrationMethod> ParseRegistrationMethod(std::string_view name) {
  if (name == "pnp") return RegistrationMethod::kPnp;
  if (name == "ransac") return RegistrationMethod::kRansac3d;
  return std::nullopt;
}

MapIndex MapIndex::Of(const ReferenceMap& map) {
  MapIndex index;
  std::vector<float> descriptors;
  index.points_in_w0.reserve(map.points.size());
  descriptors.reserve(map.points.size() * kDescriptorSize);
  std::map<int, int> image_of_id;
  for (std::size_t i = 0; i < map.images.size(); ++i)
    image_of_id[map.images[i].image_id] = static_cast<int>(i);
  index.images = static_cast<int>(map.images.size());
  index.observation_begin.push_back(0);
  for (const MapPoint& point : map.points) {
    if (point.descriptor.size() != static_cast<std::size_t>(kDescriptorSize)) continue;
    index.points_in_w0.push_back(point.p_in_w0_mm);
    descriptors.insert(descriptors.end(), point.descriptor.begin(), point.descriptor.end());
    for (const TrackElement& e : point.track) {
      const auto image = image_of_id.find(e.image_id);
      if (image == image_of_id.end()) continue;
      const std::vector<MapKeypoint>& keypoints = map.images[image->second].keypoints;
      if (e.keypoint < 0 || e.keypoint >= static_cast<int>(keypoints.size())) continue;
      index.observations.push_back({image->second, keypoints[e.keypoint].tf_px});
    }
    index.observation_begin.push_back(static_cast<int>(index.observations.size()));
  }
  index.descriptors = std::make_shared<const DescriptorIndex>(std::move(descriptors));
  return index;
}

Status FrameRegistrationOptions::Check() const {
  if (Status s = match.Check(); !s) return s;
  if (Status s = fundamental.Check(); !s) return s;
  if (Status s = pnp.Check(); !s) return s;
  if (Status s = rigid.Check(); !s) return s;
  if (!(sigma_v_relative > 0) || !std::isfinite(sigma_v_relative))
    return Error{"registration options: sigma_v_relative: expected a finite number > 0"};
  if (!(sigma_tf_px > 0) || !std::isfinite(sigma_tf_px))
    return Error{"registration options: sigma_tf_px: expected a finite number > 0"};
  if (guided_rounds < 0) return Error{"registration options: guided_rounds: expected >= 0"};
  if (!(guided_radius_px > 0) || !std::isfinite(guided_radius_px))
    return Error{"registration options: guided_radius_px: expected a finite number > 0"};
  if (!(guided_ratio > 0 && guided_ratio <= 1))
    return Error{"registration options: guided_ratio: expected in (0, 1]"};
  if (Status s = checks.Check(); !s) return s;
  return Status::Ok();
}

std::string FrameRegistration::BriefReport(RegistrationMethod method) const {
  char line[512];
  int n = std::snprintf(line, sizeof line, "%s %s: %zu inliers of %zu matches, rmse %.3f px, %.1f ms",
                std::string(ToString(method)).c_str(), status.c_str(), inliers, matches, rmse_px,
                1e3 * seconds);
  if (guided_matches >= 0 && n > 0 && static_cast<std::size_t>(n) < sizeof line)
    n += std::snprintf(line + n, sizeof line - static_cast<std::size_t>(n), ", %d guided matches",
                       guided_matches);
  if (estimated && n > 0 && static_cast<std::size_t>(n) < sizeof line)
    std::snprintf(line + n, sizeof line - static_cast<std::size_t>(n),
                  "; spread %.3f, sigma %.2f mm / %.3f deg, depth agreement %.2f (median z %.2f), "
                  "depth spread %.3f",
                  checks.spread, checks.sigma_mm, checks.sigma_deg, checks.depth_agreement,
                  checks.median_depth_z, checks.depth_spread);
  return line;
}

namespace {

// The matches whose map point the keyframe that saw most of them also saw
// go through the fundamental filter with that keyframe; its outliers are
// removed. Returns how many (-1: not applied).
int FilterMatchesByFundamental(const MapIndex& map, const FrameObservations& frame,
                               const FundamentalFilterOptions& options,
                               std::vector<Match>* matches) {
  if (map.images == 0 || map.observation_begin.size() != static_cast<std::size_t>(map.size()) + 1)
    return -1;
  std::vector<int> seen(static_cast<std::size_t>(map.images), 0);
  for (const Match& m : *matches)
    for (int o = map.observation_begin[m.train]; o < map.observation_begin[m.train + 1]; ++o)
      ++seen[map.observations[o].image];
  const int keyframe = static_cast<int>(std::max_element(seen.begin(), seen.end()) - seen.begin());
  std::vector<Eigen::Vector2d> query, reference;
  std::vector<std::size_t> which;  // index into matches of each pair
  for (std::size_t i = 0; i < matches->size(); ++i) {
    const Match& m = (*matches)[i];
    for (int o = map.observation_begin[m.train]; o < map.observation_begin[m.train + 1]; ++o) {
      if (map.observations[o].image != keyframe) continue;
      query.push_back(frame.tf_px[m.query]);
      reference.push_back(map.observations[o].tf_px.cast<double>());
      which.push_back(i);
      break;
    }
  }
  const FundamentalFilterResult f = FilterByFundamental(query, reference, options);
  if (!f.applied) return -1;
  std::vector<char> drop(matches->size(), 0);
  for (std::size_t k = 0; k < which.size(); ++k) drop[which[k]] = f.inlier[k] ? 0 : 1;
  std::size_t out = 0;
  for (std::size_t i = 0; i < matches->size(); ++i)
    if (!drop[i]) (*matches)[out++] = (*matches)[i];
  matches->resize(out);
  return f.outliers;
}

// Map point j (MapIndex order) matched to keypoint i of the frame.
struct Pair {
  int point = 0;
  int query = 0;
};

// Guided re-matching (FrameRegistrationOptions::guided_rounds): the map
// points projected by cam_from_w0, each keypoint against those within
// radius_px of it, the ratio test among them, each point its nearest
// keypoint.
std::vector<Pair> GuidedPairs(const MapIndex& map, const processing::CameraModel& camera,
                              const FrameObservations& frame, const Pose& cam_from_w0,
                              double radius_px, double ratio) {
  const ProjectedMapGrid grid(map, camera, cam_from_w0, camera.intrinsics().width_px / 2,
                              camera.intrinsics().height_px / 2, radius_px);
  const float ratio2 = static_cast<float>(ratio * ratio);
  std::map<int, std::pair<float, int>> best_of_point;  // point -> (distance^2, keypoint)
  for (int i = 0; i < frame.features.size(); ++i) {
    float d1 = 0;
    const int nearest = grid.Nearest(frame.tf_px[i], frame.features.Descriptor(i), ratio2, &d1);
    if (nearest < 0) continue;
    const auto [it, added] = best_of_point.try_emplace(nearest, d1, i);
    if (!added && d1 < it->second.first) it->second = {d1, i};
  }
  std::vector<Pair> pairs;
  pairs.reserve(best_of_point.size());
  for (const auto& [point, best] : best_of_point) pairs.push_back({point, best.second});
  return pairs;
}

}  // namespace

FrameRegistration RegisterFrame(const MapIndex& map, const processing::CameraModel& camera,
                                const FrameObservations& frame, RegistrationMethod method,
                                const FrameRegistrationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  FrameRegistration result;
  const auto finish = [&](std::string status) {
    result.status = std::move(status);
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
  };
  std::vector<Match> matches = MatchDescriptors(
      frame.features.descriptors.data(), frame.features.size(), *map.descriptors, options.match);
  if (method == RegistrationMethod::kPnp && options.fundamental.enabled)
    result.fundamental_outliers = FilterMatchesByFundamental(map, frame, options.fundamental, &matches);
  result.matches = matches.size();
  result.match_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  if (method == RegistrationMethod::kPnp) {
    PnpOptions pnp_options = options.pnp;
    pnp_options.sigma_v_relative = options.sigma_v_relative;
    std::vector<Pair> pairs;
    pairs.reserve(matches.size());
    for (const Match& m : matches) pairs.push_back({m.train, m.query});
    std::vector<Eigen::Vector3d> points;
    std::vector<Eigen::Vector2d> tf;
    std::vector<double> v;
    const auto solve = [&](const std::vector<Pair>& with) {
      points.clear();
      tf.clear();
      v.clear();
      for (const Pair& p : with) {
        points.push_back(map.points_in_w0[p.point]);
        tf.push_back(frame.tf_px[p.query]);
        v.push_back(frame.virtual_depth[p.query]);
      }
      return EstimatePlenopticPnp(camera, {points, tf, v}, pnp_options);
    };
    // The pose's checks (pose_checks.h), filling the result's inliers and figures.
    const auto judge = [&](const PnpResult& pnp, const std::vector<Pair>& with) {
      result.inliers = pnp.num_inliers;
      result.rmse_px = pnp.rmse_px;
      result.w0_from_cam = Inverse(PoseWithCovariance{pnp.cam_from_world, pnp.covariance});
      result.inlier_points.clear();
      result.inlier_tf_px.clear();
      result.inlier_queries.clear();
      std::vector<Eigen::Vector3d> inlier_points_in_w0;
      std::vector<double> inlier_v;
      for (std::size_t i = 0; i < with.size() && i < pnp.inlier_mask.size(); ++i) {
        if (!pnp.inlier_mask[i]) continue;
        result.inlier_points.push_back(with[i].point);
        result.inlier_tf_px.push_back(frame.tf_px[with[i].query]);
        result.inlier_queries.push_back(with[i].query);
        inlier_points_in_w0.push_back(map.points_in_w0[with[i].point]);
        inlier_v.push_back(frame.virtual_depth[with[i].query]);
      }
      result.estimated = true;
      std::vector<double> depth_z, depth_mm;
      InlierDepths(camera, pnp.cam_from_world, inlier_points_in_w0, inlier_v,
                   options.sigma_v_relative, &depth_z, &depth_mm);
      PoseEvidence evidence;
      evidence.inliers = static_cast<int>(pnp.num_inliers);
      evidence.inlier_tf_px = result.inlier_tf_px;
      evidence.tf_width = camera.intrinsics().width_px / 2;
      evidence.tf_height = camera.intrinsics().height_px / 2;
      evidence.rmse_px = pnp.rmse_px;
      evidence.covariance = result.w0_from_cam.covariance;
      evidence.w0_from_cam = result.w0_from_cam.pose;
      evidence.inlier_depth_z = depth_z;
      evidence.inlier_depth_mm = depth_mm;
      result.checks = MeasurePose(evidence, options.checks);
      return CheckPose(evidence, options.checks);
    };
    PnpResult pnp = solve(pairs);
    result.inliers = pnp.num_inliers;
    result.rmse_px = pnp.rmse_px;
    if (!pnp.success) return finish(pnp.status);
    std::string verdict = judge(pnp, pairs);
    // A refused pose only: where the descriptor search found enough, the
    // extra guided matches (of weaker keypoints, noisier) do not make the
    // pose better (the default small rig: c0_from_cx 0.30 -> 0.49 mm median
    // with them on every frame; docs/registration.md).
    for (int round = 0; round < options.guided_rounds && verdict != "ok"; ++round) {
      std::vector<Pair> guided =
          GuidedPairs(map, camera, frame, pnp.cam_from_world, options.guided_radius_px,
                      options.guided_ratio);
      result.guided_matches = static_cast<int>(guided.size());
      // The pose's inliers that guided matching did not pair.
      std::vector<char> point_used(static_cast<std::size_t>(map.size()), 0),
          query_used(static_cast<std::size_t>(frame.features.size()), 0);
      for (const Pair& p : guided) point_used[p.point] = query_used[p.query] = 1;
      for (std::size_t i = 0; i < pairs.size() && i < pnp.inlier_mask.size(); ++i)
        if (pnp.inlier_mask[i] && !point_used[pairs[i].point] && !query_used[pairs[i].query])
          guided.push_back(pairs[i]);
      PnpResult again = solve(guided);
      if (!again.success) break;
      pnp = std::move(again);
      pairs = std::move(guided);
      verdict = judge(pnp, pairs);
    }
    result.success = verdict == "ok";
    return finish(std::move(verdict));
  }

  std::vector<Eigen::Vector3d> src, dst;
  std::vector<Eigen::Matrix3d> covariance;
  std::vector<Eigen::Vector2d> tf;
  for (const Match& m : matches) {
    const Eigen::Vector3d& p = frame.p_in_cam[m.query];
    if (!p.allFinite()) continue;
    src.push_back(p);
    dst.push_back(map.points_in_w0[m.train]);
    covariance.push_back(PlenopticPointCovariance(
        camera, p, options.sigma_v_relative * frame.virtual_depth[m.query], options.sigma_tf_px));
    tf.push_back(frame.tf_px[m.query]);
  }
  const Rigid3dResult rigid = EstimateRigid3d({src, covariance, dst}, options.rigid);
  result.inliers = rigid.num_inliers;
  if (!rigid.success) return finish(rigid.status);
  result.w0_from_cam = {rigid.dst_from_src, rigid.covariance};
  // Reprojection RMS of the inliers, comparable with PnP's.
  const TfProjection projection = TfProjection::Of(camera);
  const Pose cam_from_w0 = rigid.dst_from_src.inverse();
  double sum = 0;
  std::size_t count = 0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    if (!rigid.inlier_mask[i]) continue;
    const double e2 = projection.SquaredError(cam_from_w0 * dst[i], tf[i]);
    if (!std::isfinite(e2)) continue;
    sum += e2;
    ++count;
  }
  result.rmse_px = count ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
  result.success = true;
  return finish("ok");
}

}  // namespace lifmcr::registration
