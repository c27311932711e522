#include "acquisition/vicon_csv_appender.h"

#include "replay/vicon_csv.h"

#include <climits>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

namespace lifmcr {
namespace {

std::string TrackerName(const std::string& object) { return object + ":" + object; }

// The file text of an Objects block holding `rows` (the writer's own format).
Expected<std::string> FormatObjects(int rate_hz, const std::vector<std::string>& subjects,
                                    const std::vector<std::vector<ViconPoseSample>>& samples,
                                    const ViconPoseOptions& options) {
  std::vector<std::string> names;
  for (const std::string& s : subjects) names.push_back(TrackerName(s));
  Expected<ViconBlock> block = MakeObjectsBlock(rate_hz, names, samples, options);
  if (!block) return block.error();
  ViconCsv csv;
  csv.crlf = true;  // Tracker runs on Windows
  csv.blocks.push_back(std::move(*block));
  return FormatViconCsv(csv);
}

}  // namespace

Expected<ViconCsvAppender> ViconCsvAppender::Create(const std::filesystem::path& path,
                                                    std::vector<std::string> subjects, int rate_hz,
                                                    const ViconPoseOptions& pose_options) {
  ViconCsvAppender appender;
  appender.path_ = path;
  appender.subjects_ = std::move(subjects);
  appender.rate_hz_ = rate_hz;
  appender.pose_options_ = pose_options;
  appender.fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (appender.fd_ < 0)
    return MakeError(path.string(), 0, 0, std::string("cannot create: ") + std::strerror(errno));
  return appender;
}

ViconCsvAppender::ViconCsvAppender(ViconCsvAppender&& other) noexcept { *this = std::move(other); }

ViconCsvAppender& ViconCsvAppender::operator=(ViconCsvAppender&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    path_ = std::move(other.path_);
    fd_ = std::exchange(other.fd_, -1);
    size_bytes_ = other.size_bytes_;
    header_written_ = other.header_written_;
    broken_ = other.broken_;
    last_frame_ = other.last_frame_;
    subjects_ = std::move(other.subjects_);
    rate_hz_ = other.rate_hz_;
    pose_options_ = other.pose_options_;
    stats_ = other.stats_;
  }
  return *this;
}

ViconCsvAppender::~ViconCsvAppender() {
  if (fd_ >= 0) ::close(fd_);
}

Status ViconCsvAppender::WriteText(const std::string& text, int* error_number) {
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd_, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int e = n < 0 ? errno : EIO;
      // Cut a half-written line so the file ends with a complete one.
      if (done > 0 && ::ftruncate(fd_, size_bytes_) != 0) {
        // Nothing more can be done; the reader reports the short row.
      }
      broken_ = true;
      if (error_number != nullptr) *error_number = e;
      return MakeError(path_.string(), 0, 0, std::string("write failed: ") + std::strerror(e));
    }
    done += static_cast<std::size_t>(n);
  }
  size_bytes_ += static_cast<std::int64_t>(text.size());
  return Status::Ok();
}

Status ViconCsvAppender::Append(const ViconFrame& frame, int* error_number) {
  if (error_number != nullptr) *error_number = 0;
  if (broken_ || fd_ < 0) {
    ++stats_.frames_failed;
    return MakeError(path_.string(), 0, 0, "not written: an earlier write failed");
  }
  if (frame.vicon_frame <= last_frame_) {
    ++stats_.out_of_order;
    return Status::Ok();
  }
  if (!header_written_) {
    for (const ViconObjectPose& object : frame.objects) {
      if (std::find(subjects_.begin(), subjects_.end(), object.name) == subjects_.end())
        subjects_.push_back(object.name);
    }
  }
  std::vector<std::vector<ViconPoseSample>> samples(subjects_.size());
  for (std::size_t s = 0; s < subjects_.size(); ++s)
    samples[s].push_back(ViconPoseSample{frame.vicon_frame, std::nullopt});
  for (const ViconObjectPose& object : frame.objects) {
    auto it = std::find(subjects_.begin(), subjects_.end(), object.name);
    if (it == subjects_.end()) {
      ++stats_.unknown_objects;
      continue;
    }
    samples[static_cast<std::size_t>(it - subjects_.begin())][0].vicon_from_marker =
        object.vicon_from_marker;
  }
  Expected<std::string> text = FormatObjects(rate_hz_, subjects_, samples, pose_options_);
  if (!text) {
    ++stats_.frames_failed;
    return MakeError(
        path_.string(), 0, 0,
        "Vicon frame " + std::to_string(frame.vicon_frame) + ": " + text.error().message);
  }
  // The block text is the five header rows and then the one data row.
  std::string out;
  if (!header_written_) {
    out = *text;
  } else {
    std::size_t at = 0;
    for (int line = 0; line < 5 && at != std::string::npos; ++line) {
      at = text->find('\n', at);
      if (at != std::string::npos) ++at;
    }
    if (at == std::string::npos) {
      ++stats_.frames_failed;
      return MakeError(path_.string(), 0, 0, "internal: the Objects block has no data row");
    }
    out = text->substr(at);
  }
  if (Status s = WriteText(out, error_number); !s) {
    ++stats_.frames_failed;
    return s;
  }
  header_written_ = true;
  last_frame_ = frame.vicon_frame;
  ++stats_.frames_written;
  return Status::Ok();
}

Status ViconCsvAppender::Finish() {
  if (header_written_ || broken_ || fd_ < 0) return Status::Ok();
  // The dataset reader refuses a block without rows, so no frame means no file.
  ::close(fd_);
  fd_ = -1;
  if (::unlink(path_.c_str()) != 0)
    return MakeError(path_.string(), 0, 0, std::string("cannot remove: ") + std::strerror(errno));
  return Status::Ok();
}

}  // namespace lifmcr
