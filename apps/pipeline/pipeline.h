#pragma once
// The live pipeline: FrameSets and Vicon frames from the grab loop
// (acquisition/rig_controller.h, whose FrameSetAssembler is the run's only
// one) -> processing (FrameProcessor: the processing chain and the
// encodings, on a TBB flow graph node with bounded concurrency) -> the
// registration stage (processing/registration_stage.h; pass-through by
// default) -> the publisher (publisher.h, a serial node), which owns LCM.
// docs/architecture.md follows a frame through it.
//
// Skip policy (skip_when_busy; the rig file's processing.skip_policy:
// newest_wins): at most max_concurrency frames are processed at once and
// each camera has a one-deep slot for the frame that waits; a camera's
// frame arriving while its slot is taken replaces the waiting one, which is
// counted as skipped: the newest wins, so a camera's published view is never
// stale by more than one frame. A freed worker takes the slot of the camera
// served least recently, so no camera starves.
// Without skipping (block; replay --rate max) a frame waits in the
// pipeline's queue until a worker is free (Poll waits for one at most 50 ms,
// so the caller's loop notices a stop at once; Finish waits for all): the
// back-pressure reaches the replay driver through its frame pool, so every
// frame is processed. Either way every frame that enters is
// processed (and published), skipped, or failed, each counted: frames_in ==
// processed + skipped + failed once Finish returned. A recorder, when one
// runs, gets its frames before the pipeline does and never waits for it.
//
// Registration: under block the stage's Localize runs on the worker after
// processing; under newest_wins it runs first, on the raw frame, and the
// worker publishes the pose at once (POSE, and EXTRINSICS when the trigger's
// other pose is there); the frame goes on to the lens lane (per-lens depth
// and TF preview; a thread per worker, at most one per camera, below the
// workers' priority, up to lens_queue frames waiting per camera, the newest
// winning beyond), then, with that per-lens depth,
// to the depth lane (one thread at the lowest priority, newest wins per
// camera) whose dense map it seeds: a pose never waits for a depth, its own
// frame's or another's; the per-lens depth comes for every frame localised
// where the CPU suffices, the dense depth, TF and previews at the rate
// processing allows. Each lane publishes its products on its own thread as
// soon as they are computed, never waiting for a worker.
// Either way its poses are grouped per trigger (on the worker under
// newest_wins, the publishing node under block), and once the reference
// camera (reference_serial) and camera X both have a pose of a trigger,
// Relate gives c0_from_cx, published on <PREFIX>_<SERIAL>_EXTRINSICS.
// Every pose the stage gives (w0_from_cx, failed ones too) goes out on
// <PREFIX>_<SERIAL>_POSE as well; a process that holds only some of the rig's
// cameras (relate = false) publishes those only, and `lifmcr relate`
// (apps/pipeline/pose_pairing.h) pairs them across processes and hosts.
//
// Threads: AddFrameSet, SetSyncDrops and AddVicon from any thread (the grab
// loop's); a Vicon frame is published on the caller's thread, at once. Poll and Finish from
// one thread (the command's loop). Frames are processed and published on
// the pipeline's own TBB arena of `threads` workers at a lower priority
// (processing_nice), the lanes' frames on the lanes' threads. Process-wide
// settings (allocator, TBB's worker limit) are the command's:
// process_settings.h.

