#include "acquisition/recorder.h"

#include "acquisition/raw_frame_writer.h"
#include "drivers/vicon_udp_source.h"
#include "replay/layout.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <sstream>
#include <system_error>

namespace lifmcr {
namespace {

namespace fs = std::filesystem;

Status MakeDirs(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return MakeError(dir.string(), 0, 0, "cannot create folder: " + ec.message());
  return Status::Ok();
}

Status CopyInto(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::copy_file(from, to, fs::copy_options::overwrite_existing, ec);
  if (ec) return MakeError(to.string(), 0, 0, "cannot copy " + from.string() + ": " + ec.message());
  return Status::Ok();
}

bool IsDiskFull(int error_number) { return error_number == ENOSPC || error_number == EFBIG; }

}  // namespace

RecorderOptions RecorderOptions::FromRig(const RecorderConfig& config) {
  RecorderOptions options;
  options.queue_frames = config.queue_frames;
  options.writer_threads = config.writer_threads;
  options.direct_io = config.direct_io;
  options.direct_io_min_bytes = std::int64_t{config.direct_io_min_kb} * 1024;
  options.max_memory_bytes = config.max_memory_mb * 1024 * 1024;
  return options;
}

Status RecorderOptions::Check() const {
  if (root_dir.empty()) return Error{"recorder: no output folder given"};
  if (scene.empty() || scene.find('/') != std::string::npos)
    return Error{"recorder: scene name '" + scene + "' must be a non-empty folder name"};
  if (sequence.empty() || sequence.find('/') != std::string::npos)
    return Error{"recorder: sequence name '" + sequence + "' must be a non-empty folder name"};
  if (vicon_csv_number < 0 || vicon_csv_number > 99)
    return Error{"recorder: Vicon CSV number must be 0..99, got " +
                 std::to_string(vicon_csv_number)};
  if (queue_frames < 1)
    return Error{"recorder: queue_frames must be >= 1, got " + std::to_string(queue_frames)};
  if (writer_threads < 1 || writer_threads > 64)
    return Error{"recorder: writer_threads must be 1..64, got " + std::to_string(writer_threads)};
  if (max_memory_bytes < 0) return Error{"recorder: max_memory must be >= 0"};
  if (direct_io_min_bytes < 0)
    return Error{"recorder: direct_io_min_bytes must be >= 0, got " +
                 std::to_string(direct_io_min_bytes)};
  return Status::Ok();
}

std::uint64_t RecorderStats::FramesWritten() const {
  std::uint64_t n = 0;
  for (const auto& c : cameras) n += c.written;
  return n;
}

std::uint64_t RecorderStats::FramesLost() const {
  std::uint64_t n = 0;
  for (const auto& c : cameras) n += c.lost();
  return n;
}

std::string RecorderStats::OneLine() const {
  std::uint64_t full = 0, write_error = 0, stopped = 0;
  for (const auto& c : cameras) {
    full += c.dropped_queue_full;
    write_error += c.lost_write_error;
    stopped += c.lost_stopped;
  }
  std::ostringstream out;
  out << "written " << FramesWritten() << " frames (" << cameras.size() << " cameras), lost "
      << FramesLost() << " (queue full " << full << ", write error " << write_error
      << ", after stop " << stopped << "), Vicon " << vicon_written << " lines written, "
      << vicon_lost << " lost; disk path: ";
  const std::uint64_t refused_or_off = buffered_files - small_buffered_files;
  if (direct_files > 0 && buffered_files > 0)
    out << "O_DIRECT " << direct_files << " files, buffered " << buffered_files;
  else if (refused_or_off > 0)
    out << "buffered (O_DIRECT refused or off)";
  else if (buffered_files > 0)
    out << "page cache (frames under the O_DIRECT minimum size)";
  else
    out << "O_DIRECT";
  if (stop_reason) out << "; stopped: " << *stop_reason;
  return out.str();
}

Expected<std::unique_ptr<Recorder>> Recorder::Create(const RigConfig& rig,
                                                     const RecorderOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  std::unique_ptr<Recorder> recorder(new Recorder());
  recorder->options_ = options;
  recorder->sequence_dir_ = options.root_dir / options.scene / options.sequence;
  recorder->calibration_dir_ = options.root_dir / layout::kCalibrationFolder;
  const fs::path& seq = recorder->sequence_dir_;
  if (fs::exists(seq / layout::kViconFolder) || (fs::exists(seq) && !fs::is_empty(seq))) {
    return MakeError(seq.string(), 0, 0,
                     "the sequence folder exists and is not empty; choose another --out, "
                     "--scene or --sequence (a recording never overwrites one)");
  }
  for (const CameraConfig& camera : rig.cameras) {
    recorder->serials_.push_back(camera.serial);
    if (Status s = MakeDirs(layout::CameraDir(seq, camera.serial)); !s) return s.error();
    RecorderCameraStats stats;
    stats.serial = camera.serial;
    recorder->camera_stats_.push_back(stats);
  }
  recorder->queues_.resize(rig.cameras.size());

  // Calibration beside the scenes, as the dataset layer finds it.
  const fs::path mla_dir = recorder->calibration_dir_ / layout::kMlaCalibrationFolder;
  for (const CameraConfig& camera : rig.cameras) {
    if (camera.mla_file.empty()) continue;
    if (Status s = MakeDirs(mla_dir); !s) return s.error();
    if (Status s = CopyInto(camera.mla_file, mla_dir / layout::MlaXmlFileName(camera.serial)); !s)
      return s.error();
  }
  if (!rig.vicon.vsk.empty()) {
    const fs::path vsk_dir = recorder->calibration_dir_ / layout::kViconCalibrationFolder;
    if (Status s = MakeDirs(vsk_dir); !s) return s.error();
    if (Status s = CopyInto(rig.vicon.vsk, vsk_dir / layout::kObjectVsk); !s) return s.error();
  }

  if (rig.vicon.source != ViconSourceKind::kNone) {
    if (Status s = MakeDirs(seq / layout::kViconFolder); !s) return s.error();
    std::vector<std::string> subjects =
        options.vicon_objects.empty() ? ViconObjectsOfRig(rig) : options.vicon_objects;
    ViconPoseOptions pose_options;
    pose_options.rotation = rig.vicon.rotation;
    pose_options.handedness = rig.vicon.handedness;
    Expected<ViconCsvAppender> csv = ViconCsvAppender::Create(
        layout::ViconCsvPath(seq, options.vicon_csv_number), std::move(subjects),
        static_cast<int>(std::lround(rig.vicon.rate_hz)), pose_options);
    if (!csv) return csv.error();
    recorder->vicon_csv_.emplace(std::move(*csv));
  }

  for (int i = 0; i < options.writer_threads; ++i)
    recorder->writers_.emplace_back([r = recorder.get()] { r->WriterLoop(); });
  return recorder;
}

Recorder::~Recorder() { Stop(); }

std::size_t Recorder::ItemBytes(const Item& item) const {
  return item.frame.buffer ? item.frame.buffer->capacity_bytes
                           : item.frame.image.stride_bytes * item.frame.image.height;
}

bool Recorder::SubmitFrame(int camera_index, std::int64_t frame_number, Frame frame) {
  if (camera_index < 0 || camera_index >= static_cast<int>(queues_.size())) return false;
  Item item{camera_index, frame_number, 0, std::move(frame)};
  const std::size_t bytes = ItemBytes(item);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    RecorderCameraStats& stats = camera_stats_[camera_index];
    std::deque<Item>& queue = queues_[camera_index];
    if (stopping_ || failed_.load()) {
      ++stats.lost_stopped;
      return false;
    }
    const bool over_memory =
        options_.max_memory_bytes > 0 && backlog_frames_ > 0 &&
        backlog_bytes_ + bytes > static_cast<std::size_t>(options_.max_memory_bytes);
    if (queue.size() >= static_cast<std::size_t>(options_.queue_frames) || over_memory) {
      ++stats.dropped_queue_full;
      return false;
    }
    item.order = next_order_++;
    queue.push_back(std::move(item));
    stats.queue_high_water = std::max(stats.queue_high_water, queue.size());
    backlog_bytes_ += bytes;
    ++backlog_frames_;
  }
  work_.notify_one();
  return true;
}

