// `lifmcr info` run as a user runs it: on the real sample files and on a
// small LiFMCR tree written with the dataset writers.

#include "config/mla.h"
#include "replay/bmp.h"
#include "replay/layout.h"
#include "replay/mla_xml.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "replay/vsk.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::RunLifmcr;

json InfoJson(const fs::path& path, int expected_exit = 0) {
  const auto result = RunLifmcr("info --json '" + path.string() + "'");
  EXPECT_EQ(result.exit_code, expected_exit) << result.err << result.out;
  return json::parse(result.out);
}

TEST(InfoCli, HelpDescribesEveryKindOfPath) {
  const auto result = RunLifmcr("info --help");
  EXPECT_EQ(result.exit_code, 0);
  for (const char* word :
       {"dataset root", "sequence", "RayCalibData", "Vicon", ".vsk", "--json", "Exit code"})
    EXPECT_NE(result.out.find(word), std::string::npos) << word;
}

TEST(InfoCli, MlaSamplesReportTheirGeometry) {
  const json r42 = InfoJson(test::SamplePath("raytrix_mla_R42_sc2_klein.xml"));
  EXPECT_EQ(r42["kind"], "MLA calibration");
  EXPECT_NEAR(r42["mla"]["diameter_px"].get<double>(), 34.8647, 1e-3);
  ASSERT_EQ(r42["mla"]["lens_types"].size(), 3u);
  EXPECT_EQ(r42["mla"]["lens_types"][2]["paper_type"], 3);
  EXPECT_DOUBLE_EQ(r42["mla"]["lens_types"][2]["depth_max"].get<double>(), 100.0);

  const json frog = InfoJson(test::SamplePath("raytrix_mla_frog1_tree_Calibration_rot90.xml"));
  EXPECT_NEAR(frog["mla"]["rotation_deg"].get<double>(), 90.0, 1e-4);

  const json r29 = InfoJson(test::SamplePath("raytrix_mla_R29_Cards2_Processed.xml"));
  EXPECT_EQ(r29["mla"]["distortion"]["function"], "Brown");
  EXPECT_EQ(r29["mla"]["distortion"]["parameters"].size(), 2u);

  const auto text = RunLifmcr(
      "info '" + test::SamplePath("raytrix_mla_frog1_tree_Calibration_rot90.xml").string() + "'");
  EXPECT_EQ(text.exit_code, 0);
  EXPECT_NE(text.out.find("rotation 1.570796 rad (90.000 deg)"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("lens type id 0 (paper type 1)"), std::string::npos);
}

TEST(InfoCli, ViconAndVskSamples) {
  const json csv =
      InfoJson(test::SamplePath("vicon_nexus_trajectories_pyomeca_markers_first135frames.csv"));
  ASSERT_EQ(csv["vicon"]["blocks"].size(), 1u);
  const json& block = csv["vicon"]["blocks"][0];
  EXPECT_EQ(block["name"], "Trajectories");
  EXPECT_EQ(block["rate_hz"], 100);
  EXPECT_EQ(block["frames"], 135);
  EXPECT_EQ(block["entities"], 51);
  EXPECT_EQ(csv["vicon"]["line_endings"], "CRLF");
  // Occluded markers start at frame 119: only those frames of Daphnee miss data.
  ASSERT_EQ(block["subjects"].size(), 2u);
  EXPECT_EQ(block["subjects"][0]["name"], "boite");
  EXPECT_EQ(block["subjects"][0]["frames_with_missing_data"], 0);
  EXPECT_EQ(block["subjects"][1]["name"], "Daphnee");
  EXPECT_GT(block["subjects"][1]["frames_with_missing_data"].get<int>(), 0);
  EXPECT_LE(block["subjects"][1]["frames_with_missing_data"].get<int>(), 135 - 118);

  const json vsk = InfoJson(test::SamplePath("vicon_tracker_object_go2_body.vsk"));
  EXPECT_EQ(vsk["vsk"]["version"], "3.2");
  ASSERT_EQ(vsk["vsk"]["subjects"].size(), 1u);
  EXPECT_EQ(vsk["vsk"]["subjects"][0]["name"], "Go2");
  EXPECT_EQ(vsk["vsk"]["subjects"][0]["markers"].size(), 11u);
}

TEST(InfoCli, ExampleRigFile) {
  const fs::path rig = fs::path(LIFMCR_SOURCE_DIR) / "config/examples/lifmcr_two_r32.yaml";
  const json r = InfoJson(rig);
  EXPECT_EQ(r["kind"], "rig file");
  ASSERT_EQ(r["rig"]["cameras"].size(), 2u);
  EXPECT_EQ(r["rig"]["cameras"][0]["serial"], "40398678");
  EXPECT_EQ(r["rig"]["cameras"][0]["role"], "reference");
  EXPECT_EQ(r["rig"]["vicon"]["trigger_divider"], 8);
}

TEST(InfoCli, MissingPathAndUnknownFileAreErrors) {
  auto missing = RunLifmcr("info /nonexistent/lifmcr/path");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("/nonexistent/lifmcr/path: no such file or folder"),
            std::string::npos);
  test::TempDir dir;
  test::WriteFile(dir / "notes.txt", "hello");
  auto unknown = RunLifmcr("info '" + (dir / "notes.txt").string() + "'");
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_NE(unknown.err.find("notes.txt: not a file lifmcr knows"), std::string::npos)
      << unknown.err;
  auto usage = RunLifmcr("info");
  EXPECT_EQ(usage.exit_code, 2);
}

