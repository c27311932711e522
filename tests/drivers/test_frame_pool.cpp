#include "drivers/frame_pool.h"

#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <thread>
#include <vector>

namespace lifmcr {
namespace {

TEST(FramePool, BuffersAreAlignedPaddedAndReturnedByTheLastHolder) {
  auto pool = FramePool::Create(3, 10000);
  EXPECT_EQ(pool->size(), 3u);
  EXPECT_EQ(pool->capacity_bytes(), 12288u);  // padded to 4096 for O_DIRECT
  BufferRef a = pool->Acquire();
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(a->data) % FramePool::kAlignment, 0u);
  BufferRef a2 = a;  // a second consumer
  a.reset();
  EXPECT_EQ(pool->free_count(), 2u);  // still held by a2
  a2.reset();
  EXPECT_EQ(pool->free_count(), 3u);
}

// A camera's first frames must not pay for faulting the pool's pages in
// (340 ms per r32 frame on the CI machine): every page of every buffer is
// resident when Create returns, large (huge-page) and small buffers alike.
TEST(FramePool, BuffersAreResidentBeforeTheFirstFrame) {
  const std::size_t page = static_cast<std::size_t>(sysconf(_SC_PAGESIZE));
  for (const std::size_t payload : {std::size_t{5000}, std::size_t{(5u << 20) + 123}}) {
    auto pool = FramePool::Create(3, payload);
    std::vector<BufferRef> held;
    for (int i = 0; i < 3; ++i) held.push_back(pool->Acquire());
    for (const BufferRef& buffer : held) {
      ASSERT_NE(buffer, nullptr);
      const std::size_t pages = (buffer->capacity_bytes + page - 1) / page;
      std::vector<unsigned char> resident(pages);
      ASSERT_EQ(mincore(buffer->data, buffer->capacity_bytes, resident.data()), 0);
      std::size_t missing = 0;
      for (unsigned char r : resident) missing += (r & 1) ? 0 : 1;
      EXPECT_EQ(missing, 0u) << payload << "-byte frames: " << missing << " of " << pages
                             << " pages not resident";
      if (payload >= FramePool::kHugePage) {
        EXPECT_EQ(reinterpret_cast<std::uintptr_t>(buffer->data) % FramePool::kHugePage, 0u);
      }
    }
  }
}

TEST(FramePool, ExhaustionReturnsNullInsteadOfBlockingOrAllocating) {
  auto pool = FramePool::Create(2, 64);
  BufferRef a = pool->Acquire(), b = pool->Acquire();
  EXPECT_NE(a->data, b->data);
  EXPECT_EQ(pool->Acquire(), nullptr);
  b.reset();
  EXPECT_NE(pool->Acquire(), nullptr);
  EXPECT_EQ(pool->high_water(), 2u);
}

TEST(FramePool, OutlivesItsOwnerWhileBuffersAreOut) {
  BufferRef held;
  {
    auto pool = FramePool::Create(1, 16);
    held = pool->Acquire();
  }
  held->data[0] = 42;  // the pool is kept alive by the buffer (ASan would catch a use after free)
  EXPECT_EQ(held->data[0], 42);
}

TEST(FramePool, ConcurrentAcquireAndReleaseNeverHandsOutABufferTwice) {
  auto pool = FramePool::Create(8, 64);
  std::vector<std::thread> threads;
  std::atomic<int> failures{0};
  std::array<std::atomic<int>, 8> in_use{};
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&] {
      for (int i = 0; i < 20000; ++i) {
        BufferRef buffer = pool->Acquire();
        if (!buffer) continue;
        if (in_use[buffer->index].exchange(1) != 0) failures++;  // someone else holds it
        in_use[buffer->index] = 0;
      }
    });
  }
  for (auto& thread : threads) thread.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(pool->free_count(), 8u);
}

}  // namespace
}  // namespace lifmcr
