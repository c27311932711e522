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
// (M_MMAP_MAX 0: a large block comes from the heap) and never trims the heap
// (M_TRIM_THRESHOLD -1), so after the first frames the steady state touches
// no new pages; the price is that the heap keeps its high-water size.
//
// Arenas (HeapArenas): glibc gives each thread an arena of its own (up to
// 8 per core). A thread arena grows in heaps of at most 64 MiB, and glibc
// maps a larger block for it with mmap whatever M_MMAP_MAX says, so such a
// block is faulted in afresh every time (r32's depth maps, 123 MiB, eight
// per frame). One arena (M_ARENA_MAX 1) keeps every block in the main heap,
// but then every thread's malloc beyond its small-block cache (tcache) takes
// one lock, and at r32 the localising workers lose most of their time to it
// (bench_live r32, live registration on a quiet machine: tracked frames
// 61-81 ms with one arena against 18 ms with one per thread, 1.46 -> 6.44
// extrinsics/s per camera; medium 7.30 -> 7.85). The likely mechanism: the
// lock's holder is often the depth lane at nice 19, whose large blocks make
// malloc walk long free lists, preempted while it holds the lock. So:
//   kOne        where frames are processed on the workers (block: replay
//               --rate max, live without a reference map): their depth maps
//               stay resident.
//   kPerThread  live registration (newest_wins with a reference map): the
//               workers localise (blocks far below 64 MiB) and only the
//               depth lane maps r32's largest blocks afresh.

#include <cstddef>

namespace lifmcr {

// Asks for transparent huge pages for the whole 2 MiB pages inside
// [data, data + bytes) before they are first written (a hint: where the
// kernel offers none, nothing changes). For large buffers filled once, such
// as a text file read whole: 512 times fewer page faults (reading a 90 MB
// CSV into fresh 4 KiB pages cost 0.4 s of system time on the CI machine).
void AdviseHugePages(void* data, std::size_t bytes);

enum class HeapArenas { kOne, kPerThread };

// Call once, before threads are started (apps/pipeline/process_settings.h
// does for the commands that run the pipeline). Idempotent for one value;
// the arena limit applies to threads that have not allocated yet.
void KeepHeapResident(HeapArenas arenas = HeapArenas::kOne);

}  // namespace lifmcr
