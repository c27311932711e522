// `lifmcr synth` as a dataset: everything it writes reads back through the
// dataset layer (layout discovery, sequence reader, Vicon CSV, VSK, MLA XML,
// BMP), the Vicon poses are the ground-truth camera poses composed with the
// marker offset within the noise, triggers fall on every 8th Vicon frame, and
// the same seed gives the same bytes.

#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/sequence.h"
#include "replay/synth/gt_images.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/synth_writer.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "replay/vsk.h"
#include "tests/test_util.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace lifmcr::synth {
namespace {

// A small sensor so that the whole dataset is written in well under a second.
SynthParams TinyRig(std::uint64_t seed) {
  Expected<SynthParams> params = MakePreset("small");
  EXPECT_TRUE(params.ok());
  params->camera.width_px = 320;
  params->camera.height_px = 240;
  params->rig.frames = 4;
  params->rig.seed = seed;
  params->camera.read_noise_dn = 1.5;
  return *params;
}

Pose PoseFromFields(const std::vector<double>& f, std::size_t first) {
  Pose pose = Pose::Identity();
  pose.translation() = Eigen::Vector3d(f[first], f[first + 1], f[first + 2]);
  pose.linear() =
      Eigen::Quaterniond(f[first + 3], f[first + 4], f[first + 5], f[first + 6]).toRotationMatrix();
  return pose;
}

// Rows of a ground-truth CSV (header skipped) as numbers.
std::vector<std::vector<double>> ReadNumbers(const std::filesystem::path& path,
                                             std::string* header) {
  std::istringstream in(test::ReadFile(path));
  std::string line;
  std::getline(in, *header);
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::stringstream fields(line);
    std::string field;
    while (std::getline(fields, field, ',')) row.push_back(std::stod(field));
    rows.push_back(row);
  }
  return rows;
}

Pose PoseFromYaml(const YAML::Node& node) {
  return PoseFromFields({node["tx_mm"].as<double>(), node["ty_mm"].as<double>(),
                         node["tz_mm"].as<double>(), node["qw"].as<double>(),
                         node["qx"].as<double>(), node["qy"].as<double>(), node["qz"].as<double>()},
                        0);
}

double AngleDeg(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle() * 180.0 / M_PI;
}

