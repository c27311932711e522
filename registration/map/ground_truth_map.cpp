#include "registration/map/ground_truth_map.h"

#include "registration/features/frame_observations.h"
#include "registration/map/poses_csv.h"
#include "replay/layout.h"

#include <cmath>
#include <map>

namespace lifmcr::registration {

Status GroundTruthMapOptions::Check() const {
  if (Status s = features.Check(); !s) return Error{"ground-truth map: " + s.error().message};
  if (Status s = match.Check(); !s) return Error{"ground-truth map: " + s.error().message};
  if (!(merge_distance_mm > 0) || !std::isfinite(merge_distance_mm))
    return Error{"ground-truth map: merge_distance_mm: expected > 0"};
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
  std::vector<float> descriptors;  // of map.points, contiguous for matching
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
    // Which keypoints continue an existing point.
    std::vector<std::int64_t> existing(obs->features.keypoints.size(), -1);
    if (!map.points.empty()) {
      for (const Match& m :
           MatchDescriptors(obs->features.descriptors.data(), obs->features.size(),
                            descriptors.data(), static_cast<int>(map.points.size()), options.match)) {
        if (!obs->p_in_cam[m.query].allFinite()) continue;
        const Eigen::Vector3d p_in_w0 = image.w0_from_c0 * obs->p_in_cam[m.query];
        if ((p_in_w0 - map.points[m.train].p_in_w0_mm).norm() < options.merge_distance_mm)
          existing[m.query] = m.train;
      }
    }
    for (std::size_t k = 0; k < obs->features.keypoints.size(); ++k) {
      if (!obs->p_in_cam[k].allFinite()) continue;
      std::int64_t index = existing[k];
      if (index < 0) {
        MapPoint point;
        point.id = static_cast<std::int64_t>(map.points.size()) + 1;
        point.p_in_w0_mm = image.w0_from_c0 * obs->p_in_cam[k];
        point.descriptor.assign(obs->features.Descriptor(static_cast<int>(k)),
                                obs->features.Descriptor(static_cast<int>(k)) + kDescriptorSize);
        descriptors.insert(descriptors.end(), point.descriptor.begin(), point.descriptor.end());
        index = static_cast<std::int64_t>(map.points.size());
        map.points.push_back(std::move(point));
      }
      MapKeypoint keypoint;
      keypoint.tf_px = obs->features.keypoints[k].xy_px;
      keypoint.virtual_depth = static_cast<float>(obs->virtual_depth[k]);
      const Eigen::Vector2d raw = processing::CameraModel::RawOfTf(obs->tf_px[k]);
      keypoint.pinhole_px = processing::CameraModel::TfOfRaw(
          camera.FeatureImagePoint({raw.x(), raw.y(), obs->virtual_depth[k]}));
      keypoint.point_id = map.points[index].id;
      map.points[index].track.push_back(
          {image.image_id, static_cast<int>(image.keypoints.size())});
      image.keypoints.push_back(keypoint);
    }
    map.images.push_back(std::move(image));
  }
  return map;
}

}  // namespace lifmcr::registration
