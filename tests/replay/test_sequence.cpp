#include "replay/layout.h"
#include "replay/sequence.h"
#include "tests/test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <random>
#include <string>
#include <sys/stat.h>
#include <vector>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

constexpr char kCam3[] = "40398673";
constexpr char kCam8[] = "40398678";

void Touch(const fs::path& path) { test::WriteFile(path, "x"); }

std::vector<std::string> Names(const std::vector<fs::path>& paths) {
  std::vector<std::string> names;
  for (const fs::path& path : paths) names.push_back(path.filename().string());
  return names;
}

// A hand-built dataset: two scenes, three sequences, cameras with gaps and
// different padding, stray files at every level, and a calibration folder.
//   ROOT/README.txt                                     stray
//   ROOT/00_Plants/seq_random/Vicon/{sequence_00.csv, notes.txt}
//   ROOT/00_Plants/seq_random/TypeE_40398673/ frames 0 1 2 4 5 (6 digits), Thumbs.db,
//                                              a frame of the other camera
//   ROOT/00_Plants/seq_random/TypeE_40398678/ frames 1..5 (no padding)
//   ROOT/00_Plants/seq_random/GroundTruth/
//   ROOT/00_Plants/seq_handheld/TypeE_40398673/ frame 7 ("_07_")
//   ROOT/01_Bike/seq_xyz/Vicon/sequence_02.csv
//   ROOT/01_Bike/stray_folder/
//   ROOT/Calibration/01_White_Images/ 2 images of 73, 1 of 78
//   ROOT/Calibration/02_MLA_Calibration/ 2 XML files and readme.md
//   ROOT/Calibration/03_Vicon/Object.vsk
struct Fixture {
  test::TempDir temp;
  fs::path root = temp / "LiFMCR";
  fs::path plants = root / "00_Plants";
  fs::path random = plants / "seq_random";
  fs::path handheld = plants / "seq_handheld";
  fs::path bike = root / "01_Bike";
  fs::path xyz = bike / "seq_xyz";
  fs::path calibration = root / "Calibration";

  Fixture() {
    Touch(root / "README.txt");
    Touch(layout::ViconCsvPath(random, 0));
    Touch(random / "Vicon" / "notes.txt");
    for (int frame : {0, 1, 2, 4, 5}) Touch(layout::RawFramePath(random, kCam3, frame));
    Touch(layout::CameraDir(random, kCam3) / "Thumbs.db");
    Touch(layout::CameraDir(random, kCam3) / layout::RawFrameFileName(kCam8, 3));
    for (int frame = 1; frame <= 5; ++frame) {
      Touch(layout::CameraDir(random, kCam8) /
            ("TypeE_40398678_" + std::to_string(frame) + "_Raw.bmp"));
    }
    fs::create_directories(layout::GroundTruthDir(random));
    Touch(layout::CameraDir(handheld, kCam3) / "TypeE_40398673_07_Raw.bmp");
    Touch(layout::ViconCsvPath(xyz, 2));
    fs::create_directories(bike / "stray_folder");
    Touch(layout::WhiteImagePath(calibration, kCam3, 1));
    Touch(layout::WhiteImagePath(calibration, kCam3, 0));
    Touch(layout::WhiteImagePath(calibration, kCam8, 0));
    Touch(layout::MlaXmlPath(calibration, kCam3));
    Touch(layout::MlaXmlPath(calibration, kCam8));
    Touch(calibration / "02_MLA_Calibration" / "readme.md");
    Touch(layout::VskPath(calibration));
  }
};

