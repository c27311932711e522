// The pipeline's scheduling (pipeline.h): the grab loop's FrameSets handed
// over under a mutex, a TBB flow graph for processing and publication, the
// publisher as the only way out.

#include "apps/pipeline/pipeline.h"

#include "config/thread_cpu.h"
#include "drivers/host_clock.h"

#include <spdlog/spdlog.h>
#include <tbb/flow_graph.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <deque>
#include <iterator>
#include <map>
#include <set>
#include <mutex>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/task_arena.h>
#include <oneapi/tbb/task_scheduler_observer.h>
#include <optional>
#include <sched.h>
#include <sstream>
#include <sys/resource.h>
#include <thread>
#include <sys/syscall.h>
#include <unistd.h>
#include <utility>

namespace lifmcr::apps {
namespace {

// Latencies kept for percentiles (the last kWindow; counts go on).
class LatencyWindow {
 public:
  void Add(double ms) {
    ++count_;
    if (samples_.size() < kWindow) {
      samples_.push_back(ms);
    } else {
      samples_[next_] = ms;
      next_ = (next_ + 1) % kWindow;
    }
  }
  LatencySummary Summary() const {
    LatencySummary s;
    s.count = count_;
    if (samples_.empty()) return s;
    std::vector<double> sorted = samples_;
    std::sort(sorted.begin(), sorted.end());
    auto at = [&](double q) {
      return sorted[std::min(sorted.size() - 1, static_cast<std::size_t>(q * sorted.size()))];
    };
    s.p50_ms = at(0.5);
    s.p99_ms = at(0.99);
    s.max_ms = sorted.back();
    return s;
  }

 private:
  static constexpr std::size_t kWindow = 4096;
  std::vector<double> samples_;
  std::size_t next_ = 0;
  std::uint64_t count_ = 0;
};

// Lowers the priority (raises the nice value) of every worker thread that
// enters the processing arena, so processing, which skips frames when it
// falls behind anyway, never starves the threads that must be on time: the
// camera and Vicon threads and the command's loop. Lowering a thread's own
// priority needs no privilege; a worker keeps it when it leaves the arena
// (raising it back would), which only matters to other TBB work of the process.
class WorkerPriority final : public tbb::task_scheduler_observer {
 public:
  // `nice`: the workers' nice value (the creating thread's plus the
  // pipeline's processing_nice, at most 19).
  WorkerPriority(tbb::task_arena& arena, int nice)
      : tbb::task_scheduler_observer(arena), nice_(nice) {
    observe(true);
  }
  ~WorkerPriority() override { observe(false); }
  void on_scheduler_entry(bool is_worker) override {
    if (!is_worker) return;
    const auto thread = static_cast<id_t>(syscall(SYS_gettid));
    errno = 0;
    const int current = getpriority(PRIO_PROCESS, thread);
    if (errno == 0 && current < nice_) (void)setpriority(PRIO_PROCESS, thread, nice_);
  }

 private:
  int nice_;
};

struct Job {
  Frame frame;
  std::int64_t trigger_index = 0;
  std::optional<std::int64_t> vicon_frame;  // of the trigger, when known
  std::int64_t arrival_ns = 0;  // host clock when the frame reached the pipeline
  std::uint64_t pass = 0;       // of a looped replay (Pipeline::EndPass): its triggers restart
  std::uint64_t camera_order = 0;  // the frame's place among its camera's frames taken
  // Lanes: offered to the lens lane when it was taken (Impl::SubmitQueued),
  // not again after its localisation or when the workers skip it.
  bool lens_offered = false;
};

struct Result {
  Job job;
  Expected<ProcessedFrame> processed{Error{"not processed"}};
  std::optional<processing::CameraPose> w0_from_cx;  // the registration stage's pose
};

}  // namespace

std::string CameraChannel(const std::string& serial, const std::string& kind) {
  return ChannelNames{}.Camera(serial, kind);
}

PipelineOptions PipelineOptions::FromRig(const RigConfig& rig) {
  PipelineOptions options;
  options.threads = rig.processing.threads;
  options.skip_when_busy = rig.processing.skip_policy == SkipPolicy::kNewestWins;
  options.publisher = PublisherOptions::FromRig(rig.lcm);
  return options;
}

PreviewOptions PreviewOptionsFromRig(const RigConfig& rig) {
  PreviewOptions options;
  options.max_side = rig.processing.preview_max_px;
  return options;
}

int PipelineOptions::FramesHeldPerCamera() const {
  return 1 + (max_concurrency + 1) + (lens_queue + max_concurrency) + 2;
}

Status PipelineOptions::Check() const {
  if (max_concurrency < 1 || max_concurrency > 64)
    return Error{"pipeline: max_concurrency: expected 1..64"};
  if (threads < 0 || threads > 1024) return Error{"pipeline: threads: expected 0..1024"};
  if (stats_period.count() <= 0) return Error{"pipeline: stats_period: expected > 0"};
  if (processing_nice < 0 || processing_nice > 19)
    return Error{"pipeline: processing_nice: expected 0..19"};
  if (lens_nice < 0 || lens_nice > 19) return Error{"pipeline: lens_nice: expected 0..19"};
  if (lens_queue < 1 || lens_queue > 8) return Error{"pipeline: lens_queue: expected 1..8"};
  // skip_when_busy: any value; registration: null is the pass-through stage.
  if (Status s = publisher.Check(); !s) return s;
  return Status::Ok();
}

struct Pipeline::Impl {
  FrameSetAssemblerOptions sync_options;
  PipelineOptions options;
  std::unique_ptr<FrameProcessor> processor;
  std::shared_ptr<processing::RegistrationStage> registration;
  bool localizes = false;  // a stage other than the pass-through
  // Registration ahead of processing (a stage, newest_wins): the workers
  // localise every frame they take from the raw frame and offer it to the
  // depth lane, one low-priority thread that processes the newest offered
  // frame of the camera served least recently (the others are skipped), so
  // extrinsics keep the frame rate while depth, TF and previews are
  // published at the rate processing allows.
  bool lanes = false;
  int reference_camera = 0;  // camera index of options.reference_serial
  // Block with a registration stage: each camera's turn to localise
  // (RunProcess), by Job::camera_order; `taken` numbers the frames queued
  // (Poll's thread).
  std::mutex turn_mutex;
  std::condition_variable turn_cv;
  std::map<int, std::uint64_t> localize_turn;
  std::map<int, std::uint64_t> taken;
  std::string reference_serial;  // camera 0's serial (POSE messages name it)
  std::unique_ptr<Publisher> publisher;

  // The grab loop's hand-over (sync_mutex): sets waiting for Poll, the
  // losses of this pass's assembler and of the earlier passes', and f0 (the
  // Vicon frame of trigger 0) as the sets say it.
  std::mutex sync_mutex;
  std::vector<FrameSet> sets_in;
  DropCounter drops_this_pass;
  DropCounter drops_before;
  std::optional<std::int64_t> sets_f0;

