// `lifmcr vicon`: runs the built executable on written synthetic Objects
// files and on the real Nexus sample, and checks stdout, stderr and exit codes.

#include "config/frames.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

std::vector<std::string> Split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(text);
  while (std::getline(in, part, separator)) parts.push_back(part);
  if (!text.empty() && text.back() == separator) parts.push_back("");
  return parts;
}

std::string Quoted(const std::filesystem::path& path) { return "'" + path.string() + "'"; }

Pose MakePose(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  pose.translation() = t;
  return pose;
}

// Two objects, frames 10..14; cam2 is not tracked at frame 12.
class CliVicon : public ::testing::Test {
 protected:
  void SetUp() override {
    for (int64_t frame = 10; frame < 15; ++frame) {
      const double k = static_cast<double>(frame);
      cam0_.push_back({frame, MakePose(0.1 * k, {1, 2, 3}, {k, -2 * k, 1000 + k})});
      ViconPoseSample cam2{frame, MakePose(2.5 - 0.05 * k, {-1, 0.5, 0.2}, {-k, 300.25, 0.5})};
      if (frame == 12) cam2.vicon_from_marker.reset();
      cam2_.push_back(cam2);
    }
    auto block = MakeObjectsBlock(80, {"cam0:cam0", "cam2:cam2"}, {cam0_, cam2_}, {});
    ASSERT_TRUE(block.ok()) << block.error().message;
    ViconCsv csv;
    csv.blocks.push_back(*block);
    csv.crlf = true;
    ASSERT_TRUE(WriteViconCsv(objects_, csv).ok());
  }

  // Compares `lifmcr vicon` output rows with the expected samples.
  void ExpectRows(const std::string& out, const std::vector<ViconPoseSample>& expected,
                  double y_sign = 1.0) {
    const std::vector<std::string> lines = Split(out, '\n');
    ASSERT_EQ(lines.size(), expected.size() + 2) << out;  // header, rows, final ""
    EXPECT_EQ(lines[0], "vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz");
    EXPECT_EQ(lines.back(), "");
    for (size_t i = 0; i < expected.size(); ++i) {
      const std::string& line = lines[i + 1];
      const ViconPoseSample& sample = expected[i];
      if (!sample.vicon_from_marker) {
        EXPECT_EQ(line, std::to_string(sample.vicon_frame) + ",,,,,,,");
        continue;
      }
      const std::vector<std::string> fields = Split(line, ',');
      ASSERT_EQ(fields.size(), 8u) << line;
      EXPECT_EQ(std::stoll(fields[0]), sample.vicon_frame);
      const Eigen::Vector3d t(std::stod(fields[1]), std::stod(fields[2]), std::stod(fields[3]));
      const Eigen::Quaterniond q(std::stod(fields[4]), std::stod(fields[5]), std::stod(fields[6]),
                                 std::stod(fields[7]));
      EXPECT_GE(q.w(), 0.0);
      EXPECT_NEAR(q.norm(), 1.0, 1e-12);
      const Pose& pose = *sample.vicon_from_marker;
      const Eigen::Vector3d expected_t(pose.translation().x(), y_sign * pose.translation().y(),
                                       pose.translation().z());
      EXPECT_LT((t - expected_t).norm(), 1e-9) << line;
      if (y_sign > 0) {
        EXPECT_LT((q.toRotationMatrix() - pose.linear()).cwiseAbs().maxCoeff(), 1e-9) << line;
      }
    }
  }

  test::TempDir dir_;
  std::filesystem::path objects_ = dir_ / "sequence_01.csv";
  std::vector<ViconPoseSample> cam0_;
  std::vector<ViconPoseSample> cam2_;
};

TEST_F(CliVicon, PrintsThePosesOfOneSubject) {
  const auto result = test::RunLifmcr("vicon " + Quoted(objects_) + " --subject cam2");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(result.err, "");
  ExpectRows(result.out, cam2_);
  EXPECT_TRUE(Contains(result.out, "\n12,,,,,,,\n"));

  const auto full_name = test::RunLifmcr("vicon " + Quoted(objects_) + " --subject cam0:cam0");
  ASSERT_EQ(full_name.exit_code, 0) << full_name.err;
  ExpectRows(full_name.out, cam0_);
}

TEST_F(CliVicon, OptionsChangeTheConversion) {
  // The file was written left-handed (y mirrored); read as right-handed, y changes sign.
  const auto right = test::RunLifmcr("vicon " + Quoted(objects_) +
                                     " --subject cam0 --handedness right --rotation helical_rad");
  ASSERT_EQ(right.exit_code, 0) << right.err;
  ExpectRows(right.out, cam0_, -1.0);

  const auto degrees =
      test::RunLifmcr("vicon " + Quoted(objects_) + " --subject cam0 --rotation helical_deg");
  EXPECT_EQ(degrees.exit_code, 1);
  EXPECT_EQ(degrees.out, "");
  EXPECT_TRUE(Contains(degrees.err, objects_.string() + ":5:"));
  EXPECT_TRUE(Contains(degrees.err, "units row says 'rad'"));
}

