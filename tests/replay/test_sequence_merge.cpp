// replay/sequence_merge.h: per-host recordings joined by trigger index into
// the sequence one host recording every camera writes (byte for byte), the
// triggers a camera lacks reported, Vicon taken once (joined frame by frame
// where the hosts started at other times), and the errors that name the
// files: a camera on two hosts, hosts disagreeing on Vicon, nothing written.
#include "replay/layout.h"
#include "replay/sequence_merge.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <sys/stat.h>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

const std::string kViconHeader =
    "Objects\r\n80\r\n,,plate,,,,,\r\nFrame,Sub "
    "Frame,RX,RY,RZ,TX,TY,TZ\r\n,,rad,rad,rad,mm,mm,mm\r\n";
std::string ViconLine(int frame) {
  return std::to_string(frame) + ",0,0.1,0.2,0.3," + std::to_string(frame) + ",2,3\r\n";
}

// A host's recording: ROOT/00_Recording/seq with the frames `frames` of
// each camera, Vicon frames [v0, v1), and ROOT/Calibration with the cameras'
// MLA files and the VSK.
fs::path Host(const fs::path& root, const std::vector<std::string>& serials,
              const std::vector<int>& frames, int v0 = 0, int v1 = 16) {
  const fs::path seq = root / "00_Recording" / "seq";
  for (const std::string& serial : serials) {
    for (int frame : frames)
      test::WriteFile(layout::CameraDir(seq, serial) / layout::RawFrameFileName(serial, frame),
                      "BM raw " + serial + " " + std::to_string(frame));
    test::WriteFile(root / "Calibration" / "02_MLA_Calibration" / ("TypeE_" + serial + "_MLA.xml"),
                    "<mla " + serial + "/>");
  }
  test::WriteFile(root / "Calibration" / "03_Vicon" / "Object.vsk", "<vsk/>");
  std::string csv = kViconHeader;
  for (int v = v0; v < v1; ++v) csv += ViconLine(v);
  test::WriteFile(layout::ViconCsvPath(seq, 1), csv);
  return seq;
}

// Every file under `a` has the same bytes under `b`, and no other file is there.
void ExpectSameTree(const fs::path& a, const fs::path& b) {
  std::size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(a)) {
    if (!entry.is_regular_file()) continue;
    const fs::path other = b / fs::relative(entry.path(), a);
    ASSERT_TRUE(fs::exists(other)) << other;
    EXPECT_EQ(test::ReadFile(entry.path()), test::ReadFile(other)) << other;
    ++files;
  }
  std::size_t other_files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(b))
    other_files += entry.is_regular_file() ? 1 : 0;
  EXPECT_EQ(files, other_files);
}

TEST(SequenceMerge, JoinsTwoHostsIntoTheSingleHostRecordingByteForByte) {
  test::TempDir dir;
  const fs::path single = Host(dir / "single", {"A", "B"}, {0, 1, 2, 3});
  SequenceMergeOptions options;
  options.hosts = {Host(dir / "h1", {"A"}, {0, 1, 2, 3}), Host(dir / "h2", {"B"}, {0, 1, 2, 3})};
  options.out = dir / "merged" / "00_Recording" / "seq";
  ASSERT_TRUE(options.Check());
  auto report = MergeSequences(options);
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_TRUE(report->Complete());
  EXPECT_EQ(report->triggers, 4u);
  ASSERT_EQ(report->cameras.size(), 2u);
  EXPECT_EQ(report->cameras[1].serial, "B");
  EXPECT_EQ(report->cameras[1].host, options.hosts[1]);
  // Frames, MLA files and the VSK (once) hard-linked; the identical Vicon CSV once.
  EXPECT_EQ(report->linked, 8u + 1u + 2u + 1u);
  EXPECT_EQ(report->copied, 0u);
  EXPECT_EQ(report->joined, 0u);
  ASSERT_EQ(report->vicon.size(), 1u);
  EXPECT_EQ(report->vicon[0], "Vicon/sequence_01.csv: the same on 2 host(s)");
  ExpectSameTree(dir / "single", dir / "merged");
  struct stat linked {};
  ASSERT_EQ(stat(layout::CameraDir(options.out, "B").c_str(), &linked), 0);
  ASSERT_EQ(stat((layout::CameraDir(options.out, "B") / layout::RawFrameFileName("B", 2)).c_str(),
                 &linked),
            0);
  EXPECT_EQ(linked.st_nlink, 2u) << "hard link to host 2's file";
  // The description names every camera and what it lacks.
  EXPECT_NE(report->Describe().find("camera A (from " + options.hosts[0].string() +
                                    "): 4 frames, none lacking"),
            std::string::npos)
      << report->Describe();
}

