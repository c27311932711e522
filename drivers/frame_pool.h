#pragma once
// Pre-allocated frame buffers shared from the driver to the last consumer.
//
// A camera allocates its pool once, at its payload size, before acquisition
// starts; a frame holds a BufferRef (shared ownership) and the buffer goes
// back to the pool when the last holder (recorder, processing, publisher)
// drops it. Nothing is allocated or copied per frame. Buffers are aligned to
// 4096 bytes and padded to a multiple of 4096 so the recorder can write them
// with O_DIRECT.
//
// Their pages are made resident when the pool is made, not when a camera
// first writes a frame into them: a first write into fresh pages faults
// each 4 KiB page in, which cost 340 ms for one r32 frame (97 MB) on the
// 2-core CI machine against 9 ms into resident memory (bench/README.md,
// "Page faults"): the first frames of every camera would arrive late, or be
// lost. Each buffer is aligned to 2 MiB and asked for transparent huge
// pages (MADV_HUGEPAGE, where the kernel offers them: 512 times fewer
// faults), then written once.
//
// When every buffer is in use, Acquire returns nullptr: the driver counts an
// underrun (the frame is lost, and counted), it never blocks or allocates.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace lifmcr {

class FramePool;

// One pooled buffer. `data` is valid until the last BufferRef to it is gone.
struct PooledBuffer {
  std::uint8_t* data = nullptr;
  std::size_t capacity_bytes = 0;  // usable size (>= the requested payload)
  int index = 0;                   // position in the pool, for logs
};

using BufferRef = std::shared_ptr<PooledBuffer>;

class FramePool {
 public:
  static constexpr std::size_t kAlignment = 4096;
  // Allocation granularity: a transparent huge page.
  static constexpr std::size_t kHugePage = std::size_t{2} << 20;

  // `count` buffers of at least `payload_bytes` each.
  static std::shared_ptr<FramePool> Create(std::size_t count, std::size_t payload_bytes);
  ~FramePool();
  FramePool(const FramePool&) = delete;
  FramePool& operator=(const FramePool&) = delete;

  // A free buffer, or nullptr when all are in use (never blocks).
  BufferRef Acquire();

  std::size_t size() const { return buffers_.size(); }
  std::size_t capacity_bytes() const { return capacity_bytes_; }
  std::size_t free_count() const;
  // Largest number of buffers that were in use at once since creation.
  std::size_t high_water() const;

 private:
  FramePool(std::size_t count, std::size_t capacity_bytes);
  void Release(int index);

  std::size_t capacity_bytes_;
  std::vector<PooledBuffer> buffers_;
  mutable std::mutex mutex_;
  std::vector<int> free_;
  std::size_t high_water_ = 0;
  std::weak_ptr<FramePool> self_;
};

}  // namespace lifmcr
