#include "replay/sequence.h"

#include "config/input_file.h"
#include "replay/layout.h"

#include <algorithm>
#include <cctype>
#include <limits>
#include <system_error>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

// `path` made absolute and without a trailing separator, so names of "." or
// "seq/" are the real folder names.
fs::path Absolute(const fs::path& path) {
  std::error_code ec;
  fs::path abs = fs::absolute(path, ec);
  if (ec) abs = path;
  abs = abs.lexically_normal();
  if (abs.filename().empty() && abs.has_parent_path() && abs != abs.root_path()) {
    abs = abs.parent_path();
  }
  return abs;
}

std::string NameOf(const fs::path& path) { return Absolute(path).filename().string(); }

bool IsDir(const fs::path& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

// The entries of a folder, sorted by name; an error when `dir` does not exist,
// is not a folder or cannot be read.
Expected<std::vector<fs::path>> ListDir(const fs::path& dir,
                                        std::string_view expected = "a folder") {
  const std::string where = dir.string();
  std::error_code ec;
  const fs::file_status status = fs::status(dir, ec);
  if (!fs::exists(status)) {
    const std::string missing = DescribeMissingPath(dir);
    return MakeError(where, 0, 0,
                     (missing.empty() ? std::string("no such file or folder") : missing) +
                         ", expected " + std::string(expected));
  }
  if (!fs::is_directory(status)) {
    const std::string type = DescribeNonRegular(dir);
    return MakeError(where, 0, 0,
                     (type.empty() ? std::string("is a file") : type) + ", expected " +
                         std::string(expected));
  }
  std::vector<fs::path> entries;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    entries.push_back(it->path());
  }
  if (ec) return MakeError(where, 0, 0, "cannot list the folder: " + ec.message());
  std::sort(entries.begin(), entries.end(),
            [](const fs::path& a, const fs::path& b) { return a.filename() < b.filename(); });
  return entries;
}

// Names of the entries of `dir`, for cheap classification (empty on error).
std::vector<std::string> ChildNames(const fs::path& dir, bool dirs_only) {
  std::vector<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code type_ec;
    if (dirs_only && !it->is_directory(type_ec)) continue;
    names.push_back(it->path().filename().string());
  }
  return names;
}

bool IsCalibrationName(const std::string& name) {
  return name == layout::kWhiteImagesFolder || name == layout::kMlaCalibrationFolder ||
         name == layout::kViconCalibrationFolder;
}

bool LooksLikeCalibration(const fs::path& dir) {
  if (NameOf(dir) == layout::kCalibrationFolder) return true;
  const std::vector<std::string> children = ChildNames(dir, true);
  return std::any_of(children.begin(), children.end(), IsCalibrationName);
}

bool LooksLikeSequence(const fs::path& dir) {
  for (const std::string& child : ChildNames(dir, true)) {
    if (child == layout::kViconFolder || layout::ParseCameraFolderName(child)) return true;
  }
  return false;
}

bool LooksLikeScene(const fs::path& dir) {
  for (const std::string& child : ChildNames(dir, true)) {
    if (LooksLikeSequence(dir / child)) return true;
  }
  return false;
}

bool LooksLikeDatasetRoot(const fs::path& dir) {
  for (const std::string& child : ChildNames(dir, true)) {
    if (child == layout::kCalibrationFolder || LooksLikeScene(dir / child)) return true;
  }
  return false;
}

std::string EmptyFolderMessage(const std::string& expected) {
  return "empty folder; expected " + expected;
}

// "a, b, c" of the first few names, for messages.
std::string SomeNames(const std::vector<fs::path>& entries) {
  constexpr std::size_t kShown = 5;
  std::string names;
  for (std::size_t i = 0; i < entries.size() && i < kShown; ++i) {
    if (i > 0) names += ", ";
    names += entries[i].filename().string();
  }
  if (entries.size() > kShown) names += ", ...";
  return names;
}

constexpr std::string_view kSequenceContent =
    "a LiFMCR sequence (a Vicon/ folder and TypeE_<serial>/ camera folders)";
