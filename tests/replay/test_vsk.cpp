#include "replay/vsk.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <random>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

constexpr char kTracker[] = "vicon_tracker_object_go2_body.vsk";
constexpr char kNexus[] = "vicon_nexus_pig_v2.5_pycgm_Sample_SM.vsk";

void ExpectError(const std::string& text, const std::vector<std::string>& fragments) {
  const Expected<Vsk> result = ParseVsk(text, "bad.vsk");
  ASSERT_FALSE(result.ok()) << "expected an error containing " << fragments.front();
  test::ExpectMessageHas(result.error(), fragments);
}

const VskMarker* FindMarker(const Vsk& vsk, const std::string& name) {
  for (const VskMarker& marker : vsk.markers) {
    if (marker.name == name) return &marker;
  }
  return nullptr;
}

const VskSegment* FindSegment(const Vsk& vsk, const std::string& name) {
  for (const VskSegment& segment : vsk.segments) {
    if (segment.name == name) return &segment;
  }
  return nullptr;
}

// ------------------------------------------------------------ real samples

TEST(Vsk, ReadsTrackerObjectWithParameterReferences) {
  const Expected<Vsk> vsk = ReadVsk(test::SamplePath(kTracker));
  ASSERT_TRUE(vsk.ok()) << vsk.error().message;
  EXPECT_EQ(vsk->version, "3.2");
  EXPECT_EQ(vsk->model, "");
  ASSERT_EQ(vsk->segments.size(), 1u);
  EXPECT_EQ(vsk->segments[0].name, "Go2");
  EXPECT_EQ(vsk->segments[0].parent, "");
  EXPECT_EQ(VskSubjects(*vsk), std::vector<std::string>{"Go2"});
  EXPECT_EQ(vsk->parameters.size(), 33u);
  ASSERT_EQ(vsk->markers.size(), 11u);
  for (int i = 0; i < 11; ++i) {
    EXPECT_EQ(vsk->markers[i].name, "Go2" + std::to_string(i + 1));
    EXPECT_EQ(vsk->markers[i].segment, "Go2");
    EXPECT_EQ(vsk->markers[i].radius_mm, 14.0);
    EXPECT_EQ(vsk->markers[i].status, i == 0 ? "required" : "optional");
  }
  EXPECT_EQ(vsk->markers[0].position_mm, Eigen::Vector3d(261.96, 0.0, 91.57));
  EXPECT_EQ(vsk->markers[1].position_mm, Eigen::Vector3d(300.12, -51.0, 22.35));
  EXPECT_EQ(vsk->markers[9].position_mm, Eigen::Vector3d(-144.053263, 0.0, 44.566731));
  EXPECT_EQ(vsk->markers[10].position_mm, Eigen::Vector3d(-110.2, -71.7, 77.5));
  EXPECT_EQ(VskMarkersOfSegment(*vsk, "Go2").size(), 11u);
  const Expected<Eigen::Vector3d> centroid = VskMarkerCentroidMm(*vsk, "Go2");
  ASSERT_TRUE(centroid.ok());
  EXPECT_NEAR(centroid->x(), 174.106067, 1e-9);
  EXPECT_NEAR(centroid->y(), -3.794545454545455, 1e-9);
  EXPECT_NEAR(centroid->z(), 69.62243009090909, 1e-9);
  EXPECT_FALSE(VskMarkerCentroidMm(*vsk, "cam0").ok());
}

