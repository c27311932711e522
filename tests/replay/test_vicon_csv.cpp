// The CSV tokenizer, the Vicon CSV reader/writer and pose extraction: the real
// Nexus sample, random round trips over every rotation representation and
// handedness, and bad input whose messages must name file, line and column.

#include "config/frames.h"
#include "replay/csv_tokenizer.h"
#include "replay/vicon_csv.h"
#include "replay/vicon_poses.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace lifmcr {
namespace {

// Whether `text` contains `part`, printing both when not.
::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

constexpr const char* kSample = "vicon_nexus_trajectories_pyomeca_markers_first135frames.csv";

constexpr RotationRepresentation kAllRotations[] = {
    RotationRepresentation::kHelicalRad, RotationRepresentation::kHelicalDeg,
    RotationRepresentation::kEulerXyzDeg, RotationRepresentation::kEulerXyzRad};
constexpr Handedness kAllHandedness[] = {Handedness::kRight, Handedness::kLeftFlipX,
                                         Handedness::kLeftFlipY, Handedness::kLeftFlipZ};

// ---------------------------------------------------------------- tokenizer

TEST(CsvTokenizer, SplitsQuotedFieldsAndKeepsPositions) {
  const std::string text =
      "\xEF\xBB\xBF"
      "a,\"b,c\",\"say \"\"hi\"\"\"\r\n,x,\r\n\r\n\"multi\nline\",z";
  auto document = TokenizeCsv(text, "t.csv");
  ASSERT_TRUE(document.ok()) << document.error().message;
  EXPECT_TRUE(document->had_bom);
  EXPECT_TRUE(document->crlf);
  ASSERT_EQ(document->rows.size(), 4u);
  const CsvRow& first = document->rows[0];
  ASSERT_EQ(first.fields.size(), 3u);
  EXPECT_EQ(first.fields[0].text, "a");
  EXPECT_EQ(first.fields[1].text, "b,c");
  EXPECT_TRUE(first.fields[1].quoted);
  EXPECT_EQ(first.fields[1].column, 3);
  EXPECT_EQ(first.fields[2].text, "say \"hi\"");
  EXPECT_EQ(first.fields[2].column, 9);
  const CsvRow& second = document->rows[1];
  EXPECT_EQ(second.line, 2);
  ASSERT_EQ(second.fields.size(), 3u);
  EXPECT_EQ(second.fields[1].text, "x");
  EXPECT_EQ(second.fields[1].column, 2);
  EXPECT_EQ(second.fields[2].text, "");
  EXPECT_EQ(second.fields[2].column, 4);
  EXPECT_EQ(second.WidthWithoutTrailingEmpty(), 2u);
  EXPECT_TRUE(document->rows[2].fields.empty());
  EXPECT_TRUE(document->rows[2].IsBlank());
  const CsvRow& last = document->rows[3];
  EXPECT_EQ(last.line, 4);
  EXPECT_EQ(last.fields[0].text, "multi\nline");
  EXPECT_EQ(last.fields[1].text, "z");
  EXPECT_EQ(last.fields[1].line, 5);
}

TEST(CsvTokenizer, SemicolonDelimiterAndDetection) {
  EXPECT_EQ(DetectCsvDelimiter("Objects\n80\n;;a\nFrame;Sub Frame;RX\n"), ';');
  EXPECT_EQ(DetectCsvDelimiter("\xEF\xBB\xBF"
                               "Frame,Sub Frame\n"),
            ',');
  EXPECT_EQ(DetectCsvDelimiter("no frame row"), ',');
  auto document = TokenizeCsv("1;0,5;\"x;y\"\n", "t.csv", ';');
  ASSERT_TRUE(document.ok());
  ASSERT_EQ(document->rows[0].fields.size(), 3u);
  EXPECT_EQ(document->rows[0].fields[1].text, "0,5");
  EXPECT_EQ(document->rows[0].fields[2].text, "x;y");
  EXPECT_FALSE(document->crlf);
}

TEST(CsvTokenizer, BadQuotesAreErrorsWithPlace) {
  auto unterminated = TokenizeCsv("a,b\nc,\"open\n", "q.csv");
  ASSERT_FALSE(unterminated.ok());
  EXPECT_TRUE(Contains(unterminated.error().message, "q.csv:2:3:"));
  auto trailing = TokenizeCsv("a,\"b\"c,d\n", "q.csv");
  ASSERT_FALSE(trailing.ok());
  EXPECT_TRUE(Contains(trailing.error().message, "q.csv:1:6:"));
}

TEST(CsvTokenizer, FormattedFieldsTokenizeBackProperty) {
  std::mt19937 rng(11);
  const std::string alphabet = "ab ,;\"\n\r1.";
  std::uniform_int_distribution<size_t> pick(0, alphabet.size() - 1);
  std::uniform_int_distribution<int> length(0, 8);
  for (const char delimiter : {',', ';'}) {
    for (int trial = 0; trial < 300; ++trial) {
      std::vector<std::string> fields(1 + length(rng) % 5);
      std::string line;
      for (size_t i = 0; i < fields.size(); ++i) {
        const int n = length(rng);
        for (int k = 0; k < n; ++k) fields[i] += alphabet[pick(rng)];
        // A lone CR inside quotes reads back as '\n' (a line break), so write breaks as '\n'.
        for (char& c : fields[i])
          if (c == '\r') c = '\n';
        if (i > 0) line += delimiter;
        line += FormatCsvField(fields[i], delimiter);
      }
      if (fields.size() == 1 && fields[0].empty()) continue;  // an empty line has no field
      auto document = TokenizeCsv(line + "\n", "p.csv", delimiter);
      ASSERT_TRUE(document.ok()) << document.error().message;
      ASSERT_EQ(document->rows.size(), 1u) << line;
      ASSERT_EQ(document->rows[0].fields.size(), fields.size()) << line;
      for (size_t i = 0; i < fields.size(); ++i)
        EXPECT_EQ(document->rows[0].fields[i].text, fields[i]) << line;
    }
  }
}

// ---------------------------------------------------------- the real sample

TEST(ViconCsvSample, NexusTrajectoriesParse) {
  const auto path = test::SamplePath(kSample);
  auto csv = ReadViconCsv(path);
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_TRUE(csv->crlf);
  EXPECT_EQ(csv->delimiter, ',');
  ASSERT_EQ(csv->blocks.size(), 1u);
  const ViconBlock* block = csv->Find("Trajectories");
  ASSERT_NE(block, nullptr);
  EXPECT_EQ(csv->Find("Objects"), nullptr);
  EXPECT_EQ(block->rate_hz, 100);
  EXPECT_EQ(block->first_line, 1);
  EXPECT_EQ(block->Entities().size(), 51u);
  EXPECT_EQ(block->num_columns(), 153u);
  EXPECT_EQ(block->subjects, (std::vector<std::string>{"boite", "Daphnee"}));
  EXPECT_EQ(block->Entities().front(), "boite:gauche_ext");
  ASSERT_EQ(block->num_rows(), 135u);
  EXPECT_EQ(block->frames.front(), 1);
  EXPECT_EQ(block->frames.back(), 135);
  EXPECT_EQ(block->LineOf(0), 6);
  for (const ViconColumn& column : block->columns) EXPECT_EQ(column.unit, "mm");
  EXPECT_EQ(block->columns[0].name, "X");
  EXPECT_EQ(block->columns[152].name, "Z");

  // Frame 119 (line 124): fields 147..149, Daphnee:LASTC, are empty cells.
  const size_t row = 118;
  ASSERT_EQ(block->frames[row], 119);
  EXPECT_EQ(block->LineOf(row), 124);
  const auto lastc_x = block->FindColumn("Daphnee:LASTC", "X");
  ASSERT_TRUE(lastc_x.has_value());
  EXPECT_EQ(*lastc_x, 144u);
  for (size_t c = 144; c < 147; ++c) EXPECT_TRUE(std::isnan(block->at(row, c))) << c;
  EXPECT_DOUBLE_EQ(block->at(row, 143), 752.445);  // field 146, the marker before
  EXPECT_DOUBLE_EQ(block->at(row - 1, 144), 138.52);
  EXPECT_DOUBLE_EQ(block->at(0, 0), 44.1628);
  EXPECT_FALSE(std::isnan(block->at(row - 1, 144)));

  const ViconBlockSummary summary = Summarize(*block);
  EXPECT_EQ(summary.num_frames, 135u);
  EXPECT_EQ(summary.first_frame, 1);
  EXPECT_EQ(summary.last_frame, 135);
  EXPECT_EQ(summary.num_entities, 51u);
  EXPECT_EQ(summary.units, std::vector<std::string>{"mm"});
  EXPECT_EQ(summary.frames_with_missing, (std::vector<size_t>{0, 13}));
  EXPECT_TRUE(Contains(summary.OneLine(), "Trajectories: 100 Hz, 135 frames 1..135"));
  EXPECT_TRUE(Contains(summary.OneLine(), "Daphnee (13 frames with missing data)"));
}

TEST(ViconCsvSample, TrajectoriesHaveNoPoses) {
  auto csv = ReadViconCsv(test::SamplePath(kSample));
  ASSERT_TRUE(csv.ok());
  auto poses = ExtractSubjectPoses(*csv, "boite", {});
  ASSERT_FALSE(poses.ok());
  EXPECT_TRUE(Contains(poses.error().message, "no Objects/Segments block"));
  EXPECT_TRUE(Contains(poses.error().message, "Trajectories with 51 markers"));
  EXPECT_TRUE(Contains(poses.error().message, kSample));
}

// -------------------------------------------------------------- round trips

Pose RandomPose(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Eigen::Vector3d axis(unit(rng), unit(rng), unit(rng));
  axis.normalize();
  Pose pose = Pose::Identity();
  pose.linear() = Eigen::AngleAxisd(std::abs(unit(rng)) * 3.1, axis).toRotationMatrix();
  pose.translation() = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * 3000.0;
  return pose;
}

TEST(ViconCsvRoundTrip, RandomObjectsBlocksEveryRepresentationAndHandedness) {
  std::mt19937 rng(2024);
  std::uniform_int_distribution<int> num_subjects(1, 4);
  std::uniform_int_distribution<int> num_frames(1, 30);
  std::uniform_int_distribution<int> gap(1, 9);
  std::bernoulli_distribution missing(0.25);
  std::bernoulli_distribution coin(0.5);
  for (const RotationRepresentation rotation : kAllRotations) {
    for (const Handedness handedness : kAllHandedness) {
      for (int trial = 0; trial < 4; ++trial) {
        const ViconPoseOptions options{rotation, handedness};
        std::vector<std::string> subjects;
        for (int s = 0, n = num_subjects(rng); s < n; ++s)
          subjects.push_back("cam" + std::to_string(2 * s) + ":cam" + std::to_string(2 * s));
        std::vector<std::vector<ViconPoseSample>> samples(subjects.size());
        int64_t frame = std::uniform_int_distribution<int>(0, 100000)(rng);
        for (int f = 0, n = num_frames(rng); f < n; ++f, frame += gap(rng)) {
          for (auto& list : samples) {
            ViconPoseSample sample{frame, std::nullopt};
            if (!missing(rng)) sample.vicon_from_marker = RandomPose(rng);
            list.push_back(sample);
          }
        }
        auto block = MakeObjectsBlock(80, subjects, samples, options);
        ASSERT_TRUE(block.ok()) << block.error().message;
        ViconCsv written;
        written.blocks.push_back(*block);
        written.crlf = coin(rng);
        written.delimiter = coin(rng) ? ',' : ';';
        const std::string text = FormatViconCsv(written);
        auto read = ParseViconCsv(text, "round.csv");
        ASSERT_TRUE(read.ok()) << read.error().message << "\n" << text;
        EXPECT_EQ(read->crlf, written.crlf);
        EXPECT_EQ(read->delimiter, written.delimiter);
        ASSERT_EQ(read->blocks.size(), 1u);
        EXPECT_EQ(read->blocks[0].rate_hz, 80);
        EXPECT_EQ(read->blocks[0].Entities(), subjects);
        for (size_t s = 0; s < subjects.size(); ++s) {
          // By the full name and by the subject part alone.
          const std::string name = coin(rng) ? subjects[s] : std::string(SubjectOf(subjects[s]));
          auto poses = ExtractSubjectPoses(*read, name, options);
          ASSERT_TRUE(poses.ok()) << poses.error().message;
          ASSERT_EQ(poses->size(), samples[s].size());
          for (size_t i = 0; i < samples[s].size(); ++i) {
            const ViconPoseSample& expected = samples[s][i];
            const ViconPoseSample& actual = (*poses)[i];
            EXPECT_EQ(actual.vicon_frame, expected.vicon_frame);
            ASSERT_EQ(actual.vicon_from_marker.has_value(), expected.vicon_from_marker.has_value());
            if (!expected.vicon_from_marker) continue;
            EXPECT_LT((actual.vicon_from_marker->matrix() - expected.vicon_from_marker->matrix())
                          .cwiseAbs()
                          .maxCoeff(),
                      1e-9)
                << ToString(rotation) << " " << ToString(handedness) << " " << subjects[s]
                << " frame " << expected.vicon_frame;
          }
        }
        // The block itself reads back exactly (shortest round-trip numbers).
        const ViconBlock& back = read->blocks[0];
        ASSERT_EQ(back.values.size(), block->values.size());
        for (size_t k = 0; k < back.values.size(); ++k) {
          if (std::isnan(block->values[k])) {
            EXPECT_TRUE(std::isnan(back.values[k]));
          } else {
            EXPECT_EQ(back.values[k], block->values[k]);
          }
        }
      }
    }
  }
}

TEST(ViconCsvRoundTrip, WritesTrackerStyleObjectsBlock) {
  Pose pose = Pose::Identity();
  pose.translation() = Eigen::Vector3d(1.5, -2, 3);
  auto block = MakeObjectsBlock(80, {"cam0:cam0", "cam2:cam2"},
                                {{{7, pose}, {8, std::nullopt}}, {{7, std::nullopt}, {8, pose}}},
                                {RotationRepresentation::kHelicalRad, Handedness::kRight});
  ASSERT_TRUE(block.ok()) << block.error().message;
  ViconCsv csv;
  csv.blocks.push_back(*block);
  EXPECT_EQ(FormatViconCsv(csv),
            "Objects\n80\n"
            ",,cam0:cam0,,,,,,cam2:cam2,,,,,\n"
            "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n"
            ",,rad,rad,rad,mm,mm,mm,rad,rad,rad,mm,mm,mm\n"
            "7,0,0,0,0,1.5,-2,3,,,,,,\n"
            "8,0,,,,,,,0,0,0,1.5,-2,3\n");

  test::TempDir dir;
  ASSERT_TRUE(WriteViconCsv(dir / "objects.csv", csv).ok());
  auto read = ReadViconCsv(dir / "objects.csv");
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(read->path, (dir / "objects.csv").string());
  const Status bad = WriteViconCsv(dir / "no_such_dir" / "x.csv", csv);
  ASSERT_FALSE(bad.ok());
  EXPECT_TRUE(Contains(bad.error().message, "no_such_dir"));
}

TEST(ViconCsvRoundTrip, MakeObjectsBlockRefusesInconsistentInput) {
  const std::vector<ViconPoseSample> one = {{1, Pose::Identity()}};
  EXPECT_FALSE(MakeObjectsBlock(80, {"a:a", "b:b"}, {one}).ok());
  EXPECT_FALSE(MakeObjectsBlock(80, {"a:a", "a:a"}, {one, one}).ok());
  EXPECT_FALSE(MakeObjectsBlock(0, {"a:a"}, {one}).ok());
  EXPECT_FALSE(MakeObjectsBlock(80, {"a:a"}, {{{1, Pose::Identity()}, {1, std::nullopt}}}).ok());
}

// ------------------------------------------------------- headers and blocks

TEST(ViconCsv, MultiBlockNexusFileWithPaddedNamesAndDegrees) {
  const std::string text =
      "Segments\n100\n,,New Subject:gripper,,,,,,\n"
      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,deg,deg,deg,mm,mm,mm\n"
      "1,0,90,0,0,1,2,3\n2,0,0,90,0,4,5,6\n"
      "\n"
      "Trajectories\n100\n,,New Subject:m1,,,New Subject:m2,,\n"
      "Frame,Sub Frame,X,Y,Z,X,Y,Z\n,,mm,mm,mm,mm,mm,mm\n"
      "1,0,1,2,3,,,\n";
  auto csv = ParseViconCsv(text, "nexus.csv");
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  EXPECT_EQ(csv->BlockNames(), (std::vector<std::string>{"Segments", "Trajectories"}));
  EXPECT_EQ(csv->Find("Trajectories")->first_line, 9);
  EXPECT_EQ(csv->Find("Segments")->subjects, std::vector<std::string>{"New Subject"});

  auto wrong_unit = ExtractSubjectPoses(*csv, "New Subject", {});
  ASSERT_FALSE(wrong_unit.ok());
  EXPECT_TRUE(Contains(wrong_unit.error().message, "nexus.csv:5:"));
  EXPECT_TRUE(Contains(wrong_unit.error().message, "units row says 'deg'"));
  EXPECT_TRUE(Contains(wrong_unit.error().message, "helical_rad"));

  const ViconPoseOptions euler{RotationRepresentation::kEulerXyzDeg, Handedness::kRight};
  auto poses = ExtractSubjectPoses(*csv, "New Subject", euler);
  ASSERT_TRUE(poses.ok()) << poses.error().message;
  ASSERT_EQ(poses->size(), 2u);
  const Pose& first = *(*poses)[0].vicon_from_marker;
  EXPECT_LT((first.linear() * Eigen::Vector3d::UnitY() - Eigen::Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_EQ(first.translation(), Eigen::Vector3d(1, 2, 3));

  // Left-handed, y mirrored: t' = S t and R' = S R S.
  const ViconPoseOptions flip_y{RotationRepresentation::kEulerXyzDeg, Handedness::kLeftFlipY};
  auto flipped = ExtractSubjectPoses(*csv, "New Subject:gripper", flip_y);
  ASSERT_TRUE(flipped.ok());
  const Pose& second = *(*flipped)[1].vicon_from_marker;
  EXPECT_EQ(second.translation(), Eigen::Vector3d(4, -5, 6));
  const Eigen::Matrix3d s = ReflectionOf(Handedness::kLeftFlipY);
  EXPECT_LT((second.linear() - s * (*poses)[1].vicon_from_marker->linear() * s).norm(), 1e-12);
}

TEST(ViconCsv, GlobalAnglePrefixIsKeptApart) {
  const std::string text =
      "Objects\n80\n,,Global Angle cam0:cam0,,,,,\n"
      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n,,rad,rad,rad,mm,mm,mm\n1,0,0,0,0,1,2,3\n";
  auto csv = ParseViconCsv(text, "tracker.csv");
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  const ViconBlock& block = csv->blocks[0];
  EXPECT_EQ(block.columns[0].subject, "cam0:cam0");
  EXPECT_EQ(block.columns[0].prefix, "Global Angle ");
  EXPECT_EQ(block.subjects, std::vector<std::string>{"cam0"});
  for (const char* name : {"cam0", "cam0:cam0", "Global Angle cam0:cam0"})
    EXPECT_TRUE(ExtractSubjectPoses(*csv, name, {}).ok()) << name;
  EXPECT_TRUE(Contains(FormatViconCsv(*csv), ",,Global Angle cam0:cam0,,,,,\n"));
}

TEST(ViconCsv, SubjectLookupErrorsListTheSubjects) {
  const std::string text =
      "Segments\n100\n,,Daphnee:Pelvis,,,,,,Daphnee:Thorax,,,,,\n"
      "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n"
      ",,deg,deg,deg,mm,mm,mm,deg,deg,deg,mm,mm,mm\n1,0,0,0,0,0,0,0,0,0,0,0,0,0\n";
  auto csv = ParseViconCsv(text, "seg.csv");
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  const ViconPoseOptions deg{RotationRepresentation::kHelicalDeg, Handedness::kRight};
  auto ambiguous = ExtractSubjectPoses(*csv, "Daphnee", deg);
  ASSERT_FALSE(ambiguous.ok());
  EXPECT_TRUE(Contains(ambiguous.error().message, "ambiguous"));
  EXPECT_TRUE(Contains(ambiguous.error().message, "Daphnee:Pelvis, Daphnee:Thorax"));
  auto unknown = ExtractSubjectPoses(*csv, "boite", deg);
  ASSERT_FALSE(unknown.ok());
  EXPECT_TRUE(Contains(unknown.error().message, "seg.csv:3:"));
  EXPECT_TRUE(Contains(unknown.error().message, "no subject 'boite'"));
  EXPECT_TRUE(Contains(unknown.error().message, "Daphnee:Pelvis, Daphnee:Thorax"));
  EXPECT_TRUE(ExtractSubjectPoses(*csv, "Daphnee:Thorax", deg).ok());
}

TEST(ViconCsv, ShortRowsCanBeMissingByOption) {
  const std::string text =
      "Objects\n80\n,,cam0:cam0,,,,,\nFrame,Sub Frame,RX,RY,RZ,TX,TY,TZ\n"
      ",,rad,rad,rad,mm,mm,mm\n1,0,0,0,0,1,2,3\n2,0\n3,0,0,0,0,1,2,3,,,\n";
  auto strict = ParseViconCsv(text, "short.csv");
  ASSERT_FALSE(strict.ok());
  EXPECT_TRUE(Contains(strict.error().message, "short.csv:7:3: line 7 has 2 fields, expected 8"));
  ViconCsvOptions options;
  options.short_rows_are_missing = true;
  auto lenient = ParseViconCsv(text, "short.csv", options);
  ASSERT_TRUE(lenient.ok()) << lenient.error().message;
  auto poses = ExtractSubjectPoses(*lenient, "cam0", {});
  ASSERT_TRUE(poses.ok());
  ASSERT_EQ(poses->size(), 3u);
  EXPECT_TRUE((*poses)[0].vicon_from_marker.has_value());
  EXPECT_FALSE((*poses)[1].vicon_from_marker.has_value());
  EXPECT_TRUE((*poses)[2].vicon_from_marker.has_value());  // trailing empty fields tolerated
}

TEST(ViconCsv, DecimalCommaOnlyByOption) {
  const std::string text =
      "Objects\r\n80\r\n;;cam0:cam0;;;;;\r\nFrame;Sub Frame;RX;RY;RZ;TX;TY;TZ\r\n"
      ";;rad;rad;rad;mm;mm;mm\r\n1;0;0,5;0;0;1,25;2;3\r\n";
  auto refused = ParseViconCsv(text, "comma.csv");
  ASSERT_FALSE(refused.ok());
  EXPECT_TRUE(Contains(refused.error().message, "comma.csv:6:5: field 3 (cam0:cam0 RX)"));
  EXPECT_TRUE(Contains(refused.error().message, "decimal comma"));
  ViconCsvOptions options;
  options.allow_decimal_comma = true;
  auto accepted = ParseViconCsv(text, "comma.csv", options);
  ASSERT_TRUE(accepted.ok()) << accepted.error().message;
  EXPECT_EQ(accepted->delimiter, ';');
  EXPECT_DOUBLE_EQ(accepted->blocks[0].at(0, 0), 0.5);
  EXPECT_DOUBLE_EQ(accepted->blocks[0].at(0, 3), 1.25);
}

// ---------------------------------------------------------------- bad input

// A valid two-object Tracker file; the bad-input tests break one thing.
const std::string kValid =
    "Objects\n"                                              // 1
    "80\n"                                                   // 2
    ",,cam0:cam0,,,,,,cam2:cam2,,,,,\n"                      // 3
    "Frame,Sub Frame,RX,RY,RZ,TX,TY,TZ,RX,RY,RZ,TX,TY,TZ\n"  // 4
    ",,rad,rad,rad,mm,mm,mm,rad,rad,rad,mm,mm,mm\n"          // 5
    "1,0,0.1,0.2,0.3,10,20,30,0,0,0,1,2,3\n"                 // 6
    "2,0,0.1,0.2,0.3,10,20,30,,,,,,\n";                      // 7

void ExpectError(const std::string& text, const std::string& place, const std::string& what) {
  auto csv = ParseViconCsv(text, "bad.csv");
  ASSERT_FALSE(csv.ok()) << "parsed:\n" << text;
  EXPECT_TRUE(Contains(csv.error().message, "bad.csv" + (place.empty() ? "" : ":" + place) + ": "));
  EXPECT_TRUE(Contains(csv.error().message, what));
}

TEST(ViconCsvBadInput, ValidBaseParses) {
  auto csv = ParseViconCsv(kValid, "bad.csv");
  ASSERT_TRUE(csv.ok()) << csv.error().message;
  auto poses = ExtractSubjectPoses(*csv, "cam2", {});
  ASSERT_TRUE(poses.ok());
  EXPECT_TRUE((*poses)[0].vicon_from_marker.has_value());
  EXPECT_FALSE((*poses)[1].vicon_from_marker.has_value());
}

TEST(ViconCsvBadInput, TruncatedFiles) {
  ExpectError("", "", "no Vicon block");
  ExpectError("Objects\n80\n", "3", "ends inside the header of block 'Objects'");
  ExpectError(kValid.substr(0, kValid.find("1,0,")), "6", "has a header but no data rows");
  // Cut in the middle of the last row.
  const std::string cut = kValid.substr(0, kValid.find("20,30,,") + 1);
  ExpectError(cut, "7:20", "line 7 has 7 fields, expected 14");
  ExpectError(kValid.substr(0, kValid.find("Frame,") + 3), "4:1",
              "expected 'Frame' in the columns row");
}

TEST(ViconCsvBadInput, WrongBlockHeader) {
  ExpectError("80\n" + kValid.substr(kValid.find("80\n")), "1:1", "expected a block name");
  ExpectError(test::ReplaceFirst(kValid, "80\n", "eighty\n"), "2:1", "expected the frame rate");
  ExpectError(test::ReplaceFirst(kValid, "Sub Frame", "SubFrame"), "4:7", "expected 'Sub Frame'");
  ExpectError(test::ReplaceFirst(kValid, "\n80\n", "\n80\n\n"), "3",
              "empty line inside the header");
  ExpectError(test::ReplaceFirst(kValid, ",,cam0:cam0", "x,,cam0:cam0"), "3:1", "must be empty");
  ExpectError(test::ReplaceFirst(kValid, "cam2:cam2", "cam0:cam0"), "3:18",
              "names 'cam0:cam0' twice");
  ExpectError(test::ReplaceFirst(kValid, "\n2,0,", "\n\n2,0,"), "8:3",
              "got 14 fields (a blank line ended block 'Objects' above");
  ExpectError(test::ReplaceFirst(kValid, "Objects\n", "Objects,x\n"), "1:9",
              "expected only a block name");
}

TEST(ViconCsvBadInput, MissingTzColumn) {
  std::string text = test::ReplaceFirst(kValid, ",TX,TY,TZ\n", ",TX,TY\n");
  text = test::ReplaceFirst(text, "mm,mm,mm\n", "mm,mm\n");
  text = test::ReplaceFirst(text, ",1,2,3\n", ",1,2\n");
  text = test::ReplaceFirst(text, ",,,,,,\n", ",,,,,\n");
  ExpectError(text, "4:35", "'cam2:cam2' in block 'Objects' has no TZ column (fields 9..13)");
}

TEST(ViconCsvBadInput, NonNumericValue) {
  ExpectError(test::ReplaceFirst(kValid, "0.1,0.2,0.3,10,20,30,0", "0.1,0.2,abc,10,20,30,0"),
              "6:13", "field 5 (cam0:cam0 RZ): expected a number, got 'abc'");
  ExpectError(test::ReplaceFirst(kValid, "1,0,0.1", "1,0,nan"), "6:5",
              "expected a number, got 'nan'");
  ExpectError(test::ReplaceFirst(kValid, "1,0,0.1", "1,0,1e999"), "6:5",
              "expected a finite number");
  ExpectError(test::ReplaceFirst(kValid, "2,0,0.1", "2x,0,0.1"), "7:1",
              "expected an integer frame number");
}

// A value too small for a double is finite: it reads as 0 (what strtod
// rounds it to), only one too large is an error, and it says so.
TEST(ViconCsv, UnderflowReadsAsZero) {
  for (const std::string tiny : {"1e-400", "-1e-400", "0.000001e-320", "2e-324"}) {
    auto csv = ParseViconCsv(test::ReplaceFirst(kValid, "1,0,0.1", "1,0," + tiny), "tiny.csv");
    ASSERT_TRUE(csv.ok()) << tiny << ": " << csv.error().message;
    EXPECT_EQ(csv->blocks[0].at(0, 0), 0.0) << tiny;
    EXPECT_FALSE(std::signbit(csv->blocks[0].at(0, 0))) << tiny;
  }
  // Subnormal values keep their value.
  auto subnormal = ParseViconCsv(test::ReplaceFirst(kValid, "1,0,0.1", "1,0,1e-310"), "s.csv");
  ASSERT_TRUE(subnormal.ok()) << subnormal.error().message;
  EXPECT_EQ(subnormal->blocks[0].at(0, 0), 1e-310);
  ExpectError(test::ReplaceFirst(kValid, "1,0,0.1", "1,0,1e400"), "6:5",
              "'1e400' is larger than a double can hold");
  ExpectError(test::ReplaceFirst(kValid, "1,0,0.1", "1,0,0.5e309"), "6:5",
              "expected a finite number");
}

// Blocks are found by name: a second block of a name would never be read.
TEST(ViconCsvBadInput, TheSameBlockTwice) {
  ExpectError(kValid + "\n" + kValid, "9:1",
              "a second block 'Objects' (the first starts at line 1); expected each block once");
  // Different blocks side by side still parse.
  const std::string trajectories =
      "Trajectories\n100\n,,m:a,,\nFrame,Sub Frame,X,Y,Z\n,,mm,mm,mm\n1,0,1,2,3\n";
  auto both = ParseViconCsv(kValid + "\n" + trajectories, "two.csv");
  ASSERT_TRUE(both.ok()) << both.error().message;
  EXPECT_EQ(both->blocks.size(), 2u);
}

TEST(ViconCsvBadInput, ShortAndLongRows) {
  ExpectError(test::ReplaceFirst(kValid, "0,0,0,1,2,3\n", "0,0,0,1,2\n"), "6:34",
              "line 6 has 13 fields, expected 14");
  ExpectError(test::ReplaceFirst(kValid, "0,0,0,1,2,3\n", "0,0,0,1,2,3,4\n"), "6:38",
              "line 6 has 15 fields, expected 14");
}

TEST(ViconCsvBadInput, PartialTuple) {
  ExpectError(test::ReplaceFirst(kValid, "2,0,0.1,0.2,0.3", "2,0,0.1,,0.3"), "7:9",
              "partial tuple for 'cam0:cam0' at frame 2: RX,RZ,TX,TY,TZ present but RY empty");
}

TEST(ViconCsvBadInput, UnknownUnit) {
  ExpectError(test::ReplaceFirst(kValid, "rad,mm,mm,mm\n", "rad,mm,mm,m\n"), "5:42",
              "field 14 (cam2:cam2 TZ): unknown unit 'm', expected 'mm'");
  ExpectError(test::ReplaceFirst(kValid, ",,rad,", ",,grad,"), "5:3", "unknown unit 'grad'");
  ExpectError(test::ReplaceFirst(kValid, ",,rad,rad,", ",,rad,deg,"), "5:7", "differs from 'rad'");
}

TEST(ViconCsvBadInput, DecreasingFrameNumbers) {
  ExpectError(test::ReplaceFirst(kValid, "2,0,", "0,0,"), "7:1",
              "frame 0 sub frame 0 follows frame 1 sub frame 0 (line 6)");
  ExpectError(test::ReplaceFirst(kValid, "2,0,", "1,0,"), "7:1", "frame numbers must increase");
}

TEST(ViconCsvBadInput, DecimalCommaInSemicolonFile) {
  std::string text = kValid;
  for (char& c : text)
    if (c == ',') c = ';';
  text = test::ReplaceFirst(text, "10;20", "10,5;20");
  ExpectError(text, "6:17", "field 6 (cam0:cam0 TX)");
  ExpectError(text, "6:17", "decimal comma");
}

// A rotation no capture can hold is refused where it is read (it used to
// reach the pose conversion and fail there as "not a rotation").
TEST(ViconCsvBadInput, RotationThatIsNotARotation) {
  auto csv = ParseViconCsv(test::ReplaceFirst(kValid, "1,0,0.1,0.2,0.3", "1,0,1e300,1e300,1e300"),
                           "bad.csv");
  ASSERT_FALSE(csv.ok());
  EXPECT_TRUE(Contains(csv.error().message, "bad.csv:6:5: field 3 (cam0:cam0 RX)"));
  EXPECT_TRUE(Contains(csv.error().message, "outside +-62.832 rad"));
}

TEST(ViconCsvBadInput, NoCrashOnAnyTruncationOrByteFlip) {
  std::mt19937 rng(5);
  const std::string bytes = ",;\"\n\r0.-eX ";
  std::uniform_int_distribution<size_t> pick(0, bytes.size() - 1);
  for (size_t cut = 0; cut <= kValid.size(); ++cut) {
    auto csv = ParseViconCsv(kValid.substr(0, cut), "cut.csv");
    if (csv.ok()) {
      for (const char* subject : {"cam0", "cam2"}) (void)ExtractSubjectPoses(*csv, subject, {});
    } else {
      EXPECT_TRUE(Contains(csv.error().message, "cut.csv")) << cut;
    }
  }
  for (int trial = 0; trial < 2000; ++trial) {
    std::string text = kValid;
    std::uniform_int_distribution<size_t> at(0, text.size() - 1);
    for (int flips = 0; flips < 3; ++flips) text[at(rng)] = bytes[pick(rng)];
    auto csv = ParseViconCsv(text, "flip.csv");
    if (csv.ok()) {
      (void)Summarize(*csv);
      (void)FormatViconCsv(*csv);
      for (const char* subject : {"cam0", "cam2"}) (void)ExtractSubjectPoses(*csv, subject, {});
    } else {
      EXPECT_TRUE(Contains(csv.error().message, "flip.csv"));
    }
  }
}

TEST(ViconCsvBadInput, MissingFile) {
  auto csv = ReadViconCsv("/nonexistent/sequence_01.csv");
  ASSERT_FALSE(csv.ok());
  EXPECT_TRUE(Contains(csv.error().message, "/nonexistent/sequence_01.csv: no such file"));
}

}  // namespace
}  // namespace lifmcr
