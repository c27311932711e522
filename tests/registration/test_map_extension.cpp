// registration/map/map_extension.h on a scene with a known answer: points
// seen by two cameras 120 mm apart (the `small` camera, 1.5 m away) with
// exact keypoints and virtual depths fuse to the true points; a keypoint
// whose depth is off disagrees and adds nothing; points seen by one camera
// alone stay out when min_cameras asks for two.
#include "registration/estimators/plenoptic_point_noise.h"
#include "registration/estimators/tf_projection.h"
#include "registration/map/map_extension.h"
#include "tests/registration/random_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <vector>

namespace lifmcr::registration {
namespace {

struct Scene {
  std::vector<Eigen::Vector3d> points_in_w0;
  std::vector<std::vector<float>> descriptors;  // one per point, unit length
};

Scene MakeScene(std::mt19937_64& rng, int count) {
  Scene scene;
  std::uniform_real_distribution<double> lateral(-150, 150), depth(1400, 1600);
  std::normal_distribution<float> component(0, 1);
  for (int i = 0; i < count; ++i) {
    scene.points_in_w0.emplace_back(60 + lateral(rng), lateral(rng), depth(rng));
    std::vector<float> d(kDescriptorSize);
    float norm = 0;
    for (float& x : d) {
      x = component(rng);
      norm += x * x;
    }
    for (float& x : d) x /= std::sqrt(norm);
    scene.descriptors.push_back(d);
  }
  return scene;
}

// The keypoints of every point the camera at w0_from_cam sees, exact; the
// points listed in `depth_scale` get their virtual depth scaled.
FrameObservations Observe(const processing::CameraModel& camera, const Pose& w0_from_cam,
                          const Scene& scene, std::int64_t frame,
                          const std::map<int, double>& depth_scale = {}) {
  const TfProjection projection = TfProjection::Of(camera);
  FrameObservations obs;
  obs.frame = frame;
  const Pose cam_from_w0 = w0_from_cam.inverse();
  for (std::size_t i = 0; i < scene.points_in_w0.size(); ++i) {
    const Eigen::Vector3d p = cam_from_w0 * scene.points_in_w0[i];
    Eigen::Vector2d tf;
    if (!projection(p.data(), tf.data())) continue;
    if (tf.x() < 0 || tf.y() < 0 || tf.x() > camera.intrinsics().width_px / 2.0 ||
        tf.y() > camera.intrinsics().height_px / 2.0)
      continue;
    Keypoint k;
    k.xy_px = tf.cast<float>();
    obs.features.keypoints.push_back(k);
    obs.features.descriptors.insert(obs.features.descriptors.end(), scene.descriptors[i].begin(),
                                    scene.descriptors[i].end());
    const auto scale = depth_scale.find(static_cast<int>(i));
    obs.virtual_depth.push_back(camera.VirtualDepthOfDepth(p.z()) *
                                (scale == depth_scale.end() ? 1.0 : scale->second));
  }
  CompleteObservations(camera, &obs);
  return obs;
}

TEST(MapExtension, PointsSeenByTwoCamerasFuseToTheTruth) {
  std::mt19937_64 rng(5);
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  const Scene scene = MakeScene(rng, 150);
  const Pose w0_from_a = Pose::Identity();
  Pose w0_from_b = Pose::Identity();
  w0_from_b.translation() = Eigen::Vector3d(120, 0, 0);
  // The back-projection of an exact observation is the point itself.
  const FrameObservations a = Observe(camera, w0_from_a, scene, 0);
  ASSERT_GT(a.features.size(), 50);
  for (int k = 0; k < a.features.size(); ++k)
    ASSERT_TRUE(a.p_in_cam[static_cast<std::size_t>(k)].allFinite());
  // Ten points camera B sees 5 % deeper in virtual depth.
  std::map<int, double> wrong;
  for (int i = 0; i < 10; ++i) wrong[i] = 1.05;
  const FrameObservations b = Observe(camera, w0_from_b, scene, 0, wrong);
  ReferenceMap map;
  const MapIndex empty = MapIndex::Of(map);
  SharedMapBuilder builder{MapExtensionOptions{}};
  ASSERT_TRUE(builder.AddFrame(0, camera, a, w0_from_a, empty));
  ASSERT_TRUE(builder.AddFrame(1, camera, b, w0_from_b, empty));
  const MapExtension report = builder.AddTracksTo(&map);
  std::printf("%s\n", report.BriefReport().c_str());
  // Every point both see joins the map but the ten of wrong depth.
  int both = 0, wrong_seen_by_both = 0;
  for (std::size_t i = 0; i < scene.points_in_w0.size(); ++i) {
    const auto sees = [&](const FrameObservations& o) {
      for (int k = 0; k < o.features.size(); ++k)
        if (o.features.Descriptor(k)[0] == scene.descriptors[i][0]) return true;
      return false;
    };
    if (sees(a) && sees(b)) {
      ++both;
      if (wrong.count(static_cast<int>(i))) ++wrong_seen_by_both;
    }
  }
  ASSERT_GT(both, 40);
  EXPECT_EQ(report.disagreed, wrong_seen_by_both);
  EXPECT_EQ(report.added, both - wrong_seen_by_both);
  ASSERT_EQ(static_cast<int>(map.points.size()), report.added);
  for (const MapPoint& point : map.points) {
    // Its descriptor names its scene point.
    std::size_t i = 0;
    while (i < scene.descriptors.size() && scene.descriptors[i] != point.descriptor) ++i;
    ASSERT_LT(i, scene.descriptors.size());
    EXPECT_FALSE(wrong.count(static_cast<int>(i)));
    // Keypoints are stored as float: a micrometre of rounding.
    EXPECT_LT((point.p_in_w0_mm - scene.points_in_w0[i]).norm(), 1e-3);
    // Two rays 4.6 deg apart fix the point's depth better than camera A's
    // virtual depth alone (its rays run nearly along w0's z).
    const Eigen::Vector3d p_in_a = w0_from_a.inverse() * scene.points_in_w0[i];
    const double one = std::sqrt(PlenopticRayVariance(
        camera, p_in_a,
        MapExtensionOptions{}.sigma_v_relative * camera.VirtualDepthOfDepth(p_in_a.z())));
    EXPECT_GT(point.sigma_mm.minCoeff(), 0.0f);
    EXPECT_LT(point.sigma_mm.z(), one);
  }
  // A second call adds nothing more.
  EXPECT_EQ(builder.AddTracksTo(&map).added, 0);
}

TEST(MapExtension, MinCamerasKeepsOutPointsOfOneCamera) {
  std::mt19937_64 rng(6);
  const processing::CameraModel camera(test::SmallCameraIntrinsics());
  const Scene scene = MakeScene(rng, 100);
  Pose second = Pose::Identity();
  second.translation() = Eigen::Vector3d(10, 0, 0);
  const FrameObservations f0 = Observe(camera, Pose::Identity(), scene, 0);
  const FrameObservations f1 = Observe(camera, second, scene, 1);
  for (const int min_cameras : {1, 2}) {
    MapExtensionOptions options;
    options.min_cameras = min_cameras;
    ReferenceMap map;
    const MapIndex empty = MapIndex::Of(map);
    SharedMapBuilder builder(options);
    // Neighbouring triggers of one camera pair with each other.
    ASSERT_TRUE(builder.AddFrame(0, camera, f0, Pose::Identity(), empty));
    ASSERT_TRUE(builder.AddFrame(0, camera, f1, second, empty));
    const MapExtension report = builder.AddTracksTo(&map);
    std::printf("min_cameras %d: %s\n", min_cameras, report.BriefReport().c_str());
    if (min_cameras == 1)
      EXPECT_GT(report.added, 40);
    else
      EXPECT_EQ(report.added, 0);
  }
  MapExtensionOptions bad;
  bad.min_cameras = 0;
  EXPECT_NE(bad.Check().error().message.find("min_cameras"), std::string::npos);
}

}  // namespace
}  // namespace lifmcr::registration
