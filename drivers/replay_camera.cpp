#include "drivers/replay_camera.h"

#include "drivers/frame_id_tracker.h"
#include "drivers/frame_pool.h"
#include "drivers/host_clock.h"
#include "replay/bmp.h"
#include "replay/sequence.h"

#include <ctime>
#include <thread>

namespace lifmcr {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

Status ReplayCameraOptions::Check() const {
  if (pool_buffers < 1)
    return Error{"replay options: pool_buffers must be >= 1, got " + std::to_string(pool_buffers)};
  if (trigger_period.count() <= 0) return Error{"replay options: trigger_period must be > 0"};
  if (camera_index < 0) return Error{"replay options: camera_index must be >= 0"};
  return Status::Ok();
}

struct ReplayCamera::State {
  std::filesystem::path dir;
  ReplayCameraOptions options;
  CameraFolder folder;
  std::shared_ptr<FramePool> pool;
  FrameIdTracker ids{FrameIdWidth::k64Bit};
  bool opened = false;
  bool started = false;
  std::size_t cursor = 0;  // next frame to serve (grab thread)
  Clock::time_point anchor_time{};
  std::int64_t anchor_frame = 0;
  std::int64_t lap_offset = 0;  // added to file frame numbers on later laps (loop)

  mutable std::mutex mutex;  // guards the fields below
  std::condition_variable triggered;
  int pending_triggers = 0;
  bool finished = false;
  CameraInfo info;
  CameraStats stats;

  Error Fail(const std::string& what) const {
    return Error{"replay camera " + dir.string() + ": " + what};
  }

  void Advance() {
    ++cursor;
    if (cursor >= folder.frames.size() && options.loop) {
      // Next lap: numbers continue after the last frame, one period later.
      lap_offset += folder.frames.back() - folder.frames.front() + 1;
      cursor = 0;
      return;
    }
    if (cursor >= folder.frames.size()) {
      std::lock_guard<std::mutex> lock(mutex);
      finished = true;
    }
  }
};

ReplayCamera::ReplayCamera(std::filesystem::path camera_dir, ReplayCameraOptions options)
    : state_(std::make_unique<State>()) {
  state_->dir = std::move(camera_dir);
  state_->options = options;
}

ReplayCamera::~ReplayCamera() = default;

Status ReplayCamera::Open() {
  State& s = *state_;
  if (s.opened) return s.Fail("already open");
  if (Status status = s.options.Check(); !status) return s.Fail(status.error().message);
  Expected<CameraFolder> folder = DiscoverCameraFolder(s.dir);
  if (!folder) return folder.error();
  s.folder = std::move(*folder);
  if (s.folder.frames.empty()) return s.Fail("no frame files");
  std::optional<BmpHeader> header;
  std::string first_error;
  for (const std::string& name : s.folder.frame_files) {
    Expected<BmpHeader> read = ReadBmpHeader(s.folder.dir / name);
    if (read) {
      header = *read;
      break;
    }
    if (first_error.empty()) first_error = read.error().message;
  }
  if (!header) return s.Fail("no readable frame; first error: " + first_error);
  const std::size_t payload =
      static_cast<std::size_t>(header->width) * header->height * BytesPerPixel(header->format);
  s.pool = FramePool::Create(static_cast<std::size_t>(s.options.pool_buffers), payload);
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    s.info.serial = s.folder.serial;
    s.info.vendor = "lifmcr";
    s.info.model = "replay";
    s.info.device_id = s.folder.dir.string();
    s.info.width = header->width;
    s.info.height = header->height;
    s.info.format = header->format;
    s.info.payload_bytes = payload;
    // device_ns = frame number * trigger period on every camera of the
    // sequence: one clock.
    s.info.device_clock = "replay:" + s.folder.dir.parent_path().lexically_normal().string();
  }
  s.opened = true;
  s.cursor = 0;
  return Status::Ok();
}

Status ReplayCamera::Start() {
  State& s = *state_;
  if (!s.opened) return s.Fail("Start before Open");
  s.started = true;
  // Timing restarts from the next frame: a Stop/Start pause is not replayed.
  s.anchor_time = Clock::now();
  s.anchor_frame = s.cursor < s.folder.frames.size() ? s.folder.frames[s.cursor] + s.lap_offset : 0;
  return Status::Ok();
}

Status ReplayCamera::Stop() {
  State& s = *state_;
  if (!s.opened) return s.Fail("Stop before Open");
  s.started = false;
  return Status::Ok();
}

