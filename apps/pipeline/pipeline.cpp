// The pipeline's wiring (pipeline.h): sync under a mutex, a TBB flow graph
// for processing and publication, LCM as the only way out.

#include "apps/pipeline/pipeline.h"

#include <lcm/lcm-cpp.hpp>
#include <tbb/flow_graph.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/pipeline_stats_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <limits>
#include <malloc.h>
#include <map>
#include <mutex>
#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/task_arena.h>
#include <oneapi/tbb/task_scheduler_observer.h>
#include <optional>
#include <sstream>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

namespace lifmcr::apps {
namespace {

std::int64_t NowRealtimeNs() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

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
  std::int64_t arrival_ns = 0;  // host clock when the frame reached the pipeline
};

struct Result {
  Job job;
  Expected<ProcessedFrame> processed{Error{"not processed"}};
};

lifmcr_lcm::preview_image_t ToPreviewMessage(const EncodedImage& image, const Job& job,
                                             std::int64_t utime) {
  lifmcr_lcm::preview_image_t m;
  m.utime = utime;
  m.serial = job.frame.serial;
  m.frame_id = static_cast<std::int64_t>(job.frame.frame_id);
  m.trigger_index = job.trigger_index;
  m.source_width = image.source_width;
  m.source_height = image.source_height;
  m.width = image.width;
  m.height = image.height;
  m.row_stride = 0;
  m.channels = static_cast<std::int8_t>(image.channels);
  m.encoding = image.encoding == EncodedImage::Encoding::kJpeg
                   ? lifmcr_lcm::preview_image_t::ENCODING_JPEG
                   : lifmcr_lcm::preview_image_t::ENCODING_PNG;
  m.data = image.bytes;
  m.size = static_cast<std::int32_t>(m.data.size());
  return m;
}

}  // namespace

std::string CameraChannel(const std::string& serial, const std::string& kind) {
  return "LIFMCR_" + serial + "_" + kind;
}

Status PipelineOptions::Check() const {
  if (max_concurrency < 1 || max_concurrency > 64)
    return Error{"pipeline: max_concurrency: expected 1..64"};
  if (stats_period.count() <= 0) return Error{"pipeline: stats_period: expected > 0"};
  if (processing_nice < 0 || processing_nice > 19)
    return Error{"pipeline: processing_nice: expected 0..19"};
  return Status::Ok();
}

struct Pipeline::Impl {
  FrameSetAssemblerOptions sync_options;
  PipelineOptions options;
  std::unique_ptr<FrameProcessor> processor;
  std::unique_ptr<lcm::LCM> own_lcm;
  lcm::LCM* lcm = nullptr;
  std::mutex lcm_mutex;
  // When the pipeline opens the URL itself, Vicon goes out on an instance of
  // its own (its own socket and send lock): a Vicon message never waits
  // behind the fragments of a depth map that a lower-priority worker is
  // sending. On a given bus (tests, memq://) both share it.
  std::unique_ptr<lcm::LCM> vicon_lcm;
  std::mutex vicon_lcm_mutex;

  std::mutex sync_mutex;
  std::unique_ptr<FrameSetAssembler> assembler;
  // When each frame reached the pipeline (host clock), for the latency to
  // publication; keyed by camera index and frame id.
  std::map<std::pair<int, std::uint64_t>, std::int64_t> arrival_ns;
  DropCounter drops_before;  // of the assemblers of earlier passes
  std::uint64_t lost_before = 0;

  // Processing gets every core: TBB starts cores - 1 workers and its default
  // arena keeps a slot for a master thread, which here (the command's loop)
  // never helps, so the graph would process on one core. Its own arena has
  // no master slot, and the workers to fill it are allowed.
  std::unique_ptr<tbb::global_control> worker_limit;
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

  // Counted on the Vicon thread without a lock that a lower-priority worker
  // takes: a worker preempted while holding it would hold up Vicon.
  std::atomic<std::uint64_t> published_vicon{0}, publish_errors{0};
  // Counters (report_mutex).
  mutable std::mutex report_mutex;
  PipelineReport report;
  LatencyWindow process_latency, publication_latency;
  std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point next_stats = start;
  std::uint64_t stats_last_processed = 0;
  std::chrono::steady_clock::time_point stats_last_time = start;