TEST(Vsk, ReadsNexusV25WithInlinePositionsAndSegmentTree) {
  const Expected<Vsk> vsk = ReadVsk(test::SamplePath(kNexus));
  ASSERT_TRUE(vsk.ok()) << vsk.error().message;
  EXPECT_EQ(vsk->version, "2.5");
  EXPECT_EQ(vsk->model, "PlugInGait");
  ASSERT_EQ(vsk->markers.size(), 35u);
  ASSERT_EQ(vsk->segments.size(), 19u);
  EXPECT_EQ(vsk->segments[0].name, "Pelvis");  // parents come first
  EXPECT_EQ(VskSubjects(*vsk), std::vector<std::string>{"Pelvis"});
  ASSERT_NE(FindSegment(*vsk, "Head"), nullptr);
  EXPECT_EQ(FindSegment(*vsk, "Head")->parent, "Pelvis");
  EXPECT_EQ(FindSegment(*vsk, "LeftHand")->parent, "LeftRadius");
  EXPECT_EQ(FindSegment(*vsk, "RightFoot")->parent, "RightTibialTorsioned");
  // 90 of the 112 parameters have a VALUE; the others are EXPRESSIONs.
  EXPECT_EQ(vsk->parameters.size(), 90u);
  EXPECT_EQ(vsk->parameters.at("Bodymass"), 75.0);
  EXPECT_EQ(vsk->parameters.at("ASISy"), 107.901016235352);
  EXPECT_EQ(vsk->parameters.count("LKNEy"), 0u);

  const VskMarker* lfhd = FindMarker(*vsk, "LFHD");
  ASSERT_NE(lfhd, nullptr);
  EXPECT_EQ(lfhd->segment, "Head");
  EXPECT_EQ(lfhd->position_mm, Eigen::Vector3d(0.0, 70.3721, 0.0));
  EXPECT_EQ(lfhd->radius_mm, 12.5);
  EXPECT_EQ(lfhd->status, "required");
  const VskMarker* rbak = FindMarker(*vsk, "RBAK");
  ASSERT_NE(rbak, nullptr);
  EXPECT_EQ(rbak->segment, "Thorax");
  EXPECT_EQ(rbak->position_mm, Eigen::Vector3d(-220.451, -109.437, -58.2279));
  const VskMarker* lasi = FindMarker(*vsk, "LASI");
  ASSERT_NE(lasi, nullptr);
  EXPECT_EQ(lasi->segment, "Pelvis");
  EXPECT_EQ(lasi->position_mm, Eigen::Vector3d(43.8126, 107.901, 99.8542));
  EXPECT_EQ(FindMarker(*vsk, "RTOE")->position_mm, Eigen::Vector3d(145.732, 10.0517, -39.5598));

  EXPECT_EQ(VskMarkersOfSegment(*vsk, "Head").size(), 4u);
  EXPECT_EQ(VskMarkersOfSegment(*vsk, "Pelvis").size(), 4u);
  EXPECT_EQ(VskMarkersOfSubject(*vsk, "Pelvis").size(), 35u);
  EXPECT_EQ(VskMarkersOfSubject(*vsk, "LeftFemur").size(), 6u);  // LTHI LKNE, LTIB, LANK, LHEE LTOE
}

TEST(Vsk, V25PositionsMayNameParametersWithASignPrefix) {
  std::string text = test::ReadSample(kNexus);
  text = test::ReplaceFirst(text, "NAME=\"LFHD\" POSITION=\"0 70.3721 0\"",
                            "NAME=\"LFHD\" POSITION=\"0 +HEADy 0\"");
  text = test::ReplaceFirst(text, "NAME=\"RFHD\" POSITION=\"0 -70.3721 0\"",
                            "NAME=\"RFHD\" POSITION=\"0 -HEADy 0\"");
  text = test::ReplaceFirst(text, "NAME=\"LBHD\" POSITION=\"-159.08 54.5502 0\"",
                            "NAME=\"LBHD\" POSITION=\"LBHDx BHDy 0\"");
  const Expected<Vsk> vsk = ParseVsk(text, "signs.vsk");
  ASSERT_TRUE(vsk.ok()) << vsk.error().message;
  EXPECT_EQ(FindMarker(*vsk, "LFHD")->position_mm.y(), 70.3721237182617);
  EXPECT_EQ(FindMarker(*vsk, "RFHD")->position_mm.y(), -70.3721237182617);
  EXPECT_EQ(FindMarker(*vsk, "LBHD")->position_mm,
            Eigen::Vector3d(-159.080215454102, 54.5502090454102, 0.0));
}

// ------------------------------------------------------------ round trips