  DropCounter SyncDrops() const {  // sync_mutex held
    DropCounter drops = drops_before;
    for (int k = 0; k < kDropKindCount; ++k)
      drops.Add(static_cast<DropKind>(k), drops_this_pass[static_cast<DropKind>(k)]);
    return drops;
  }
  std::vector<FrameSet> TakeSets() {
    std::lock_guard lock(sync_mutex);
    return std::exchange(sets_in, {});
  }

  // Processing gets `threads` workers: its own arena has no master slot (the
  // command's loop never helps), and the process allows the workers to fill
  // it (process_settings.h).
  std::unique_ptr<tbb::task_arena> arena;
  std::unique_ptr<WorkerPriority> worker_priority;
  std::unique_ptr<tbb::flow::graph> graph;  // made inside `arena`: its tasks run there
  std::unique_ptr<tbb::flow::function_node<Job, Result>> process_node;
  std::unique_ptr<tbb::flow::function_node<Result>> publish_node;

  // Skip policy state.
  std::mutex slot_mutex;
  std::condition_variable slot_cv;
  int in_flight = 0;
  std::map<int, Job> slots;             // by camera index: the newest frame waiting
  std::map<int, std::uint64_t> served;  // by camera index: when it last got a worker
  std::uint64_t serve_count = 0;
  // Registration (lanes) pairs the cameras' frames: c0_from_cx needs both
  // cameras' poses of one trigger, and each camera's newest frame alone
  // seldom shares its trigger with the other's once localisations take
  // different times (bench_live r32, every frame relocalised: 248 frames
  // localised, 39 pairs). The trigger a worker took a frame of last
  // (pairing_key: pass, trigger) goes first among the waiting frames, and a
  // waiting frame of that trigger is not replaced by its camera's newer one,
  // which waits behind it in `later` (newest wins there) until it is taken.
  std::map<int, Job> later;  // by camera index; only where slots holds a frame
  std::optional<std::pair<std::uint64_t, std::int64_t>> pairing_key;
  static std::pair<std::uint64_t, std::int64_t> Key(const Job& job) {
    return {job.pass, job.trigger_index};
  }
  // A worker took `job` (slot_mutex held).
  void Took(const Job& job) {
    if (!lanes) return;
    pairing_key = Key(job);
    const int camera = job.frame.camera_index;
    if (auto l = later.find(camera); l != later.end() && !slots.count(camera)) {
      slots.insert_or_assign(camera, std::move(l->second));
      later.erase(l);
    }
  }

  // Registration poses by pass and trigger, then camera index (publishing
  // node only): a loop's passes number their triggers from 0 again, and
  // under newest_wins a pass's last frames may be published after the next
  // pass's first.
  struct TriggerPoses {
    struct Entry {
      std::string serial;
      processing::CameraPose w0_from_cx;
      std::int64_t arrival_ns = 0;
    };
    std::map<int, Entry> by_camera;
  };
  std::map<std::pair<std::uint64_t, std::int64_t>, TriggerPoses> poses;  // relate_mutex
  // Relate's state (poses, the stage's Relate): the workers publish poses
  // under lanes, the publishing node under block.
  std::mutex relate_mutex;
  std::uint64_t pass = 0;  // the pass whose frames come in (Poll's thread)
  static constexpr std::size_t kTriggersKept = 64;

  // Counted on the Vicon thread without a lock that a lower-priority worker
  // takes: a worker preempted while holding it would hold up Vicon.
  std::atomic<std::uint64_t> published_vicon{0};
  // Counters (report_mutex).
  mutable std::mutex report_mutex;
  PipelineReport report;
  LatencyWindow process_latency, publication_latency;
  LatencyWindow pose_latency;  // frame arrival -> its pose published
  LatencyWindow lens_latency;  // frame arrival -> its per-lens depth published (lens lane)
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point first_frame_in;  // report_mutex
  std::chrono::steady_clock::time_point next_stats = start;
  std::uint64_t stats_last_processed = 0;
  std::chrono::steady_clock::time_point stats_last_time = start;

  // A frame offered to a lane: the frame, its registration input (the image
  // the localisation took: a Bayer frame's demosaiced copy, made once) and,
  // for the depth lane, what ProcessLenses made of it (the per-lens depth's
  // pooled workspace and the demosaiced image: shared, not copied), so the
  // dense map is seeded without estimating it again.
  struct Offer {
    Job job;
    std::optional<RegistrationInput> input;
    ProcessedFrame from_lenses;  // lenses and demosaiced only; empty: none
  };
  // A lane (lanes): the newest frame offered per camera, taken by the lane's
  // threads, the camera served least recently first; each thread computes in
  // an arena of its own (one slot, reserved for it): open to the workers, a
  // worker inside a lane's parallel loop finished its chunk before it took
  // the next frame to localise, and a lane's thread would help the workers.
  struct Lane {
    std::mutex mutex;
    std::condition_variable cv;
    // By camera index: the frames waiting, oldest first, at most `depth`
    // (an empty queue is erased, so `slots.empty()` means none waits).
    std::map<int, std::deque<Offer>> slots;
    std::size_t depth = 1;
    std::map<int, std::uint64_t> served;
    std::uint64_t serve_count = 0;
    // Per camera: 1 + the newest Job::camera_order the lane took (OfferTo).
    std::map<int, std::uint64_t> taken_before;
    // Frames the lane took and whose products are not published yet: the
    // one each thread processes or publishes (PublishLaneFrame). A count,
    // not a flag set when the lane took a frame and cleared when one was
    // published: the flag let WaitIdle return while the lane processed the
    // next (when the publishing node published the lanes' frames, that
    // frame reached it after the graph's nodes were destroyed: bench_live,
    // segmentation fault at the run's end).
    int held = 0;
    // By camera: the Job::camera_order of its frames on the lane's threads
    // (computing, not yet parked or published). A free thread takes a camera
    // with none first, else the next waiting frame of a camera another
    // thread computes (Take): with one camera's thread starved on a core a
    // relocalising worker holds, the other thread no longer idles while that
    // camera's frames wait and are replaced (a timed replay: one camera's
    // frames at 50 ms each, the other's at 400 ms, its queue overflowing).
    std::map<int, std::set<std::uint64_t>> computing;
    // By camera: frames computed while an older frame of the camera was still
    // computing, parked by camera_order until it is published, and the
    // cameras one thread publishes now (PublishLaneFrame): each camera's
    // products go out in its frames' order (two threads on one camera's
    // frames, the newer one's per-lens depth went out first).
    std::map<int, std::map<std::uint64_t, Result>> parked;
    std::set<int> publishing;
    bool stop = false;
    std::vector<std::unique_ptr<tbb::task_arena>> arenas;  // one per thread
    std::vector<std::thread> threads;
    // What a frame the lane published counts (PublishLaneFrame).
    struct Counts {
      std::uint64_t PipelineReport::*published;  // report_mutex
      std::uint64_t PipelineReport::*failed;     // report_mutex
      const char* what;                          // the error's prefix in last_error
      LatencyWindow* latency;  // frame arrival -> published (report_mutex); null: none
    };
    const Counts counts;
    explicit Lane(Counts c) : counts(c) {}
  };
  // The per-lens depth and TF preview of every frame taken, offered as it
  // is taken, beside its localisation (a frame that shares the workers'
  // image once its pose is out, or when the workers skip it), below the
  // workers' priority and above the depth lane's. Offered after its pose, a
  // frame the workers held waited while the lane could have computed it,
  // and one localised after its camera's newer frame came too late (stale).
  //
  // A lane of its own rather than on the worker after the pose: at medium
  // the per-lens depth and its preview cost several times a tracked
  // frame's localisation (docs/processing.md, "Live pipeline"), and on the
  // worker every frame waiting for a worker waited for a per-lens estimate
  // too, so the poses (the extrinsics) fell with the per-lens work. Here a
  // worker is free for the next frame as soon as it published a pose, and
  // the lane takes the newest frame per camera. Below the
  // workers: at their priority the lane took the CPU a relocalisation
  // needs, poses fell behind their frames, fewer frames could be tracked
  // and the extrinsics fell (medium, quiet: 2.65 against 4.4-4.8 per second
  // per camera). Each frame is counted: lens processed, skipped (replaced
  // by its camera's newer frame) or failed.
  Lane lens_lane{{&PipelineReport::lens_frames, &PipelineReport::lens_failed,
                  "per-lens depth: ", &lens_latency}};
  // The dense map, at the lowest priority: depth takes what is left.
  Lane depth_lane{{&PipelineReport::depth_processed, &PipelineReport::depth_failed, "", nullptr}};

