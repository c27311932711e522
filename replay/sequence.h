#pragma once
// Discovery of LiFMCR datasets, scenes, sequences and calibration folders
// (names from replay/layout.h), and a reader that walks a sequence trigger by
// trigger. Discovery only lists names; it opens no file.
//
// What a folder is (ClassifyPath), checked in this order:
//   camera folder  its name is TypeE_<serial>
//   calibration    its name is Calibration, or it holds 01_White_Images/,
//                  02_MLA_Calibration/ or 03_Vicon/
//   sequence       it holds Vicon/ or a TypeE_<serial>/ folder
//   scene          it holds a sequence folder
//   dataset root   it holds Calibration/ or a scene folder
// Entries whose names follow no rule are listed in `unrecognised` at every
// level, never dropped silently. Lists are sorted (by name, frames by number).
// Frames, calibration files (MLA XML, white images, VSK) and Vicon CSVs are
// taken by their names whatever they are: the reader of each says what a folder, FIFO
// or device of such a name is. A Calibration, 01_White_Images,
// 02_MLA_Calibration, 03_Vicon or a sequence's Vicon that is not a folder is
// an error.

#include "config/error.h"

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace lifmcr {

struct CameraFolder {
  std::string serial;
  std::filesystem::path dir;
  std::vector<std::int64_t> frames;      // sorted, unique
  std::vector<std::string> frame_files;  // file name of frames[i] in dir
  // Frame numbers between the first and the last frame without a file, in
  // order; at most kMaxListedMissing of them, missing_count has the total.
  std::vector<std::int64_t> missing;
  std::int64_t missing_count = 0;
  std::vector<std::string> unrecognised_files;  // names in dir that are not frames of this camera

  static constexpr std::size_t kMaxListedMissing = 100000;

  // Path of `frame`'s file, or nullopt when this camera has no such frame.
  std::optional<std::filesystem::path> FramePath(std::int64_t frame) const;
};

struct SequenceLayout {
  std::filesystem::path dir;
  std::string scene;                                // name of the parent folder
  std::string name;                                 // name of dir
  std::vector<CameraFolder> cameras;                // sorted by serial
  std::vector<std::filesystem::path> vicon_csvs;    // Vicon/sequence_XX.csv, sorted
  bool has_ground_truth = false;                    // GroundTruth/ exists
  std::vector<std::filesystem::path> unrecognised;  // in dir and in Vicon/

  // One line: "00_Plants/seq: 2 cameras (40398673: 323 frames 0..322, ...), 1 Vicon CSV".
  std::string Describe() const;
};

struct SceneLayout {
  std::filesystem::path dir;
  std::string name;
  std::vector<SequenceLayout> sequences;  // sorted by name
  std::vector<std::filesystem::path> unrecognised;
};

struct CalibrationLayout {
  std::filesystem::path dir;
  std::map<std::string, std::vector<std::filesystem::path>> white_images;  // serial -> by index
  std::map<std::string, std::filesystem::path> mla_xml;                    // serial -> XML
  std::vector<std::filesystem::path> vsk;                                  // *.vsk in 03_Vicon
  std::vector<std::filesystem::path> unrecognised;
};

struct DatasetLayout {
  std::filesystem::path root;
  std::vector<SceneLayout> scenes;  // sorted by name
  std::optional<CalibrationLayout> calibration;
  std::vector<std::filesystem::path> unrecognised;
};

enum class PathKind {
  kDatasetRoot,
  kScene,
  kSequence,
  kCameraFolder,
  kCalibration,
  kFile,
  kUnknown,  // also a path that does not exist
};

std::string_view ToString(PathKind kind);  // "dataset root", "scene", ...

// What `path` is, by the rules at the top of this file.
PathKind ClassifyPath(const std::filesystem::path& path);

// Each fails with a message naming the path when it does not exist, is not a
// folder, is empty, or holds nothing of the expected kind. A sequence also
// fails when two files of one camera name the same frame ("_7_" and "_007_").
Expected<CameraFolder> DiscoverCameraFolder(const std::filesystem::path& dir);
Expected<SequenceLayout> DiscoverSequence(const std::filesystem::path& dir);
Expected<SceneLayout> DiscoverScene(const std::filesystem::path& dir);
Expected<CalibrationLayout> DiscoverCalibration(const std::filesystem::path& dir);
Expected<DatasetLayout> DiscoverDataset(const std::filesystem::path& root);

// The Calibration/ folder for a sequence: beside the scenes
// (SEQ/../../Calibration), else beside the sequence (SEQ/../Calibration);
// when neither is a folder, the first of them that exists as something else
// (a file, a dangling link), so that reading it reports what it is.
std::optional<std::filesystem::path> FindCalibrationFor(const std::filesystem::path& sequence_dir);

struct SequenceReaderOptions {
  // Vicon frames per camera trigger: LiFMCR's Vicon runs at 80 Hz and the
  // cameras are triggered at 10 Hz from it.
  int trigger_divider = 8;
  // Vicon frame number of the first frame of the sequence (CSV frames are 1-based).
  std::int64_t vicon_frame_of_first_trigger = 1;

  Status Check() const;
};

// The files of one trigger.
struct TriggerFrames {
  std::int64_t frame = 0;        // the frame number in the file names
  std::int64_t vicon_frame = 0;  // the Vicon frame it was triggered at
  // One entry per camera, in the layout's camera order; nullopt where that
  // camera has no file for this frame (a dropped frame), explicitly.
  std::vector<std::pair<std::string, std::optional<std::filesystem::path>>> files;

  int CamerasPresent() const;
};

// Walks a sequence in trigger order. The triggers are the frame numbers for
// which at least one camera has a file; a trigger that no camera kept does not
// appear, its absence shows as a jump in `frame` and `vicon_frame`.
//
//   vicon_frame = vicon_frame_of_first_trigger
//                 + trigger_divider * (frame - first_frame)
//
// where first_frame is the smallest frame number over all cameras. This
// assumes the cameras fire on every trigger_divider-th Vicon frame from the
// first one on, as LiFMCR's hardware triggering does.
class SequenceReader {
 public:
  // Fails on invalid options or a sequence without any camera frame.
  static Expected<SequenceReader> Create(const SequenceLayout& sequence,
                                         const SequenceReaderOptions& options = {});

  // Number of triggers Next() yields in all.
  std::size_t size() const { return size_; }
  std::int64_t first_frame() const { return first_frame_; }
  std::int64_t last_frame() const { return last_frame_; }
  // Vicon frame of `frame` by the rule above.
  std::int64_t ViconFrameOf(std::int64_t frame) const;

  // The next trigger, or nullopt after the last.
  std::optional<TriggerFrames> Next();
  // Back to the first trigger.
  void Rewind();

 private:
  SequenceReader() = default;

  struct Camera {
    std::string serial;
    std::filesystem::path dir;
    std::vector<std::int64_t> frames;
    std::vector<std::string> files;
    std::size_t cursor = 0;
  };
  std::vector<Camera> cameras_;
  SequenceReaderOptions options_;
  std::size_t size_ = 0;
  std::int64_t first_frame_ = 0;
  std::int64_t last_frame_ = 0;
};

}  // namespace lifmcr
