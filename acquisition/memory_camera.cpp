#include "acquisition/memory_camera.h"

#include "drivers/host_clock.h"

#include <chrono>
#include <cstring>
#include <thread>
#include <vector>

namespace lifmcr {
namespace {

std::uint64_t NextId16(std::uint64_t id) { return id >= 65535 ? 1 : id + 1; }

}  // namespace

Status MemoryCameraOptions::Check() const {
  if (serial.empty()) return Error{"memory camera: empty serial"};
  if (width <= 0 || height <= 0)
    return Error{"memory camera " + serial + ": width and height must be > 0"};
  if (pool_frames < 1) return Error{"memory camera " + serial + ": pool_frames must be >= 1"};
  if (frames_per_second < 0) return Error{"memory camera " + serial + ": frames_per_second < 0"};
  if (first_frame_id == 0 || first_frame_id > 65535)
    return Error{"memory camera " + serial + ": first_frame_id must be 1..65535"};
  return Status::Ok();
}

MemoryCamera::MemoryCamera(MemoryCameraOptions options) : options_(std::move(options)) {}

std::uint8_t MemoryCamera::PatternAt(int x, int y, int c) {
  return static_cast<std::uint8_t>(x * 7 + y * 3 + c * 85);
}

Status MemoryCamera::Open() {
  if (Status s = options_.Check(); !s) return s;
  std::lock_guard<std::mutex> lock(mutex_);
  const int bpp = BytesPerPixel(options_.format);
  // Rows padded to 4 bytes, as a BMP stores them, so frames go to disk as they are.
  row_bytes_ = (static_cast<std::size_t>(options_.width) * bpp + 3) / 4 * 4;
  pool_ = FramePool::Create(static_cast<std::size_t>(options_.pool_frames),
                            row_bytes_ * static_cast<std::size_t>(options_.height));
  // The pattern is drawn once into every buffer; frames only get their id stamped.
  std::vector<BufferRef> all;
  for (int i = 0; i < options_.pool_frames; ++i) all.push_back(pool_->Acquire());
  std::vector<std::uint8_t> row(row_bytes_, 0);
  for (int y = 0; y < options_.height; ++y) {
    for (int x = 0; x < options_.width; ++x)
      for (int c = 0; c < bpp; ++c) row[static_cast<std::size_t>(x) * bpp + c] = PatternAt(x, y, c);
    for (BufferRef& buffer : all)
      std::memcpy(buffer->data + static_cast<std::size_t>(y) * row_bytes_, row.data(), row_bytes_);
  }
  next_id_ = options_.first_frame_id;
  open_ = true;
  return Status::Ok();
}

Status MemoryCamera::Start() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!open_) return Error{"memory camera " + options_.serial + ": Start before Open"};
  started_ = true;
  next_due_ = std::chrono::steady_clock::now();
  return Status::Ok();
}

Status MemoryCamera::Stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    started_ = false;
    made_.clear();  // their buffers go back to the pool
  }
  triggered_.notify_all();
  return Status::Ok();
}

Status MemoryCamera::SoftwareTrigger() {
  // The exposure's time is the trigger's, not when the lock below is had
  // (a starved grab thread may hold it a while).
  const std::int64_t exposed_ns = HostRealtimeNs();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!started_) return Error{"memory camera " + options_.serial + ": trigger while stopped"};
    if (options_.free_run)
      return Error{"memory camera " + options_.serial + ": free-running, not in trigger mode"};
    if (std::optional<Frame> frame = Produce(pool_->Acquire(), exposed_ns))
      made_.push_back(std::move(*frame));
  }
  triggered_.notify_one();
  return Status::Ok();
}

std::optional<Frame> MemoryCamera::Produce(BufferRef buffer, std::int64_t host_ns) {
  const std::uint64_t id = next_id_;
  next_id_ = NextId16(next_id_);
  ++produced_;
  if (!buffer) {
    ++stats_.underruns;
    return std::nullopt;
  }
  Frame frame;
  frame.serial = options_.serial;
  frame.frame_id = id;
  frame.host_ns = host_ns;
  frame.device_ns = host_ns;
  frame.status = FrameStatus::kOk;
  frame.image =
      ImageView{buffer->data, options_.width, options_.height, row_bytes_, options_.format};
  // The id in the first bytes (little-endian) tells frames apart on disk.
  std::memcpy(buffer->data, &id, std::min<std::size_t>(sizeof(id), row_bytes_));
  frame.buffer = std::move(buffer);
  ++stats_.completed;
  stats_.transferred_bytes += row_bytes_ * static_cast<std::size_t>(options_.height);
  return frame;
}

Expected<std::optional<Frame>> MemoryCamera::NextFrame(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!open_) return Error{"memory camera " + options_.serial + ": NextFrame before Open"};
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  if (!options_.free_run) {
    if (!triggered_.wait_until(lock, deadline, [&] { return !made_.empty() || !started_; }) ||
        !started_)
      return std::optional<Frame>();
    Frame frame = std::move(made_.front());
    made_.pop_front();
    return std::optional<Frame>(std::move(frame));
  }
  if (!started_ || (options_.max_frames > 0 && produced_ >= options_.max_frames)) {
    lock.unlock();
    std::this_thread::sleep_until(
        std::min(deadline, std::chrono::steady_clock::now() + std::chrono::milliseconds(10)));
    return std::optional<Frame>();
  }
  if (options_.frames_per_second > 0) {
    if (next_due_ > deadline) return std::optional<Frame>();
    const auto due = next_due_;
    next_due_ +=
        std::chrono::nanoseconds(static_cast<std::int64_t>(1e9 / options_.frames_per_second));
    lock.unlock();
    std::this_thread::sleep_until(due);
    lock.lock();
  }
  BufferRef buffer = pool_->Acquire();
  if (!buffer && options_.wait_for_buffer) {
    // The pool has no wake-up; a short poll costs nothing next to a frame write.
    lock.unlock();
    while (!buffer && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      buffer = pool_->Acquire();
    }
    lock.lock();
    if (!buffer) return std::optional<Frame>();
  }
  return Produce(std::move(buffer), HostRealtimeNs());
}

CameraInfo MemoryCamera::Info() const {
  std::lock_guard<std::mutex> lock(mutex_);
  CameraInfo info;
  info.serial = options_.serial;
  info.vendor = "lifmcr";
  info.model = "memory camera";
  info.device_id = "memory:" + options_.serial;
  info.width = options_.width;
  info.height = options_.height;
  info.format = options_.format;
  info.payload_bytes = row_bytes_ * static_cast<std::size_t>(options_.height);
  // Frames are stamped with CLOCK_REALTIME when made at the software
  // trigger: every triggered memory camera is on that one clock, and equal
  // stamps mean one trigger. A free-running one makes frames on its own
  // schedule (as fast as its pool allows), so its stamps say nothing about the
  // rig's triggers: for the first-frame placement it has a clock of its own.
  if (!options_.free_run) info.device_clock = "host CLOCK_REALTIME";
  return info;
}

CameraStats MemoryCamera::Stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace lifmcr