// A two-camera sequence: frames 0..5 of camera A, frames 0..5 without 3 of
// camera B, and a truncated last frame of B; MLA files, a VSK and a Vicon CSV.
class InfoOnDataset : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = dir_.path() / "dataset";
    seq_ = root_ / "00_Test" / "00_random";
    const fs::path calibration = root_ / "Calibration";
    for (const std::string serial : {"40398678", "40398673"}) {
      auto image = OwnedImage::Allocate(66, 40, PixelFormat::kMono8);
      for (std::size_t i = 0; i < image.pixels.size(); ++i)
        image.pixels[i] = static_cast<std::uint8_t>(i);
      for (int frame = 0; frame < 6; ++frame) {
        if (serial == "40398673" && frame == 3) continue;
        const fs::path path = layout::RawFramePath(seq_, serial, frame);
        fs::create_directories(path.parent_path());
        ASSERT_TRUE(WriteBmp(path, image.View()).ok());
      }
      MlaCalibration mla;
      mla.diameter_px = 15.5;
      mla.offset_px = Eigen::Vector2d(1.5, -2.0);
      mla.tcp_virtual_depth = 2.1;
      for (int id = 0; id < 3; ++id) {
        mla.lens_types[id].id = id;
        mla.lens_types[id].offset_lens = Eigen::Vector2d(id == 0 ? 0 : (id == 1 ? 1 : -1), 0);
        mla.lens_types[id].depth_min = 1.0 + id;
        mla.lens_types[id].depth_max = 3.0 + id;
      }
      const fs::path xml = layout::MlaXmlPath(calibration, serial);
      fs::create_directories(xml.parent_path());
      ASSERT_TRUE(WriteMlaXml(xml, mla).ok());
    }
    // Cut the last frame of camera B short, as a kill -9 during a write would.
    const fs::path last = layout::RawFramePath(seq_, "40398673", 5);
    fs::resize_file(last, fs::file_size(last) - 100);

    std::vector<ViconPoseSample> cam0, cam2;
    for (int f = 1; f <= 41; ++f) {
      Pose pose = Pose::Identity();
      pose.translation() = Eigen::Vector3d(f, 2 * f, 300);
      cam0.push_back({f, pose});
      cam2.push_back({f, f == 9 ? std::optional<Pose>() : std::optional<Pose>(pose)});
    }
    auto block = MakeObjectsBlock(80, {"cam0:cam0", "cam2:cam2"}, {cam0, cam2});
    ASSERT_TRUE(block.ok()) << block.error().message;
    ViconCsv csv;
    csv.blocks.push_back(*block);
    const fs::path csv_path = layout::ViconCsvPath(seq_, 0);
    fs::create_directories(csv_path.parent_path());
    ASSERT_TRUE(WriteViconCsv(csv_path, csv).ok());

    Vsk vsk;
    vsk.version = "3.2";
    for (const std::string object : {"cam0", "cam2"}) {
      vsk.segments.push_back({object, ""});
      for (int m = 0; m < 4; ++m)
        vsk.markers.push_back({object + "_" + std::to_string(m), object,
                               Eigen::Vector3d(10.0 * m, 5.0 * (m % 2), 1.0), "required", 7.0});
    }
    const fs::path vsk_path = layout::VskPath(calibration);
    fs::create_directories(vsk_path.parent_path());
    const auto written = WriteVsk(vsk_path, vsk);
    ASSERT_TRUE(written.ok()) << written.error().message;
  }

  test::TempDir dir_;
  fs::path root_, seq_;
};