TEST(Layout, NamesFollowThePaper) {
  EXPECT_EQ(layout::CameraFolderName(kCam3), "TypeE_40398673");
  EXPECT_EQ(layout::RawFrameFileName(kCam3, 7), "TypeE_40398673_000007_Raw.bmp");
  EXPECT_EQ(layout::RawFrameFileName(kCam3, 12345678), "TypeE_40398673_12345678_Raw.bmp");
  EXPECT_EQ(layout::WhiteImageFileName(kCam8, 3), "TypeE_40398678_03_Raw.bmp");
  EXPECT_EQ(layout::ViconCsvFileName(4), "sequence_04.csv");
  EXPECT_EQ(layout::MlaXmlFileName(kCam8), "TypeE_40398678_MLA.xml");
  EXPECT_EQ(layout::PosesCsvFileName(kCam3), "poses_40398673.csv");
  EXPECT_EQ(layout::MarkerFromCamCsvFileName(kCam3), "marker_from_cam_40398673.csv");
  EXPECT_EQ(layout::VirtualDepthFileName(kCam3, 12), "40398673_000012_virtual_depth.tiff");
  EXPECT_EQ(layout::DepthMmFileName(kCam3, 12), "40398673_000012_depth_mm.tiff");

  const fs::path seq = "/d/00_Plants/seq";
  EXPECT_EQ(layout::RawFramePath(seq, kCam3, 2),
            "/d/00_Plants/seq/TypeE_40398673/TypeE_40398673_000002_Raw.bmp");
  EXPECT_EQ(layout::ViconCsvPath(seq, 1), "/d/00_Plants/seq/Vicon/sequence_01.csv");
  EXPECT_EQ(layout::CamerasYamlPath(seq), "/d/00_Plants/seq/GroundTruth/cameras.yaml");
  EXPECT_EQ(layout::PosesCsvPath(seq, kCam8), "/d/00_Plants/seq/GroundTruth/poses_40398678.csv");
  EXPECT_EQ(layout::MarkerFromCamCsvPath(seq, kCam8),
            "/d/00_Plants/seq/GroundTruth/marker_from_cam_40398678.csv");
  EXPECT_EQ(layout::VirtualDepthPath(seq, kCam8, 3),
            "/d/00_Plants/seq/GroundTruth/depth/40398678_000003_virtual_depth.tiff");
  EXPECT_EQ(layout::DepthMmPath(seq, kCam8, 3),
            "/d/00_Plants/seq/GroundTruth/depth/40398678_000003_depth_mm.tiff");
  const fs::path cal = "/d/Calibration";
  EXPECT_EQ(layout::WhiteImagePath(cal, kCam3, 0),
            "/d/Calibration/01_White_Images/TypeE_40398673_00_Raw.bmp");
  EXPECT_EQ(layout::MlaXmlPath(cal, kCam3),
            "/d/Calibration/02_MLA_Calibration/TypeE_40398673_MLA.xml");
  EXPECT_EQ(layout::VskPath(cal), "/d/Calibration/03_Vicon/Object.vsk");
}

TEST(Layout, RawFrameNamesRoundTripOverRandomSerialsAndFrames) {
  std::mt19937 rng(7);
  const std::string alphabet = "0123456789ABCDEFXYZabc-";
  std::uniform_int_distribution<std::size_t> letter(0, alphabet.size() - 1);
  std::uniform_int_distribution<int> length(1, 12);
  std::uniform_int_distribution<std::int64_t> frame(0, 999999999999);
  for (int i = 0; i < 500; ++i) {
    std::string serial;
    for (int n = length(rng); n > 0; --n) serial += alphabet[letter(rng)];
    const std::int64_t number = i < 50 ? i : frame(rng);
    const auto parsed = layout::ParseRawFrameFileName(layout::RawFrameFileName(serial, number));
    ASSERT_TRUE(parsed.has_value()) << serial << " " << number;
    EXPECT_EQ(parsed->serial, serial);
    EXPECT_EQ(parsed->frame, number);
    EXPECT_EQ(layout::ParseCameraFolderName(layout::CameraFolderName(serial)), serial);
    EXPECT_EQ(layout::ParseMlaXmlFileName(layout::MlaXmlFileName(serial)), serial);
  }
}