  void PublishOn(lcm::LCM& bus, std::mutex& bus_mutex, const std::string& channel,
                 const auto& message) {
    std::lock_guard lock(bus_mutex);
    if (bus.publish(channel, &message) != 0) ++publish_errors;
  }
  void Publish(const std::string& channel, const auto& message) {
    PublishOn(*lcm, lcm_mutex, channel, message);
  }
  void PublishVicon(const lifmcr_lcm::vicon_frame_t& message) {
    if (vicon_lcm)
      PublishOn(*vicon_lcm, vicon_lcm_mutex, kViconChannel, message);
    else
      Publish(kViconChannel, message);
  }

  Result RunProcess(Job job) {
    Result result{std::move(job), Error{""}};
    result.processed = processor->Process(result.job.frame);
    return result;
  }

  void RunPublish(Result result) {
    const Job& job = result.job;
    const std::int64_t now_ns = NowRealtimeNs();
    const std::int64_t utime = now_ns / 1000;
    if (!result.processed) {
      std::lock_guard r(report_mutex);
      ++report.failed;
      report.last_error = job.frame.serial + " frame " + std::to_string(job.frame.frame_id) + ": " +
                          result.processed.error().message;
    } else {
      const ProcessedFrame& p = *result.processed;
      std::uint64_t previews = 0, depths = 0, tfs = 0;
      if (p.preview) {
        Publish(CameraChannel(job.frame.serial, "PREVIEW"),
                ToPreviewMessage(*p.preview, job, utime));
        ++previews;
      }
      if (p.tf) {
        Publish(CameraChannel(job.frame.serial, "TF"), ToPreviewMessage(*p.tf, job, utime));
        ++tfs;
      }
      if (p.depth) {
        lifmcr_lcm::depth_image_t m;
        m.utime = utime;
        m.serial = job.frame.serial;
        m.frame_id = static_cast<std::int64_t>(job.frame.frame_id);
        m.trigger_index = job.trigger_index;
        m.kind = lifmcr_lcm::depth_image_t::KIND_VIRTUAL;
        m.geometry = lifmcr_lcm::depth_image_t::GEOMETRY_TOTALLY_FOCUSED;
        m.width = p.depth->width;
        m.height = p.depth->height;
        m.scale = p.depth->scale;
        m.offset = p.depth->offset;
        m.valid_fraction = p.depth->valid_fraction;
        m.min_value = p.depth->min_value;
        m.max_value = p.depth->max_value;
        m.encoding = lifmcr_lcm::preview_image_t::ENCODING_PNG;
        m.data = p.depth->png;
        m.size = static_cast<std::int32_t>(m.data.size());
        Publish(CameraChannel(job.frame.serial, "DEPTH"), m);
        ++depths;
      }
      const double to_pub_ms = static_cast<double>(NowRealtimeNs() - job.arrival_ns) / 1e6;
      std::lock_guard r(report_mutex);
      ++report.processed;
      report.published_previews += previews;
      report.published_depth += depths;
      report.published_tf += tfs;
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
        auto pick = slots.begin();
        for (auto it = slots.begin(); it != slots.end(); ++it)
          if (served[it->first] < served[pick->first]) pick = it;
        next = std::move(pick->second);
        slots.erase(pick);
        served[next->frame.camera_index] = ++serve_count;
      } else {
        --in_flight;
      }
      slot_cv.notify_all();
    }
    if (next) process_node->try_put(std::move(*next));
  }

  // One frame into processing, by the skip policy.
  void Submit(Job job) {
    std::unique_lock lock(slot_mutex);
    {
      std::lock_guard r(report_mutex);
      ++report.frames_in;
    }
    if (!options.skip_when_busy) {
      slot_cv.wait(lock, [&] { return in_flight < options.max_concurrency; });
    }
    if (in_flight < options.max_concurrency) {
      ++in_flight;
      served[job.frame.camera_index] = ++serve_count;
      lock.unlock();
      process_node->try_put(std::move(job));
      return;
    }
    const int camera = job.frame.camera_index;
    if (slots.count(camera)) {
      std::lock_guard r(report_mutex);
      ++report.skipped;
    }
    slots.insert_or_assign(camera, std::move(job));
  }

  void SubmitSets(std::vector<FrameSet> sets) {
    for (FrameSet& set : sets) {
      {
        std::lock_guard r(report_mutex);
        ++report.frame_sets;
        if (!set.missing.empty()) ++report.incomplete_sets;
      }
      for (std::optional<Frame>& frame : set.frames) {
        if (!frame) continue;
        std::int64_t arrival = frame->host_ns;
        {
          std::lock_guard lock(sync_mutex);
          const auto it = arrival_ns.find({frame->camera_index, frame->frame_id});
          if (it != arrival_ns.end()) {
            arrival = it->second;
            arrival_ns.erase(it);
          }
        }
        if (frame->status != FrameStatus::kOk) continue;  // counted by sync
        Submit(Job{std::move(*frame), set.trigger_index, arrival});
      }
    }
  }

  void WaitIdle() {
    // A frame in the slot with no worker left cannot happen: every worker
    // takes the slot before it ends. The last worker's publication done, the
    // graph only has its tasks to finish: waiting on it earlier would let
    // this thread (not a worker: its priority is not lowered) process frames.
    {
      std::unique_lock lock(slot_mutex);
      slot_cv.wait(lock, [&] { return in_flight == 0 && slots.empty(); });
    }
    graph->wait_for_all();
  }

  lifmcr_lcm::pipeline_stats_t StatsMessage() {
    const PipelineReport r = Snapshot();
    const auto now = std::chrono::steady_clock::now();
    const double dt = std::chrono::duration<double>(now - stats_last_time).count();
    const double rate = dt > 0 ? static_cast<double>(r.processed - stats_last_processed) / dt : 0;
    stats_last_processed = r.processed;
    stats_last_time = now;
    lifmcr_lcm::pipeline_stats_t m;
    m.utime = NowRealtimeNs() / 1000;
    lifmcr_lcm::stage_stats_t process;
    process.name = "process:" + processor->name();
    process.rate_hz = rate;
    {
      std::lock_guard lock(slot_mutex);
      process.queue_depth = in_flight + static_cast<std::int32_t>(slots.size());
    }
    process.queue_capacity =
        options.max_concurrency + static_cast<std::int32_t>(sync_options.serials.size());
    process.latency_p50_ms = r.process.p50_ms;
    process.latency_p99_ms = r.process.p99_ms;
    process.processed = static_cast<std::int64_t>(r.processed);
    process.skipped = static_cast<std::int64_t>(r.skipped);
    lifmcr_lcm::stage_stats_t publish;
    publish.name = "publish";
    publish.rate_hz = rate;
    publish.queue_depth = 0;
    publish.queue_capacity = 0;
    publish.latency_p50_ms = r.to_publication.p50_ms;  // frame arrival -> on LCM
    publish.latency_p99_ms = r.to_publication.p99_ms;
    publish.processed = static_cast<std::int64_t>(r.processed);
    publish.skipped = 0;
    m.stages = {process, publish};
    m.num_stages = static_cast<std::int32_t>(m.stages.size());
    DropCounter drops;
    {
      std::lock_guard lock(sync_mutex);
      drops = assembler->drops();
    }
    for (int k = 0; k < kDropKindCount; ++k) {
      const auto kind = static_cast<DropKind>(k);
      const std::uint64_t count = drops[kind] + drops_before[kind];
      if (count == 0) continue;
      lifmcr_lcm::drop_count_t d;
      d.kind = std::string(ToString(kind));
      d.count = static_cast<std::int64_t>(count);
      m.drops.push_back(d);
    }
    lifmcr_lcm::drop_count_t skipped;
    skipped.kind = "skipped_for_processing";
    skipped.count = static_cast<std::int64_t>(r.skipped);
    m.drops.push_back(skipped);
    lifmcr_lcm::drop_count_t failed;
    failed.kind = "processing_failed";
    failed.count = static_cast<std::int64_t>(r.failed);
    m.drops.push_back(failed);
    m.num_drops = static_cast<std::int32_t>(m.drops.size());
    return m;
  }

  void PublishStats() {
    const auto m = StatsMessage();
    Publish(kStatsChannel, m);
    std::lock_guard r(report_mutex);
    ++report.published_stats;
  }

  PipelineReport Snapshot() {
    PipelineReport r;
    {
      std::lock_guard lock(report_mutex);
      r = report;
      r.published_vicon = published_vicon.load();
      r.publish_errors = publish_errors.load();
      r.process = process_latency.Summary();
      r.to_publication = publication_latency.Summary();
    }
    r.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::lock_guard lock(sync_mutex);
    DropCounter drops = drops_before;
    for (int k = 0; k < kDropKindCount; ++k)
      drops.Add(static_cast<DropKind>(k), assembler->drops()[static_cast<DropKind>(k)]);
    r.drops = drops.OneLine();
    r.sync_lost = drops.lost();
    return r;
  }
};