TEST(SynthDataset, ViconReadsBackAsGroundTruthPosesComposedWithTheMarkerOffset) {
  test::TempDir dir;
  SynthParams params = TinyRig(4);
  params.vicon.occlusion_gaps = 2;
  params.vicon.occlusion_gap_frames = 3;
  const Expected<SynthSummary> summary = WriteSyntheticDataset(dir.path(), params);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const std::filesystem::path seq = summary->sequence_dir;

  // Discovery and the trigger walk see two cameras and four frames, at Vicon
  // frames 1, 9, 17, 25.
  const Expected<SequenceLayout> layout = DiscoverSequence(seq);
  ASSERT_TRUE(layout.ok()) << layout.error().message;
  ASSERT_EQ(layout->cameras.size(), 2u);
  EXPECT_TRUE(layout->has_ground_truth);
  Expected<SequenceReader> reader = SequenceReader::Create(*layout);
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  ASSERT_EQ(reader->size(), 4u);

  const YAML::Node cameras_yaml = YAML::LoadFile(layout::CamerasYamlPath(seq).string());
  const Pose vicon_from_world = PoseFromYaml(cameras_yaml["vicon"]["vicon_from_world"]);
  ASSERT_EQ(cameras_yaml["cameras"].size(), 2u);
  EXPECT_EQ(cameras_yaml["cameras"][0]["serial"].as<std::string>(), "40398678");
  EXPECT_EQ(cameras_yaml["cameras"][0]["vicon_subject"].as<std::string>(), "cam0");
  EXPECT_EQ(cameras_yaml["cameras"][1]["serial"].as<std::string>(), "40398673");
  EXPECT_EQ(cameras_yaml["cameras"][1]["vicon_subject"].as<std::string>(), "cam2");

  const Expected<ViconCsv> csv = ReadViconCsv(layout::ViconCsvPath(seq, kSequenceCsvIndex));
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  ASSERT_NE(csv->Find("Objects"), nullptr);
  EXPECT_EQ(csv->Find("Objects")->rate_hz, 80);

  int compared = 0, occluded = 0;
  for (const auto& camera : cameras_yaml["cameras"]) {
    const std::string serial = camera["serial"].as<std::string>();
    const std::string subject = camera["vicon_subject"].as<std::string>();
    std::string header;
    const auto offset_rows = ReadNumbers(layout::MarkerFromCamCsvPath(seq, serial), &header);
    EXPECT_EQ(header, "tx_mm,ty_mm,tz_mm,qw,qx,qy,qz");
    ASSERT_EQ(offset_rows.size(), 1u);
    const Pose marker_from_cam = PoseFromFields(offset_rows[0], 0);
    // Realistic: tens of mm, a few degrees.
    EXPECT_GT(marker_from_cam.translation().norm(), 20.0);
    EXPECT_LT(marker_from_cam.translation().norm(), 150.0);
    EXPECT_LT(AngleDeg(marker_from_cam.linear(), Eigen::Matrix3d::Identity()), 10.0);
    EXPECT_TRUE(marker_from_cam.isApprox(PoseFromYaml(camera["marker_from_cam"]), 1e-6));

    const auto pose_rows = ReadNumbers(layout::PosesCsvPath(seq, serial), &header);
    EXPECT_EQ(header, "frame,vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz");
    ASSERT_EQ(pose_rows.size(), 4u);
    const Expected<std::vector<ViconPoseSample>> samples = ExtractSubjectPoses(*csv, subject);
    ASSERT_TRUE(samples.ok()) << samples.error().message;
    std::map<std::int64_t, const ViconPoseSample*> by_frame;
    for (const ViconPoseSample& s : *samples) {
      by_frame[s.vicon_frame] = &s;
      if (!s.vicon_from_marker) ++occluded;
    }
    for (const auto& row : pose_rows) {
      const auto frame = static_cast<std::int64_t>(row[0]);
      const auto vicon_frame = static_cast<std::int64_t>(row[1]);
      EXPECT_EQ(vicon_frame, 1 + 8 * frame) << "trigger every 8th Vicon frame";
      EXPECT_EQ(reader->ViconFrameOf(frame), vicon_frame);
      ASSERT_TRUE(by_frame.count(vicon_frame));
      const ViconPoseSample& sample = *by_frame[vicon_frame];
      if (!sample.vicon_from_marker) continue;  // an occlusion gap
      const Pose expected = vicon_from_world * PoseFromFields(row, 2) * marker_from_cam.inverse();
      EXPECT_LT((sample.vicon_from_marker->translation() - expected.translation()).norm(), 1.0)
          << serial << " frame " << frame;
      EXPECT_LT(AngleDeg(sample.vicon_from_marker->linear(), expected.linear()), 0.5);
      // Noise is there: not exactly the truth.
      EXPECT_GT((sample.vicon_from_marker->translation() - expected.translation()).norm(), 1e-6);
      ++compared;
    }
  }
  EXPECT_GE(compared, 5);
  EXPECT_GT(occluded, 0) << "occlusion gaps were requested";

  // The plate subject sits where the world frame says.
  const Expected<std::vector<ViconPoseSample>> plate = ExtractSubjectPoses(*csv, "plate");
  ASSERT_TRUE(plate.ok()) << plate.error().message;
  const Pose world_from_plate = PoseFromYaml(cameras_yaml["vicon"]["world_from_plate_marker"]);
  ASSERT_TRUE(plate->front().vicon_from_marker.has_value());
  EXPECT_LT((plate->front().vicon_from_marker->translation() -
             (vicon_from_world * world_from_plate).translation())
                .norm(),
            1.0);
}