TEST(Layout, ParsingAcceptsAnyDigitCountAndRejectsOtherNames) {
  for (const char* name : {"TypeE_40398673_7_Raw.bmp", "TypeE_40398673_07_Raw.bmp",
                           "TypeE_40398673_000007_Raw.bmp", "TypeE_40398673_7_Raw.BMP"}) {
    const auto parsed = layout::ParseRawFrameFileName(name);
    ASSERT_TRUE(parsed.has_value()) << name;
    EXPECT_EQ(parsed->serial, kCam3);
    EXPECT_EQ(parsed->frame, 7);
  }
  for (const char* name :
       {"TypeE_40398673_Raw.bmp", "TypeE__7_Raw.bmp", "TypeE_40398673_x7_Raw.bmp",
        "TypeE_40398673_7_Raw.png", "TypeE_40398673_7_raw.bmp", "TypeE_40398673_-7_Raw.bmp",
        "TypeF_40398673_7_Raw.bmp", "TypeE_40398673_7.bmp", "TypeE_403_98673_7_Raw.bmp",
        "TypeE_40398673_1234567890123456789_Raw.bmp", "TypeE_40398673__Raw.bmp", ""}) {
    EXPECT_FALSE(layout::ParseRawFrameFileName(name).has_value()) << name;
  }
  EXPECT_EQ(layout::ParseViconCsvFileName("sequence_07.csv"), 7);
  EXPECT_FALSE(layout::ParseViconCsvFileName("sequence_7.csv").has_value());
  EXPECT_FALSE(layout::ParseViconCsvFileName("sequence_007.csv").has_value());
  EXPECT_FALSE(layout::ParseViconCsvFileName("sequence_ab.csv").has_value());
  EXPECT_FALSE(layout::ParseCameraFolderName("TypeE_").has_value());
  EXPECT_FALSE(layout::ParseCameraFolderName("Vicon").has_value());
  EXPECT_FALSE(layout::ParseMlaXmlFileName("TypeE__MLA.xml").has_value());
}

TEST(Sequence, ClassifiesEveryLevel) {
  Fixture f;
  EXPECT_EQ(ClassifyPath(f.root), PathKind::kDatasetRoot);
  EXPECT_EQ(ClassifyPath(f.plants), PathKind::kScene);
  EXPECT_EQ(ClassifyPath(f.bike), PathKind::kScene);
  EXPECT_EQ(ClassifyPath(f.random), PathKind::kSequence);
  EXPECT_EQ(ClassifyPath(f.xyz), PathKind::kSequence);
  EXPECT_EQ(ClassifyPath(layout::CameraDir(f.random, kCam3)), PathKind::kCameraFolder);
  EXPECT_EQ(ClassifyPath(f.calibration), PathKind::kCalibration);
  EXPECT_EQ(ClassifyPath(f.root / "README.txt"), PathKind::kFile);
  EXPECT_EQ(ClassifyPath(f.bike / "stray_folder"), PathKind::kUnknown);
  EXPECT_EQ(ClassifyPath(f.root / "missing"), PathKind::kUnknown);
  EXPECT_EQ(ClassifyPath(f.random.string() + "/"), PathKind::kSequence);
  EXPECT_EQ(ToString(PathKind::kCalibration), "calibration folder");
}