// The processing workers allocate and free buffers of megabytes per frame
// (preview and TF encoding, OpenCV temporaries). glibc serves those with
// mmap and returns them with munmap, and trims its heap on free; both take
// the process's memory-map lock, and every page fault of the Vicon and
// camera threads then waits behind it: Vicon packet -> LCM p99 went from
// 0.2-0.7 ms to 6-19 ms with frames flowing (bench_pipeline). Serving up to
// 32 MB (glibc's upper limit) from the heap and never trimming it keeps the
// freed memory in the process for the next frame instead.
static void KeepFreedMemoryInProcess() {
  static std::once_flag once;
  std::call_once(once, [] {
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
  });
}

Expected<std::unique_ptr<Pipeline>> Pipeline::Create(FrameSetAssemblerOptions sync,
                                                     std::unique_ptr<FrameProcessor> processor,
                                                     PipelineOptions options) {
  if (Status s = options.Check(); !s) return s.error();
  KeepFreedMemoryInProcess();
  if (Status s = sync.Check(); !s) return s.error();
  if (!processor) return Error{"pipeline: no processing stage"};
  auto impl = std::make_unique<Impl>();
  impl->sync_options = sync;
  impl->options = options;
  impl->processor = std::move(processor);
  if (options.bus) {
    impl->lcm = options.bus;
  } else {
    impl->own_lcm = std::make_unique<lcm::LCM>(options.lcm_url);
    impl->lcm = impl->own_lcm.get();
    // Only UDP multicast: two memq:// instances are two buses, two file://
    // instances two writers of one log.
    const char* default_url = std::getenv("LCM_DEFAULT_URL");
    const std::string url = !options.lcm_url.empty() ? options.lcm_url
                            : default_url            ? default_url
                                                     : "udpm://";
    if (impl->lcm->good() && url.starts_with("udpm://"))
      impl->vicon_lcm = std::make_unique<lcm::LCM>(options.lcm_url);
  }
  if (!impl->lcm->good() || (impl->vicon_lcm && !impl->vicon_lcm->good()))
    return Error{"LCM: cannot open '" +
                 (options.lcm_url.empty() ? std::string("default URL") : options.lcm_url) +
                 "' (for UDP multicast on loopback: ip link set lo multicast on; ip route add "
                 "239.255.76.67/32 dev lo)"};
  impl->assembler = std::make_unique<FrameSetAssembler>(sync);
  const int cores = tbb::info::default_concurrency();
  impl->worker_limit = std::make_unique<tbb::global_control>(
      tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(cores) + 1);
  impl->arena = std::make_unique<tbb::task_arena>(cores, /*reserved_for_masters=*/0);
  if (options.processing_nice > 0) {
    // Relative to this thread's (the command's): a rig run at nice -5 processes at +5.
    errno = 0;
    const int base = getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)));
    impl->worker_priority = std::make_unique<WorkerPriority>(
        *impl->arena, std::min(19, (errno == 0 ? base : 0) + options.processing_nice));
  }
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
  return std::unique_ptr<Pipeline>(new Pipeline(std::move(impl)));
}

