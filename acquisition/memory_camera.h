#pragma once
// A camera that produces frames in memory: a fixed test pattern in its own
// frame pool, each frame stamped with its frame id. It stands in for a camera
// where the disk, not the sensor, is under test: the recorder benchmark (full
// R32 frames as fast as the recorder takes them) and recorder tests.
//
// Frames come on SoftwareTrigger (one frame per trigger) or, when
// `frames_per_second` is set, free-running at that rate; 0 with free_run
// means as fast as NextFrame is called. A triggered frame is made at the
// trigger, as a real camera exposes, stamps and fills a host buffer then:
// SoftwareTrigger takes its buffer and stamps it, and NextFrame only hands
// over frames already made, however late the grab thread asks (a starved
// grab thread must not move a frame off the trigger's time, which the
// FrameSet assembler places it by). The device counter behaves like GigE
// Vision 1: 16-bit, skipping 0, starting at `first_frame_id`. When the pool
// is exhausted the frame is lost and counted as an underrun, and its id is
// skipped, as a real camera's would be.

#include "drivers/camera.h"
#include "drivers/frame_pool.h"

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>

namespace lifmcr {

struct MemoryCameraOptions {
  std::string serial = "MEM0";
  int width = 64;
  int height = 48;
  PixelFormat format = PixelFormat::kMono8;
  int pool_frames = 8;
  bool free_run = false;           // false: one frame per SoftwareTrigger
  double frames_per_second = 0.0;  // free run only; 0 = as fast as possible
  std::uint64_t first_frame_id = 65400;
  std::uint64_t max_frames = 0;  // free run: stop producing after this many; 0 = no limit
  // Free run: wait (up to NextFrame's timeout) for a free buffer instead of
  // losing the frame, so the consumer sets the pace (a benchmark source).
  bool wait_for_buffer = false;

  Status Check() const;
};

class MemoryCamera : public Camera {
 public:
  explicit MemoryCamera(MemoryCameraOptions options);

  Status Open() override;
  Status Start() override;
  Status Stop() override;
  Expected<std::optional<Frame>> NextFrame(std::chrono::milliseconds timeout) override;
  Status SoftwareTrigger() override;
  CameraInfo Info() const override;
  CameraStats Stats() const override;

  // The pixel value the pattern has at (x, y) of channel c (tests check frames with it).
  static std::uint8_t PatternAt(int x, int y, int c);

 private:
  // Makes one frame (called with mutex_ held) in `buffer`, stamped
  // `host_ns` (device time too: the host's clock), or counts an underrun
  // when it is null.
  std::optional<Frame> Produce(BufferRef buffer, std::int64_t host_ns);

  MemoryCameraOptions options_;
  std::shared_ptr<FramePool> pool_;
  std::size_t row_bytes_ = 0;
  mutable std::mutex mutex_;
  std::condition_variable triggered_;
  bool open_ = false;
  bool started_ = false;
  std::deque<Frame> made_;  // triggered frames not yet taken by NextFrame
  std::uint64_t produced_ = 0;
  std::uint64_t next_id_ = 0;
  std::chrono::steady_clock::time_point next_due_;
  CameraStats stats_;
};

}  // namespace lifmcr
