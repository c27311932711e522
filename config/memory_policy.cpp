#include "config/memory_policy.h"

#include <malloc.h>
#include <sys/mman.h>

#include <cstdint>

namespace lifmcr {

void AdviseHugePages(void* data, std::size_t bytes) {
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + kHugePage - 1) & ~(kHugePage - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kHugePage - 1);
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
}

void KeepHeapResident() {
  // Both calls only change glibc's tunables; they fail (return 0) only for
  // out-of-range values, which these are not.
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, -1);
  // One arena: a thread's own arena grows in heaps of at most 64 MiB, and
  // glibc maps a larger block for it with mmap whatever M_MMAP_MAX says
  // (and deletes an emptied heap), so a worker's 130 MB depth map would be
  // faulted in every frame. Small blocks still come from per-thread caches
  // (tcache) without the arena's lock.
  mallopt(M_ARENA_MAX, 1);
}

}  // namespace lifmcr
