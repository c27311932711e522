// The plate's ArUco centres in the map from corners seen in posed frames
// (registration/map/aruco_corners.h): exact recovery from exact observations,
// graceful with detection noise, the CSV read back, and the errors of too
// few or parallel rays.
#include "registration/map/aruco_corners.h"
#include "evaluation/plate_alignment.h"
#include "tests/test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace lifmcr::registration {
namespace {

// A camera 1.8 m from the plate centre, looking at it from `azimuth_deg`.
Pose LookingAtPlate(double azimuth_deg, double elevation_deg) {
  const Eigen::Vector3d target(200, 140, 0);
  const double a = azimuth_deg * M_PI / 180, e = elevation_deg * M_PI / 180;
  const Eigen::Vector3d eye =
      target + 1800 * Eigen::Vector3d(std::sin(a) * std::cos(e), -std::cos(a) * std::cos(e), std::sin(e));
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Pose w0_from_c0 = Pose::Identity();
  w0_from_c0.linear().col(0) = x;
  w0_from_c0.linear().col(1) = y;
  w0_from_c0.linear().col(2) = z;
  w0_from_c0.translation() = eye;
  return w0_from_c0;
}

// The 16 corners of markers 0..3 (100 mm squares about the template's centres).
Eigen::Vector3d CornerOf(const PlateTemplate& plate, int id, int corner) {
  static const double dx[4] = {-50, 50, 50, -50}, dy[4] = {50, 50, -50, -50};
  return plate.aruco_centers_mm[id] + Eigen::Vector3d(dx[corner], dy[corner], 0);
}

std::vector<ArucoCornerObservation> Observe(const std::vector<Pose>& poses,
                                            const processing::CameraModel& camera,
                                            double noise_tf_px, std::uint64_t seed) {
  const PlateTemplate plate = DefaultPlateTemplate();
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0, noise_tf_px);
  std::vector<ArucoCornerObservation> out;
  for (std::size_t f = 0; f < poses.size(); ++f)
    for (int id = 0; id < 4; ++id)
      for (int c = 0; c < 4; ++c) {
        const Eigen::Vector3d v = camera.Project(poses[f].inverse() * CornerOf(plate, id, c));
        const Eigen::Vector2d tf =
            processing::CameraModel::TfOfRaw(v.head<2>()) + Eigen::Vector2d(n(rng), n(rng));
        out.push_back({static_cast<std::int64_t>(f), id, c, tf, v.z()});
      }
  return out;
}

class ArucoCorners : public ::testing::Test {
 protected:
  ArucoCorners() : camera_(processing::CameraIntrinsics{}) {
    for (int f = 0; f < 6; ++f) {
      poses_.push_back(LookingAtPlate(-15 + 6 * f, 35 + 3 * (f % 3)));
      w0_from_c0_[f] = poses_.back();
    }
  }
  processing::CameraModel camera_;
  std::vector<Pose> poses_;
  std::map<std::int64_t, Pose> w0_from_c0_;
};

TEST_F(ArucoCorners, ExactObservationsGiveTheTemplate) {
  const PlateTemplate plate = DefaultPlateTemplate();
  Expected<ArucoCentersInMap> r = TriangulateArucoCenters(Observe(poses_, camera_, 0, 1), w0_from_c0_, camera_);
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_EQ(r->corners, 16);
  EXPECT_EQ(r->observations, 96);
  EXPECT_EQ(r->frames, 6);
  EXPECT_LT(r->ray_rms_mm, 1e-6);
  for (int id = 0; id < 4; ++id) EXPECT_LT((r->centers_mm[id] - plate.aruco_centers_mm[id]).norm(), 1e-6);
}

