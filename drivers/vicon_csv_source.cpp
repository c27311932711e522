#include "drivers/vicon_csv_source.h"

#include "drivers/host_clock.h"

#include <chrono>
#include <cmath>
#include <ctime>
#include <map>
#include <thread>

namespace lifmcr {

Status ViconCsvSourceOptions::Check() const {
  if (objects.empty())
    return Error{"Vicon CSV source: objects: expected at least one to play back"};
  if (!(rate_hz >= 0.0) || !std::isfinite(rate_hz))
    return Error{"Vicon CSV source: rate_hz: expected >= 0 (0: the file's rate)"};
  // pose: enumerations; realtime, sequence_clock_start_ns: any.
  return Status::Ok();
}

Expected<std::unique_ptr<ViconCsvSource>> ViconCsvSource::Open(
    const std::filesystem::path& csv, const ViconCsvSourceOptions& options) {
  auto parsed = ReadViconCsv(csv);
  if (!parsed) return parsed.error();
  return FromCsv(*parsed, options);
}

Expected<std::unique_ptr<ViconCsvSource>> ViconCsvSource::FromCsv(
    const ViconCsv& csv, const ViconCsvSourceOptions& options) {
  if (Status s = options.Check(); !s) return Error{csv.path + ": " + s.error().message};
  // frame number -> one pose per object (in options.objects order)
  std::map<std::int64_t, std::vector<std::optional<Pose>>> rows;
  int file_rate_hz = 0;
  for (std::size_t i = 0; i < options.objects.size(); ++i) {
    auto columns = FindSubjectColumns(csv, options.objects[i]);
    if (!columns) return columns.error();
    file_rate_hz = columns->block->rate_hz;
    auto samples = ExtractSubjectPoses(csv, options.objects[i], options.pose);
    if (!samples) return samples.error();
    const ViconBlock& block = *columns->block;
    for (std::size_t row = 0; row < samples->size(); ++row) {
      if (row < block.sub_frames.size() && block.sub_frames[row] != 0) continue;
      const ViconPoseSample& sample = (*samples)[row];
      auto& poses = rows[sample.vicon_frame];
      poses.resize(options.objects.size());
      poses[i] = sample.vicon_from_marker;
    }
  }
  const double rate_hz = options.rate_hz > 0.0 ? options.rate_hz : file_rate_hz;
  if (!(rate_hz > 0.0))
    return Error{"Vicon CSV source " + csv.path +
                 ": the file's rate is not > 0 and no rate_hz was given"};
  std::unique_ptr<ViconCsvSource> source(new ViconCsvSource());
  source->rate_hz_ = rate_hz;
  source->realtime_ = options.realtime;
  source->sequence_clock_start_ns_ = options.sequence_clock_start_ns;
  source->frames_.reserve(rows.size());
  for (auto& [frame_number, poses] : rows) {
    ViconFrame frame;
    frame.vicon_frame = frame_number;
    poses.resize(options.objects.size());
    for (std::size_t i = 0; i < options.objects.size(); ++i)
      frame.objects.push_back({options.objects[i], poses[i]});
    source->frames_.push_back(std::move(frame));
  }
  return source;
}

Status ViconCsvSource::Start() {
  started_ = true;
  next_.store(0, std::memory_order_release);
  start_host_ns_ = HostRealtimeNs();
  return Status::Ok();
}

Status ViconCsvSource::Stop() {
  started_ = false;
  return Status::Ok();
}

ViconSourceStats ViconCsvSource::Stats() const {
  ViconSourceStats stats;
  stats.frames = delivered_.load();
  stats.gaps = gaps_.load();
  return stats;
}

Expected<std::optional<ViconFrame>> ViconCsvSource::Next(std::chrono::milliseconds timeout) {
  if (!started_) return Error{"Vicon CSV source: Next before Start"};
  // Written only here (and by Start, before this thread calls Next).
  const std::size_t next = next_.load(std::memory_order_relaxed);
  if (next >= frames_.size()) return std::optional<ViconFrame>();
  std::int64_t host_ns = HostRealtimeNs();
  if (realtime_) {
    const double offset_s =
        static_cast<double>(frames_[next].vicon_frame - frames_.front().vicon_frame) / rate_hz_;
    const std::int64_t due_ns = start_host_ns_ + std::llround(offset_s * 1e9);
    if (due_ns - host_ns > std::chrono::nanoseconds(timeout).count()) {
      std::this_thread::sleep_for(timeout);
      return std::optional<ViconFrame>();
    }
    if (due_ns > host_ns) std::this_thread::sleep_for(std::chrono::nanoseconds(due_ns - host_ns));
    host_ns = due_ns;
  }
  ViconFrame frame = frames_[next];
  frame.host_ns = host_ns;
  if (sequence_clock_start_ns_)
    frame.host_ns = *sequence_clock_start_ns_ +
                    std::llround(static_cast<double>(frame.vicon_frame - frames_.front().vicon_frame) /
                                 rate_hz_ * 1e9);
  if (next > 0 && frame.vicon_frame > frames_[next - 1].vicon_frame + 1)
    gaps_.fetch_add(
        static_cast<std::uint64_t>(frame.vicon_frame - frames_[next - 1].vicon_frame - 1));
  next_.store(next + 1, std::memory_order_release);
  delivered_.fetch_add(1);
  return std::optional<ViconFrame>(std::move(frame));
}

}  // namespace lifmcr