TEST(Sequence, DiscoversTheWholeDataset) {
  Fixture f;
  Expected<DatasetLayout> dataset = DiscoverDataset(f.root);
  ASSERT_TRUE(dataset.ok()) << dataset.error().message;
  EXPECT_EQ(Names(dataset->unrecognised), std::vector<std::string>{"README.txt"});
  ASSERT_EQ(dataset->scenes.size(), 2u);
  const SceneLayout& plants = dataset->scenes[0];
  const SceneLayout& bike = dataset->scenes[1];
  EXPECT_EQ(plants.name, "00_Plants");
  EXPECT_EQ(bike.name, "01_Bike");
  EXPECT_EQ(Names(bike.unrecognised), std::vector<std::string>{"stray_folder"});
  ASSERT_EQ(plants.sequences.size(), 2u);
  EXPECT_EQ(plants.sequences[0].name, "seq_handheld");
  EXPECT_EQ(plants.sequences[1].name, "seq_random");

  const SequenceLayout& random = plants.sequences[1];
  EXPECT_EQ(random.scene, "00_Plants");
  EXPECT_TRUE(random.has_ground_truth);
  EXPECT_EQ(Names(random.vicon_csvs), std::vector<std::string>{"sequence_00.csv"});
  EXPECT_EQ(Names(random.unrecognised), std::vector<std::string>{"notes.txt"});
  ASSERT_EQ(random.cameras.size(), 2u);
  const CameraFolder& cam3 = random.cameras[0];
  const CameraFolder& cam8 = random.cameras[1];
  EXPECT_EQ(cam3.serial, kCam3);
  EXPECT_EQ(cam3.frames, (std::vector<std::int64_t>{0, 1, 2, 4, 5}));
  EXPECT_EQ(cam3.missing, std::vector<std::int64_t>{3});
  EXPECT_EQ(cam3.missing_count, 1);
  EXPECT_EQ(cam3.unrecognised_files,
            (std::vector<std::string>{"Thumbs.db", "TypeE_40398678_000003_Raw.bmp"}));
  EXPECT_EQ(cam8.serial, kCam8);
  EXPECT_EQ(cam8.frames, (std::vector<std::int64_t>{1, 2, 3, 4, 5}));
  EXPECT_TRUE(cam8.missing.empty());
  EXPECT_EQ(cam8.FramePath(3), layout::CameraDir(f.random, kCam8) / "TypeE_40398678_3_Raw.bmp");
  EXPECT_FALSE(cam8.FramePath(0).has_value());
  EXPECT_EQ(random.Describe(),
            "00_Plants/seq_random: 2 cameras (40398673: 5 frames 0..5, 1 missing, 40398678: 5 "
            "frames 1..5), 1 Vicon CSV, ground truth, 1 unrecognised entries");

  EXPECT_EQ(plants.sequences[0].cameras.at(0).frames, std::vector<std::int64_t>{7});
  EXPECT_EQ(bike.sequences.at(0).cameras.size(), 0u);
  EXPECT_EQ(Names(bike.sequences.at(0).vicon_csvs), std::vector<std::string>{"sequence_02.csv"});

  ASSERT_TRUE(dataset->calibration.has_value());
  const CalibrationLayout& cal = *dataset->calibration;
  ASSERT_EQ(cal.white_images.size(), 2u);
  EXPECT_EQ(Names(cal.white_images.at(kCam3)),
            (std::vector<std::string>{"TypeE_40398673_00_Raw.bmp", "TypeE_40398673_01_Raw.bmp"}));
  EXPECT_EQ(cal.white_images.at(kCam8).size(), 1u);
  EXPECT_EQ(cal.mla_xml.at(kCam8), layout::MlaXmlPath(f.calibration, kCam8));
  EXPECT_EQ(cal.mla_xml.size(), 2u);
  EXPECT_EQ(Names(cal.vsk), std::vector<std::string>{"Object.vsk"});
  EXPECT_EQ(Names(cal.unrecognised), std::vector<std::string>{"readme.md"});
}

TEST(Sequence, NamesComeFromTheRealFolderWithATrailingSlash) {
  Fixture f;
  Expected<SequenceLayout> sequence = DiscoverSequence(f.random.string() + "/");
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  EXPECT_EQ(sequence->name, "seq_random");
  EXPECT_EQ(sequence->scene, "00_Plants");
}

TEST(Sequence, FindsTheCalibrationBesideTheScenes) {
  Fixture f;
  EXPECT_EQ(FindCalibrationFor(f.random), f.calibration);
  EXPECT_EQ(FindCalibrationFor(f.xyz.string() + "/"), f.calibration);
  test::TempDir lonely;
  fs::create_directories(lonely / "scene" / "seq" / "Vicon");
  EXPECT_FALSE(FindCalibrationFor(lonely / "scene" / "seq").has_value());
  // A sequence copied on its own with its calibration beside it.
  fs::create_directories(lonely / "scene" / "Calibration" / "03_Vicon");
  EXPECT_EQ(FindCalibrationFor(lonely / "scene" / "seq"), lonely / "scene" / "Calibration");
}