constexpr std::string_view kSceneContent =
    "a LiFMCR scene (sequence folders, each holding Vicon/ or TypeE_<serial>/)";
constexpr std::string_view kCalibrationContent =
    "a LiFMCR Calibration folder (01_White_Images/, 02_MLA_Calibration/, 03_Vicon/)";
constexpr std::string_view kDatasetContent =
    "a LiFMCR dataset root (scene folders and Calibration/)";

}  // namespace

std::optional<fs::path> CameraFolder::FramePath(std::int64_t frame) const {
  const auto it = std::lower_bound(frames.begin(), frames.end(), frame);
  if (it == frames.end() || *it != frame) return std::nullopt;
  return dir / frame_files[static_cast<std::size_t>(it - frames.begin())];
}

std::string SequenceLayout::Describe() const {
  std::string text = scene + "/" + name + ": " + std::to_string(cameras.size()) + " camera" +
                     (cameras.size() == 1 ? "" : "s");
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    const CameraFolder& camera = cameras[i];
    text += (i == 0 ? " (" : ", ") + camera.serial + ": " + std::to_string(camera.frames.size()) +
            " frames";
    if (!camera.frames.empty()) {
      text +=
          " " + std::to_string(camera.frames.front()) + ".." + std::to_string(camera.frames.back());
    }
    if (camera.missing_count > 0) text += ", " + std::to_string(camera.missing_count) + " missing";
    if (i + 1 == cameras.size()) text += ")";
  }
  text +=
      ", " + std::to_string(vicon_csvs.size()) + " Vicon CSV" + (vicon_csvs.size() == 1 ? "" : "s");
  if (has_ground_truth) text += ", ground truth";
  if (!unrecognised.empty()) {
    text += ", " + std::to_string(unrecognised.size()) + " unrecognised entries";
  }
  return text;
}

std::string_view ToString(PathKind kind) {
  switch (kind) {
    case PathKind::kDatasetRoot:
      return "dataset root";
    case PathKind::kScene:
      return "scene";
    case PathKind::kSequence:
      return "sequence";
    case PathKind::kCameraFolder:
      return "camera folder";
    case PathKind::kCalibration:
      return "calibration folder";
    case PathKind::kFile:
      return "file";
    case PathKind::kUnknown:
      return "unknown";
  }
  return "unknown";
}

PathKind ClassifyPath(const fs::path& path) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) return PathKind::kUnknown;
  if (!fs::is_directory(status)) return PathKind::kFile;
  if (layout::ParseCameraFolderName(NameOf(path))) return PathKind::kCameraFolder;
  if (LooksLikeCalibration(path)) return PathKind::kCalibration;
  if (LooksLikeSequence(path)) return PathKind::kSequence;
  if (LooksLikeScene(path)) return PathKind::kScene;
  if (LooksLikeDatasetRoot(path)) return PathKind::kDatasetRoot;
  return PathKind::kUnknown;
}

Expected<CameraFolder> DiscoverCameraFolder(const fs::path& dir) {
  Expected<std::vector<fs::path>> entries = ListDir(dir, "a camera folder TypeE_<serial>/");
  if (!entries) return entries.error();
  std::optional<std::string> serial = layout::ParseCameraFolderName(NameOf(dir));
  if (!serial) {
    return MakeError(dir.string(), 0, 0,
                     "not a camera folder: expected a name TypeE_<serial> (letters, digits, '-')");
  }
  CameraFolder camera;
  camera.serial = *serial;
  camera.dir = dir;
  std::vector<std::pair<std::int64_t, std::string>> frames;
  for (const fs::path& entry : *entries) {
    const std::string name = entry.filename().string();
    const std::optional<layout::RawFrameName> parsed = layout::ParseRawFrameFileName(name);
    // By name, as the calibration files: a frame file that is a folder or a
    // FIFO is this camera's frame that cannot be read (its reader says so),
    // not a name "not of a frame".
    if (parsed && parsed->serial == camera.serial) {
      frames.emplace_back(parsed->frame, name);
    } else {
      camera.unrecognised_files.push_back(name);
    }
  }
  std::sort(frames.begin(), frames.end());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (i > 0 && frames[i].first == frames[i - 1].first) {
      return MakeError(dir.string(), 0, 0,
                       "frame " + std::to_string(frames[i].first) + " has two files, " +
                           camera.frame_files.back() + " and " + frames[i].second +
                           "; expected one file per frame");
    }
    if (i > 0) {
      for (std::int64_t gap = frames[i - 1].first + 1; gap < frames[i].first; ++gap) {
        ++camera.missing_count;
        if (camera.missing.size() >= CameraFolder::kMaxListedMissing) {
          camera.missing_count += frames[i].first - gap - 1;
          break;
        }
        camera.missing.push_back(gap);
      }
    }
    camera.frames.push_back(frames[i].first);
    camera.frame_files.push_back(std::move(frames[i].second));
  }
  return camera;
}

