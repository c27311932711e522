#pragma once
// Appends live Vicon frames to a sequence's Vicon CSV, one complete line per
// frame, in the Tracker export format the dataset layer reads
// (replay/vicon_csv.h, replay/vicon_poses.h): an Objects block, CRLF line
// ends as Tracker on Windows writes them, one RX,RY,RZ,TX,TY,TZ group per
// subject, empty cells where a subject was not tracked.
//
// Every line goes out with one write() on an O_APPEND descriptor, so a kill
// leaves the file complete up to its last line. A write that fails half-way
// (disk full) is cut back to the last complete line, and the appender refuses
// further frames.
//
// The subjects (columns) are fixed when the header is written, at the first
// frame: the configured subjects, then any other object that first frame
// carries. Objects that appear only later are counted, not written.

#include "config/error.h"
#include "drivers/vicon_source.h"
#include "replay/vicon_poses.h"

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace lifmcr {

struct ViconCsvAppenderStats {
  std::uint64_t frames_written = 0;
  std::uint64_t frames_failed = 0;    // not written: write error or appender stopped
  std::uint64_t unknown_objects = 0;  // object poses not in the header's subjects
  std::uint64_t out_of_order = 0;     // frame numbers not after the last written (not written)
};

class ViconCsvAppender {
 public:
  // `subjects` are object names as the stream sends them ("cam0"); each is
  // written "cam0:cam0" as Tracker names objects. Creates (or truncates) `path`.
  static Expected<ViconCsvAppender> Create(const std::filesystem::path& path,
                                           std::vector<std::string> subjects, int rate_hz,
                                           const ViconPoseOptions& pose_options);
  ViconCsvAppender(ViconCsvAppender&& other) noexcept;
  ViconCsvAppender& operator=(ViconCsvAppender&& other) noexcept;
  ViconCsvAppender(const ViconCsvAppender&) = delete;
  ViconCsvAppender& operator=(const ViconCsvAppender&) = delete;
  ~ViconCsvAppender();

  // Appends one line. An error (naming the file) means the disk refused it;
  // the file stays complete to its previous line and later calls fail too.
  // `error_number` receives errno of a failed write (0 otherwise).
  Status Append(const ViconFrame& frame, int* error_number = nullptr);

  // Ends the file. When no frame came the file is removed: the dataset layer
  // refuses an Objects block without rows, and an absent CSV says the same
  // thing truthfully (the recorder's report counts the Vicon frames).
  Status Finish();

  const ViconCsvAppenderStats& stats() const { return stats_; }
  const std::filesystem::path& path() const { return path_; }
  const std::vector<std::string>& subjects() const { return subjects_; }

 private:
  ViconCsvAppender() = default;
  Status WriteText(const std::string& text, int* error_number);

  std::filesystem::path path_;
  int fd_ = -1;
  std::int64_t size_bytes_ = 0;  // bytes of complete lines in the file
  bool header_written_ = false;
  bool broken_ = false;
  std::int64_t last_frame_ = INT64_MIN;
  std::vector<std::string> subjects_;
  int rate_hz_ = 0;
  ViconPoseOptions pose_options_;
  ViconCsvAppenderStats stats_;
};

}  // namespace lifmcr