// Calibration files and Vicon CSVs are taken by their names: an MLA file
// that is a folder, a FIFO or a link to a device stays the camera's MLA
// file, for its reader to say what it is (lifmcr info reports it), instead
// of vanishing into `unrecognised` and the camera reading as having none.
TEST(Sequence, CalibrationFilesAreTakenByNameWhateverTheyAre) {
  Fixture f;
  const fs::path mla3 = layout::MlaXmlPath(f.calibration, kCam3);
  const fs::path mla8 = layout::MlaXmlPath(f.calibration, kCam8);
  fs::remove(mla3);
  fs::create_directories(mla3);
  fs::remove(mla8);
  fs::create_symlink("/dev/zero", mla8);
  fs::remove(layout::VskPath(f.calibration));
  ASSERT_EQ(mkfifo(layout::VskPath(f.calibration).c_str(), 0600), 0);
  fs::remove(layout::ViconCsvPath(f.random, 0));
  fs::create_directories(layout::ViconCsvPath(f.random, 0));
  Expected<CalibrationLayout> cal = DiscoverCalibration(f.calibration);
  ASSERT_TRUE(cal.ok()) << cal.error().message;
  EXPECT_EQ(cal->mla_xml.at(kCam3), mla3);
  EXPECT_EQ(cal->mla_xml.at(kCam8), mla8);
  EXPECT_EQ(Names(cal->vsk), std::vector<std::string>{"Object.vsk"});
  EXPECT_EQ(Names(cal->unrecognised), std::vector<std::string>{"readme.md"});
  // A frame that is a folder is still the camera's frame 4.
  const fs::path frame4 = layout::RawFramePath(f.random, kCam3, 4);
  fs::remove(frame4);
  fs::create_directories(frame4);
  Expected<SequenceLayout> sequence = DiscoverSequence(f.random);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  EXPECT_EQ(Names(sequence->vicon_csvs), std::vector<std::string>{"sequence_00.csv"});
  EXPECT_EQ(sequence->cameras.at(0).frames, (std::vector<std::int64_t>{0, 1, 2, 4, 5}));
  EXPECT_EQ(sequence->cameras.at(0).FramePath(4), frame4);
}

// A Calibration that is not a folder: the dataset's MLA files cannot be
// found, which is an error naming it, not an entry listed as unrecognised.
TEST(Sequence, ACalibrationThatIsAFileIsAnError) {
  Fixture f;
  fs::remove_all(f.calibration);
  Touch(f.calibration);
  const Expected<DatasetLayout> dataset = DiscoverDataset(f.root);
  ASSERT_FALSE(dataset.ok());
  test::ExpectMessageHas(dataset.error(),
                         {f.calibration.string(), "is a file, expected a LiFMCR Calibration folder"});
  // A sequence's lookup returns it, so that reading it says the same.
  EXPECT_EQ(FindCalibrationFor(f.random), f.calibration);
  test::ExpectMessageHas(DiscoverCalibration(f.calibration).error(), {"is a file"});
  // A folder beside the sequence still wins over a file beside the scenes.
  fs::create_directories(f.plants / "Calibration" / "02_MLA_Calibration");
  EXPECT_EQ(FindCalibrationFor(f.random), f.plants / "Calibration");
  // 02_MLA_Calibration as a file is an error too.
  fs::remove_all(f.plants / "Calibration" / "02_MLA_Calibration");
  Touch(f.plants / "Calibration" / "02_MLA_Calibration");
  test::ExpectMessageHas(DiscoverCalibration(f.plants / "Calibration").error(),
                         {"02_MLA_Calibration", "is a file, expected a folder of the Calibration layout"});
  // And a sequence's Vicon that is a file.
  fs::remove_all(f.random / "Vicon");
  Touch(f.random / "Vicon");
  test::ExpectMessageHas(DiscoverSequence(f.random).error(),
                         {"Vicon", "is a file, expected the Vicon/ folder"});
}