// Random subjects (root segments), some with child segments, each with
// markers; positions with many significant digits.
Vsk RandomVsk(std::mt19937& rng, int subjects) {
  std::uniform_real_distribution<double> coordinate(-800.0, 800.0);
  std::uniform_int_distribution<int> markers_per_segment(1, 6);
  Vsk vsk;
  vsk.version = "3.2";
  const std::vector<std::string> names = {"cam0", "cam2", "plate", "wand", "helmet"};
  for (int s = 0; s < subjects; ++s) {
    const std::string subject = names[s % names.size()] + (s >= 5 ? std::to_string(s) : "");
    std::vector<std::string> segments = {subject};
    vsk.segments.push_back({subject, ""});
    if (rng() % 3 == 0) {  // a nested segment, written and read in pre-order
      segments.push_back(subject + "_arm");
      vsk.segments.push_back({subject + "_arm", subject});
    }
    for (const std::string& segment : segments) {
      const int count = markers_per_segment(rng);
      for (int m = 0; m < count; ++m) {
        VskMarker marker;
        marker.name = segment + "_m" + std::to_string(m + 1);
        marker.segment = segment;
        marker.position_mm = {coordinate(rng), coordinate(rng), coordinate(rng)};
        if (m == 0) marker.position_mm.x() = 0.0;
        marker.status = rng() % 2 == 0 ? "required" : "optional";
        marker.radius_mm = std::vector<double>{7.0, 9.5, 14.0}[rng() % 3];
        vsk.markers.push_back(marker);
      }
    }
    vsk.parameters[subject + "_scale"] = coordinate(rng) * 1e-3;
  }
  return vsk;
}

void ExpectSameVsk(const Vsk& a, const Vsk& b) {
  EXPECT_EQ(a.version, b.version);
  EXPECT_EQ(a.model, b.model);
  ASSERT_EQ(a.segments.size(), b.segments.size());
  for (size_t i = 0; i < a.segments.size(); ++i) {
    EXPECT_EQ(a.segments[i].name, b.segments[i].name);
    EXPECT_EQ(a.segments[i].parent, b.segments[i].parent);
  }
  ASSERT_EQ(a.markers.size(), b.markers.size());
  for (size_t i = 0; i < a.markers.size(); ++i) {
    EXPECT_EQ(a.markers[i].name, b.markers[i].name);
    EXPECT_EQ(a.markers[i].segment, b.markers[i].segment);
    EXPECT_EQ(a.markers[i].position_mm, b.markers[i].position_mm) << a.markers[i].name;
    EXPECT_EQ(a.markers[i].status, b.markers[i].status);
    EXPECT_EQ(a.markers[i].radius_mm, b.markers[i].radius_mm);
  }
  // The written file adds one parameter per marker coordinate.
  for (const auto& [name, value] : a.parameters) {
    ASSERT_EQ(b.parameters.count(name), 1u) << name;
    EXPECT_EQ(b.parameters.at(name), value) << name;
  }
  EXPECT_EQ(b.parameters.size(), a.parameters.size() + 3 * a.markers.size());
}

TEST(Vsk, RoundTripOfRandomModelsWithSeveralSubjects) {
  std::mt19937 rng(424242);
  test::TempDir dir;
  for (int trial = 0; trial < 60; ++trial) {
    const Vsk original = RandomVsk(rng, 1 + trial % 6);
    const auto path = dir / ("object_" + std::to_string(trial) + ".vsk");
    const Status written = WriteVsk(path, original);
    ASSERT_TRUE(written.ok()) << written.error().message;
    const Expected<Vsk> back = ReadVsk(path);
    ASSERT_TRUE(back.ok()) << back.error().message;
    SCOPED_TRACE("trial " + std::to_string(trial));
    ExpectSameVsk(original, *back);
    EXPECT_EQ(VskSubjects(*back), VskSubjects(original));
  }
}