TEST_F(CliVicon, SingleSubjectNeedsNoSubjectOption) {
  auto block = MakeObjectsBlock(80, {"plate:plate"}, {cam0_}, {});
  ASSERT_TRUE(block.ok());
  ViconCsv csv;
  csv.blocks.push_back(*block);
  const auto path = dir_ / "single.csv";
  ASSERT_TRUE(WriteViconCsv(path, csv).ok());
  const auto result = test::RunLifmcr("vicon " + Quoted(path));
  ASSERT_EQ(result.exit_code, 0) << result.err;
  ExpectRows(result.out, cam0_);
}

TEST_F(CliVicon, SubjectErrorsListTheSubjects) {
  const auto several = test::RunLifmcr("vicon " + Quoted(objects_));
  EXPECT_EQ(several.exit_code, 1);
  EXPECT_EQ(several.out, "");
  EXPECT_TRUE(Contains(several.err, "cam0:cam0, cam2:cam2"));
  EXPECT_TRUE(Contains(several.err, "--subject"));

  const auto unknown = test::RunLifmcr("vicon " + Quoted(objects_) + " --subject cam1");
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_TRUE(Contains(unknown.err, "no subject 'cam1'"));
  EXPECT_TRUE(Contains(unknown.err, "cam0:cam0, cam2:cam2"));
}

TEST_F(CliVicon, TrajectoriesOnlyFileIsAClearError) {
  const auto sample =
      test::SamplePath("vicon_nexus_trajectories_pyomeca_markers_first135frames.csv");
  const auto result = test::RunLifmcr("vicon " + Quoted(sample));
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_EQ(result.out, "");
  EXPECT_TRUE(Contains(result.err, "no Objects/Segments block"));
  EXPECT_TRUE(Contains(result.err, "it has Trajectories with 51 markers"));
  EXPECT_TRUE(Contains(result.err, "subjects boite, Daphnee"));
}

TEST_F(CliVicon, BadFilesExitOneWithThePlace) {
  std::string text = test::ReadFile(objects_);
  // Line 6 is frame 10: empty its RY (field 4) to make a partial tuple.
  const size_t line6 = text.find("\r\n10,0,") + 2;
  const size_t ry = text.find(',', text.find(',', text.find(',', line6) + 1) + 1) + 1;
  text.erase(ry, text.find(',', ry) - ry);
  const auto broken = dir_ / "broken.csv";
  test::WriteFile(broken, text);
  const auto result = test::RunLifmcr("vicon " + Quoted(broken) + " --subject cam0");
  EXPECT_EQ(result.exit_code, 1);
  EXPECT_EQ(result.out, "");
  EXPECT_TRUE(Contains(result.err, broken.string() + ":6:" + std::to_string(ry - line6 + 1) + ":"));
  EXPECT_TRUE(Contains(result.err, "partial tuple"));

  const auto missing = test::RunLifmcr("vicon " + Quoted(dir_ / "nope.csv"));
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_TRUE(Contains(missing.err, "nope.csv: no such file"));
}

TEST_F(CliVicon, UsageErrorsAreRefusedByTheParser) {
  const auto bad_rotation =
      test::RunLifmcr("vicon " + Quoted(objects_) + " --subject cam0 --rotation quaternion");
  EXPECT_NE(bad_rotation.exit_code, 0);
  EXPECT_NE(bad_rotation.exit_code, 1);  // a usage error, not a file error
  EXPECT_TRUE(Contains(bad_rotation.err, "--rotation"));
  const auto bad_handedness =
      test::RunLifmcr("vicon " + Quoted(objects_) + " --subject cam0 --handedness up");
  EXPECT_NE(bad_handedness.exit_code, 0);
  EXPECT_NE(bad_handedness.exit_code, 1);
  const auto no_file = test::RunLifmcr("vicon");
  EXPECT_NE(no_file.exit_code, 0);
  EXPECT_NE(no_file.exit_code, 1);
}

TEST(CliViconHelp, MentionsTheOptionsAndDefaults) {
  const auto result = test::RunLifmcr("vicon --help");
  EXPECT_EQ(result.exit_code, 0);
  for (const char* part :
       {"--subject", "--rotation", "--handedness", "helical_rad", "euler_xyz_deg", "left_flip_y",
        "left-handed", "does not say", "vicon_frame,tx_mm,ty_mm,tz_mm,qw,qx,qy,qz"})
    EXPECT_TRUE(Contains(result.out, part));
}

}  // namespace
}  // namespace lifmcr
