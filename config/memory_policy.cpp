#include "config/memory_policy.h"

#include <malloc.h>
#include <sys/mman.h>

#include <algorithm>
#include <cstdint>
#include <thread>

namespace lifmcr {

void AdviseHugePages(void* data, std::size_t bytes) {
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + kHugePage - 1) & ~(kHugePage - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kHugePage - 1);
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
}

void KeepHeapResident(HeapArenas arenas) {
  // Each call only changes glibc's tunables; they fail (return 0) only for
  // out-of-range values, which these are not.
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, -1);
  // HeapArenas (memory_policy.h). glibc refuses 0 ("unset"): per thread
  // is its default spelled out, 8 arenas per core.
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  mallopt(M_ARENA_MAX, arenas == HeapArenas::kOne ? 1 : static_cast<int>(8 * cores));
}

}  // namespace lifmcr