Expected<SequenceLayout> DiscoverSequence(const fs::path& dir) {
  Expected<std::vector<fs::path>> entries = ListDir(dir, kSequenceContent);
  if (!entries) return entries.error();
  if (entries->empty()) {
    return MakeError(dir.string(), 0, 0, EmptyFolderMessage(std::string(kSequenceContent)));
  }
  SequenceLayout sequence;
  sequence.dir = dir;
  const fs::path abs = Absolute(dir);
  sequence.name = abs.filename().string();
  sequence.scene = abs.parent_path().filename().string();
  bool has_vicon_folder = false;
  for (const fs::path& entry : *entries) {
    const std::string name = entry.filename().string();
    // Vicon/ by its name first, as Calibration/ in DiscoverDataset: a file
    // of that name is an error, not the sequence's Vicon data left out.
    if (name == layout::kViconFolder) {
      has_vicon_folder = true;
      Expected<std::vector<fs::path>> vicon = ListDir(entry, "the Vicon/ folder of sequence_XX.csv files");
      if (!vicon) return vicon.error();
      for (const fs::path& file : *vicon) {
        // By name, as the calibration files: the CSV reader says what a
        // non-regular sequence_XX.csv is.
        if (layout::ParseViconCsvFileName(file.filename().string())) {
          sequence.vicon_csvs.push_back(file);
        } else {
          sequence.unrecognised.push_back(file);
        }
      }
    } else if (!IsDir(entry)) {
      sequence.unrecognised.push_back(entry);
    } else if (name == layout::kGroundTruthFolder) {
      sequence.has_ground_truth = true;
    } else if (layout::ParseCameraFolderName(name)) {
      Expected<CameraFolder> camera = DiscoverCameraFolder(entry);
      if (!camera) return camera.error();
      sequence.cameras.push_back(std::move(*camera));
    } else {
      sequence.unrecognised.push_back(entry);
    }
  }
  if (!has_vicon_folder && sequence.cameras.empty()) {
    return MakeError(dir.string(), 0, 0,
                     "not " + std::string(kSequenceContent) + "; found " + SomeNames(*entries));
  }
  std::sort(sequence.cameras.begin(), sequence.cameras.end(),
            [](const CameraFolder& a, const CameraFolder& b) { return a.serial < b.serial; });
  return sequence;
}

Expected<SceneLayout> DiscoverScene(const fs::path& dir) {
  Expected<std::vector<fs::path>> entries = ListDir(dir, kSceneContent);
  if (!entries) return entries.error();
  if (entries->empty()) {
    return MakeError(dir.string(), 0, 0, EmptyFolderMessage(std::string(kSceneContent)));
  }
  SceneLayout scene;
  scene.dir = dir;
  scene.name = NameOf(dir);
  for (const fs::path& entry : *entries) {
    if (IsDir(entry) && LooksLikeSequence(entry)) {
      Expected<SequenceLayout> sequence = DiscoverSequence(entry);
      if (!sequence) return sequence.error();
      scene.sequences.push_back(std::move(*sequence));
    } else {
      scene.unrecognised.push_back(entry);
    }
  }
  if (scene.sequences.empty()) {
    return MakeError(dir.string(), 0, 0,
                     "not " + std::string(kSceneContent) + "; found " + SomeNames(*entries));
  }
  return scene;
}