TEST(Vsk, LifmcrObjectWithThreeClustersOfFourMarkers) {
  Vsk vsk;
  vsk.model = "LiFMCR";
  for (const std::string subject : {"cam0", "cam2", "plate"}) {
    vsk.segments.push_back({subject, ""});
    for (int m = 1; m <= 4; ++m) {
      vsk.markers.push_back({subject + "_" + std::to_string(m), subject,
                             Eigen::Vector3d(10.0 * m, m % 2 == 0 ? 25.5 : -25.5, 3.25 * m),
                             "required", 7.0});
    }
  }
  const Expected<std::string> text = FormatVsk(vsk);
  ASSERT_TRUE(text.ok()) << text.error().message;
  EXPECT_NE(text->find("POSITION=\"'cam2_cam2_3_x' 'cam2_cam2_3_y' 'cam2_cam2_3_z'\""),
            std::string::npos);
  EXPECT_NE(text->find("<JointFree NAME=\"World_plate\""), std::string::npos);
  EXPECT_NE(text->find("<Parameter NAME=\"cam0_cam0_1_x\" VALUE=\"10\" PRIOR=\"10\""),
            std::string::npos);
  const Expected<Vsk> back = ParseVsk(*text, "Object.vsk");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->version, "3.2");
  EXPECT_EQ(back->model, "LiFMCR");
  EXPECT_EQ(VskSubjects(*back), (std::vector<std::string>{"cam0", "cam2", "plate"}));
  for (const std::string subject : {"cam0", "cam2", "plate"}) {
    EXPECT_EQ(VskMarkersOfSubject(*back, subject).size(), 4u) << subject;
    const Expected<Eigen::Vector3d> centroid = VskMarkerCentroidMm(*back, subject);
    ASSERT_TRUE(centroid.ok());
    EXPECT_NEAR((*centroid - Eigen::Vector3d(25.0, 0.0, 8.125)).norm(), 0.0, 1e-12);
  }
}

TEST(Vsk, TrackerSampleSurvivesWriteAndRead) {
  const Expected<Vsk> vsk = ReadVsk(test::SamplePath(kTracker));
  ASSERT_TRUE(vsk.ok()) << vsk.error().message;
  test::TempDir dir;
  ASSERT_TRUE(WriteVsk(dir / "go2.vsk", *vsk).ok());
  const Expected<Vsk> back = ReadVsk(dir / "go2.vsk");
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_EQ(back->markers.size(), 11u);
  for (size_t i = 0; i < 11; ++i) {
    EXPECT_EQ(back->markers[i].position_mm, vsk->markers[i].position_mm);
  }
  EXPECT_EQ(back->parameters, vsk->parameters);  // the same generated names
}

TEST(Vsk, WriterRefusesWhatCannotBeReadBack) {
  Vsk vsk;
  vsk.segments = {{"cam0", ""}};
  vsk.markers = {{"m 1", "cam0", Eigen::Vector3d::Zero(), "", 7.0}};
  test::TempDir dir;
  Status status = WriteVsk(dir / "a.vsk", vsk);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.error().message.find("'m 1': names must not contain whitespace or quotes"),
            std::string::npos)
      << status.error().message;
  EXPECT_FALSE(std::filesystem::exists(dir / "a.vsk"));
  vsk.markers = {{"m1", "cam9", Eigen::Vector3d::Zero(), "", 7.0}};
  status = WriteVsk(dir / "a.vsk", vsk);
  ASSERT_FALSE(status.ok());
  EXPECT_NE(status.error().message.find("its segment 'cam9' is not in the segments"),
            std::string::npos);
  vsk.markers = {{"m1", "cam0", Eigen::Vector3d(0, NAN, 0), "", 7.0}};
  EXPECT_FALSE(WriteVsk(dir / "a.vsk", vsk).ok());
}

// A model of N root segments each with one child and one marker on the child.
Vsk WideVsk(int n) {
  Vsk vsk;
  for (int i = 0; i < n; ++i) {
    const std::string root = "s" + std::to_string(i);
    vsk.segments.push_back({root, ""});
    vsk.segments.push_back({root + "c", root});
    vsk.markers.push_back({"m" + std::to_string(i), root + "c",
                           Eigen::Vector3d(i % 100, 1.5, -2.0), "", 7.0});
  }
  return vsk;
}

// Process CPU seconds of the fastest of three FormatVsk calls (the least
// disturbed by other processes on the machine).
double FormatCpuSeconds(const Vsk& vsk) {
  double best = 1e9;
  for (int run = 0; run < 3; ++run) {
    const std::clock_t start = std::clock();
    const Expected<std::string> text = FormatVsk(vsk);
    const double seconds = static_cast<double>(std::clock() - start) / CLOCKS_PER_SEC;
    EXPECT_TRUE(text.ok()) << text.error().message;
    best = std::min(best, seconds);
  }
  return best;
}

