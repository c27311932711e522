#pragma once
// The live pipeline: frames and Vicon frames from the drivers -> sync
// (FrameSetAssembler) -> processing (a TBB flow graph node with bounded
// concurrency) -> the LCM publisher (a serial node).
//
// Channels: LIFMCR_<SERIAL>_PREVIEW (preview_image_t), LIFMCR_<SERIAL>_DEPTH
// (depth_image_t), LIFMCR_<SERIAL>_TF (preview_image_t of the totally focused
// image), LIFMCR_VICON (vicon_frame_t), LIFMCR_STATS (pipeline_stats_t, about
// once a second and at the end). LIFMCR_<SERIAL>_EXTRINSICS is reserved for
// registration.
//
// Skip policy (skip_when_busy): at most max_concurrency frames are processed
// at once and each camera has a one-deep slot for the frame that waits; a
// camera's frame arriving while its slot is taken replaces the waiting one,
// which is counted as skipped: the newest wins, so a camera's published view
// is never stale by more than one frame. A freed worker takes the slot of the
// camera served least recently, so no camera starves.
// Without skipping (replay --rate max) Submit blocks until a worker is free:
// the back-pressure reaches the replay driver through its frame pool, so
// every frame is processed. Either way every frame that enters is processed
// (and published), skipped, or failed, each counted: frames_in == processed
// + skipped + failed once Finish returned. A recorder, when one runs, gets
// its frames before the pipeline does and never waits for it.
//
// Threads: AddFrame and AddVicon from any thread (driver threads); a Vicon
// frame is published on the caller's thread, at once. Poll and Finish from
// one thread (the command's loop). Frames are processed and published on
// the pipeline's own TBB arena, one worker per core, at a lower priority
// (PipelineOptions::processing_nice).

#include "apps/pipeline/frame_processor.h"
#include "config/error.h"
#include "drivers/frame.h"
#include "drivers/vicon_source.h"
#include "sync/frame_set_assembler.h"

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace lcm {
class LCM;
}

namespace lifmcr::apps {

struct PipelineOptions {
  std::string lcm_url;  // empty: LCM's default (LCM_DEFAULT_URL or udpm 239.255.76.67:7667)
  // An LCM instance to publish on instead of opening lcm_url (tests: one
  // memq:// instance shared with the subscriber); must outlive the pipeline.
  lcm::LCM* bus = nullptr;
  int max_concurrency = 2;  // frames processed at once, >= 1
  bool skip_when_busy = true;
  std::chrono::milliseconds stats_period{1000};
  // How much lower than the creating thread's the priority of the threads
  // that process and publish frames is (added to its nice value, at most 19;
  // 0 leaves them equal), so processing never delays the camera and Vicon
  // threads: on a saturated 2-core host a Vicon packet otherwise waits
  // milliseconds for a core.
  int processing_nice = 10;
  Status Check() const;
};

struct LatencySummary {
  std::uint64_t count = 0;
  double p50_ms = 0, p99_ms = 0, max_ms = 0;
};

struct PipelineReport {
  double elapsed_s = 0;
  std::uint64_t frames_in = 0;  // frames of emitted FrameSets given to processing
  std::uint64_t processed = 0;  // processed and published
  std::uint64_t skipped = 0;    // replaced in its camera's slot by a newer frame (skip policy)
  std::uint64_t failed = 0;     // processing returned an error (last_error)
  std::uint64_t frame_sets = 0, incomplete_sets = 0;
  std::uint64_t published_previews = 0, published_depth = 0, published_tf = 0;
  std::uint64_t published_vicon = 0, published_stats = 0;
  std::uint64_t publish_errors = 0;
  LatencySummary process;         // processing time per frame
  LatencySummary to_publication;  // frame arrival (host_ns) to its last message on LCM
  std::string drops;              // the assembler's DropCounter::OneLine
  std::uint64_t sync_lost = 0;    // DropCounter::lost
  std::string last_error;

  bool Accounted() const { return frames_in == processed + skipped + failed; }
  // "12.3s in 40 processed 38 skipped 2 failed 0 | 8.1 fps | latency p50 120 ms"
  std::string StatusLine() const;
  std::string FinalReport() const;  // several lines
};

class Pipeline {
 public:
  static Expected<std::unique_ptr<Pipeline>> Create(FrameSetAssemblerOptions sync,
                                                    std::unique_ptr<FrameProcessor> processor,
                                                    PipelineOptions options);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  void AddFrame(Frame frame);
  void AddVicon(const ViconFrame& frame);
  // Emits the ready FrameSets into processing (blocking without skipping)
  // and publishes the statistics when due.
  void Poll();
  // End of a pass: flushes the assembler, waits for processing and starts a
  // fresh assembler (for --loop); the counters go on.
  void EndPass();
  // EndPass, then the final statistics message.
  void Finish();
  PipelineReport Report() const;

 private:
  struct Impl;
  explicit Pipeline(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// The channel of `kind` ("PREVIEW", "DEPTH", "TF", "EXTRINSICS") for a camera.
std::string CameraChannel(const std::string& serial, const std::string& kind);
inline constexpr const char* kViconChannel = "LIFMCR_VICON";
inline constexpr const char* kStatsChannel = "LIFMCR_STATS";

}  // namespace lifmcr::apps
