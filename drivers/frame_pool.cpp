#include "drivers/frame_pool.h"

#include <sys/mman.h>

#include <cstdlib>
#include <cstring>
#include <new>

namespace lifmcr {

std::shared_ptr<FramePool> FramePool::Create(std::size_t count, std::size_t payload_bytes) {
  const std::size_t capacity = (payload_bytes + kAlignment - 1) / kAlignment * kAlignment;
  std::shared_ptr<FramePool> pool(new FramePool(count, capacity == 0 ? kAlignment : capacity));
  pool->self_ = pool;
  return pool;
}

FramePool::FramePool(std::size_t count, std::size_t capacity_bytes)
    : capacity_bytes_(capacity_bytes), buffers_(count) {
  free_.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    // Buffers of a huge page or more: whole huge pages (aligned_alloc wants
    // the size a multiple of the alignment; the pool reports capacity_bytes_,
    // the rest is unused). Smaller ones (tests, small sensors) stay at 4 KiB
    // so a pool of many small frames does not take 2 MiB per frame.
    const std::size_t alignment = capacity_bytes_ >= kHugePage ? kHugePage : kAlignment;
    const std::size_t bytes = (capacity_bytes_ + alignment - 1) / alignment * alignment;
    void* memory = std::aligned_alloc(alignment, bytes);
    if (memory == nullptr) throw std::bad_alloc();
    // A hint: where transparent huge pages are off (or under a sanitizer's
    // allocator) it fails or changes nothing, and the buffer keeps 4 KiB pages.
    if (alignment == kHugePage) madvise(memory, bytes, MADV_HUGEPAGE);
    std::memset(memory, 0, bytes);  // resident now, not at the first frame
    buffers_[i] = {static_cast<std::uint8_t*>(memory), capacity_bytes_, static_cast<int>(i)};
    free_.push_back(static_cast<int>(count - 1 - i));
  }
}

FramePool::~FramePool() {
  for (PooledBuffer& buffer : buffers_) std::free(buffer.data);
}

BufferRef FramePool::Acquire() {
  int index = -1;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (free_.empty()) return nullptr;
    index = free_.back();
    free_.pop_back();
    high_water_ = std::max(high_water_, buffers_.size() - free_.size());
  }
  // The deleter keeps the pool alive while any buffer is out.
  std::shared_ptr<FramePool> pool = self_.lock();
  return BufferRef(&buffers_[index],
                   [pool](PooledBuffer* buffer) { pool->Release(buffer->index); });
}

void FramePool::Release(int index) {
  std::lock_guard<std::mutex> lock(mutex_);
  free_.push_back(index);
}

std::size_t FramePool::free_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return free_.size();
}

std::size_t FramePool::high_water() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return high_water_;
}

}  // namespace lifmcr