TEST(Vsk, WriterIsLinearInTheModel) {
  // 1250 and 5000 subjects (10000 segments, the limit). A writer that scans
  // every segment for each segment's children takes 16x as long for the 4x
  // model; a linear one 4x. The test allows 8x.
  const Vsk small = WideVsk(1250);
  const Vsk large = WideVsk(5000);
  const double small_s = FormatCpuSeconds(small);
  const double large_s = FormatCpuSeconds(large);
  std::printf("FormatVsk: %zu segments %.4f s, %zu segments %.4f s, ratio %.2f (linear 4)\n",
              small.segments.size(), small_s, large.segments.size(), large_s,
              large_s / std::max(small_s, 1e-6));
  EXPECT_LT(large_s, 8.0 * std::max(small_s, 1e-4));
  EXPECT_LT(large_s, 1.0);
  const Expected<Vsk> back = ParseVsk(*FormatVsk(large), "wide.vsk");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->segments.size(), large.segments.size());
  EXPECT_EQ(VskSubjects(*back).size(), 5000u);
}

TEST(Vsk, WriterAndReaderBoundTheNesting) {
  Vsk vsk;
  vsk.segments.push_back({"s1", ""});
  for (std::size_t depth = 2; depth <= kVskLimits.max_segment_depth; ++depth) {
    vsk.segments.push_back({"s" + std::to_string(depth), "s" + std::to_string(depth - 1)});
  }
  vsk.markers.push_back({"tip", vsk.segments.back().name, Eigen::Vector3d::Zero(), "", 7.0});
  const Expected<std::string> deepest = FormatVsk(vsk);
  ASSERT_TRUE(deepest.ok()) << deepest.error().message;
  const Expected<Vsk> back = ParseVsk(*deepest, "deep.vsk");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->segments.size(), kVskLimits.max_segment_depth);
  EXPECT_EQ(VskMarkersOfSubject(*back, "s1").size(), 1u);

  const std::string last = vsk.segments.back().name;
  vsk.segments.push_back({"deeper", last});
  const Expected<std::string> refused = FormatVsk(vsk);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("'deeper': nested 65 segments deep; at most 64"),
            std::string::npos)
      << refused.error().message;

  // The same nesting by hand: the reader names the element.
  std::string text = *deepest;
  const std::string tip = "<Segment NAME=\"" + last + "\"";
  const std::size_t at = text.find("</JointFree>", text.find(tip));
  ASSERT_NE(at, std::string::npos);
  text.insert(at + std::string("</JointFree>").size(), "<Segment NAME=\"deeper\"/>");
  const Expected<Vsk> read = ParseVsk(text, "deep.vsk");
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.error().message.find("segments nested more than 64 deep"), std::string::npos)
      << read.error().message;
}

// ------------------------------------------------------------ bad input

TEST(VskBadInput, WrongRoot) {
  std::string text = test::ReadSample(kTracker);
  text = test::ReplaceFirst(text, "<KinematicModel VERSION", "<SubjectModel VERSION");
  text = test::ReplaceFirst(text, "</KinematicModel>", "</SubjectModel>");
  ExpectError(text, {"bad.vsk:2:", "/SubjectModel", "root element is <SubjectModel>",
                     "expected <KinematicModel>"});
}

TEST(VskBadInput, UndefinedParameterReference) {
  ExpectError(
      test::ReplaceFirst(
          test::ReadSample(kTracker),
          "\t\t<Parameter NAME=\"Go2_Go21_y\" VALUE=\"0.0\" PRIOR=\"0.0\" HIDDEN=\"true\" />\n",
          ""),
      {"bad.vsk:118:", "TargetLocalPointToWorldPoint[@MARKER='Go21']",
       "marker Go21 references undefined parameter 'Go2_Go21_y'"});
  // A v2.5 name with a sign prefix that does not resolve.
  ExpectError(test::ReplaceFirst(test::ReadSample(kNexus), "POSITION=\"0 -70.3721 0\"",
                                 "POSITION=\"0 -HEADz 0\""),
              {"bad.vsk:222:", "Marker[@NAME='RFHD']",
               "marker RFHD references undefined parameter 'HEADz'"});
  // An EXPRESSION parameter is named, but not evaluated.
  ExpectError(test::ReplaceFirst(test::ReadSample(kNexus), "POSITION=\"0 70.3721 0\"",
                                 "POSITION=\"0 LKNEy 0\""),
              {"bad.vsk:219:", "marker LFHD references parameter 'LKNEy', which has no VALUE"});
}