TEST(Sequence, ReaderYieldsTriggersInOrderWithViconFrames) {
  Fixture f;
  Expected<SequenceLayout> sequence = DiscoverSequence(f.random);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  Expected<SequenceReader> reader = SequenceReader::Create(*sequence);
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_EQ(reader->size(), 6u);  // the union of {0,1,2,4,5} and {1,...,5}
  EXPECT_EQ(reader->first_frame(), 0);
  EXPECT_EQ(reader->last_frame(), 5);

  std::vector<std::int64_t> frames;
  for (std::optional<TriggerFrames> trigger = reader->Next(); trigger; trigger = reader->Next()) {
    frames.push_back(trigger->frame);
    EXPECT_EQ(trigger->vicon_frame, 1 + 8 * trigger->frame);
    ASSERT_EQ(trigger->files.size(), 2u);
    EXPECT_EQ(trigger->files[0].first, kCam3);
    EXPECT_EQ(trigger->files[1].first, kCam8);
    EXPECT_EQ(trigger->files[0].second.has_value(), trigger->frame != 3);
    EXPECT_EQ(trigger->files[1].second.has_value(), trigger->frame != 0);
    EXPECT_EQ(trigger->CamerasPresent(), trigger->frame == 0 || trigger->frame == 3 ? 1 : 2);
    if (trigger->files[0].second) {
      EXPECT_EQ(*trigger->files[0].second, layout::RawFramePath(f.random, kCam3, trigger->frame));
    }
    if (trigger->files[1].second) {
      EXPECT_TRUE(fs::exists(*trigger->files[1].second));
    }
  }
  EXPECT_EQ(frames, (std::vector<std::int64_t>{0, 1, 2, 3, 4, 5}));
  EXPECT_FALSE(reader->Next().has_value());
  reader->Rewind();
  ASSERT_TRUE(reader->Next().has_value());
}

TEST(Sequence, ReaderSkipsTriggersNoCameraKeptAndAppliesOptions) {
  test::TempDir temp;
  const fs::path seq = temp / "scene" / "seq";
  for (int frame : {10, 11, 14}) Touch(layout::RawFramePath(seq, "A", frame));
  for (int frame : {11, 15}) Touch(layout::RawFramePath(seq, "B", frame));
  Expected<SequenceLayout> sequence = DiscoverSequence(seq);
  ASSERT_TRUE(sequence.ok()) << sequence.error().message;
  SequenceReaderOptions options;
  options.trigger_divider = 4;
  options.vicon_frame_of_first_trigger = 100;
  Expected<SequenceReader> reader = SequenceReader::Create(*sequence, options);
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  EXPECT_EQ(reader->size(), 4u);
  std::vector<std::pair<std::int64_t, std::int64_t>> seen;
  while (auto trigger = reader->Next()) seen.emplace_back(trigger->frame, trigger->vicon_frame);
  EXPECT_EQ(seen, (std::vector<std::pair<std::int64_t, std::int64_t>>{
                      {10, 100}, {11, 104}, {14, 116}, {15, 120}}));
  EXPECT_EQ(sequence->cameras[0].missing, (std::vector<std::int64_t>{12, 13}));
}

TEST(Sequence, ReaderRejectsBadOptionsAndSequencesWithoutFrames) {
  Fixture f;
  Expected<SequenceLayout> random = DiscoverSequence(f.random);
  ASSERT_TRUE(random.ok());
  SequenceReaderOptions options;
  options.trigger_divider = 0;
  Expected<SequenceReader> bad = SequenceReader::Create(*random, options);
  ASSERT_FALSE(bad.ok());
  test::ExpectMessageHas(bad.error(), {"trigger_divider", "got 0, expected >= 1"});

  Expected<SequenceLayout> vicon_only = DiscoverSequence(f.xyz);
  ASSERT_TRUE(vicon_only.ok());
  Expected<SequenceReader> empty = SequenceReader::Create(*vicon_only);
  ASSERT_FALSE(empty.ok());
  test::ExpectMessageHas(empty.error(), {f.xyz.string(), "no camera frames"});
}