Pipeline::Pipeline(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

Pipeline::~Pipeline() { impl_->WaitIdle(); }

void Pipeline::AddFrame(Frame frame) {
  const std::int64_t now = NowRealtimeNs();
  std::lock_guard lock(impl_->sync_mutex);
  // Frames the assembler drops never come back: the map is bounded by
  // dropping entries far older than any pending trigger.
  if (impl_->arrival_ns.size() > 4096) impl_->arrival_ns.erase(impl_->arrival_ns.begin());
  impl_->arrival_ns[{frame.camera_index, frame.frame_id}] = now;
  impl_->assembler->AddFrame(std::move(frame));
}

void Pipeline::AddVicon(const ViconFrame& frame) {
  std::optional<std::int64_t> f0;
  {
    std::lock_guard lock(impl_->sync_mutex);
    impl_->assembler->AddVicon(frame);
    f0 = impl_->assembler->vicon_f0();
  }
  lifmcr_lcm::vicon_frame_t m;
  m.utime = frame.host_ns / 1000;
  m.vicon_frame = frame.vicon_frame;
  const int divider = impl_->sync_options.vicon_divider;
  m.is_trigger = f0 && (frame.vicon_frame - *f0) % divider == 0;
  for (const ViconObjectPose& object : frame.objects) {
    lifmcr_lcm::vicon_object_t o{};
    o.name = object.name;
    o.occluded = !object.vicon_from_marker.has_value();
    if (object.vicon_from_marker) {
      const Eigen::Vector3d t = object.vicon_from_marker->translation();
      const Eigen::Quaterniond q(object.vicon_from_marker->rotation());
      for (int k = 0; k < 3; ++k) o.t_mm[k] = t[k];
      o.q_wxyz[0] = q.w();
      o.q_wxyz[1] = q.x();
      o.q_wxyz[2] = q.y();
      o.q_wxyz[3] = q.z();
    }
    m.objects.push_back(o);
  }
  m.num_objects = static_cast<std::int32_t>(m.objects.size());
  impl_->PublishVicon(m);
  ++impl_->published_vicon;
}

void Pipeline::Poll() {
  std::vector<FrameSet> sets;
  {
    std::lock_guard lock(impl_->sync_mutex);
    sets = impl_->assembler->Poll(NowRealtimeNs());
  }
  impl_->SubmitSets(std::move(sets));
  const auto now = std::chrono::steady_clock::now();
  if (now >= impl_->next_stats) {
    impl_->PublishStats();
    impl_->next_stats = now + impl_->options.stats_period;
  }
}

void Pipeline::EndPass() {
  std::vector<FrameSet> sets;
  {
    std::lock_guard lock(impl_->sync_mutex);
    sets = impl_->assembler->Flush();
  }
  impl_->SubmitSets(std::move(sets));
  impl_->WaitIdle();
  std::lock_guard lock(impl_->sync_mutex);
  for (int k = 0; k < kDropKindCount; ++k)
    impl_->drops_before.Add(static_cast<DropKind>(k),
                            impl_->assembler->drops()[static_cast<DropKind>(k)]);
  impl_->assembler = std::make_unique<FrameSetAssembler>(impl_->sync_options);
  impl_->arrival_ns.clear();
}

void Pipeline::Finish() {
  EndPass();
  impl_->PublishStats();
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
      << "\n"
      << "published: " << published_previews << " previews, " << published_depth << " depth, "
      << published_tf << " TF, " << published_vicon << " Vicon, " << published_stats
      << " stats messages";
  if (publish_errors) out << ", " << publish_errors << " publish errors";
  out << "\n";
  char line[200];
  std::snprintf(line, sizeof line,
                "processing: p50 %.1f ms p99 %.1f ms; frame arrival -> LCM: p50 %.1f ms p99 %.1f "
                "ms; %.2f frames/s over %.1f s\n",
                process.p50_ms, process.p99_ms, to_publication.p50_ms, to_publication.p99_ms,
                elapsed_s > 0 ? static_cast<double>(processed) / elapsed_s : 0.0, elapsed_s);
  out << line << "sync: " << drops << "\n";
  if (!last_error.empty()) out << "last processing error: " << last_error << "\n";
  return out.str();
}

}  // namespace lifmcr::apps