TEST(SynthDataset, CalibrationAndGroundTruthFilesReadBack) {
  test::TempDir dir;
  const SynthParams params = TinyRig(5);
  const Expected<SynthSummary> summary = WriteSyntheticDataset(dir.path(), params);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const std::filesystem::path seq = summary->sequence_dir;
  const std::filesystem::path calib = summary->calibration_dir;
  const std::vector<SynthCamera> cameras = MakeSynthCameras(params);
  ASSERT_EQ(cameras.size(), 2u);

  for (const SynthCamera& camera : cameras) {
    const PlenopticModel model(camera.params);
    const Expected<MlaCalibration> mla = ReadMlaXml(layout::MlaXmlPath(calib, camera.serial));
    ASSERT_TRUE(mla.ok()) << mla.error().message;
    EXPECT_NEAR(mla->diameter_px, camera.params.micro_image_pitch_px, 1e-9);
    EXPECT_NEAR(mla->offset_px.x(), camera.params.mla_offset_px.x(), 1e-9);
    EXPECT_NEAR(mla->lens_types[2].depth_min, model.SharpRange(2).x(), 1e-9);

    const Expected<OwnedImage> white = ReadBmp(layout::WhiteImagePath(calib, camera.serial, 0));
    ASSERT_TRUE(white.ok()) << white.error().message;
    EXPECT_EQ(white->width, 320);
    EXPECT_EQ(white->format, PixelFormat::kBgr8);

    const Expected<OwnedImage> raw = ReadBmp(layout::RawFramePath(seq, camera.serial, 3));
    ASSERT_TRUE(raw.ok()) << raw.error().message;
    EXPECT_EQ(raw->height, 240);

    int width = 0, height = 0;
    const Expected<std::vector<float>> v =
        ReadFloatTiff(layout::VirtualDepthPath(seq, camera.serial, 3), &width, &height);
    ASSERT_TRUE(v.ok()) << v.error().message;
    EXPECT_EQ(width, 320);
    EXPECT_EQ(height, 240);
    int finite = 0, nan = 0;
    for (float x : *v) {
      if (std::isfinite(x)) {
        ++finite;
        EXPECT_GT(x, 1.0f);
        EXPECT_LT(x, 20.0f);
      } else {
        ++nan;
      }
    }
    EXPECT_GT(finite, 0.5 * v->size());  // the micro images
    EXPECT_GT(nan, 0);                   // the gaps between them

    const Expected<std::vector<float>> depth =
        ReadFloatTiff(layout::DepthMmPath(seq, camera.serial, 3), &width, &height);
    ASSERT_TRUE(depth.ok()) << depth.error().message;
    EXPECT_EQ(width, 160);
    EXPECT_EQ(height, 120);
    for (float z : *depth)
      if (std::isfinite(z)) {
        EXPECT_GT(z, 300.0f);
        EXPECT_LT(z, 4000.0f);
      }
    EXPECT_TRUE(std::filesystem::exists(AllInFocusPath(seq, camera.serial, 3)));
  }

  const Expected<Vsk> vsk = ReadVsk(layout::VskPath(calib));
  ASSERT_TRUE(vsk.ok()) << vsk.error().message;
  const std::vector<std::string> subjects = VskSubjects(*vsk);
  ASSERT_EQ(subjects.size(), 3u);
  for (const std::string& subject : subjects) {
    EXPECT_EQ(VskMarkersOfSubject(*vsk, subject).size(), 4u) << subject;
    const Expected<Eigen::Vector3d> centroid = VskMarkerCentroidMm(*vsk, subject);
    ASSERT_TRUE(centroid.ok());
    EXPECT_LT(centroid->norm(), 1e-6) << "the object origin is the cluster centroid";
  }
}

std::map<std::string, std::string> AllFiles(const std::filesystem::path& root) {
  std::map<std::string, std::string> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root))
    if (entry.is_regular_file())
      files[std::filesystem::relative(entry.path(), root).string()] = test::ReadFile(entry.path());
  return files;
}