  // Offers `offer` to `lane`: it waits behind the frames of its camera
  // already there, in its camera's order (Job::camera_order); with more
  // than the lane's depth waiting, the oldest of them is skipped (counted
  // in `*skipped`): newest wins beyond the depth. So is a frame older than
  // one the lane took of its camera (each camera's products go out in its
  // frames' order). The lens lane gets the frames the workers skip when
  // they come and the ones they localised when their pose is out, so an
  // older frame can come after a newer one.
  // `stale`, `replaced` (may be null): the skipped frame's reason, counted
  // too (the lens lane's; PipelineReport).
  void OfferTo(Lane& lane, Impl::Offer offer, std::uint64_t* skipped,
               std::uint64_t* stale = nullptr, std::uint64_t* replaced = nullptr) {
    {
      std::lock_guard lock(lane.mutex);
      const int camera = offer.job.frame.camera_index;
      auto taken = lane.taken_before.find(camera);
      if (taken != lane.taken_before.end() && offer.job.camera_order < taken->second) {
        std::lock_guard r(report_mutex);
        ++*skipped;
        if (stale) ++*stale;
      } else {
        std::deque<Offer>& queue = lane.slots[camera];
        auto at = queue.end();
        while (at != queue.begin() && std::prev(at)->job.camera_order > offer.job.camera_order)
          --at;
        queue.insert(at, std::move(offer));
        if (queue.size() > lane.depth) {
          // The oldest waiting goes: a frame the lane took since is newer
          // than every one waiting, so it is not stale here.
          queue.pop_front();
          std::lock_guard r(report_mutex);
          ++*skipped;
          if (replaced) ++*replaced;
        }
      }
    }
    lane.cv.notify_all();
  }

  // A lane's next frame (held), or nothing when the lane stops.
  std::optional<Impl::Offer> Take(Lane& lane) {
    std::unique_lock lock(lane.mutex);
    auto pick = lane.slots.end();
    lane.cv.wait(lock, [&] {
      if (lane.stop) return true;
      // The camera served longest ago among those with no frame on a
      // thread, else among all with a frame waiting.
      pick = lane.slots.end();
      bool pick_idle = false;
      for (auto it = lane.slots.begin(); it != lane.slots.end(); ++it) {
        const auto c = lane.computing.find(it->first);
        const bool idle = c == lane.computing.end() || c->second.empty();
        if (pick == lane.slots.end() || (idle && !pick_idle) ||
            (idle == pick_idle && lane.served[it->first] < lane.served[pick->first])) {
          pick = it;
          pick_idle = idle;
        }
      }
      return pick != lane.slots.end();
    });
    if (lane.stop) return std::nullopt;
    Impl::Offer offer = std::move(pick->second.front());
    pick->second.pop_front();
    if (pick->second.empty()) lane.slots.erase(pick);
    lane.served[offer.job.frame.camera_index] = ++lane.serve_count;
    lane.taken_before[offer.job.frame.camera_index] = offer.job.camera_order + 1;
    lane.computing[offer.job.frame.camera_index].insert(offer.job.camera_order);
    ++lane.held;
    return offer;
  }

  // A lane's frame, on the lane's thread: its products published and
  // counted (the lane's frames or failures, and every message by kind),
  // then no longer held. Not through the graph's publishing node: that node
  // runs on the workers, so while both relocalised (300-450 ms at medium) a
  // per-lens depth or a dense map already computed waited for one of them.
  // Publisher::PublishFrame takes the bus's lock for each message.
  // In each camera's frames' order: a frame computed while an older one of
  // its camera is still computing on another thread is parked, and the
  // thread that publishes the older one publishes it after (Lane::parked).
  void PublishLaneFrame(Lane& lane, Result result) {
    const int camera = result.job.frame.camera_index;
    std::unique_lock lock(lane.mutex);
    lane.computing[camera].erase(result.job.camera_order);
    lane.parked[camera].emplace(result.job.camera_order, std::move(result));
    if (lane.publishing.count(camera)) return;  // that thread publishes it
    lane.publishing.insert(camera);
    std::map<std::uint64_t, Result>& parked = lane.parked[camera];
    const std::set<std::uint64_t>& computing = lane.computing[camera];
    int published = 0;
    while (!parked.empty() &&
           (computing.empty() || parked.begin()->first < *computing.begin())) {
      Result next = std::move(parked.begin()->second);
      parked.erase(parked.begin());
      lock.unlock();
      PublishOne(lane, next);
      ++published;
      lock.lock();
    }
    lane.publishing.erase(camera);
    lane.held -= published;
    lock.unlock();
    lane.cv.notify_all();
  }