TEST_F(InfoOnDataset, SequenceReportsCamerasGapsTruncationMlaViconAndVsk) {
  const json r = InfoJson(seq_, /*expected_exit=*/1);  // the truncated frame is a problem
  EXPECT_EQ(r["kind"], "sequence");
  const json& s = r["sequence"];
  ASSERT_EQ(s["cameras"].size(), 2u);
  const json& b = s["cameras"][0];  // sorted by serial: 40398673 first
  EXPECT_EQ(b["serial"], "40398673");
  EXPECT_EQ(b["frame_count"], 5);
  EXPECT_EQ(b["first_frame"], 0);
  EXPECT_EQ(b["last_frame"], 5);
  EXPECT_EQ(b["missing_count"], 1);
  EXPECT_EQ(b["missing"][0], 3);
  EXPECT_EQ(b["image"]["width"], 66);
  EXPECT_EQ(b["image"]["pixel_format"], "Mono8");
  ASSERT_EQ(b["problems"].size(), 1u);
  const std::string problem = b["problems"][0];
  EXPECT_NE(problem.find("TypeE_40398673_"), std::string::npos) << problem;
  EXPECT_NEAR(b["mla"]["diameter_px"].get<double>(), 15.5, 1e-12);
  EXPECT_NEAR(b["mla"]["reference_lens_px"][0].get<double>(), 32.5 + 1.5, 1e-12);
  EXPECT_NEAR(b["mla"]["reference_lens_px"][1].get<double>(), 19.5 + 2.0, 1e-12);

  const json& a = s["cameras"][1];
  EXPECT_EQ(a["frame_count"], 6);
  EXPECT_EQ(a["missing_count"], 0);
  EXPECT_FALSE(a.contains("problems"));

  ASSERT_EQ(s["vicon"].size(), 1u);
  const json& block = s["vicon"][0]["blocks"][0];
  EXPECT_EQ(block["name"], "Objects");
  EXPECT_EQ(block["rate_hz"], 80);
  EXPECT_EQ(block["frames"], 41);
  EXPECT_EQ(block["subjects"][1]["name"], "cam2");
  EXPECT_EQ(block["subjects"][1]["frames_with_missing_data"], 1);

  ASSERT_EQ(s["vsk"].size(), 1u);
  EXPECT_EQ(s["vsk"][0]["subjects"].size(), 2u);
  EXPECT_EQ(s["vsk"][0]["subjects"][0]["markers"].size(), 4u);
  EXPECT_EQ(r["problems"].size(), 1u);
}

TEST_F(InfoOnDataset, RootAndSceneListTheSameSequence) {
  const json root = InfoJson(root_, 1);
  EXPECT_EQ(root["kind"], "dataset root");
  ASSERT_EQ(root["scenes"].size(), 1u);
  EXPECT_EQ(root["scenes"][0]["name"], "00_Test");
  EXPECT_EQ(root["scenes"][0]["sequences"][0]["name"], "00_random");
  EXPECT_EQ(root["calibration"]["mla"].size(), 2u);

  const json scene = InfoJson(root_ / "00_Test", 1);
  EXPECT_EQ(scene["kind"], "scene");
  EXPECT_EQ(scene["scene"]["sequences"].size(), 1u);

  const auto text = RunLifmcr("info '" + seq_.string() + "'");
  EXPECT_EQ(text.exit_code, 1);
  EXPECT_NE(text.out.find("camera 40398673: 5 frames (0..5), 1 missing: 3, 66x40 Mono8"),
            std::string::npos)
      << text.out;
  EXPECT_NE(text.out.find("PROBLEM:"), std::string::npos);
  EXPECT_NE(text.out.find("1 problem(s) found"), std::string::npos);
}

TEST_F(InfoOnDataset, QuickModeStillChecksTheLastFrame) {
  const auto result = RunLifmcr("info --quick --json '" + (seq_ / "TypeE_40398673").string() + "'");
  EXPECT_EQ(result.exit_code, 1);
  const json r = json::parse(result.out);
  EXPECT_EQ(r["kind"], "camera folder");
  EXPECT_EQ(r["camera"]["frames_checked"], 2);
  EXPECT_EQ(r["camera"]["problems"].size(), 1u);
  EXPECT_FALSE(r["camera"]["mla"].is_null());
}

}  // namespace
}  // namespace lifmcr