TEST(SynthDataset, SameSeedSameBytesOtherSeedOtherNoise) {
  test::TempDir a, b, c;
  SynthParams params = TinyRig(9);
  params.rig.frames = 2;
  ASSERT_TRUE(WriteSyntheticDataset(a.path(), params).ok());
  ASSERT_TRUE(WriteSyntheticDataset(b.path(), params).ok());
  const auto files_a = AllFiles(a.path()), files_b = AllFiles(b.path());
  ASSERT_EQ(files_a.size(), files_b.size());
  EXPECT_GT(files_a.size(), 20u);
  for (const auto& [name, content] : files_a) {
    ASSERT_TRUE(files_b.count(name)) << name;
    EXPECT_TRUE(files_b.at(name) == content) << name << " differs between two runs";
  }
  params.rig.seed = 10;
  ASSERT_TRUE(WriteSyntheticDataset(c.path(), params).ok());
  const auto files_c = AllFiles(c.path());
  const std::string raw =
      "00_Synthetic/Sequence_00/TypeE_40398678/" + layout::RawFrameFileName("40398678", 1);
  ASSERT_TRUE(files_a.count(raw) && files_c.count(raw));
  EXPECT_NE(files_a.at(raw), files_c.at(raw));
}

// rig.render_frames (`--render-frames`): only those triggers' images, each
// the same bytes as in the whole sequence; poses and ground truth of every
// trigger as without it; a trigger outside the sequence is an error.
TEST(SynthDataset, RenderFramesWritesThoseTriggersAsInTheWholeSequence) {
  test::TempDir whole, part;
  SynthParams params = TinyRig(11);
  params.rig.frames = 3;
  params.rig.cameras = 1;
  ASSERT_TRUE(WriteSyntheticDataset(whole.path(), params).ok());
  params.rig.render_frames = {1};
  ASSERT_TRUE(WriteSyntheticDataset(part.path(), params).ok());
  const auto files_whole = AllFiles(whole.path()), files_part = AllFiles(part.path());
  const std::string dir = "00_Synthetic/Sequence_00/TypeE_40398678/";
  for (int n = 0; n < 3; ++n) {
    const std::string raw = dir + layout::RawFrameFileName("40398678", n);
    ASSERT_TRUE(files_whole.count(raw)) << raw;
    EXPECT_EQ(files_part.count(raw), n == 1 ? 1u : 0u) << raw;
  }
  const std::string raw1 = dir + layout::RawFrameFileName("40398678", 1);
  EXPECT_TRUE(files_part.at(raw1) == files_whole.at(raw1));
  const std::string poses = "00_Synthetic/Sequence_00/GroundTruth/poses_40398678.csv";
  ASSERT_TRUE(files_part.count(poses));
  EXPECT_TRUE(files_part.at(poses) == files_whole.at(poses));
  params.rig.render_frames = {3};
  test::TempDir bad;
  const Expected<SynthSummary> summary = WriteSyntheticDataset(bad.path(), params);
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.error().message.find("rig.render_frames"), std::string::npos);
}

