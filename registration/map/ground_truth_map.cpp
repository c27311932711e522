#include "registration/map/ground_truth_map.h"

#include "registration/features/frame_observations.h"
#include "registration/map/guided_matches.h"
#include "registration/map/poses_csv.h"
#include "replay/layout.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

namespace lifmcr::registration {
namespace {

float TrackDescriptorDistance2(const float* a, const float* b) {
  float sum = 0;
  for (int k = 0; k < kDescriptorSize; ++k) {
    const float d = a[k] - b[k];
    sum += d * d;
  }
  return sum;
}

// A map point while the map is built: its observations' back-projections
// (w0) and descriptors (rows of the builder's pool).
struct GrowingPoint {
  std::vector<Eigen::Vector3d> observed_in_w0;
  std::vector<std::size_t> descriptor_rows;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Vector3d Mean() const { return sum / static_cast<double>(observed_in_w0.size()); }
};

// The mean of the observations within `radius` of their component-wise
// median (all of them when none is).
Eigen::Vector3d RobustMean(const std::vector<Eigen::Vector3d>& x, double radius) {
  if (x.size() < 3) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : x) sum += p;
    return sum / static_cast<double>(x.size());
  }
  Eigen::Vector3d median;
  std::vector<double> c(x.size());
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < x.size(); ++i) c[i] = x[i][a];
    std::nth_element(c.begin(), c.begin() + c.size() / 2, c.end());
    median[a] = c[c.size() / 2];
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (const Eigen::Vector3d& p : x)
    if ((p - median).norm() <= radius) {
      sum += p;
      ++n;
    }
  return n > 0 ? Eigen::Vector3d(sum / n) : median;
}

// The row (of `rows`) whose descriptor has the least sum of distances to the others'.
std::size_t Medoid(const std::vector<std::size_t>& rows, const std::vector<float>& pool) {
  if (rows.size() <= 2) return rows.front();
  std::size_t best = rows.front();
  double best_sum = std::numeric_limits<double>::infinity();
  for (const std::size_t a : rows) {
    double sum = 0;
    for (const std::size_t b : rows)
      if (a != b)
        sum += std::sqrt(TrackDescriptorDistance2(pool.data() + a * kDescriptorSize,
                                             pool.data() + b * kDescriptorSize));
    if (sum < best_sum) {
      best_sum = sum;
      best = a;
    }
  }
  return best;
}

}  // namespace

Status GroundTruthMapOptions::Check() const {
  if (Status s = features.Check(); !s) return Error{"ground-truth map: " + s.error().message};
  if (Status s = match.Check(); !s) return Error{"ground-truth map: " + s.error().message};
  if (!(merge_distance_mm > 0) || !std::isfinite(merge_distance_mm))
    return Error{"ground-truth map: merge_distance_mm: expected > 0"};
  if (!(track_radius_px > 0) || !std::isfinite(track_radius_px))
    return Error{"ground-truth map: track_radius_px: expected > 0"};
  return Status::Ok();
}