Expected<CalibrationLayout> DiscoverCalibration(const fs::path& dir) {
  Expected<std::vector<fs::path>> entries = ListDir(dir, kCalibrationContent);
  if (!entries) return entries.error();
  if (entries->empty()) {
    return MakeError(dir.string(), 0, 0, EmptyFolderMessage(std::string(kCalibrationContent)));
  }
  CalibrationLayout calibration;
  calibration.dir = dir;
  bool found_any = false;
  std::map<std::string, std::vector<std::pair<std::int64_t, fs::path>>> white_by_index;
  for (const fs::path& entry : *entries) {
    const std::string name = entry.filename().string();
    if (!IsCalibrationName(name)) {
      calibration.unrecognised.push_back(entry);
      continue;
    }
    found_any = true;
    // By name, whatever it is: a file named 02_MLA_Calibration is an error
    // here, not an entry left out of the layout without a word.
    Expected<std::vector<fs::path>> files = ListDir(entry, "a folder of the Calibration layout");
    if (!files) return files.error();
    for (const fs::path& file : *files) {
      const std::string file_name = file.filename().string();
      bool recognised = false;
      // Files are taken by their names too, regular or not: the reader of
      // each (MLA XML, BMP, VSK) says what a folder, FIFO or device named
      // TypeE_<serial>_MLA.xml is instead of a regular file, where leaving
      // it out would report the camera as having no MLA file at all.
      if (name == layout::kWhiteImagesFolder) {
        if (auto white = layout::ParseRawFrameFileName(file_name)) {
          white_by_index[white->serial].emplace_back(white->frame, file);
          recognised = true;
        }
      } else if (name == layout::kMlaCalibrationFolder) {
        if (auto serial = layout::ParseMlaXmlFileName(file_name)) {
          calibration.mla_xml[*serial] = file;
          recognised = true;
        }
      } else if (file.extension() == ".vsk") {
        calibration.vsk.push_back(file);
        recognised = true;
      }
      if (!recognised) calibration.unrecognised.push_back(file);
    }
  }
  if (!found_any) {
    return MakeError(dir.string(), 0, 0,
                     "not " + std::string(kCalibrationContent) + "; found " + SomeNames(*entries));
  }
  for (auto& [serial, images] : white_by_index) {
    std::sort(images.begin(), images.end());
    for (auto& [index, path] : images) calibration.white_images[serial].push_back(std::move(path));
  }
  return calibration;
}

Expected<DatasetLayout> DiscoverDataset(const fs::path& root) {
  Expected<std::vector<fs::path>> entries = ListDir(root, kDatasetContent);
  if (!entries) return entries.error();
  if (entries->empty()) {
    return MakeError(root.string(), 0, 0, EmptyFolderMessage(std::string(kDatasetContent)));
  }
  DatasetLayout dataset;
  dataset.root = root;
  for (const fs::path& entry : *entries) {
    // Calibration/ by its name first: a file of that name is an error (the
    // dataset's MLA files cannot be found), not an entry to list.
    if (entry.filename() == layout::kCalibrationFolder) {
      Expected<CalibrationLayout> calibration = DiscoverCalibration(entry);
      if (!calibration) return calibration.error();
      dataset.calibration = std::move(*calibration);
    } else if (!IsDir(entry)) {
      dataset.unrecognised.push_back(entry);
    } else if (LooksLikeScene(entry)) {
      Expected<SceneLayout> scene = DiscoverScene(entry);
      if (!scene) return scene.error();
      dataset.scenes.push_back(std::move(*scene));
    } else {
      dataset.unrecognised.push_back(entry);
    }
  }
  if (dataset.scenes.empty() && !dataset.calibration) {
    return MakeError(root.string(), 0, 0,
                     "not " + std::string(kDatasetContent) + "; found " + SomeNames(*entries));
  }
  return dataset;
}