  // One of a lane's frames published (or its failure counted), lane.mutex
  // not held.
  void PublishOne(Lane& lane, const Result& result) {
    const Job& job = result.job;
    if (!result.processed) {
      std::lock_guard r(report_mutex);
      ++(report.*lane.counts.failed);
      report.last_error = job.frame.serial + " frame " + std::to_string(job.frame.frame_id) +
                          ": " + lane.counts.what + result.processed.error().message;
      return;
    }
    const Publisher::FrameCounts counts = publisher->PublishFrame(
        FrameMeta{job.frame.serial, job.frame.frame_id, job.trigger_index}, *result.processed);
    const double to_pub_ms = static_cast<double>(HostRealtimeNs() - job.arrival_ns) / 1e6;
    std::lock_guard r(report_mutex);
    ++(report.*lane.counts.published);
    CountPublished(counts);
    if (lane.counts.latency) lane.counts.latency->Add(to_pub_ms);
  }

  // A frame's messages by kind (report_mutex held).
  void CountPublished(const Publisher::FrameCounts& counts) {
    report.published_previews += counts.previews;
    report.published_depth += counts.depth;
    report.published_lens_depth += counts.lens_depth;
    report.published_tf += counts.tf;
  }

  // `idle`: the threads compute under SCHED_IDLE (PipelineOptions::depth_idle).
  void StartLane(Lane& lane, int threads, int nice,
                 void (Impl::*loop)(tbb::task_arena&, bool), bool idle = false) {
    for (int k = 0; k < threads; ++k) {
      lane.arenas.push_back(std::make_unique<tbb::task_arena>(1, /*reserved_for_masters=*/1,
                                                              tbb::task_arena::priority::low));
      tbb::task_arena* arena = lane.arenas.back().get();
      lane.threads.emplace_back([this, nice, loop, arena, idle] {
        (void)setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), nice);
        (this->*loop)(*arena, idle);
      });
    }
  }

  void StopLane(Lane& lane) {
    {
      std::lock_guard lock(lane.mutex);
      lane.stop = true;
    }
    lane.cv.notify_all();
    for (std::thread& thread : lane.threads) thread.join();
    lane.threads.clear();
  }

  // The lens lane's thread: the per-lens depth and TF preview of a frame
  // (with the workers' registration input where they localised it),
  // published; then the frame offered to the depth lane with them.
  void LensLoop(tbb::task_arena& arena, bool /*idle*/) {
    while (std::optional<Impl::Offer> offer = Take(lens_lane)) {
      Result result{std::move(offer->job), Error{""}, std::nullopt};
      const auto start = std::chrono::steady_clock::now();
      const double cpu_start = ThreadCpuSeconds();
      arena.execute([&] {
        result.processed = processor->ProcessLenses(
            result.job.frame, offer->input ? &*offer->input : nullptr);
      });
      // The lane's thread alone computes in its arena: this is the frame's CPU.
      const double cpu = ThreadCpuSeconds() - cpu_start;
      Impl::Offer dense{result.job, std::nullopt, ProcessedFrame{}};
      if (result.processed) {
        ProcessedFrame& p = *result.processed;
        p.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        dense.from_lenses.lenses = std::move(p.lenses);  // the publication needs the encodings only
        dense.from_lenses.demosaiced = p.demosaiced;
        std::lock_guard r(report_mutex);
        report.lens_cpu_s += cpu;
        report.lens_depth_s += p.lens_depth_s;
        report.lens_preview_s += p.lens_preview_s;
        report.lens_encode_s += p.lens_encode_s;
        report.lens_depth_cpu_s += p.lens_depth_cpu_s;
        report.lens_preview_cpu_s += p.lens_preview_cpu_s;
        report.lens_encode_cpu_s += p.lens_encode_cpu_s;
      } else if (offer->input) {
        dense.from_lenses.demosaiced = offer->input->demosaiced;
      }
      offer.reset();
      OfferTo(depth_lane, std::move(dense), &report.depth_skipped);
      PublishLaneFrame(lens_lane, std::move(result));
    }
  }

  // The depth lane's thread: the dense chain of a frame, seeded by the lens
  // lane's per-lens depth of it.
  //
  // `idle`: the dense chain is computed under SCHED_IDLE, on the CPU that
  // neither the workers nor the lens lane want; the thread returns to
  // SCHED_OTHER (its nice 19) to publish, so a preempted idle thread never
  // holds the bus's lock the poses and per-lens depth need (nor the chain's
  // short locks: taken inside Process, released before it returns).
  void DepthLoop(tbb::task_arena& arena, bool idle) {
    const auto policy = [](int which) {
      sched_param param{};
      param.sched_priority = 0;
      return sched_setscheduler(0, which, &param) == 0;
    };
    if (idle && !policy(SCHED_IDLE)) {
      spdlog::warn("pipeline: the depth lane stays at nice 19: SCHED_IDLE refused ({})",
                   std::strerror(errno));
      idle = false;
    }
    // Back to SCHED_OTHER needs the nice value within RLIMIT_NICE (19 is);
    // where refused, the lane computes and publishes idle.
    if (idle && !policy(SCHED_OTHER)) {
      spdlog::warn("pipeline: the depth lane computes and publishes under SCHED_IDLE ({})",
                   std::strerror(errno));
      (void)policy(SCHED_IDLE);
      idle = false;
    }
    while (std::optional<Impl::Offer> offer = Take(depth_lane)) {
      Result result{std::move(offer->job), Error{""}, std::nullopt};
      // The lens lane published this frame's per-lens depth already; it
      // seeds the dense map here (no second per-lens estimate).
      const ProcessedFrame* lenses = offer->from_lenses.lenses ? &offer->from_lenses : nullptr;
      if (idle) (void)policy(SCHED_IDLE);
      arena.execute(
          [&] { result.processed = processor->ProcessDense(result.job.frame, lenses); });
      if (idle) (void)policy(SCHED_OTHER);
      offer.reset();  // the per-lens workspace back to its pool
      {
        // The lane's thread alone computes in its arena: its CPU time is the lane's.
        const double cpu = ThreadCpuSeconds();
        std::lock_guard r(report_mutex);
        report.depth_cpu_s = cpu;
        if (lenses != nullptr) ++report.depth_seeded_by_lenses;
      }
      PublishLaneFrame(depth_lane, std::move(result));
    }
  }

  Result RunProcess(Job job) {
    if (lanes) return RunRegistration(std::move(job));
    Result result{std::move(job), Error{""}, std::nullopt};
    result.processed = processor->Process(result.job.frame);
    // Offline (block): a camera's frames are localised in the order they
    // came, whichever worker finished its processing first, so each pose
    // tracks from its predecessor's and a camera's poses do not depend on
    // the other cameras the process holds (a host of a rig on several hosts
    // gets the poses one process of all cameras gets). The workers take
    // frames in that order, so the one waited for is already on a worker.
    const int camera = result.job.frame.camera_index;
    if (localizes) {
      std::unique_lock lock(turn_mutex);
      turn_cv.wait(lock, [&] { return localize_turn[camera] == result.job.camera_order; });
    }
    if (localizes && result.processed && result.processed->products) {
      processing::StageFrame frame;
      frame.products = result.processed->products.get();
      frame.camera = result.processed->camera;
      frame.raw = result.processed->products->prepared.raw;
      Localize(result, std::move(frame));
    }
    if (localizes) {
      {
        std::lock_guard lock(turn_mutex);
        ++localize_turn[camera];
      }
      turn_cv.notify_all();
    }
    return result;
  }

  // Registers the job's frame (`frame` holds what the caller has: raw
  // pixels, camera, products); the pose or the error goes into `result`.
  void Localize(Result& result, processing::StageFrame frame) {
    frame.camera_index = result.job.frame.camera_index;
    frame.serial = result.job.frame.serial;
    frame.trigger_index = result.job.trigger_index;
    frame.vicon_frame = result.job.vicon_frame;
    frame.host_ns = result.job.frame.host_ns;
    auto pose = registration->Localize(frame);
    if (!pose)
      result.processed =
          Error{"registration (" + registration->name() + "): " + pose.error().message};
    else
      result.w0_from_cx = std::move(*pose);
  }

  // Lanes: the frame localised from its raw pixels and its pose published at
  // once (PublishPose, on this thread, before any depth of the frame), then
  // the frame offered to the lens lane.
  Result RunRegistration(Job job) {
    const auto start = std::chrono::steady_clock::now();
    Result result{std::move(job), ProcessedFrame{}, std::nullopt};
    const double cpu_start = ThreadCpuSeconds();
    auto input = processor->ForRegistration(result.job.frame);
    if (!input) {
      result.processed = input.error();
    } else if (input->camera) {
      processing::StageFrame frame;
      frame.raw = input->image;
      frame.camera = input->camera;
      Localize(result, std::move(frame));
    }
    const double localize_cpu = ThreadCpuSeconds() - cpu_start;
    if (result.processed && result.w0_from_cx) {
      PublishPose(result.job, *result.w0_from_cx);
      result.w0_from_cx.reset();  // published
    }
    {
      std::lock_guard r(report_mutex);
      ++report.worker_frames;
      report.localize_cpu_s += localize_cpu;
    }
    if (result.processed)
      result.processed->seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // Every frame to the lens lane, localised or not: its per-lens depth
    // needs no pose. Most went there when they were taken; here the ones
    // that share the workers' image (a Bayer frame demosaiced once).
    if (!result.job.lens_offered) {
      Impl::Offer offer{result.job, std::nullopt, ProcessedFrame{}};
      if (input) offer.input = std::move(*input);
      OfferTo(lens_lane, std::move(offer), &report.lens_skipped, &report.lens_stale,
              &report.lens_replaced);
    }
    return result;
  }

  // A frame's pose published on its POSE channel and, related to the other
  // cameras' poses of its trigger, as extrinsics; counted. On the worker
  // that localised it (lanes) or the publishing node (block).
  void PublishPose(const Job& job, const processing::CameraPose& w0_from_cx) {
    std::uint64_t extrinsics = 0;
    {
      std::lock_guard lock(relate_mutex);
      extrinsics = Relate(job, w0_from_cx);
    }
    const double ms = static_cast<double>(HostRealtimeNs() - job.arrival_ns) / 1e6;
    std::lock_guard r(report_mutex);
    report.published_extrinsics += extrinsics;
    ++report.published_poses;
    ++report.localized;
    pose_latency.Add(ms);
  }

  // Camera X's pose of a trigger: related to camera 0's of the same trigger
  // once both are there, and published (relate_mutex held: the workers
  // publish their poses themselves under lanes).
  std::uint64_t Relate(const Job& job, const processing::CameraPose& w0_from_cx) {
    publisher->PublishPose(PoseRecord{job.frame.serial, reference_serial, job.trigger_index,
                                      static_cast<std::int64_t>(job.pass), job.frame.frame_id,
                                      job.arrival_ns, w0_from_cx});
    if (!options.relate) return 0;
    TriggerPoses& trigger = poses[{job.pass, job.trigger_index}];
    const int camera = job.frame.camera_index;
    trigger.by_camera[camera] = {job.frame.serial, w0_from_cx, job.arrival_ns};
    std::uint64_t published = 0;
    auto reference = trigger.by_camera.find(reference_camera);
    if (reference != trigger.by_camera.end()) {
      const TriggerPoses::Entry& zero = reference->second;
      for (const auto& [index, entry] : trigger.by_camera) {
        if (index == reference_camera || (camera != reference_camera && index != camera))
          continue;
        ExtrinsicsRecord record{zero.serial, entry.serial, job.trigger_index,
                                registration->Relate(entry.serial, job.trigger_index,
                                                     zero.w0_from_cx, entry.w0_from_cx),
                                entry.arrival_ns, zero.w0_from_cx.localisation};
        publisher->PublishExtrinsics(record.reference_serial, record.serial,
                                     record.trigger_index, record.c0_from_cx);
        if (options.on_extrinsics) options.on_extrinsics(record);
        ++published;
      }
    }
    while (poses.size() > kTriggersKept) poses.erase(poses.begin());
    return published;
  }

  void RunPublish(Result result) {
    const Job& job = result.job;
    if (!result.processed) {
      std::lock_guard r(report_mutex);
      ++report.failed;
      report.last_error = job.frame.serial + " frame " + std::to_string(job.frame.frame_id) + ": " +
                          result.processed.error().message;
    } else {
      const ProcessedFrame& p = *result.processed;
      const Publisher::FrameCounts counts = publisher->PublishFrame(
          FrameMeta{job.frame.serial, job.frame.frame_id, job.trigger_index}, p);
      if (result.w0_from_cx) PublishPose(job, *result.w0_from_cx);
      const double to_pub_ms = static_cast<double>(HostRealtimeNs() - job.arrival_ns) / 1e6;
      std::lock_guard r(report_mutex);
      ++report.processed;
      CountPublished(counts);
      process_latency.Add(p.seconds * 1e3);
      publication_latency.Add(to_pub_ms);
    }
    // The worker's token goes to the newest waiting frame, else it ends.
    // Under slot_mutex, so Submit never leaves a frame in the slot with no
    // token to take it.
    std::optional<Job> next;
    {
      std::lock_guard lock(slot_mutex);
      if (!slots.empty()) {
        // The camera served least recently goes first (its last frame taken
        // into processing is the oldest), so no camera starves.
        // Registration: the frame that completes a pair first.
        auto pick = slots.end();
        if (lanes && pairing_key) {
          for (auto it = slots.begin(); it != slots.end(); ++it)
            if (Key(it->second) == *pairing_key) pick = it;
        }
        if (pick == slots.end()) {
          pick = slots.begin();
          for (auto it = slots.begin(); it != slots.end(); ++it)
            if (served[it->first] < served[pick->first]) pick = it;
        }
        next = std::move(pick->second);
        slots.erase(pick);
        served[next->frame.camera_index] = ++serve_count;
        Took(*next);
      } else {
        --in_flight;
      }
      slot_cv.notify_all();
    }
    if (next) process_node->try_put(std::move(*next));
  }

  // One frame into processing, by the skip policy.
  // Frames taken from the FrameSets, waiting to be handed to processing
  // (Poll's thread only). Under newest_wins they go at once; under block
  // they wait here for a free worker, still holding their pooled buffers,
  // so the back-pressure reaches a replay driver as before, while Poll
  // returns to the command's loop (a stop or the end of a sequence is
  // noticed at once; Finish hands on what is left: nothing taken is lost).
  std::deque<Job> queued;

  // Hands the queued frames to processing. Without skipping, waits for a
  // free worker until `deadline` (none: as long as it takes); what is left
  // waits for the next call.
  void SubmitQueued(std::optional<std::chrono::steady_clock::time_point> deadline) {
    while (!queued.empty()) {
      std::unique_lock lock(slot_mutex);
      if (!options.skip_when_busy) {
        const auto free = [&] { return in_flight < options.max_concurrency; };
        if (!deadline) {
          slot_cv.wait(lock, free);
        } else if (!slot_cv.wait_until(lock, *deadline, free)) {
          return;
        }
      }
      Job job = std::move(queued.front());
      queued.pop_front();
      // Lanes: the frame to the lens lane as it is taken, beside its
      // localisation (its per-lens depth needs no pose): offered after its
      // pose, a frame waited for a worker while the lane could have
      // computed it (a timed replay's first frames, while both cameras
      // relocalise), and a frame localised after its camera's newer one (two
      // workers on one camera) came to the lane after that one and was
      // skipped as stale. Not a frame whose image the workers make and the
      // lane reuses (FrameProcessor::SharesRegistrationImage): it goes with
      // their input once localised.
      if (lanes && !processor->SharesRegistrationImage(job.frame)) {
        job.lens_offered = true;
        lock.unlock();
        OfferTo(lens_lane, Impl::Offer{job, std::nullopt, ProcessedFrame{}}, &report.lens_skipped,
                &report.lens_stale, &report.lens_replaced);
        lock.lock();
      }
      if (in_flight < options.max_concurrency) {
        ++in_flight;
        served[job.frame.camera_index] = ++serve_count;
        Took(job);
        lock.unlock();
        process_node->try_put(std::move(job));
        continue;
      }
      const int camera = job.frame.camera_index;
      // The frame the workers skip (replaced by this newer one), if any.
      std::optional<Job> replaced;
      auto waiting = slots.find(camera);
      // The waiting frame completes a pair: the newer one waits behind it.
      std::map<int, Job>& into = lanes && waiting != slots.end() && pairing_key &&
                                         Key(waiting->second) == *pairing_key
                                     ? later
                                     : slots;
      if (auto old = into.find(camera); old != into.end()) {
        {
          std::lock_guard r(report_mutex);
          ++report.skipped;
        }
        replaced = std::move(old->second);
        old->second = std::move(job);
      } else {
        into.emplace(camera, std::move(job));
      }
      lock.unlock();
      // Lanes: the lens lane takes it (newest wins there too), so a frame
      // the workers skip still gets its per-lens depth when the lane has
      // the time.
      if (replaced && lanes && !replaced->lens_offered)
        OfferTo(lens_lane, Impl::Offer{std::move(*replaced), std::nullopt, ProcessedFrame{}},
                &report.lens_skipped, &report.lens_stale, &report.lens_replaced);
    }
  }

  void QueueSets(std::vector<FrameSet> sets) {
    for (FrameSet& set : sets) {
      {
        std::lock_guard r(report_mutex);
        ++report.frame_sets;
        if (!set.missing.empty()) ++report.incomplete_sets;
      }
      for (std::optional<Frame>& frame : set.frames) {
        if (!frame) continue;
        if (frame->status != FrameStatus::kOk) continue;  // counted by sync
        const std::int64_t arrival = frame->arrival_ns > 0 ? frame->arrival_ns : frame->host_ns;
        std::optional<std::int64_t> vicon;
        if (set.vicon_frame >= 0) vicon = set.vicon_frame;
        {
          const auto now = std::chrono::steady_clock::now();
          std::lock_guard r(report_mutex);
          if (report.frames_in++ == 0) first_frame_in = now;
          report.frames_in_span_s = std::chrono::duration<double>(now - first_frame_in).count();
        }
        const int camera = frame->camera_index;
        queued.push_back(
            Job{std::move(*frame), set.trigger_index, vicon, arrival, pass, taken[camera]++});
      }
    }
  }

  // Every frame taken published: the workers', and the depth lane's (its
  // waiting frames skipped, the ones it holds published).
  void WaitIdle() {
    // A frame in the slot with no worker left cannot happen: every worker
    // takes the slot before it ends. The last worker's publication done, the
    // graph only has its tasks to finish: waiting on it earlier would let
    // this thread (not a worker: its priority is not lowered) process frames.
    {
      std::unique_lock lock(slot_mutex);
      slot_cv.wait(lock, [&] { return in_flight == 0 && slots.empty(); });
    }
    if (lanes) {
      // No worker offers any more: the lens lane's waiting frames are
      // processed (each frame taken gets its per-lens depth unless a newer
      // frame of its camera replaced it), then the frames still waiting
      // for the depth lane are skipped, the ones it holds are published.
      {
        std::unique_lock lock(lens_lane.mutex);
        lens_lane.cv.wait(lock, [&] { return lens_lane.slots.empty() && lens_lane.held == 0; });
      }
      std::unique_lock lock(depth_lane.mutex);
      {
        std::lock_guard r(report_mutex);
        for (const auto& [camera, queue] : depth_lane.slots) report.depth_skipped += queue.size();
      }
      depth_lane.slots.clear();
      depth_lane.cv.wait(lock, [&] { return depth_lane.held == 0; });
    }
    // No put into the graph can come now (no worker offers; the lanes'
    // threads publish their own frames): its wait_for_all, which resets the
    // graph's task context afterwards, never runs beside one (oneTBB
    // documents no concurrent wait).
    graph->wait_for_all();
  }

  // The end of a pass (Pipeline::EndPass) or of the run (Finish: `last`).
  // Under newest_wins a pass's end waits for nothing: the frames in
  // processing (a localisation, the depth lane's depth map: at medium up to
  // seconds) go on beside the next pass, their buffers keeping their pools
  // alive (drivers/frame_pool.h), their poses keyed by pass (Relate);
  // waiting for them held the replay's cameras that long at every pass of a
  // loop (bench_live, 24 frames looped at 10 Hz: 9.8 of the 20 frames offered
  // per second came in). Under block every frame is processed before the
  // next pass's come.
  void EndPass(bool last) {
    QueueSets(TakeSets());
    SubmitQueued(std::nullopt);
    if (last || !options.skip_when_busy) WaitIdle();
    ++pass;
    // The next pass's grab loop starts a fresh assembler, its losses from 0.
    std::lock_guard lock(sync_mutex);
    drops_before = SyncDrops();
    drops_this_pass = DropCounter{};
  }

  StatsSnapshot Stats() {
    const PipelineReport r = Snapshot();
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - stats_last_time).count();
    StatsSnapshot m;
    m.rate_hz = dt > 0 ? static_cast<double>(r.processed - stats_last_processed) / dt : 0;
    stats_last_processed = r.processed;
    stats_last_time = now;
    m.stage_name = "process:" + processor->name();
    {
      std::lock_guard lock(slot_mutex);
      m.queue_depth = in_flight + static_cast<int>(slots.size() + later.size());
    }
    m.queue_capacity = options.max_concurrency + static_cast<int>(sync_options.serials.size());
    m.process_p50_ms = r.process.p50_ms;
    m.process_p99_ms = r.process.p99_ms;
    m.to_publication_p50_ms = r.to_publication.p50_ms;
    m.to_publication_p99_ms = r.to_publication.p99_ms;
    m.processed = r.processed;
    m.skipped = r.skipped;
    m.failed = r.failed;
    for (const std::string& serial : sync_options.serials)
      m.cameras += (m.cameras.empty() ? "" : ",") + serial;
    std::lock_guard lock(sync_mutex);
    m.drops = SyncDrops();
    return m;
  }

  void PublishStats() {
    publisher->PublishStats(Stats());
    std::lock_guard r(report_mutex);
    ++report.published_stats;
  }

  PipelineReport Snapshot() {
    PipelineReport r;
    {
      std::lock_guard lock(report_mutex);
      r = report;
      r.published_vicon = published_vicon.load();
      r.publish_errors = publisher->errors();
      r.process = process_latency.Summary();
      r.to_publication = publication_latency.Summary();
      r.to_pose = pose_latency.Summary();
      r.to_lens_depth = lens_latency.Summary();
    }
    r.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::lock_guard lock(sync_mutex);
    const DropCounter drops = SyncDrops();
    r.drops = drops.OneLine();
    r.sync_lost = drops.lost();
    return r;
  }
};