void Recorder::Fail(const std::string& reason) {
  // Called with mutex_ held.
  if (!stop_reason_) stop_reason_ = reason;
  failed_.store(true);
  for (std::size_t c = 0; c < queues_.size(); ++c) {
    for (const Item& item : queues_[c]) {
      backlog_bytes_ -= ItemBytes(item);
      --backlog_frames_;
      ++camera_stats_[c].lost_stopped;
    }
    queues_[c].clear();
  }
}

void Recorder::WriterLoop() {
  for (;;) {
    Item item;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      std::deque<Item>* oldest = nullptr;
      work_.wait(lock, [&] {
        oldest = nullptr;
        for (std::deque<Item>& queue : queues_)
          if (!queue.empty() && (oldest == nullptr || queue.front().order < oldest->front().order))
            oldest = &queue;
        return stopping_ || oldest != nullptr;
      });
      if (oldest == nullptr) return;  // stopping and drained
      item = std::move(oldest->front());
      oldest->pop_front();
    }
    const std::size_t bytes = ItemBytes(item);
    const fs::path path =
        layout::RawFramePath(sequence_dir_, serials_[item.camera_index], item.frame_number);
    int error_number = 0;
    const auto image_bytes = static_cast<std::int64_t>(item.frame.image.stride_bytes) *
                             static_cast<std::int64_t>(item.frame.image.height);
    const bool small = image_bytes < options_.direct_io_min_bytes;
    Expected<RawFrameWriteResult> result =
        WriteRawFrame(path, item.frame, options_.direct_io && !small, &error_number);
    item.frame = Frame{};  // the buffer goes back to its pool before the lock
    std::lock_guard<std::mutex> lock(mutex_);
    backlog_bytes_ -= bytes;
    --backlog_frames_;
    RecorderCameraStats& stats = camera_stats_[item.camera_index];
    if (result) {
      ++stats.written;
      stats.bytes_written += result->file_bytes;
      if (stats.first_frame < 0 || item.frame_number < stats.first_frame)
        stats.first_frame = item.frame_number;
      stats.last_frame = std::max(stats.last_frame, item.frame_number);
      ++(result->path == WritePath::kDirect ? direct_files_ : buffered_files_);
      if (result->path == WritePath::kBuffered && options_.direct_io && small)
        ++small_buffered_files_;
    } else {
      ++stats.lost_write_error;
      Fail((IsDiskFull(error_number) ? "disk full: " : "write error: ") + result.error().message);
    }
  }
}

