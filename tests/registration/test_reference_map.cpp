// The reference map written as a COLMAP text model, a PLY, descriptors.bin
// and poses_<serial>.csv reads back to the same map; damaged files give
// errors naming the file.

#include "registration/features/features.h"
#include "registration/map/ground_truth_map.h"
#include "registration/features/intrinsics_yaml.h"
#include "registration/map/poses_csv.h"
#include "registration/map/reference_map.h"
#include "tests/test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sys/stat.h>

namespace lifmcr::registration {
namespace {

namespace fs = std::filesystem;

ReferenceMap RandomMap(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  ReferenceMap map;
  map.camera = {"40398673", 512, 384, 2291.5, {255.5, 191.25}};
  for (int i = 0; i < 4; ++i) {
    MapImage image;
    image.image_id = i + 1;
    image.frame = 10 + i;
    image.vicon_frame = 81 + 8 * i;
    image.name = "TypeE_40398673_0000" + std::to_string(10 + i) + "_Raw.bmp";
    image.w0_from_c0.linear() =
        Eigen::AngleAxisd(u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized())
            .toRotationMatrix();
    image.w0_from_c0.translation() = Eigen::Vector3d(100 * u(rng), 200 * u(rng), 900 + u(rng));
    for (int k = 0; k < 6; ++k) {
      MapKeypoint kp;
      kp.pinhole_px = {250 + 200 * u(rng), 190 + 150 * u(rng)};
      kp.tf_px = kp.pinhole_px.cast<float>() + Eigen::Vector2f(0.5f, -0.25f);
      kp.virtual_depth = static_cast<float>(3 + u(rng));
      image.keypoints.push_back(kp);
    }
    map.images.push_back(image);
  }
  for (int p = 0; p < 5; ++p) {
    MapPoint point;
    point.id = 100 + p;
    point.p_in_w0_mm = {300 * u(rng), 200 * u(rng), 50 * u(rng)};
    point.rgb = {static_cast<std::uint8_t>(10 * p), 200, static_cast<std::uint8_t>(255 - p)};
    point.sigma_mm = Eigen::Vector3f(0.1f, 0.2f, 0.3f * (p + 1));
    point.error_px = 0.25 + 0.01 * p;
    point.descriptor.resize(kDescriptorSize);
    for (float& d : point.descriptor) d = static_cast<float>(std::abs(u(rng)) * 100);
    for (int i = 0; i < 4; i += 1 + p % 2) {
      point.track.push_back({i + 1, p});
      map.images[i].keypoints[p].point_id = point.id;
    }
    map.points.push_back(point);
  }
  return map;
}

TEST(ReferenceMap, WriteReadRoundTrip) {
  test::TempDir tmp;
  const fs::path dir = tmp.path();
  const ReferenceMap map = RandomMap(5);
  ASSERT_TRUE(WriteReferenceMap(dir, map));
  for (const char* file : {"cameras.txt", "images.txt", "points3D.txt", "points.ply",
                           "descriptors.bin", "poses_40398673.csv"})
    EXPECT_TRUE(fs::exists(dir / file)) << file;
  Expected<ReferenceMap> back = ReadReferenceMap(dir);
  ASSERT_TRUE(back) << back.error().message;
  EXPECT_EQ(back->camera.serial, map.camera.serial);
  EXPECT_EQ(back->camera.width_px, 512);
  EXPECT_NEAR(back->camera.focal_px, map.camera.focal_px, 1e-6);
  EXPECT_NEAR((back->camera.principal_point_px - map.camera.principal_point_px).norm(), 0, 1e-6);
  ASSERT_EQ(back->images.size(), map.images.size());
  for (std::size_t i = 0; i < map.images.size(); ++i) {
    const MapImage &a = map.images[i], &b = back->images[i];
    EXPECT_EQ(b.image_id, a.image_id);
    EXPECT_EQ(b.frame, a.frame);
    EXPECT_EQ(b.vicon_frame, a.vicon_frame);
    EXPECT_EQ(b.name, a.name);
    EXPECT_LT((b.w0_from_c0.matrix() - a.w0_from_c0.matrix()).cwiseAbs().maxCoeff(), 1e-5);
    ASSERT_EQ(b.keypoints.size(), a.keypoints.size());
    for (std::size_t k = 0; k < a.keypoints.size(); ++k) {
      EXPECT_LT((b.keypoints[k].pinhole_px - a.keypoints[k].pinhole_px).norm(), 1e-3);
      EXPECT_EQ(b.keypoints[k].point_id, a.keypoints[k].point_id);
      if (a.keypoints[k].point_id >= 0) {
        EXPECT_EQ(b.keypoints[k].tf_px, a.keypoints[k].tf_px);
        EXPECT_EQ(b.keypoints[k].virtual_depth, a.keypoints[k].virtual_depth);
      }
    }
  }
  ASSERT_EQ(back->points.size(), map.points.size());
  for (std::size_t p = 0; p < map.points.size(); ++p) {
    const MapPoint &a = map.points[p], &b = back->points[p];
    EXPECT_EQ(b.id, a.id);
    EXPECT_LT((b.p_in_w0_mm - a.p_in_w0_mm).norm(), 1e-5);
    EXPECT_EQ(b.rgb, a.rgb);
    EXPECT_EQ(b.sigma_mm, a.sigma_mm);
    EXPECT_NEAR(b.error_px, a.error_px, 1e-6);
    EXPECT_EQ(b.descriptor, a.descriptor);
    ASSERT_EQ(b.track.size(), a.track.size());
    for (std::size_t t = 0; t < a.track.size(); ++t) {
      EXPECT_EQ(b.track[t].image_id, a.track[t].image_id);
      EXPECT_EQ(b.track[t].keypoint, a.track[t].keypoint);
    }
  }
  // The PLY announces every point with its properties.
  std::ifstream ply(dir / "points.ply");
  std::string text((std::istreambuf_iterator<char>(ply)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("element vertex 5\n"), std::string::npos);
  EXPECT_NE(text.find("property float sigma_mm\n"), std::string::npos);
}

TEST(ReferenceMap, DamagedFilesNameTheFileAndLine) {
  test::TempDir tmp;
  const fs::path dir = tmp.path();
  ASSERT_TRUE(WriteReferenceMap(dir, RandomMap(6)));
  {
    std::ofstream out(dir / "points3D.txt", std::ios::app);
    out << "999 1 2 three 0 0 0 0\n";
  }
  Expected<ReferenceMap> back = ReadReferenceMap(dir);
  ASSERT_FALSE(back);
  EXPECT_NE(back.error().message.find("points3D.txt:"), std::string::npos)
      << back.error().message;
  ASSERT_TRUE(WriteReferenceMap(dir, RandomMap(6)));
  fs::resize_file(dir / "descriptors.bin", 100);
  back = ReadReferenceMap(dir);
  ASSERT_FALSE(back);
  EXPECT_NE(back.error().message.find("descriptors.bin"), std::string::npos);
}

// Bad options are refused before any file is read, naming the field (the
// nested feature and match options' too).
TEST(GroundTruthMap, BadOptionsNameTheirField) {
  const processing::CameraModel camera{processing::CameraIntrinsics{}};
  for (const auto& [field, spoil] :
       std::vector<std::pair<std::string, std::function<void(GroundTruthMapOptions&)>>>{
           {"merge_distance_mm", [](GroundTruthMapOptions& o) { o.merge_distance_mm = 0; }},
           {"sigma", [](GroundTruthMapOptions& o) { o.features.sigma = -1; }},
           {"ratio", [](GroundTruthMapOptions& o) { o.match.ratio = 2; }}}) {
    GroundTruthMapOptions options;
    spoil(options);
    auto map = BuildGroundTruthMap("/nonexistent", "CAM0", {0}, camera, options);
    ASSERT_FALSE(map.ok()) << field;
    EXPECT_NE(map.error().message.find(field), std::string::npos) << map.error().message;
    EXPECT_EQ(map.error().message.find("nonexistent"), std::string::npos) << map.error().message;
  }
}

TEST(PosesCsv, RoundTripAndErrors) {
  test::TempDir tmp;
  const fs::path dir = tmp.path();
  std::vector<FramePose> poses(2);
  poses[1].frame = 7;
  poses[1].vicon_frame = 57;
  poses[1].world_from_cam.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  poses[1].world_from_cam.translation() = Eigen::Vector3d(1, -2, 800.5);
  ASSERT_TRUE(WritePosesCsv(dir / "p.csv", poses));
  Expected<std::vector<FramePose>> back = ReadPosesCsv(dir / "p.csv");
  ASSERT_TRUE(back) << back.error().message;
  ASSERT_EQ(back->size(), 2u);
  EXPECT_EQ((*back)[1].frame, 7);
  EXPECT_EQ((*back)[1].vicon_frame, 57);
  EXPECT_LT(((*back)[1].world_from_cam.matrix() - poses[1].world_from_cam.matrix())
                .cwiseAbs()
                .maxCoeff(),
            1e-6);
  {
    std::ofstream out(dir / "p.csv", std::ios::app);
    out << "8,65,1,2,x,1,0,0,0\n";
  }
  back = ReadPosesCsv(dir / "p.csv");
  ASSERT_FALSE(back);
  EXPECT_NE(back.error().message.find("p.csv:4:"), std::string::npos) << back.error().message;
}

// Values a double parses but no pose file holds: each is an error at its
// field (a frame of 1e300 was cast to int64, undefined behaviour; "nan" and
// "inf" parse with from_chars and passed the unit-quaternion check).
TEST(PosesCsv, OutOfRangeAndNonFiniteValuesAreErrors) {
  test::TempDir tmp;
  const std::string header = "frame,vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"1e300,0,1,2,3,1,0,0,0", ":2:1: expected a frame number"},
      {"1.5,0,1,2,3,1,0,0,0", ":2:1: expected a frame number"},
      {"-1,0,1,2,3,1,0,0,0", ":2:1: expected a frame number"},
      {"0,-2,1,2,3,1,0,0,0", ":2:3: expected a Vicon frame number"},
      {"0,1e19,1,2,3,1,0,0,0", ":2:3: expected a Vicon frame number"},
      {"0,0,1,2,inf,1,0,0,0", ":2:9: expected a number, got 'inf'"},
      {"0,0,1,2,3,nan,nan,nan,nan", ":2:11: expected a number, got 'nan'"},
      {"0,0,1,2e7,3,1,0,0,0", ":2:7: expected a position within 1e6 mm"},
      {"0,0," + std::string(100000, '9') + ",2,3,1,0,0,0", "... (100000 bytes)"},
  };
  for (const auto& [row, expected] : cases) {
    test::WriteFile(tmp / "p.csv", header + row + "\n");
    Expected<std::vector<FramePose>> poses = ReadPosesCsv(tmp / "p.csv");
    ASSERT_FALSE(poses) << row;
    EXPECT_NE(poses.error().message.find(expected), std::string::npos) << poses.error().message;
    EXPECT_LT(poses.error().message.size(), 300u) << row.substr(0, 40);
  }
}

// A value below the smallest double (1e-400) is a finite number that rounds
// to 0, as in every reader of config/decimal_number.h; 1e400 overflows.
TEST(PosesCsv, UnderflowReadsAsZeroAndOverflowIsAnError) {
  test::TempDir tmp;
  const std::string header = "frame,vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz\n";
  test::WriteFile(tmp / "p.csv", header + "3,0,1e-400,2,3,1,0,0,-1e-400\n");
  Expected<std::vector<FramePose>> poses = ReadPosesCsv(tmp / "p.csv");
  ASSERT_TRUE(poses) << poses.error().message;
  ASSERT_EQ(poses->size(), 1u);
  EXPECT_EQ((*poses)[0].world_from_cam.translation().x(), 0.0);
  EXPECT_EQ((*poses)[0].world_from_cam.translation().y(), 2.0);
  test::WriteFile(tmp / "p.csv", header + "3,0,1e400,2,3,1,0,0,0\n");
  poses = ReadPosesCsv(tmp / "p.csv");
  ASSERT_FALSE(poses);
  EXPECT_NE(poses.error().message.find(":2:5: expected a number, got '1e400'"), std::string::npos)
      << poses.error().message;
}

// intrinsics.yaml is read through the safe open: a FIFO, a folder or
// /dev/zero is an error at once (it was read with a bare ifstream: a FIFO
// hung, /dev/zero ran out of memory).
TEST(IntrinsicsYaml, OnlyARegularFileIsRead) {
  test::TempDir tmp;
  ASSERT_EQ(::mkfifo((tmp / "fifo.yaml").c_str(), 0600), 0);
  fs::create_symlink("/dev/zero", tmp / "zero.yaml");
  fs::create_directory(tmp / "folder.yaml");
  for (const auto& [name, expected] :
       std::vector<std::pair<std::string, std::string>>{{"fifo.yaml", "FIFO"},
                                                        {"zero.yaml", "character device"},
                                                        {"folder.yaml", "folder"}}) {
    Expected<CameraCalibration> camera = ReadCameraCalibration(tmp / name, "40398673");
    ASSERT_FALSE(camera) << name;
    EXPECT_NE(camera.error().message.find(expected), std::string::npos) << camera.error().message;
    Expected<PlateLayout> plate = ReadPlateLayout(tmp / name);
    ASSERT_FALSE(plate) << name;
    EXPECT_NE(plate.error().message.find(expected), std::string::npos) << plate.error().message;
  }
}

}  // namespace
}  // namespace lifmcr::registration