Expected<std::unique_ptr<Pipeline>> Pipeline::Create(FrameSetAssemblerOptions sync,
                                                     std::unique_ptr<FrameProcessor> processor,
                                                     PipelineOptions options) {
  if (Status s = options.Check(); !s) return s.error();
  if (Status s = sync.Check(); !s) return s.error();
  if (!processor) return Error{"pipeline: no processing stage"};
  if (Status s = CheckImageEncoders(); !s) return s.error();
  auto impl = std::make_unique<Impl>();
  impl->sync_options = sync;
  impl->options = options;
  impl->processor = std::move(processor);
  impl->registration = options.registration;
  if (!impl->registration) impl->registration = std::make_shared<processing::PassThroughStage>();
  impl->localizes = dynamic_cast<processing::PassThroughStage*>(impl->registration.get()) == nullptr;
  impl->lanes = impl->localizes && options.skip_when_busy;
  impl->reference_serial =
      options.reference_serial.empty() ? sync.serials.front() : options.reference_serial;
  if (options.relate && !options.reference_serial.empty()) {
    const auto it = std::find(sync.serials.begin(), sync.serials.end(), options.reference_serial);
    if (it == sync.serials.end())
      return Error{"pipeline: reference_serial: camera " + options.reference_serial +
                   " (the reference map's) is not one of the rig's cameras"};
    impl->reference_camera = static_cast<int>(it - sync.serials.begin());
  }
  auto publisher = Publisher::Create(options.publisher);
  if (!publisher) return publisher.error();
  impl->publisher = std::move(*publisher);
  const int threads = options.threads > 0 ? options.threads : tbb::info::default_concurrency();
  impl->arena = std::make_unique<tbb::task_arena>(threads, /*reserved_for_masters=*/0);
  // Relative to this thread's (the command's): a rig run at nice -5 processes at +5.
  errno = 0;
  const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
  const int base_nice = errno == 0 ? base : 0;
  const int worker_nice = std::min(19, base_nice + options.processing_nice);
  if (options.processing_nice > 0)
    impl->worker_priority = std::make_unique<WorkerPriority>(*impl->arena, worker_nice);
  spdlog::info(
      "pipeline: processing '{}', {} frame(s) at once on {} thread(s) at nice +{}, skip policy "
      "{}, registration '{}', LCM '{}' prefix {} previews {}",
      impl->processor->name(), options.max_concurrency, threads, options.processing_nice,
      options.skip_when_busy ? "newest_wins" : "block", impl->registration->name(),
      options.publisher.bus ? std::string("(given bus)") : options.publisher.url,
      options.publisher.channel_prefix, options.publisher.publish_previews ? "on" : "off");
  Impl* raw = impl.get();
  impl->arena->execute([raw] {
    raw->graph = std::make_unique<tbb::flow::graph>();
    raw->process_node = std::make_unique<tbb::flow::function_node<Job, Result>>(
        *raw->graph, tbb::flow::unlimited,
        [raw](Job job) { return raw->RunProcess(std::move(job)); });
    raw->publish_node = std::make_unique<tbb::flow::function_node<Result>>(
        *raw->graph, tbb::flow::serial,
        [raw](Result result) { raw->RunPublish(std::move(result)); });
    tbb::flow::make_edge(*raw->process_node, *raw->publish_node);
  });
  if (impl->lanes) {
    // The lens lane: a thread per worker (at most one per camera), each
    // computing one frame at a time at lens_nice; the depth lane: one
    // thread at the lowest.
    const int lens_threads =
        std::max(1, std::min(threads, static_cast<int>(sync.serials.size())));
    impl->lens_lane.depth = static_cast<std::size_t>(options.lens_queue);
    impl->StartLane(impl->lens_lane, lens_threads,
                    std::min(19, base_nice + options.lens_nice), &Impl::LensLoop);
    impl->StartLane(impl->depth_lane, 1, 19, &Impl::DepthLoop, options.depth_idle);
  }
  return std::unique_ptr<Pipeline>(new Pipeline(std::move(impl)));
}