TEST(VskBadInput, NonNumericPositionOrValue) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kNexus), "POSITION=\"0 70.3721 0\"",
                                 "POSITION=\"0 70,3721 0\""),
              {"bad.vsk:219:", "/KinematicModel/MarkerSet/Markers/Marker[@NAME='LFHD']",
               "POSITION component '70,3721' is neither a number nor a parameter name"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kNexus), "POSITION=\"0 70.3721 0\"",
                                 "POSITION=\"0 70.3721\""),
              {"bad.vsk:219:", "expected POSITION with 3 components, got 2"});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kTracker), "VALUE=\"261.96\"", "VALUE=\"261.96mm\""),
      {"bad.vsk:4:", "Parameter[@NAME='Go2_Go21_x']",
       "expected a number in VALUE, got '261.96mm'"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kTracker), "RADIUS=\"14\"", "RADIUS=\"big\""),
              {"bad.vsk:47:", "marker Go21: expected RADIUS 0 .. 1000 mm, got 'big'"});
}

TEST(VskBadInput, MarkerReferencingMissingSegment) {
  ExpectError(test::ReplaceFirst(test::ReadSample(kNexus),
                                 "NAME=\"LFHD\" POSITION=\"0 70.3721 0\" RADIUS=\"12.5\" "
                                 "RGB=\"0 0 255\" SEGMENT=\"Head\"",
                                 "NAME=\"LFHD\" POSITION=\"0 70.3721 0\" RADIUS=\"12.5\" "
                                 "RGB=\"0 0 255\" SEGMENT=\"Hed\""),
              {"bad.vsk:219:", "marker LFHD refers to segment 'Hed', which is not in <Skeleton>"});
  ExpectError(
      test::ReplaceFirst(test::ReadSample(kTracker),
                         "MARKER=\"Go21\" OPACITY=\"255\" POSITION=\"'Go2_Go21_x' "
                         "'Go2_Go21_y' 'Go2_Go21_z'\" RGB=\"93 93 93\" SEGMENT=\"Go2\"",
                         "MARKER=\"Go21\" OPACITY=\"255\" POSITION=\"'Go2_Go21_x' 'Go2_Go21_y' "
                         "'Go2_Go21_z'\" RGB=\"93 93 93\" SEGMENT=\"Go3\""),
      {"bad.vsk:119:", "marker Go21 refers to segment 'Go3'"});
}

TEST(VskBadInput, StructuralErrors) {
  const std::string tracker = test::ReadSample(kTracker);
  ExpectError(tracker.substr(0, tracker.size() / 3), {"bad.vsk:", "malformed XML"});
  ExpectError(test::ReplaceFirst(tracker, "<Marker NAME=\"Go22\"", "<Marker NAME=\"Go21\""),
              {"bad.vsk:48:", "duplicate marker 'Go21' (first at line 47)"});
  ExpectError(test::ReplaceFirst(tracker, "MARKER=\"Go21\"", "MARKER=\"Go99\""),
              {"bad.vsk:119:", "target refers to marker 'Go99', which is not in <MarkerSet>"});
  ExpectError(test::ReplaceFirst(tracker, "<Marker NAME=\"Go21\"", "<Marker NAME=\"Go20\""),
              {"bad.vsk:119:", "target refers to marker 'Go21'"});
  ExpectError(test::ReplaceFirst(test::ReadSample(kNexus), "POSITION=\"0 70.3721 0\" ", ""),
              {"bad.vsk:219:", "marker LFHD has no position"});
  ExpectError(test::ReplaceFirst(tracker, "NAME=\"Go2_Go21_y\"", "NAME=\"Go2_Go21_x\""),
              {"bad.vsk:5:", "duplicate parameter 'Go2_Go21_x' (first at line 4)"});
  // Every prefix of a real file fails cleanly.
  for (size_t size = 0; size < tracker.size(); size += 61) {
    EXPECT_FALSE(ParseVsk(tracker.substr(0, size), "bad.vsk").ok()) << size;
  }
}

