#pragma once
// Busy threads that keep every core of the test machine occupied while they
// live (spinning, no sleeping), so a test can show that what it checks does
// not depend on the machine being idle: the grab threads, the triggers and
// the `lifmcr` child compete with them for the CPU.

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace lifmcr::test {

class CpuHogs {
 public:
  explicit CpuHogs(int threads) {
    for (int i = 0; i < threads; ++i)
      threads_.emplace_back([this] {
        std::uint64_t x = 1;
        while (running_.load(std::memory_order_relaxed)) x = x * 6364136223846793005ULL + 1;
        sink_.fetch_add(x, std::memory_order_relaxed);
      });
  }
  ~CpuHogs() {
    running_ = false;
    for (std::thread& thread : threads_) thread.join();
  }
  CpuHogs(const CpuHogs&) = delete;
  CpuHogs& operator=(const CpuHogs&) = delete;

 private:
  std::atomic<bool> running_{true};
  std::atomic<std::uint64_t> sink_{0};  // keeps the loop from being optimised away
  std::vector<std::thread> threads_;
};

}  // namespace lifmcr::test
