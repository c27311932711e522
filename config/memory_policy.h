#pragma once
// How a lifmcr process asks glibc's malloc for memory: large blocks from the
// heap, kept after free, instead of a fresh mmap per block.
//
// Processing and OpenCV allocate and free large buffers for every frame
// (virtual-depth maps, TF renders, SIFT pyramids: tens to hundreds of MB at
// the r32 preset). glibc serves a request above M_MMAP_THRESHOLD (at most
// 32 MiB) with a fresh mmap and returns it with munmap, so such a buffer is
// page-faulted in again, page by page, every frame. Where page faults are
// dear (a virtual machine) that dominates: reading one r32 raw frame
// (97 MB) into fresh 4 KiB pages took 340 ms on the 2-core CI machine,
// 9 ms into resident ones (bench/README.md, "Page faults").
// The usual recipe of real-time Linux programs: malloc never uses mmap
// (M_MMAP_MAX 0: a large block comes from the heap; one arena, M_ARENA_MAX
// 1, as a thread's arena maps its large blocks anyway) and never trims the
// heap (M_TRIM_THRESHOLD -1), so after the first frames the steady state touches
// no new pages; the price is that the heap keeps its high-water size.

#include <cstddef>

namespace lifmcr {

// Asks for transparent huge pages for the whole 2 MiB pages inside
// [data, data + bytes) before they are first written (a hint: where the
// kernel offers none, nothing changes). For large buffers filled once, such
// as a text file read whole: 512 times fewer page faults (reading a 90 MB
// CSV into fresh 4 KiB pages cost 0.4 s of system time on the CI machine).
void AdviseHugePages(void* data, std::size_t bytes);

// Call once, before threads are started (apps/pipeline/process_settings.h
// does for the commands that run the pipeline). Idempotent.
void KeepHeapResident();

}  // namespace lifmcr
