#pragma once
// Process-wide settings a command that runs the pipeline makes once, before
// it starts threads (lifmcr replay, record --publish, demo; the tests and
// benchmarks that stand in for them). The pipeline library never makes
// them itself: they change the whole process.
//
// - Allocator: the processing workers allocate and free buffers of
//   megabytes per frame (preview and TF encoding, OpenCV temporaries).
//   glibc serves those with mmap and returns them with munmap, and trims its
//   heap on free; both take the process's memory-map lock, and every page
//   fault of the Vicon and camera threads then waits behind it: Vicon packet
//   -> LCM p99 went from 0.2-0.7 ms to 6-19 ms with frames flowing
//   (bench_pipeline). Serving every block from the heap and never trimming
//   it keeps the freed memory in the process for the next frame instead
//   (config/memory_policy.h: blocks above 32 MB too; one arena, so a
//   worker's blocks above 64 MiB too, except under live registration, whose
//   workers only localise and get an arena each: ArenasFor). Only the commands
//   that run the pipeline: a one-shot command gains nothing from keeping
//   its heap (`lifmcr info` on a 90 MB CSV: 0.93 s of CPU with it, 0.88 s
//   without, against test_bad_input's 1 s bound).
// - TBB: it starts cores - 1 workers by default, keeping a slot for a master
//   thread that here (the command's loop) never helps; the pipeline's arena
//   has no master slot, so the process allows one worker more.

#include "config/memory_policy.h"

#include <memory>

namespace lifmcr::apps {

class ProcessSettings {
 public:
  // Applies both; the TBB limit holds while the returned object lives.
  // `arenas`: config/memory_policy.h (kPerThread for live registration,
  // ArenasFor); threads that allocated before keep the arena they have.
  static std::unique_ptr<ProcessSettings> ForPipeline(HeapArenas arenas = HeapArenas::kOne);
  // kPerThread where the pipeline localises under newest_wins (the workers
  // localise, the depth lane processes), else kOne.
  static HeapArenas ArenasFor(bool registration, bool newest_wins) {
    return registration && newest_wins ? HeapArenas::kPerThread : HeapArenas::kOne;
  }
  ~ProcessSettings();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  ProcessSettings();
};

}  // namespace lifmcr::apps