std::optional<fs::path> FindCalibrationFor(const fs::path& sequence_dir) {
  const fs::path abs = Absolute(sequence_dir);
  std::optional<fs::path> not_a_folder;
  for (const fs::path& base : {abs.parent_path().parent_path(), abs.parent_path()}) {
    const fs::path candidate = base / layout::kCalibrationFolder;
    if (base.empty()) continue;
    if (IsDir(candidate)) return candidate;
    std::error_code ec;
    if (!not_a_folder && fs::exists(fs::symlink_status(candidate, ec))) not_a_folder = candidate;
  }
  // A Calibration that is a file (or a dangling link): returned so that
  // reading it says what it is, instead of "no Calibration folder".
  return not_a_folder;
}

Status SequenceReaderOptions::Check() const {
  if (trigger_divider < 1) {
    return MakeErrorAt("sequence reader options", "trigger_divider",
                       "got " + std::to_string(trigger_divider) +
                           ", expected >= 1 (Vicon frames per camera trigger)");
  }
  return Status::Ok();
}

int TriggerFrames::CamerasPresent() const {
  return static_cast<int>(std::count_if(files.begin(), files.end(),
                                        [](const auto& file) { return file.second.has_value(); }));
}

Expected<SequenceReader> SequenceReader::Create(const SequenceLayout& sequence,
                                                const SequenceReaderOptions& options) {
  if (Status check = options.Check(); !check.ok()) return check.error();
  SequenceReader reader;
  reader.options_ = options;
  std::vector<std::int64_t> all_frames;
  for (const CameraFolder& folder : sequence.cameras) {
    reader.cameras_.push_back({folder.serial, folder.dir, folder.frames, folder.frame_files, 0});
    all_frames.insert(all_frames.end(), folder.frames.begin(), folder.frames.end());
  }
  if (all_frames.empty()) {
    return MakeError(sequence.dir.string(), 0, 0,
                     "no camera frames to read; expected TypeE_<serial>/ folders holding "
                     "TypeE_<serial>_<frame>_Raw.bmp files");
  }
  std::sort(all_frames.begin(), all_frames.end());
  reader.size_ = static_cast<std::size_t>(std::unique(all_frames.begin(), all_frames.end()) -
                                          all_frames.begin());
  reader.first_frame_ = all_frames.front();
  reader.last_frame_ = all_frames.back();
  // The Vicon frame of the last trigger must fit in an int64_t.
  const std::int64_t span = reader.last_frame_ - reader.first_frame_;
  const std::int64_t start = options.vicon_frame_of_first_trigger;
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  if (start < 0 || span > (kMax - start) / options.trigger_divider) {
    return MakeError(sequence.dir.string(), 0, 0,
                     "frames " + std::to_string(reader.first_frame_) + ".." +
                         std::to_string(reader.last_frame_) +
                         " give Vicon frame numbers out of range; expected a non-negative "
                         "vicon_frame_of_first_trigger and realistic frame numbers");
  }
  return reader;
}

std::int64_t SequenceReader::ViconFrameOf(std::int64_t frame) const {
  return options_.vicon_frame_of_first_trigger + options_.trigger_divider * (frame - first_frame_);
}

std::optional<TriggerFrames> SequenceReader::Next() {
  std::optional<std::int64_t> frame;
  for (const Camera& camera : cameras_) {
    if (camera.cursor < camera.frames.size()) {
      const std::int64_t candidate = camera.frames[camera.cursor];
      if (!frame || candidate < *frame) frame = candidate;
    }
  }
  if (!frame) return std::nullopt;
  TriggerFrames trigger;
  trigger.frame = *frame;
  trigger.vicon_frame = ViconFrameOf(*frame);
  for (Camera& camera : cameras_) {
    std::optional<fs::path> file;
    if (camera.cursor < camera.frames.size() && camera.frames[camera.cursor] == *frame) {
      file = camera.dir / camera.files[camera.cursor];
      ++camera.cursor;
    }
    trigger.files.emplace_back(camera.serial, std::move(file));
  }
  return trigger;
}

void SequenceReader::Rewind() {
  for (Camera& camera : cameras_) camera.cursor = 0;
}

}  // namespace lifmcr
