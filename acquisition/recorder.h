#pragma once
// The recorder: writes a live recording in the LiFMCR layout without ever
// making a grab thread wait.
//
//   ROOT/SCENE/SEQ/TypeE_<serial>/TypeE_<serial>_<frame>_Raw.bmp  (raw_frame_writer.h)
//   ROOT/SCENE/SEQ/Vicon/sequence_01.csv       every received Vicon frame, one line each
//                                              (none received: no file, the report says so)
//   ROOT/Calibration/02_MLA_Calibration/TypeE_<serial>_MLA.xml    copied from the rig file
//   ROOT/Calibration/03_Vicon/Object.vsk                           copied when the rig names one
//
// Frames: SubmitFrame puts a frame (its pooled buffer, no copy) on the queue
// of its camera and returns at once. A camera's queue holds at most
// `queue_frames` frames, and all queues together at most `max_memory_bytes`
// of buffers; a frame that does not fit is dropped and counted
// (back-pressure drops, it never stalls the cameras). Writer threads take the
// oldest queued frame of any camera. Memory is bounded by the pooled buffers
// themselves: a queued frame holds its buffer until it is written.
//
// Ending: Stop() refuses new frames, lets the writers finish the queue, joins
// them and closes the CSV. A write error (disk full: ENOSPC, or EFBIG from a
// file-size limit; any other error) stops the recording by itself: the frame
// being written is removed, frames still queued are counted as lost, later
// submissions are refused and counted, and `stop_reason` says why. Every file
// already written stays valid.

#include "acquisition/vicon_csv_appender.h"
#include "config/error.h"
#include "config/rig_config.h"
#include "drivers/frame.h"
#include "drivers/vicon_source.h"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace lifmcr {

struct RecorderOptions {
  std::filesystem::path root_dir;      // the dataset root (--out)
  std::string scene = "00_Recording";  // scene folder name
  std::string sequence = "seq";        // sequence folder name
  int vicon_csv_number = 1;            // sequence_01.csv
  int queue_frames = 16;               // per camera, >= 1
  int writer_threads = 1;              // 1..64
  bool direct_io = true;               // try O_DIRECT first (falls back where refused)
  // Frames smaller than this are written through the page cache even with
  // direct_io. An O_DIRECT write returns only when the device has the data:
  // on a shared or virtual disk a 5 KiB file's direct write took p99 80-120
  // ms and up to 880 ms here (page cache: p99 0.9 ms), longer than a small
  // pool lasts at 50 Hz, while the page-cache copy of a small frame costs
  // microseconds. Large frames keep O_DIRECT: at R32 rates that copy costs a
  // core and the dirty pages' writeback competes with the next frames.
  std::int64_t direct_io_min_bytes = std::int64_t{1} << 20;
  std::int64_t max_memory_bytes = 0;   // all queues together; 0 = queue_frames alone
  // The Vicon objects the CSV has columns for; empty: the rig's
  // (ViconObjectsOfRig). A host recording only some of the rig's cameras
  // (`record --cameras`) still records every object of the shared Vicon
  // stream, so the hosts' CSVs agree and `lifmcr merge` joins them.
  std::vector<std::string> vicon_objects;

  // From the rig file's recorder section (out_dir is not used: --out wins).
  static RecorderOptions FromRig(const RecorderConfig& config);
  Status Check() const;
};

struct RecorderCameraStats {
  std::string serial;
  std::uint64_t written = 0;  // frames on disk
  std::uint64_t bytes_written = 0;
  std::uint64_t dropped_queue_full = 0;  // back-pressure drops
  std::uint64_t lost_write_error = 0;    // the write failed (file removed)
  std::uint64_t lost_stopped = 0;        // queued or submitted after the recording stopped
  std::size_t queue_depth = 0;
  std::size_t queue_high_water = 0;
  std::int64_t first_frame = -1;  // frame numbers written, -1 when none
  std::int64_t last_frame = -1;

  std::uint64_t lost() const { return dropped_queue_full + lost_write_error + lost_stopped; }
};

struct RecorderStats {
  std::vector<RecorderCameraStats> cameras;  // by camera index
  std::uint64_t direct_files = 0;            // written with O_DIRECT
  std::uint64_t buffered_files = 0;          // written through the page cache
  std::uint64_t small_buffered_files = 0;    // of which: under direct_io_min_bytes
  std::uint64_t vicon_written = 0;
  std::uint64_t vicon_lost = 0;  // could not be written
  std::uint64_t vicon_unknown_objects = 0;
  std::size_t backlog_bytes = 0;  // queued, not yet written
  std::size_t backlog_frames = 0;
  std::optional<std::string> stop_reason;  // set when a write error stopped the recording

  std::uint64_t FramesWritten() const;
  std::uint64_t FramesLost() const;
  // "written 120 frames (2 cameras), lost 3 (queue full 3), Vicon 960 lines, O_DIRECT"
  std::string OneLine() const;
};

class Recorder {
 public:
  // Creates the folders, copies the calibration files, opens the
  // Vicon CSV (when the rig has a Vicon source) and starts the writers.
  // Errors name the folder or file that could not be made.
  static Expected<std::unique_ptr<Recorder>> Create(const RigConfig& rig,
                                                    const RecorderOptions& options);
  ~Recorder();  // Stop()
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  // Queues `frame` of camera `camera_index` to be written as frame number
  // `frame_number` (the trigger index). Never blocks on the disk; false when
  // the frame was dropped (queue full, recording stopped), which is counted.
  bool SubmitFrame(int camera_index, std::int64_t frame_number, Frame frame);

  // Appends one Vicon frame to the CSV on the caller's thread (one small
  // write; the Vicon thread, never a grab thread). False when not written.
  bool SubmitVicon(const ViconFrame& frame);

  // Writes what is queued, joins the writers, closes the CSV. Idempotent.
  void Stop();

  // True once a write error stopped the recording.
  bool failed() const { return failed_.load(); }
  RecorderStats Stats() const;

  const std::filesystem::path& sequence_dir() const { return sequence_dir_; }
  const std::filesystem::path& calibration_dir() const { return calibration_dir_; }

 private:
  struct Item {
    int camera_index = 0;
    std::int64_t frame_number = 0;
    std::uint64_t order = 0;
    Frame frame;
  };
  Recorder() = default;
  void WriterLoop();
  void Fail(const std::string& reason);
  std::size_t ItemBytes(const Item& item) const;

  RecorderOptions options_;
  std::filesystem::path sequence_dir_;
  std::filesystem::path calibration_dir_;
  std::vector<std::string> serials_;

  mutable std::mutex mutex_;
  std::condition_variable work_;
  std::vector<std::deque<Item>> queues_;  // per camera
  std::vector<RecorderCameraStats> camera_stats_;
  std::uint64_t next_order_ = 0;
  std::size_t backlog_bytes_ = 0;
  std::size_t backlog_frames_ = 0;
  std::uint64_t direct_files_ = 0;
  std::uint64_t buffered_files_ = 0;
  std::uint64_t small_buffered_files_ = 0;
  std::optional<std::string> stop_reason_;
  bool stopping_ = false;
  std::atomic<bool> failed_{false};
  std::vector<std::thread> writers_;
  bool joined_ = false;

  mutable std::mutex vicon_mutex_;
  std::optional<ViconCsvAppender> vicon_csv_;
  std::uint64_t vicon_lost_ = 0;
};

}  // namespace lifmcr