#include "apps/pipeline/frame_processor.h"
#include "apps/pipeline/publisher.h"
#include "config/error.h"
#include "config/rig_config.h"
#include "drivers/frame.h"
#include "drivers/vicon_source.h"
#include "processing/registration_stage.h"
#include "sync/frame_set_assembler.h"

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr::apps {

// One c0_from_cx as published on <PREFIX>_<SERIAL>_EXTRINSICS.
struct ExtrinsicsRecord {
  std::string reference_serial;  // camera 0
  std::string serial;            // camera X
  std::int64_t trigger_index = 0;
  processing::CameraPose c0_from_cx;
  std::int64_t arrival_ns = 0;  // camera X's frame at the pipeline (host clock)
  // How camera 0's pose of the trigger was made (its CameraPose::localisation;
  // c0_from_cx carries camera X's): not published, for bench_live's accuracy.
  std::string reference_localisation;
};

struct PipelineOptions {
  int max_concurrency = 2;  // frames processed at once, >= 1
  bool skip_when_busy = true;  // newest_wins; false: block
  int threads = 0;             // workers of the processing arena; 0 = all cores
  std::chrono::milliseconds stats_period{1000};
  // How much lower than the creating thread's the priority of the threads
  // that process and publish frames is (added to its nice value, at most 19;
  // 0 leaves them equal), so processing never delays the camera and Vicon
  // threads: on a saturated 2-core host a Vicon packet otherwise waits
  // milliseconds for a core.
  int processing_nice = 10;
  // The lens lane's threads (under lanes: newest_wins with a registration
  // stage), likewise added to the creating thread's nice value (at most 19):
  // 15, below the workers, so a relocalisation keeps its CPU (docs/processing.md,
  // "Live pipeline", for what 0, 5 and 15 gave).
  int lens_nice = 15;
  // Frames of a camera that wait for the lens lane (1..8): beyond that the
  // oldest waiting is skipped (newest wins). 4: a frame waits behind its
  // camera's previous ones instead of replacing them, so a lane held up for
  // up to four frame periods (both workers relocalising a timed replay's
  // first frames, 300-1000 ms each at medium, while the lane at nice +15
  // gets about a quarter of a core) catches up afterwards, when the workers
  // track, and every frame gets its per-lens depth, up to four frame periods
  // later. With 2 a timed replay's lane replaced 10-30 of 48 frames in its
  // first second (docs/processing.md, "Live pipeline"). Each waiting frame
  // holds one pooled buffer of its camera: FramesHeldPerCamera.
  int lens_queue = 4;
  // The depth lane's thread (nice 19 always) under SCHED_IDLE: it computes
  // only on a core that nothing else of the machine wants, so a dense map
  // never takes the CPU of the lens lane or the workers (at nice 19 it took
  // about a third of a core shared with a lens-lane thread at nice 15, CFS
  // weights 15 against 36). false: SCHED_OTHER at nice 19.
  bool depth_idle = true;
  // The stage after processing; null: processing::PassThroughStage.
  std::shared_ptr<processing::RegistrationStage> registration;
  // Camera 0 of the extrinsics (the reference map's camera), by serial;
  // empty: the camera of index 0. One of the assembler's serials when relate.
  std::string reference_serial;
  // Relate the cameras' poses of a trigger here (the process holds every
  // camera of the rig). false: the process holds only some (`--cameras`):
  // its poses go out on POSE only and `lifmcr relate` makes c0_from_cx, so
  // no pair is related twice.
  bool relate = true;
  // Called on the publishing thread after each extrinsics message (for
  // `--extrinsics-csv`); may be empty.
  std::function<void(const ExtrinsicsRecord&)> on_extrinsics;
  PublisherOptions publisher;
  // The rig file's processing: (threads, skip_policy) and lcm: sections;
  // preview_max_px and enabled are the processor's (PreviewOptionsFromRig).
  static PipelineOptions FromRig(const RigConfig& rig);
  // The most frames of one camera the pipeline holds at once, each in one
  // pooled buffer of its camera (a camera's pool needs these beyond its own
  // and a recorder's): the frame set the assembler completes (1), the
  // workers' computing ones and a waiting one (max_concurrency + 1), the lens
  // lane's waiting ones and those its threads compute or hold to publish in
  // order (lens_queue + max_concurrency), the depth lane's waiting and
  // computing ones (2). A frame in several lanes at once
  // holds one buffer, so this is a bound, not a count.
  int FramesHeldPerCamera() const;
  Status Check() const;  // every field; the message names the field
};

// processing.preview_max_px of the rig file.
PreviewOptions PreviewOptionsFromRig(const RigConfig& rig);

struct LatencySummary {
  std::uint64_t count = 0;
  double p50_ms = 0, p99_ms = 0, max_ms = 0;
};

struct PipelineReport {
  double elapsed_s = 0;
  std::uint64_t frames_in = 0;  // frames of emitted FrameSets given to processing
  // Seconds from the first frame in to the last (0 with fewer than two):
  // the rate the cameras delivered at is frames_in / frames_in_span_s, not
  // frames_in / elapsed_s (elapsed_s counts the set-up before the first
  // frame and the drain after the last).
  double frames_in_span_s = 0;
  std::uint64_t processed = 0;  // processed and published
  std::uint64_t skipped = 0;    // replaced in its camera's slot by a newer frame (skip policy)
  std::uint64_t failed = 0;     // processing or registration returned an error (last_error)
  std::uint64_t localized = 0;  // frames the registration stage gave a pose
  // Registration ahead of processing (a registration stage under
  // newest_wins): `processed` counts the frames localised (each pose
  // published by its worker); the depth lane processes (and publishes
  // previews, dense depth and TF of) the newest of the lens lane's frames
  // when it is free, the others are skipped there.
  std::uint64_t depth_processed = 0, depth_skipped = 0, depth_failed = 0;
  // Lanes: every frame taken goes to the lens lane (per-lens depth and TF
  // preview, newest wins per camera) as it is taken, beside its
  // localisation; a frame that shares the workers' image (a Bayer frame,
  // FrameProcessor::SharesRegistrationImage) once its pose is out or when
  // the workers skip it. There each is processed
  // (lens_frames), skipped for a newer frame of its camera (lens_skipped) or
  // failed; so frames_in == lens_frames + lens_skipped + lens_failed once
  // Finish returned. Why each skipped frame was: lens_replaced, a newer frame
  // of its camera came while it waited (the lane's threads were busy with
  // other frames); lens_stale, it came after a newer frame of its camera was
  // taken (only a frame that shares the workers' image, which reaches the
  // lane when its pose is out, after newer frames can have):
  // lens_skipped == lens_replaced + lens_stale.
  std::uint64_t lens_skipped = 0, lens_failed = 0;
  std::uint64_t lens_replaced = 0, lens_stale = 0;
  double depth_cpu_s = 0;  // CPU time of the depth lane's thread (its arena has no other)
  // Lanes: the dense maps the depth lane seeded with the lens lane's per-lens
  // depth (the others computed it again: the frame's per-lens depth had failed).
  std::uint64_t depth_seeded_by_lenses = 0;
  // Lanes, per frame a worker took: Localize's CPU time (with
  // ForRegistration: a Bayer frame's demosaicing; approximate: another
  // worker may run part of its parallel loops), and per frame of the lens
  // lane, ProcessLenses' CPU time (exact: its thread alone computes in its
  // arena) and its parts' CPU and wall time (the per-lens depth, the TF
  // preview at each lens's depth, the encodings).
  std::uint64_t worker_frames = 0, lens_frames = 0;
  double localize_cpu_s = 0, lens_cpu_s = 0;
  double lens_depth_s = 0, lens_preview_s = 0, lens_encode_s = 0;
  double lens_depth_cpu_s = 0, lens_preview_cpu_s = 0, lens_encode_cpu_s = 0;
  std::uint64_t frame_sets = 0, incomplete_sets = 0;
  // published_depth: TF-grid depth maps (the dense chain); published_lens_depth:
  // per-lens depth maps (every frame taken, when the processor makes them).
  std::uint64_t published_previews = 0, published_depth = 0, published_tf = 0;
  std::uint64_t published_lens_depth = 0;
  std::uint64_t published_vicon = 0, published_stats = 0, published_extrinsics = 0;
  std::uint64_t published_poses = 0;
  std::uint64_t publish_errors = 0;
  LatencySummary process;         // processing time per frame
  LatencySummary to_publication;  // frame arrival (host_ns) to its last message on LCM
  LatencySummary to_pose;  // frame arrival to its pose (and extrinsics) on LCM
  LatencySummary to_lens_depth;  // frame arrival to its per-lens depth on LCM (lanes)
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
  // `sync`: the options of the grab loop's assembler, whose FrameSets come
  // in (its serials are the camera indices; vicon_divider and vicon_f0 mark
  // the Vicon frames of triggers).
  static Expected<std::unique_ptr<Pipeline>> Create(FrameSetAssemblerOptions sync,
                                                    std::unique_ptr<FrameProcessor> processor,
                                                    PipelineOptions options);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  // A FrameSet of the grab loop's assembler (RigObserver::on_frame_set; any
  // thread): its frames are processed from the next Poll on.
  void AddFrameSet(FrameSet set);
  // The grab loop's sync losses so far (RigHealth::sync_drops), for the
  // report and the statistics message.
  void SetSyncDrops(const DropCounter& drops);
  void AddVicon(const ViconFrame& frame);
  // Takes the FrameSets given so far and hands their frames to processing (under
  // block, waiting at most 50 ms for a free worker; the rest wait for the
  // next Poll or Finish), and publishes the statistics when due.
  void Poll();
  // End of a pass (the grab loop stopped, its last sets given): hands what
  // is left to processing; under block waits for it, under newest_wins the
  // frames in processing go on beside the next pass (Finish and the
  // destructor wait for every frame); the next pass's grab loop starts a
  // fresh assembler and numbers its triggers from 0 again (--loop): poses
  // pair within a pass only. The counters go on.
  void EndPass();
  // EndPass, then the final statistics message.
  void Finish();
  PipelineReport Report() const;

 private:
  struct Impl;
  explicit Pipeline(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Channels of the default prefix (tests; publisher.h names every channel).
std::string CameraChannel(const std::string& serial, const std::string& kind);
inline constexpr const char* kViconChannel = "LIFMCR_VICON";
inline constexpr const char* kStatsChannel = "LIFMCR_STATS";

}  // namespace lifmcr::apps