bool Recorder::SubmitVicon(const ViconFrame& frame) {
  std::lock_guard<std::mutex> lock(vicon_mutex_);
  if (!vicon_csv_) return false;
  if (failed_.load()) {
    ++vicon_lost_;
    return false;
  }
  int error_number = 0;
  if (Status s = vicon_csv_->Append(frame, &error_number); !s) {
    ++vicon_lost_;
    if (error_number != 0) {
      std::lock_guard<std::mutex> frames_lock(mutex_);
      Fail((IsDiskFull(error_number) ? "disk full: " : "write error: ") + s.error().message);
    }
    return false;
  }
  return true;
}

void Recorder::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (joined_) return;
    stopping_ = true;
  }
  work_.notify_all();
  for (std::thread& writer : writers_) writer.join();
  std::lock_guard<std::mutex> vicon_lock(vicon_mutex_);
  if (vicon_csv_ && !failed_.load()) {
    if (Status s = vicon_csv_->Finish(); !s) {
      std::lock_guard<std::mutex> lock(mutex_);
      Fail("write error: " + s.error().message);
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);
  joined_ = true;
}

RecorderStats Recorder::Stats() const {
  RecorderStats stats;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stats.cameras = camera_stats_;
    for (std::size_t c = 0; c < queues_.size(); ++c)
      stats.cameras[c].queue_depth = queues_[c].size();
    stats.direct_files = direct_files_;
    stats.buffered_files = buffered_files_;
    stats.small_buffered_files = small_buffered_files_;
    stats.backlog_bytes = backlog_bytes_;
    stats.backlog_frames = backlog_frames_;
    stats.stop_reason = stop_reason_;
  }
  std::lock_guard<std::mutex> vicon_lock(vicon_mutex_);
  stats.vicon_lost = vicon_lost_;
  if (vicon_csv_) {
    stats.vicon_written = vicon_csv_->stats().frames_written;
    stats.vicon_unknown_objects = vicon_csv_->stats().unknown_objects;
  }
  return stats;
}

}  // namespace lifmcr
