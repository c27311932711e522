#include "config/memory_policy.h"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstdlib>
#include <cstring>
#include <thread>

namespace lifmcr {
namespace {

// Minor page faults of the calling thread so far.
long MinorFaults() {
  rusage usage{};
  getrusage(RUSAGE_THREAD, &usage);
  return usage.ru_minflt;
}

// A frame-sized block allocated, written and freed, then again: the second
// time (the steady state of a per-frame buffer) it must come back resident.
// Without the policy glibc maps it afresh (96 MiB = 24576 pages faulted in
// each time); with it, the block is reused from the heap. On a worker thread
// too (thread arenas cannot hold a block this large: the main arena does).
TEST(MemoryPolicy, AFrameSizedBlockIsReusedNotFaultedInAgain) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "a sanitizer's allocator replaces glibc's malloc: mallopt does not apply";
#endif
  KeepHeapResident();
  constexpr std::size_t kBytes = std::size_t{96} << 20;
  const auto second_pass_faults = [] {
    long faults = 0;
    for (int pass = 0; pass < 2; ++pass) {
      auto* block = static_cast<unsigned char*>(std::malloc(kBytes));
      EXPECT_NE(block, nullptr);
      if (block == nullptr) return -1L;
      const long before = MinorFaults();
      std::memset(block, pass + 1, kBytes);
      // Keeps the compiler from dropping the writes to a block freed unread.
      asm volatile("" : : "r"(block) : "memory");
      faults = MinorFaults() - before;
      std::free(block);
    }
    return faults;
  };
  const long here = second_pass_faults();
  long worker = -1;
  std::thread([&] { worker = second_pass_faults(); }).join();
  // 4 KiB pages: 24576 per pass without reuse; a few are allowed.
  EXPECT_LT(here, 64) << "page faults writing a freed-and-reallocated 96 MiB block";
  EXPECT_LT(worker, 64) << "the same on a worker thread";
}

// Per-thread arenas (live registration): a worker's block below a thread
// heap's 64 MiB stays resident in its own arena (SIFT pyramids, renders).
// After the test above: arena assignment is per thread, made at its first
// malloc, so this thread is new.
TEST(MemoryPolicy, PerThreadArenasKeepAWorkersBlockResidentToo) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "a sanitizer's allocator replaces glibc's malloc: mallopt does not apply";
#endif
  KeepHeapResident(HeapArenas::kPerThread);
  constexpr std::size_t kBytes = std::size_t{40} << 20;
  long faults = -1;
  std::thread([&] {
    for (int pass = 0; pass < 2; ++pass) {
      auto* block = static_cast<unsigned char*>(std::malloc(kBytes));
      ASSERT_NE(block, nullptr);
      const long before = MinorFaults();
      std::memset(block, pass + 1, kBytes);
      asm volatile("" : : "r"(block) : "memory");
      faults = MinorFaults() - before;
      std::free(block);
    }
  }).join();
  KeepHeapResident(HeapArenas::kOne);
  // 10240 pages per pass without reuse.
  EXPECT_LT(faults, 64) << "page faults writing a freed-and-reallocated 40 MiB block";
}

}  // namespace
}  // namespace lifmcr