TEST(SequenceMerge, ReportsTheTriggersACameraLacksAndJoinsViconByFrame) {
  test::TempDir dir;
  SequenceMergeOptions options;
  // Host 2 started later (Vicon from frame 8, camera B from trigger 1) and
  // lost trigger 3.
  options.hosts = {Host(dir / "h1", {"A"}, {0, 1, 2, 3, 4}, 0, 40),
                   Host(dir / "h2", {"B"}, {1, 2, 4}, 8, 44)};
  options.out = dir / "merged" / "00_Recording" / "seq";
  options.copy = true;
  auto report = MergeSequences(options);
  ASSERT_TRUE(report) << report.error().message;
  EXPECT_FALSE(report->Complete());
  EXPECT_EQ(report->cameras[0].lacking, std::vector<std::int64_t>{});
  EXPECT_EQ(report->cameras[1].lacking, (std::vector<std::int64_t>{0, 3}));
  EXPECT_NE(report->Describe().find("lacks 2 trigger(s): 0 3"), std::string::npos)
      << report->Describe();
  EXPECT_EQ(report->linked, 0u);
  EXPECT_EQ(report->joined, 1u);
  std::string expected = kViconHeader;
  for (int v = 0; v < 44; ++v) expected += ViconLine(v);
  EXPECT_EQ(test::ReadFile(layout::ViconCsvPath(options.out, 1)), expected);
}

TEST(SequenceMerge, ACameraOnTwoHostsOrDisagreeingViconIsAnErrorNamingTheFiles) {
  test::TempDir dir;
  SequenceMergeOptions options;
  options.hosts = {Host(dir / "h1", {"A", "B"}, {0, 1}), Host(dir / "h2", {"B"}, {0, 1})};
  options.out = dir / "merged" / "00_Recording" / "seq";
  auto twice = MergeSequences(options);
  ASSERT_FALSE(twice);
  test::ExpectMessageHas(twice.error(), {(dir / "h1").string(), (dir / "h2").string(),
                                         "camera B is held by two hosts"});
  EXPECT_FALSE(fs::exists(options.out)) << "nothing written";

  options.hosts = {Host(dir / "h3", {"A"}, {0, 1}), Host(dir / "h4", {"B"}, {0, 1})};
  // Host 4 received Vicon frame 5 otherwise.
  const fs::path csv = layout::ViconCsvPath(options.hosts[1], 1);
  test::WriteFile(
      csv, test::ReplaceFirst(test::ReadFile(csv), ViconLine(5), "5,0,0.1,0.2,0.3,99,2,3\r\n"));
  auto vicon = MergeSequences(options);
  ASSERT_FALSE(vicon);
  test::ExpectMessageHas(vicon.error(), {layout::ViconCsvPath(options.hosts[0], 1).string(),
                                         csv.string(), "Vicon frame 5 differs"});
  EXPECT_FALSE(fs::exists(options.out));

  // Other objects in the header: another Vicon stream.
  test::WriteFile(csv, test::ReplaceFirst(test::ReadFile(csv), ",,plate,", ",,other,"));
  auto header = MergeSequences(options);
  ASSERT_FALSE(header);
  test::ExpectMessageHas(header.error(), {csv.string(), "headers differ"});

  // An output that exists is never written into.
  test::WriteFile(options.out / "x", "");
  options.hosts = {Host(dir / "h5", {"A"}, {0})};
  auto exists = MergeSequences(options);
  ASSERT_FALSE(exists);
  test::ExpectMessageHas(exists.error(), {options.out.string(), "not an empty folder"});
  SequenceMergeOptions none;
  none.out = options.out;
  EXPECT_FALSE(none.Check());
}

}  // namespace
}  // namespace lifmcr
