#include "registration/map/map_extension.h"

#include "registration/estimators/plenoptic_point_noise.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <vector>

namespace lifmcr::registration {

namespace {
bool PositiveFinite(double x) { return x > 0 && std::isfinite(x); }
}  // namespace

Status MapExtensionOptions::Check() const {
  if (Status s = map_match.Check(); !s)
    return Error{"map extension: map_match: " + s.error().message};
  if (Status s = pair_match.Check(); !s)
    return Error{"map extension: pair_match: " + s.error().message};
  if (!PositiveFinite(sigma_v_relative))
    return Error{"map extension: sigma_v_relative: expected a finite number > 0"};
  if (!PositiveFinite(sigma_tf_px))
    return Error{"map extension: sigma_tf_px: expected a finite number > 0"};
  if (!(pose_sigma_mm >= 0) || !std::isfinite(pose_sigma_mm))
    return Error{"map extension: pose_sigma_mm: expected a finite number >= 0"};
  if (!PositiveFinite(agreement_chi2))
    return Error{"map extension: agreement_chi2: expected a finite number > 0"};
  if (min_cameras < 1) return Error{"map extension: min_cameras: expected >= 1"};
  return Status::Ok();
}

std::string MapExtension::BriefReport() const {
  char line[256];
  std::snprintf(line, sizeof line,
                "%d keypoints pending (%d matched the map, %d without depth), %d pairs joined, %d "
                "disagreed: %d points added",
                pending, matched, no_depth, joined, disagreed, added);
  return line;
}

int SharedMapBuilder::Root(int i) {
  while (observations_[static_cast<std::size_t>(i)].parent != i) {
    Observation& o = observations_[static_cast<std::size_t>(i)];
    o.parent = observations_[static_cast<std::size_t>(o.parent)].parent;  // path halving
    i = o.parent;
  }
  return i;
}

Status SharedMapBuilder::AddFrame(int camera_order, const processing::CameraModel& camera,
                                  const FrameObservations& frame, const Pose& w0_from_cam,
                                  const MapIndex& map) {
  if (Status s = options_.Check(); !s) return s;
  const int n = frame.features.size();
  if (frame.p_in_cam.size() != static_cast<std::size_t>(n) ||
      frame.virtual_depth.size() != static_cast<std::size_t>(n))
    return Error{"map extension: frame " + std::to_string(frame.frame) +
                 ": keypoints, depths and camera points differ in number"};
  std::vector<bool> in_map(static_cast<std::size_t>(n), false);
  if (map.size() > 0 && n > 0)
    for (const Match& m : MatchDescriptors(frame.features.descriptors.data(), n, *map.descriptors,
                                           options_.map_match))
      in_map[static_cast<std::size_t>(m.query)] = true;

  PendingFrame pending;
  pending.camera_order = camera_order;
  pending.frame = frame.frame;
  const int slot = static_cast<int>(frames_.size());
  const Eigen::Matrix3d rotation = w0_from_cam.linear();
  const Eigen::Matrix3d pose_covariance =
      options_.pose_sigma_mm * options_.pose_sigma_mm * Eigen::Matrix3d::Identity();
  for (int k = 0; k < n; ++k) {
    const std::size_t i = static_cast<std::size_t>(k);
    if (in_map[i]) {
      ++report_.matched;
      continue;
    }
    const Eigen::Vector3d& p_in_cam = frame.p_in_cam[i];
    if (!p_in_cam.allFinite() || !std::isfinite(frame.virtual_depth[i])) {
      ++report_.no_depth;
      continue;
    }
    Observation o;
    o.p_in_w0_mm = w0_from_cam * p_in_cam;
    o.covariance = rotation *
                       PlenopticPointCovariance(camera, p_in_cam,
                                                options_.sigma_v_relative * frame.virtual_depth[i],
                                                options_.sigma_tf_px) *
                       rotation.transpose() +
                   pose_covariance;
    o.information = o.covariance.inverse();
    if (!o.information.allFinite()) {
      ++report_.no_depth;
      continue;
    }
    o.frame_slot = slot;
    o.descriptor = static_cast<int>(pending.observations.size());
    o.parent = static_cast<int>(observations_.size());
    pending.observations.push_back(o.parent);
    pending.descriptors.insert(pending.descriptors.end(), frame.features.Descriptor(k),
                               frame.features.Descriptor(k) + kDescriptorSize);
    observations_.push_back(o);
    track_frames_.push_back({slot});
    ++report_.pending;
  }
  frames_.push_back(std::move(pending));
  // The frames it pairs with: the same trigger of the other cameras, the
  // neighbouring triggers of its own.
  for (int other = 0; other < slot; ++other) {
    const PendingFrame& f = frames_[static_cast<std::size_t>(other)];
    const bool same_trigger = f.frame == frame.frame && f.camera_order != camera_order;
    const bool neighbour = f.camera_order == camera_order && std::llabs(f.frame - frame.frame) == 1;
    if (same_trigger || neighbour) Pair(slot, other);
  }
  return Status::Ok();
}

void SharedMapBuilder::Pair(int a, int b) {
  const PendingFrame& fa = frames_[static_cast<std::size_t>(a)];
  const PendingFrame& fb = frames_[static_cast<std::size_t>(b)];
  const int na = static_cast<int>(fa.observations.size());
  const int nb = static_cast<int>(fb.observations.size());
  if (na == 0 || nb == 0) return;
  for (const Match& m : MatchDescriptors(fa.descriptors.data(), na, fb.descriptors.data(), nb,
                                         options_.pair_match)) {
    const int i = fa.observations[static_cast<std::size_t>(m.query)];
    const int j = fb.observations[static_cast<std::size_t>(m.train)];
    const Observation& oi = observations_[static_cast<std::size_t>(i)];
    const Observation& oj = observations_[static_cast<std::size_t>(j)];
    if (oi.emitted || oj.emitted) continue;
    const Eigen::Vector3d d = oi.p_in_w0_mm - oj.p_in_w0_mm;
    const double d2 = d.dot((oi.covariance + oj.covariance).ldlt().solve(d));
    if (!(d2 <= options_.agreement_chi2)) {
      ++report_.disagreed;
      continue;
    }
    const int ri = Root(i), rj = Root(j);
    if (ri == rj) continue;
    // A track holds one keypoint of a frame at most.
    std::vector<int>& fi = track_frames_[static_cast<std::size_t>(ri)];
    std::vector<int>& fj = track_frames_[static_cast<std::size_t>(rj)];
    const bool shared = std::any_of(fi.begin(), fi.end(), [&](int s) {
      return std::find(fj.begin(), fj.end(), s) != fj.end();
    });
    if (shared) continue;
    observations_[static_cast<std::size_t>(rj)].parent = ri;
    fi.insert(fi.end(), fj.begin(), fj.end());
    fj.clear();
    ++report_.joined;
  }
}

MapExtension SharedMapBuilder::AddTracksTo(ReferenceMap* map) {
  std::int64_t next_id = 1;
  for (const MapPoint& p : map->points) next_id = std::max(next_id, p.id + 1);
  // Members per root, in the order observed.
  std::map<int, std::vector<int>> tracks;
  for (int i = 0; i < static_cast<int>(observations_.size()); ++i)
    if (!observations_[static_cast<std::size_t>(i)].emitted) tracks[Root(i)].push_back(i);
  for (const auto& [root, members] : tracks) {
    if (members.size() < 2) continue;
    std::vector<int> cameras;
    for (const int i : members)
      cameras.push_back(
          frames_[static_cast<std::size_t>(observations_[static_cast<std::size_t>(i)].frame_slot)]
              .camera_order);
    std::sort(cameras.begin(), cameras.end());
    if (std::unique(cameras.begin(), cameras.end()) - cameras.begin() < options_.min_cameras)
      continue;
    Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
    Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
    int newest = members.front();
    for (const int i : members) {
      const Observation& o = observations_[static_cast<std::size_t>(i)];
      information += o.information;
      weighted += o.information * o.p_in_w0_mm;
      if (frames_[static_cast<std::size_t>(o.frame_slot)].camera_order >=
          frames_[static_cast<std::size_t>(
                      observations_[static_cast<std::size_t>(newest)].frame_slot)]
              .camera_order)
        newest = i;
    }
    const Eigen::Matrix3d covariance = information.inverse();
    MapPoint point;
    point.id = next_id++;
    point.p_in_w0_mm = covariance * weighted;
    point.sigma_mm = covariance.diagonal().cwiseMax(0.0).cwiseSqrt().cast<float>();
    const Observation& o = observations_[static_cast<std::size_t>(newest)];
    const float* descriptor = frames_[static_cast<std::size_t>(o.frame_slot)].descriptors.data() +
                              static_cast<std::size_t>(o.descriptor) * kDescriptorSize;
    point.descriptor.assign(descriptor, descriptor + kDescriptorSize);
    map->points.push_back(std::move(point));
    for (const int i : members) observations_[static_cast<std::size_t>(i)].emitted = true;
    ++report_.added;
  }
  const MapExtension report = report_;
  report_ = MapExtension{};
  return report;
}

}  // namespace lifmcr::registration