TEST_F(ArucoCorners, DetectionNoiseOfATenthPixelStaysSubMillimetre) {
  const PlateTemplate plate = DefaultPlateTemplate();
  Expected<ArucoCentersInMap> r = TriangulateArucoCenters(Observe(poses_, camera_, 0.1, 2), w0_from_c0_, camera_);
  ASSERT_TRUE(r) << r.error().message;
  std::cout << r->BriefReport() << "\n";
  for (int id = 0; id < 4; ++id) {
    const double off = (r->centers_mm[id] - plate.aruco_centers_mm[id]).norm();
    std::cout << "marker " << id << ": " << off << " mm from the template\n";
    EXPECT_LT(off, 1.0);
  }
  EXPECT_GT(r->ray_rms_mm, 0.0);
  EXPECT_LT(r->ray_rms_mm, 1.0);
  // The plate alignment with these centres: the map is the plate frame, so
  // world_from_map is near the identity and the P_1 check near zero.
  std::vector<ViconPoseSample> samples{{1, Pose(Pose::Identity())}};
  std::vector<Eigen::Vector3d> vsk(plate.vicon_markers_mm.begin(), plate.vicon_markers_mm.end());
  Expected<PlateAlignment> a = AlignPlate(samples, vsk, plate, r->centers_mm);
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_LT(a->world_from_map.translation().norm(), 2.0);
  EXPECT_LT(a->aruco_check_mm, 1.0);
}

TEST_F(ArucoCorners, CsvRoundTripAndErrors) {
  std::vector<ArucoCornerObservation> obs = Observe(poses_, camera_, 0, 3);
  obs[0].virtual_depth = std::nan("");
  test::TempDir dir;
  test::WriteFile(dir / "aruco_corners.csv", FormatArucoCornersCsv(obs));
  Expected<std::vector<ArucoCornerObservation>> back = ReadArucoCornersCsv(dir / "aruco_corners.csv");
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->size(), obs.size());
  EXPECT_TRUE(std::isnan((*back)[0].virtual_depth));
  EXPECT_NEAR((*back)[5].tf_px.x(), obs[5].tf_px.x(), 1e-4);
  EXPECT_EQ((*back)[17].marker_id, obs[17].marker_id);

  test::WriteFile(dir / "bad.csv", "frame,marker_id,corner,tf_x_px,tf_y_px,virtual_depth\n0,1,7,1,2,3\n");
  Expected<std::vector<ArucoCornerObservation>> bad = ReadArucoCornersCsv(dir / "bad.csv");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().message.find("bad.csv:2"), std::string::npos) << bad.error().message;

  // Out of range: checked before the integer casts (a frame of 1e300 was
  // cast to int64, undefined behaviour) and the row formatting.
  const std::string header = "frame,marker_id,corner,tf_x_px,tf_y_px,virtual_depth\n";
  for (const auto& [row, expected] : std::vector<std::pair<std::string, std::string>>{
           {"1e300,1,2,1,2,3", ":2:1: expected an integer frame"},
           {"0,1e10,2,1,2,3", ":2:1: expected an integer frame"},
           {"0,1,2.5,1,2,3", ":2:1: expected an integer frame"},
           {"0,1,2,1e300,2,3", ":2:7: expected a TF coordinate"},
           {"0,1,2,1,2,-1e6", ":2:11: expected a TF coordinate or virtual depth"},
           {"0,1,2,1,2," + std::string(5000, 'x'), "... (5000 bytes)"}}) {
    test::WriteFile(dir / "bad.csv", header + row + "\n");
    bad = ReadArucoCornersCsv(dir / "bad.csv");
    ASSERT_FALSE(bad) << row;
    EXPECT_NE(bad.error().message.find(expected), std::string::npos) << bad.error().message;
    EXPECT_LT(bad.error().message.size(), 300u);
  }

  // One frame only: a corner needs two rays.
  std::map<std::int64_t, Pose> one{{0, poses_[0]}};
  Expected<ArucoCentersInMap> r = TriangulateArucoCenters(obs, one, camera_);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("triangulation needs two"), std::string::npos) << r.error().message;
  // Two frames from the same place: parallel rays.
  std::map<std::int64_t, Pose> same{{0, poses_[1]}, {1, poses_[1]}};
  std::vector<ArucoCornerObservation> twice;
  for (ArucoCornerObservation o : Observe({poses_[1], poses_[1]}, camera_, 0, 4)) twice.push_back(o);
  r = TriangulateArucoCenters(twice, same, camera_);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("parallel"), std::string::npos) << r.error().message;
}

}  // namespace
}  // namespace lifmcr::registration