TEST(SynthDataset, BadParametersAreErrorsNotFiles) {
  test::TempDir dir;
  SynthParams params = TinyRig(1);
  params.rig.motion = "teleport";
  const Expected<SynthSummary> summary = WriteSyntheticDataset(dir.path(), params);
  ASSERT_FALSE(summary.ok());
  EXPECT_NE(summary.error().message.find("rig.motion"), std::string::npos);
  EXPECT_NE(summary.error().message.find("teleport"), std::string::npos);
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

// `--motion orbit`, read back from GroundTruth/poses_*.csv: over a sequence
// each camera turns by more than 20 degrees about its x and its y axis, and
// the two cameras see common structure (points of the table around the
// scene, projected with the `small` camera) in most frames.
TEST(SynthDataset, OrbitMotionViewsFromVariedAnglesWithCommonStructure) {
  test::TempDir dir;
  SynthParams params = TinyRig(5);
  params.camera.width_px = 128;  // poses do not depend on the sensor size
  params.camera.height_px = 96;
  params.rig.frames = 24;
  params.rig.motion = "orbit";
  Expected<SynthSummary> summary = WriteSyntheticDataset(dir.path(), params);
  ASSERT_TRUE(summary.ok()) << summary.error().message;
  const PlenopticModel small(MakePreset("small")->camera);
  std::vector<std::vector<Pose>> world_from_cam;
  for (const char* serial : {"40398678", "40398673"}) {
    std::string header;
    const auto rows = ReadNumbers(layout::PosesCsvPath(summary->sequence_dir, serial), &header);
    ASSERT_EQ(rows.size(), 24u) << serial;
    std::vector<Pose> poses;
    for (const auto& row : rows) poses.push_back(PoseFromFields(row, 2));
    // Rotation of each view relative to the first, in the first view's axes.
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e9), hi = -lo;
    for (const Pose& pose : poses) {
      const Eigen::AngleAxisd turn(poses.front().linear().transpose() * pose.linear());
      const Eigen::Vector3d r = turn.angle() * turn.axis() * 180.0 / M_PI;
      lo = lo.cwiseMin(r);
      hi = hi.cwiseMax(r);
    }
    const Eigen::Vector3d spread = hi - lo;
    std::printf("camera %s: rotation spread over %zu frames: %.1f deg about x, %.1f about y, "
                "%.1f about z\n",
                serial, poses.size(), spread.x(), spread.y(), spread.z());
    EXPECT_GE(spread.x(), 20.0) << serial;
    EXPECT_GE(spread.y(), 20.0) << serial;
    world_from_cam.push_back(poses);
  }
  // Table points around the scene seen by both cameras (no occlusion test).
  const auto visible = [&](const Pose& world_from, const Eigen::Vector3d& p_in_world) {
    const Eigen::Vector3d p = world_from.inverse() * p_in_world;
    if (p.z() <= small.params().main_focal_length_mm * 2) return false;
    const Eigen::Vector3d x = small.VirtualPoint(p);
    return x.x() >= 0 && x.y() >= 0 && x.x() < small.width() && x.y() < small.height();
  };
  int frames_in_common = 0;
  double worst = 1.0;
  for (std::size_t f = 0; f < 24; ++f) {
    int a = 0, b = 0, both = 0;
    for (double x = -400; x <= 800; x += 10)
      for (double y = -300; y <= 900; y += 10) {
        const Eigen::Vector3d p(x, y, 0);
        const bool in_a = visible(world_from_cam[0][f], p), in_b = visible(world_from_cam[1][f], p);
        a += in_a;
        b += in_b;
        both += in_a && in_b;
      }
    ASSERT_GT(std::min(a, b), 0) << "frame " << f << ": a camera sees no table";
    const double common = static_cast<double>(both) / std::min(a, b);
    worst = std::min(worst, common);
    frames_in_common += common >= 0.5;
  }
  std::printf("frames where the cameras share >= 50 %% of the table they see: %d of 24 (worst "
              "%.0f %%)\n",
              frames_in_common, 100 * worst);
  EXPECT_GE(frames_in_common, 20);

  // At `medium` (the calibration gates' preset), the same motion keeps the
  // whole marker plate (every ArUco corner) in view of both cameras in most
  // frames; at `small` (240 mm of field) part of it.
  for (const char* preset : {"medium", "small"}) {
    SynthParams p = *MakePreset(preset);
    p.rig.frames = 24;
    p.rig.motion = "orbit";
    p.rig.seed = 5;
    const PlenopticModel model(p.camera);
    const Scene scene = *MakeScene(p.rig.scene, p.rig.seed);
    int whole_plate = 0;
    const std::vector<std::vector<Pose>> poses = TriggerPoses(p, scene);
    for (std::size_t k = 0; k < poses.size(); ++k)
      for (const Pose& pose : poses[k]) {
        bool all = true;
        for (const Eigen::Vector2d& c : scene.plate.aruco_centers_mm)
          for (double dx : {-0.5, 0.5})
            for (double dy : {-0.5, 0.5}) {
              const Eigen::Vector3d corner(c.x() + dx * scene.plate.aruco_side_mm,
                                           c.y() + dy * scene.plate.aruco_side_mm, 0);
              const Eigen::Vector3d q = pose.inverse() * corner;
              const Eigen::Vector3d x = model.VirtualPoint(q);
              all = all && q.z() > 0 && x.x() >= 0 && x.y() >= 0 && x.x() < model.width() &&
                    x.y() < model.height();
            }
        whole_plate += all;
      }
    std::printf("%s: the whole plate in view in %d of %zu views\n", preset, whole_plate,
                poses.size() * 24);
    if (std::string(preset) == "medium") {
      EXPECT_GE(whole_plate, 0.8 * poses.size() * 24);
    }
  }
}

}  // namespace
}  // namespace lifmcr::synth
