#include "replay/synth/vicon_sim.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/SVD>

#include <random>

namespace lifmcr::synth {
namespace {

Eigen::Matrix3d SmallRotation(std::mt19937_64& rng, double max_rad) {
  std::uniform_real_distribution<double> angle(-max_rad, max_rad);
  return (Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitX()) *
          Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitZ()))
      .toRotationMatrix();
}

std::uint64_t Mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

}  // namespace

MarkerCluster MakeCameraCluster(const std::string& subject, std::uint64_t seed) {
  std::mt19937_64 rng(Mix(seed ^ 0xC1u));
  std::uniform_real_distribution<double> jitter(-8.0, 8.0);
  MarkerCluster cluster;
  cluster.subject = subject;
  // A skewed quadrilateral in the cluster's x-z plane (mounted on top of the
  // camera body), one marker raised so that no two distances are equal.
  const std::array<Eigen::Vector3d, 4> base{
      Eigen::Vector3d(-55, 0, -30), Eigen::Vector3d(45, 0, -35), Eigen::Vector3d(50, -15, 30),
      Eigen::Vector3d(-35, 0, 40)};
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (int k = 0; k < 4; ++k) {
    cluster.markers_mm[k] = base[k] + Eigen::Vector3d(jitter(rng), 0.3 * jitter(rng), jitter(rng));
    centroid += cluster.markers_mm[k] / 4.0;
  }
  for (Eigen::Vector3d& m : cluster.markers_mm) m -= centroid;
  return cluster;
}

Pose MakeMarkerFromCam(std::uint64_t seed) {
  std::mt19937_64 rng(Mix(seed ^ 0xC2u));
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  // The optical centre in the cluster frame's terms: the cluster sits on top
  // of the body (camera -y), behind the lens (camera -z), roughly centred in x.
  Pose cam_from_marker = Pose::Identity();
  cam_from_marker.translation() =
      Eigen::Vector3d(15 * unit(rng), -75 + 12 * unit(rng), -45 + 15 * unit(rng));
  cam_from_marker.linear() = SmallRotation(rng, 4.0 * M_PI / 180.0);
  return cam_from_marker.inverse();
}

MarkerCluster MakePlateCluster(const std::string& subject,
                               const std::array<Eigen::Vector3d, 4>& corners_in_world,
                               Pose* world_from_plate_marker) {
  MarkerCluster cluster;
  cluster.subject = subject;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& c : corners_in_world) centroid += c / 4.0;
  for (int k = 0; k < 4; ++k) cluster.markers_mm[k] = corners_in_world[k] - centroid;
  *world_from_plate_marker = Pose::Identity();
  world_from_plate_marker->translation() = centroid;
  return cluster;
}

Pose DefaultViconFromWorld() {
  Pose pose = Pose::Identity();
  pose.linear() =
      Eigen::AngleAxisd(25.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(1250.0, -430.0, 760.0);
  return pose;
}

Pose ObserveCluster(const MarkerCluster& cluster, const Pose& vicon_from_marker, double noise_mm,
                    std::uint64_t seed, std::uint64_t index) {
  if (noise_mm <= 0) return vicon_from_marker;
  std::mt19937_64 rng(Mix(seed ^ Mix(index)));
  std::normal_distribution<double> noise(0.0, noise_mm);
  Eigen::Matrix<double, 3, 4> model, seen;
  for (int k = 0; k < 4; ++k) {
    model.col(k) = cluster.markers_mm[k];
    seen.col(k) = vicon_from_marker * cluster.markers_mm[k] +
                  Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  }
  Pose pose = Pose::Identity();
  pose.matrix() = Eigen::umeyama(model, seen, false);
  return pose;
}

std::int64_t ViconFrameOfImage(const SynthViconParams& vicon, std::int64_t image_frame) {
  return vicon.first_trigger_frame + image_frame * vicon.trigger_divider;
}

double TimeOfViconFrame(const SynthViconParams& vicon, std::int64_t vicon_frame) {
  return static_cast<double>(vicon_frame - vicon.first_trigger_frame) / vicon.rate_hz;
}

std::vector<std::int64_t> RecordedViconFrames(const SynthViconParams& vicon, int image_frames) {
  const std::int64_t first =
      std::max<std::int64_t>(1, vicon.first_trigger_frame - vicon.lead_in_frames);
  const std::int64_t last = ViconFrameOfImage(vicon, image_frames - 1) + vicon.trigger_divider - 1;
  std::vector<std::int64_t> frames;
  for (std::int64_t f = first; f <= last; ++f) frames.push_back(f);
  return frames;
}

std::vector<bool> OcclusionMask(int frame_count, int gaps, int length, std::uint64_t seed) {
  std::vector<bool> mask(frame_count, false);
  if (gaps <= 0 || frame_count <= 0) return mask;
  std::mt19937_64 rng(Mix(seed ^ 0x0CC1u));
  std::uniform_int_distribution<int> start(0, std::max(0, frame_count - length));
  for (int g = 0; g < gaps; ++g) {
    const int s = start(rng);
    for (int k = s; k < std::min(frame_count, s + length); ++k) mask[k] = true;
  }
  return mask;
}

}  // namespace lifmcr::synth