Expected<ReferenceMap> BuildGroundTruthMap(const std::filesystem::path& sequence_dir,
                                           const std::string& serial,
                                           const std::vector<std::int64_t>& frames,
                                           const processing::CameraModel& camera,
                                           const GroundTruthMapOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  Expected<std::vector<FramePose>> poses = ReadPosesCsv(layout::PosesCsvPath(sequence_dir, serial));
  if (!poses) return poses.error();
  std::map<std::int64_t, FramePose> pose_of;
  for (const FramePose& p : *poses) pose_of[p.frame] = p;
  Expected<std::unique_ptr<FrameObserver>> observer = FrameObserver::Open(
      ObservationSource::kGroundTruth, sequence_dir, serial, camera, {}, options.features);
  if (!observer) return observer.error();

  ReferenceMap map;
  map.camera.serial = serial;
  map.camera.width_px = camera.intrinsics().width_px / 2;
  map.camera.height_px = camera.intrinsics().height_px / 2;
  map.camera.focal_px = camera.FeatureFocalPx() / 2;
  map.camera.principal_point_px = processing::CameraModel::TfOfRaw(camera.principal_point_px());
  std::vector<GrowingPoint> growing;
  std::vector<float> pool;  // every observation's descriptor, one row each
  const double cell = options.track_radius_px, radius2 = cell * cell;
  const int grid_w = static_cast<int>(std::ceil(map.camera.width_px / cell)),
            grid_h = static_cast<int>(std::ceil(map.camera.height_px / cell));
  const float ratio2 = static_cast<float>(options.match.ratio * options.match.ratio);
  const float max2 = options.match.max_distance > 0
                         ? static_cast<float>(options.match.max_distance * options.match.max_distance)
                         : std::numeric_limits<float>::infinity();
  for (const std::int64_t frame : frames) {
    const auto pose = pose_of.find(frame);
    if (pose == pose_of.end())
      return Error{layout::PosesCsvPath(sequence_dir, serial).string() + ": no pose for frame " +
                   std::to_string(frame)};
    Expected<FrameObservations> obs = (*observer)->Observe(frame);
    if (!obs) return obs.error();
    MapImage image;
    image.image_id = static_cast<int>(map.images.size()) + 1;
    image.frame = frame;
    image.vicon_frame = pose->second.vicon_frame;
    image.name = layout::RawFramePath(sequence_dir, serial, frame).filename().string();
    image.w0_from_c0 = pose->second.world_from_cam;
    const Pose cam_from_w0 = image.w0_from_c0.inverse();
    // The map so far projected into this frame, in a grid of track_radius_px cells.
    std::vector<std::vector<int>> grid(static_cast<std::size_t>(grid_w) * grid_h);
    std::vector<Eigen::Vector2d> projected(growing.size());
    for (std::size_t j = 0; j < growing.size(); ++j) {
      double v = 0;
      if (!ProjectMapPoint(camera, cam_from_w0, growing[j].Mean(), &projected[j], &v)) continue;
      const Eigen::Vector2d& p = projected[j];
      if (!(p.x() >= 0 && p.y() >= 0 && p.x() < grid_w * cell && p.y() < grid_h * cell)) continue;
      grid[static_cast<std::size_t>(p.y() / cell) * grid_w + static_cast<int>(p.x() / cell)]
          .push_back(static_cast<int>(j));
    }
    // Each keypoint's candidate; each point keeps its nearest keypoint.
    const int n = obs->features.size();
    std::vector<Eigen::Vector3d> p_in_w0(static_cast<std::size_t>(n));
    std::vector<int> continues(static_cast<std::size_t>(n), -1);
    std::map<int, std::pair<float, int>> best_of_point;  // point -> (distance^2, keypoint)
    for (int k = 0; k < n; ++k) {
      if (!obs->p_in_cam[k].allFinite()) continue;
      p_in_w0[k] = image.w0_from_c0 * obs->p_in_cam[k];
      const Eigen::Vector2d xy = obs->tf_px[k];
      const int gx = static_cast<int>(std::floor(xy.x() / cell)),
                gy = static_cast<int>(std::floor(xy.y() / cell));
      int nearest = -1;
      float d1 = std::numeric_limits<float>::infinity(), d2 = d1;
      for (int y = std::max(0, gy - 1); y <= std::min(grid_h - 1, gy + 1); ++y)
        for (int x = std::max(0, gx - 1); x <= std::min(grid_w - 1, gx + 1); ++x)
          for (const int j : grid[static_cast<std::size_t>(y) * grid_w + x]) {
            if ((projected[j] - xy).squaredNorm() > radius2) continue;
            if ((growing[j].Mean() - p_in_w0[k]).norm() > options.merge_distance_mm) continue;
            float d = std::numeric_limits<float>::infinity();
            for (const std::size_t row : growing[j].descriptor_rows)
              d = std::min(d, TrackDescriptorDistance2(obs->features.Descriptor(k),
                                                  pool.data() + row * kDescriptorSize));
            if (d < d1) {
              d2 = d1;
              d1 = d;
              nearest = j;
            } else if (d < d2) {
              d2 = d;
            }
          }
      if (nearest < 0 || !(d1 < ratio2 * d2) || !(d1 <= max2)) continue;
      const auto [it, added] = best_of_point.try_emplace(nearest, d1, k);
      if (!added && d1 < it->second.first) it->second = {d1, k};
    }
    for (const auto& [point, best] : best_of_point) continues[best.second] = point;
    for (int k = 0; k < n; ++k) {
      if (!obs->p_in_cam[k].allFinite()) continue;
      int index = continues[k];
      if (index < 0) {
        index = static_cast<int>(growing.size());
        growing.emplace_back();
      }
      GrowingPoint& point = growing[index];
      point.observed_in_w0.push_back(p_in_w0[k]);
      point.sum += p_in_w0[k];
      point.descriptor_rows.push_back(pool.size() / kDescriptorSize);
      pool.insert(pool.end(), obs->features.Descriptor(k),
                  obs->features.Descriptor(k) + kDescriptorSize);
      MapKeypoint keypoint;
      keypoint.tf_px = obs->features.keypoints[k].xy_px;
      keypoint.virtual_depth = static_cast<float>(obs->virtual_depth[k]);
      const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(obs->tf_px[k]);
      keypoint.pinhole_px = processing::CameraModel::TfOfRaw(
          camera.FeatureImagePoint({raw.x(), raw.y(), obs->virtual_depth[k]}));
      keypoint.point_id = index + 1;
      image.keypoints.push_back(keypoint);
    }
    map.images.push_back(std::move(image));
  }
  // The points: robust mean position, medoid descriptor, the track.
  map.points.resize(growing.size());
  for (std::size_t j = 0; j < growing.size(); ++j) {
    MapPoint& point = map.points[j];
    point.id = static_cast<std::int64_t>(j) + 1;
    point.p_in_w0_mm = RobustMean(growing[j].observed_in_w0, options.merge_distance_mm / 2);
    const std::size_t row = Medoid(growing[j].descriptor_rows, pool);
    point.descriptor.assign(pool.begin() + static_cast<std::ptrdiff_t>(row * kDescriptorSize),
                            pool.begin() + static_cast<std::ptrdiff_t>((row + 1) * kDescriptorSize));
  }
  for (const MapImage& image : map.images)
    for (std::size_t k = 0; k < image.keypoints.size(); ++k)
      map.points[static_cast<std::size_t>(image.keypoints[k].point_id - 1)].track.push_back(
          {image.image_id, static_cast<int>(k)});
  return map;
}

}  // namespace lifmcr::registration