Pipeline::Pipeline(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Pipeline::~Pipeline() {
  impl_->WaitIdle();
  if (impl_->lanes) {
    impl_->StopLane(impl_->lens_lane);
    impl_->StopLane(impl_->depth_lane);
    // The lanes' threads never put into the graph: WaitIdle's wait_for_all
    // ended its last tasks before its nodes are destroyed (the members, in
    // reverse order).
  }
}

void Pipeline::AddFrameSet(FrameSet set) {
  std::lock_guard lock(impl_->sync_mutex);
  if (!impl_->sets_f0 && set.vicon_frame >= 0)
    impl_->sets_f0 =
        set.vicon_frame -
        static_cast<std::int64_t>(impl_->sync_options.vicon_divider) * set.trigger_index;
  impl_->sets_in.push_back(std::move(set));
}

void Pipeline::SetSyncDrops(const DropCounter& drops) {
  std::lock_guard lock(impl_->sync_mutex);
  impl_->drops_this_pass = drops;
}

void Pipeline::AddVicon(const ViconFrame& frame) {
  std::optional<std::int64_t> f0;
  {
    std::lock_guard lock(impl_->sync_mutex);
    f0 = impl_->sets_f0 ? impl_->sets_f0 : impl_->sync_options.vicon_f0;
  }
  const int divider = impl_->sync_options.vicon_divider;
  impl_->publisher->PublishVicon(frame, f0 && (frame.vicon_frame - *f0) % divider == 0);
  ++impl_->published_vicon;
}

void Pipeline::Poll() {
  impl_->QueueSets(impl_->TakeSets());
  // At most a poll period's wait for a worker: the caller's loop stays responsive.
  impl_->SubmitQueued(std::chrono::steady_clock::now() + std::chrono::milliseconds(50));
  const auto now = std::chrono::steady_clock::now();
  if (now >= impl_->next_stats) {
    impl_->PublishStats();
    impl_->next_stats = now + impl_->options.stats_period;
  }
}

void Pipeline::EndPass() { impl_->EndPass(/*last=*/false); }

void Pipeline::Finish() {
  impl_->EndPass(/*last=*/true);
  impl_->PublishStats();
  const PipelineReport r = impl_->Snapshot();
  if (r.skipped > 0)
    spdlog::warn("pipeline: {} frame(s) skipped for processing (newest wins: processing slower "
                 "than the frames)",
                 r.skipped);
  if (r.failed > 0)
    spdlog::warn("pipeline: {} frame(s) failed; last: {}", r.failed, r.last_error);
  if (r.sync_lost > 0) spdlog::warn("pipeline: sync losses: {}", r.drops);
}

PipelineReport Pipeline::Report() const { return impl_->Snapshot(); }

std::string PipelineReport::StatusLine() const {
  char buffer[256];
  std::snprintf(
      buffer, sizeof buffer,
      "%.1fs in %llu processed %llu skipped %llu failed %llu | %.1f fps | to LCM p50 %.0f "
      "ms p99 %.0f ms",
      elapsed_s, static_cast<unsigned long long>(frames_in),
      static_cast<unsigned long long>(processed), static_cast<unsigned long long>(skipped),
      static_cast<unsigned long long>(failed),
      elapsed_s > 0 ? static_cast<double>(processed) / elapsed_s : 0.0, to_publication.p50_ms,
      to_publication.p99_ms);
  return buffer;
}

std::string PipelineReport::FinalReport() const {
  std::ostringstream out;
  out << "frames in: " << frames_in << " (frame sets " << frame_sets << ", incomplete "
      << incomplete_sets << ")\n"
      << "processed: " << processed << "  skipped (newest wins): " << skipped
      << "  failed: " << failed << (Accounted() ? "  (all accounted for)" : "  (NOT ACCOUNTED)")
      << "\n";
  if (worker_frames > 0) {
    const auto per = [](double total, std::uint64_t n) {
      return n > 0 ? 1e3 * total / static_cast<double>(n) : 0.0;
    };
    char line[700];
    std::snprintf(line, sizeof line,
                  "workers (registration first): %llu frames, localisation %.1f CPU-ms per "
                  "frame; lens lane: processed %llu skipped %llu failed %llu, %.1f CPU-ms per "
                  "frame (CPU-ms: per-lens depth %.1f, TF preview %.1f, encodings %.1f; wall: "
                  "per-lens depth %.1f ms, TF preview %.1f ms, encodings %.1f ms)\n"
                  "lens lane skipped: %llu replaced by a newer frame of its camera while the "
                  "lane was busy, %llu came after a newer frame of its camera (localised "
                  "first)\n",
                  static_cast<unsigned long long>(worker_frames), per(localize_cpu_s, worker_frames),
                  static_cast<unsigned long long>(lens_frames),
                  static_cast<unsigned long long>(lens_skipped),
                  static_cast<unsigned long long>(lens_failed), per(lens_cpu_s, lens_frames),
                  per(lens_depth_cpu_s, lens_frames), per(lens_preview_cpu_s, lens_frames),
                  per(lens_encode_cpu_s, lens_frames), per(lens_depth_s, lens_frames),
                  per(lens_preview_s, lens_frames),
                  per(lens_encode_s, lens_frames), static_cast<unsigned long long>(lens_replaced),
                  static_cast<unsigned long long>(lens_stale));
    out << line;
  }
  if (depth_processed + depth_skipped + depth_failed > 0)
    out << "depth lane (registration first): processed " << depth_processed << " ("
        << depth_seeded_by_lenses << " seeded by the lens lane's per-lens depth)  skipped "
        << depth_skipped << "  failed " << depth_failed << "  CPU " << depth_cpu_s << " s\n";
  out << "published: " << published_previews << " previews, "
      << published_depth + published_lens_depth << " depth, " << published_tf << " TF, "
      << published_extrinsics << " extrinsics, " << published_vicon << " Vicon, " << published_stats
      << " stats messages";
  if (publish_errors) out << ", " << publish_errors << " publish errors";
  out << "\n";
  if (published_poses > 0) out << "poses (POSE channels): " << published_poses << "\n";
  if (published_lens_depth > 0)
    out << "depth messages: " << published_lens_depth << " per-lens (lens grid), "
        << published_depth << " dense (TF grid)\n";
  char line[200];
  std::snprintf(line, sizeof line,
                "processing: p50 %.1f ms p99 %.1f ms; frame arrival -> LCM: p50 %.1f ms p99 %.1f "
                "ms; %.2f frames/s over %.1f s\n",
                process.p50_ms, process.p99_ms, to_publication.p50_ms, to_publication.p99_ms,
                elapsed_s > 0 ? static_cast<double>(processed) / elapsed_s : 0.0, elapsed_s);
  out << line;
  if (to_pose.count > 0) {
    std::snprintf(line, sizeof line, "frame arrival -> pose on LCM: p50 %.1f ms p99 %.1f ms\n",
                  to_pose.p50_ms, to_pose.p99_ms);
    out << line;
  }
  if (to_lens_depth.count > 0) {
    std::snprintf(line, sizeof line,
                  "frame arrival -> per-lens depth on LCM: p50 %.1f ms p99 %.1f ms\n",
                  to_lens_depth.p50_ms, to_lens_depth.p99_ms);
    out << line;
  }
  out << "sync: " << drops << "\n";
  if (!last_error.empty()) out << "last processing error: " << last_error << "\n";
  return out.str();
}

}  // namespace lifmcr::apps