// Models that parse as XML but describe nothing a capture can use, or are
// not a VSK at all: each an error at its element, not a valid empty model.
TEST(VskBadInput, NoSegmentEmptyNameOrGarbageVersion) {
  ExpectError("<KinematicModel VERSION=\"3.2\">\n<Skeleton/>\n</KinematicModel>\n",
              {"bad.vsk:2:", "/KinematicModel/Skeleton", "no <Segment>; expected at least one"});
  ExpectError("<KinematicModel VERSION=\"3.2\"><Parameters/></KinematicModel>",
              {"bad.vsk:1:", "missing element /KinematicModel/Skeleton"});
  ExpectError("<KinematicModel VERSION=\"3.2\"><Skeleton>\n<Segment NAME=\"\"/>\n"
              "</Skeleton></KinematicModel>",
              {"bad.vsk:2:", "/KinematicModel/Skeleton/Segment", "empty segment NAME"});
  const std::string tracker = test::ReadSample(kTracker);
  ExpectError(test::ReplaceFirst(tracker, "<Marker NAME=\"Go21\"", "<Marker NAME=\" \""),
              {"bad.vsk:47:", "empty marker NAME"});
  ExpectError(test::ReplaceFirst(tracker, "NAME=\"Go2_Go21_x\"", "NAME=\"\""),
              {"bad.vsk:4:", "empty parameter NAME"});
  for (const std::string version : {"garbage!!", "", "3.", ".2", "3..2", "v3.2", "3.2 "}) {
    ExpectError(test::ReplaceFirst(tracker, "VERSION=\"3.2\"", "VERSION=\"" + version + "\""),
                {"bad.vsk:2:", "/KinematicModel", "VERSION is '" + version + "'",
                 "expected a version number such as 3.2"});
  }
  ExpectError(test::ReplaceFirst(tracker, " VERSION=\"3.2\"", ""),
              {"bad.vsk:2:", "missing attribute VERSION"});
  // Versions as Vicon writes them still read.
  for (const std::string version : {"3.2", "2.5", "3", "1.0.4"}) {
    const Expected<Vsk> vsk =
        ParseVsk(test::ReplaceFirst(tracker, "VERSION=\"3.2\"", "VERSION=\"" + version + "\""),
                 "ok.vsk");
    ASSERT_TRUE(vsk.ok()) << version << ": " << vsk.error().message;
    EXPECT_EQ(vsk->version, version);
  }
  // The writer refuses what the reader would (tests above).
  Vsk empty;
  const Expected<std::string> refused = FormatVsk(empty);
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("without segments"), std::string::npos)
      << refused.error().message;
}

// XML text that is not UTF-8 (a Latin-1 name) is named with its element and
// byte, not read into names that reports and JSON then carry.
TEST(VskBadInput, TextThatIsNotUtf8) {
  const std::string tracker = test::ReadSample(kTracker);
  ExpectError(test::ReplaceFirst(tracker, "<Segment NAME=\"Go2\"", "<Segment NAME=\"Go\xE9" "2\""),
              {"bad.vsk:39:", "/KinematicModel/Skeleton/Segment", "attribute NAME is not UTF-8 (byte 0xE9",
               "Go\\xE92", "expected UTF-8 text"});
}

TEST(VskBadInput, RandomByteCorruptionNeverCrashes) {
  const std::string text = test::ReadSample(kNexus);
  std::mt19937 rng(5);
  const std::string alphabet = "<>/=\"' \r\n\t0123456789.-+eE'abcXYZ&";
  for (int trial = 0; trial < 500; ++trial) {
    std::string corrupt = text;
    for (int e = 0; e < 3; ++e) corrupt[rng() % corrupt.size()] = alphabet[rng() % alphabet.size()];
    const Expected<Vsk> result = ParseVsk(corrupt, "corrupt.vsk");
    if (!result.ok()) {
      EXPECT_EQ(result.error().message.rfind("corrupt.vsk", 0), 0u) << result.error().message;
    }
  }
}

}  // namespace
}  // namespace lifmcr