TEST(Sequence, TwoFilesForOneFrameAreAnError) {
  test::TempDir temp;
  const fs::path seq = temp / "seq";
  Touch(layout::CameraDir(seq, kCam3) / "TypeE_40398673_7_Raw.bmp");
  Touch(layout::CameraDir(seq, kCam3) / "TypeE_40398673_007_Raw.bmp");
  Expected<SequenceLayout> sequence = DiscoverSequence(seq);
  ASSERT_FALSE(sequence.ok());
  test::ExpectMessageHas(sequence.error(),
                         {layout::CameraDir(seq, kCam3).string(), "frame 7 has two files",
                          "TypeE_40398673_007_Raw.bmp", "TypeE_40398673_7_Raw.bmp"});
}

TEST(Sequence, LongGapsAreCountedButListedOnlyUpToTheCap) {
  test::TempDir temp;
  const fs::path camera = temp / "TypeE_1";
  Touch(camera / "TypeE_1_0_Raw.bmp");
  Touch(camera / "TypeE_1_250000_Raw.bmp");
  Touch(camera / "TypeE_1_250002_Raw.bmp");
  Expected<CameraFolder> folder = DiscoverCameraFolder(camera);
  ASSERT_TRUE(folder.ok()) << folder.error().message;
  EXPECT_EQ(folder->missing_count, 249999 + 1);
  EXPECT_EQ(folder->missing.size(), CameraFolder::kMaxListedMissing);
  EXPECT_EQ(folder->missing.front(), 1);
}

TEST(Sequence, MissingEmptyAndWrongFoldersAreClearErrors) {
  Fixture f;
  const fs::path missing = f.root / "99_Nothing";
  for (const Error& error :
       {DiscoverDataset(missing).error(), DiscoverScene(missing).error(),
        DiscoverSequence(missing).error(), DiscoverCalibration(missing).error(),
        DiscoverCameraFolder(missing).error()}) {
    test::ExpectMessageHas(error, {missing.string(), "no such file or folder"});
  }
  const fs::path empty = f.temp / "empty";
  fs::create_directories(empty);
  test::ExpectMessageHas(DiscoverDataset(empty).error(),
                         {empty.string(), "empty folder; expected a LiFMCR dataset root"});
  test::ExpectMessageHas(DiscoverScene(empty).error(), {"empty folder; expected a LiFMCR scene"});
  test::ExpectMessageHas(DiscoverSequence(empty).error(),
                         {"empty folder; expected a LiFMCR sequence"});
  test::ExpectMessageHas(DiscoverCalibration(empty).error(),
                         {"empty folder; expected a LiFMCR Calibration folder"});

  test::ExpectMessageHas(DiscoverSequence(f.root / "README.txt").error(),
                         {"README.txt", "is a file, expected a LiFMCR sequence"});
  test::ExpectMessageHas(
      DiscoverSequence(f.plants).error(),
      {f.plants.string(), "not a LiFMCR sequence", "found seq_handheld, seq_random"});
  test::ExpectMessageHas(DiscoverScene(f.random).error(),
                         {"not a LiFMCR scene", "found GroundTruth"});
  test::ExpectMessageHas(DiscoverDataset(f.random).error(), {"not a LiFMCR dataset root"});
  test::ExpectMessageHas(DiscoverCalibration(f.plants).error(),
                         {"not a LiFMCR Calibration folder"});
  test::ExpectMessageHas(DiscoverCameraFolder(f.random / "Vicon").error(),
                         {"not a camera folder", "TypeE_<serial>"});
}

}  // namespace
}  // namespace lifmcr
