#include "config/memory_policy.h"

#include <malloc.h>

namespace lifmcr {

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