Expected<std::optional<Frame>> ReplayCamera::NextFrame(std::chrono::milliseconds timeout) {
  State& s = *state_;
  if (!s.opened) return s.Fail("NextFrame before Open");
  const Clock::time_point deadline = Clock::now() + timeout;
  if (!s.started || s.cursor >= s.folder.frames.size()) {
    std::this_thread::sleep_until(deadline);
    return std::optional<Frame>();
  }
  const std::int64_t number = s.folder.frames[s.cursor] + s.lap_offset;

  BufferRef buffer;
  switch (s.options.pacing) {
    case ReplayPacing::kOriginal: {
      const Clock::time_point due =
          s.anchor_time + (number - s.anchor_frame) * s.options.trigger_period;
      if (due > deadline) {
        std::this_thread::sleep_until(deadline);
        return std::optional<Frame>();
      }
      std::this_thread::sleep_until(due);
      buffer = s.pool->Acquire();
      break;
    }
    case ReplayPacing::kAsFastAsPossible:
      while (!(buffer = s.pool->Acquire())) {
        if (Clock::now() >= deadline) return std::optional<Frame>();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
      break;
    case ReplayPacing::kSoftwareTrigger: {
      std::unique_lock<std::mutex> lock(s.mutex);
      if (!s.triggered.wait_until(lock, deadline, [&] { return s.pending_triggers > 0; }))
        return std::optional<Frame>();
      --s.pending_triggers;
      lock.unlock();
      buffer = s.pool->Acquire();
      break;
    }
  }

  const std::uint64_t missing = s.ids.Observe(static_cast<std::uint64_t>(number));
  if (!buffer) {
    // Due, but every buffer is held downstream: lost like a hardware frame.
    {
      std::lock_guard<std::mutex> lock(s.mutex);
      s.stats.missing_ids += missing;
      ++s.stats.underruns;
    }
    s.Advance();
    return std::optional<Frame>();
  }

  Frame frame;
  frame.camera_index = s.options.camera_index;
  frame.serial = s.folder.serial;
  frame.frame_id = static_cast<std::uint64_t>(number);
  frame.device_ns = number * s.options.trigger_period.count();
  const std::filesystem::path path = s.folder.dir / s.folder.frame_files[s.cursor];
  CameraInfo info = Info();
  Status read = Status::Ok();
  Expected<BmpHeader> header = ReadBmpHeader(path);
  if (!header) {
    read = header.error();
  } else if (header->width != info.width || header->height != info.height ||
             header->format != info.format) {
    read = s.Fail(path.filename().string() + " is " + header->Describe() + ", the camera's " +
                  "frames are " + std::to_string(info.width) + "x" + std::to_string(info.height) +
                  " " + std::string(ToString(info.format)));
  } else {
    const ImageView view{buffer->data, info.width, info.height,
                         static_cast<std::size_t>(info.width) * BytesPerPixel(info.format),
                         info.format};
    read = ReadBmpInto(path, *header, view);
    if (read) {
      frame.image = view;
      frame.buffer = std::move(buffer);
    }
  }
  frame.status = read ? FrameStatus::kOk : FrameStatus::kError;
  frame.host_ns = s.options.sequence_clock_start_ns
                      ? *s.options.sequence_clock_start_ns + frame.device_ns -
                            s.options.sequence_origin_device_ns
                      : HostRealtimeNs();
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    s.stats.missing_ids += missing;
    if (read) {
      ++s.stats.completed;
      s.stats.transferred_bytes += info.payload_bytes;
    } else {
      ++s.stats.failed;
    }
  }
  s.Advance();
  return std::optional<Frame>(std::move(frame));
}

Status ReplayCamera::SoftwareTrigger() {
  State& s = *state_;
  if (s.options.pacing != ReplayPacing::kSoftwareTrigger)
    return s.Fail("software trigger needs pacing kSoftwareTrigger; this camera paces itself");
  {
    std::lock_guard<std::mutex> lock(s.mutex);
    ++s.pending_triggers;
  }
  s.triggered.notify_one();
  return Status::Ok();
}

CameraInfo ReplayCamera::Info() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->info;
}

CameraStats ReplayCamera::Stats() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->stats;
}

bool ReplayCamera::Finished() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->finished;
}

std::size_t ReplayCamera::frame_count() const { return state_->folder.frames.size(); }

}  // namespace lifmcr
