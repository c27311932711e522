// LCM messages of the pipeline (publisher.h).

#include "apps/pipeline/publisher.h"

#include "drivers/host_clock.h"
#include "lcm_types/safe_decode.h"

#include <Eigen/Geometry>
#include <lcm/lcm-cpp.hpp>

#include <cstdlib>
#include <ctime>
#include <lifmcr_lcm/camera_extrinsics_t.hpp>
#include <lifmcr_lcm/camera_pose_t.hpp>
#include <lifmcr_lcm/depth_image_t.hpp>
#include <lifmcr_lcm/pipeline_stats_t.hpp>
#include <lifmcr_lcm/preview_image_t.hpp>
#include <lifmcr_lcm/vicon_frame_t.hpp>
#include <unistd.h>

namespace lifmcr::apps {
namespace {

std::int64_t NowRealtimeUs() { return HostRealtimeNs() / 1000; }

// The pose fields camera_extrinsics_t and camera_pose_t share (the same
// names): method, localisation, t_mm, q_wxyz, covariance, inliers, rmse_px,
// status.
template <typename Message>
void SetPoseFields(const processing::CameraPose& pose, Message* m) {
  m->method = pose.method;
  m->localisation = pose.localisation;
  const Eigen::Vector3d t = pose.transform.translation();
  const Eigen::Quaterniond q(pose.transform.rotation());
  for (int k = 0; k < 3; ++k) m->t_mm[k] = t[k];
  m->q_wxyz[0] = q.w();
  m->q_wxyz[1] = q.x();
  m->q_wxyz[2] = q.y();
  m->q_wxyz[3] = q.z();
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) m->covariance[r][c] = pose.covariance(r, c);
  m->inliers = pose.inliers;
  m->rmse_px = pose.rmse_px;
  m->status = pose.status;
}

lifmcr_lcm::preview_image_t ToPreviewMessage(const EncodedImage& image, const FrameMeta& meta,
                                             std::int64_t utime) {
  lifmcr_lcm::preview_image_t m;
  m.utime = utime;
  m.serial = meta.serial;
  m.frame_id = static_cast<std::int64_t>(meta.frame_id);
  m.trigger_index = meta.trigger_index;
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

// A depth map's message without its geometry; the lens fields zero.
lifmcr_lcm::depth_image_t ToDepthMessage(const EncodedDepth& depth, const FrameMeta& meta,
                                         std::int64_t utime) {
  lifmcr_lcm::depth_image_t m{};
  m.utime = utime;
  m.serial = meta.serial;
  m.frame_id = static_cast<std::int64_t>(meta.frame_id);
  m.trigger_index = meta.trigger_index;
  m.kind = lifmcr_lcm::depth_image_t::KIND_VIRTUAL;
  m.width = depth.width;
  m.height = depth.height;
  m.scale = depth.scale;
  m.offset = depth.offset;
  m.valid_fraction = depth.valid_fraction;
  m.min_value = depth.min_value;
  m.max_value = depth.max_value;
  m.encoding = lifmcr_lcm::preview_image_t::ENCODING_PNG;
  m.raw_width = depth.raw_width;
  m.raw_height = depth.raw_height;
  m.data = depth.png;
  m.size = static_cast<std::int32_t>(m.data.size());
  return m;
}

bool ValidPrefix(const std::string& prefix) {
  if (prefix.empty()) return false;
  for (char c : prefix)
    if (!((c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_')) return false;
  return true;
}

}  // namespace

PublisherOptions PublisherOptions::FromRig(const LcmConfig& lcm) {
  PublisherOptions options;
  options.url = lcm.url;
  options.channel_prefix = lcm.channel_prefix;
  options.publish_previews = lcm.publish_previews;
  return options;
}

Status PublisherOptions::Check() const {
  if (!ValidPrefix(channel_prefix))
    return Error{"publisher: channel_prefix: expected [A-Z0-9_]+, got '" + channel_prefix + "'"};
  // url: any text LCM accepts (checked by opening it); bus: any;
  // publish_previews: any value.
  return Status::Ok();
}

Publisher::~Publisher() = default;

Expected<std::unique_ptr<Publisher>> Publisher::Create(const PublisherOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  std::unique_ptr<Publisher> p(new Publisher());
  p->options_ = options;
  p->channels_.prefix = options.channel_prefix;
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  p->source_ = std::string(host[0] ? host : "unknown") + ":" + std::to_string(getpid());
  if (options.bus) {
    p->lcm_ = options.bus;
  } else {
    p->own_lcm_ = std::make_unique<lcm::LCM>(options.url);
    p->lcm_ = p->own_lcm_.get();
    // Only UDP multicast: two memq:// instances are two buses, two file://
    // instances two writers of one log.
    const char* default_url = std::getenv("LCM_DEFAULT_URL");
    const std::string url = !options.url.empty() ? options.url
                            : default_url        ? default_url
                                                 : "udpm://";
    if (p->lcm_->good() && url.starts_with("udpm://"))
      p->vicon_lcm_ = std::make_unique<lcm::LCM>(options.url);
  }
  if (!p->lcm_->good() || (p->vicon_lcm_ && !p->vicon_lcm_->good()))
    return Error{"LCM: cannot open '" +
                 (options.url.empty() ? std::string("default URL") : options.url) +
                 "' (for UDP multicast on loopback: ip link set lo multicast on; ip route add "
                 "239.255.76.67/32 dev lo)"};
  return p;
}

template <typename Message>
void Publisher::PublishOn(lcm::LCM& bus, std::mutex& bus_mutex, const std::string& channel,
                          const Message& message) {
  std::lock_guard lock(bus_mutex);
  if (bus.publish(channel, &message) != 0) ++errors_;
}

Publisher::FrameCounts Publisher::PublishFrame(const FrameMeta& meta, const ProcessedFrame& p) {
  const std::int64_t utime = NowRealtimeUs();
  FrameCounts counts;
  if (p.preview && options_.publish_previews) {
    PublishOn(*lcm_, lcm_mutex_, channels_.Camera(meta.serial, "PREVIEW"),
              ToPreviewMessage(*p.preview, meta, utime));
    ++counts.previews;
  }
  if (p.tf && options_.publish_previews) {
    PublishOn(*lcm_, lcm_mutex_, channels_.Camera(meta.serial, "TF"),
              ToPreviewMessage(*p.tf, meta, utime));
    ++counts.tf;
  }
  if (p.depth) {
    lifmcr_lcm::depth_image_t m = ToDepthMessage(*p.depth, meta, utime);
    m.geometry = lifmcr_lcm::depth_image_t::GEOMETRY_TOTALLY_FOCUSED;
    PublishOn(*lcm_, lcm_mutex_, channels_.Camera(meta.serial, "DEPTH"), m);
    ++counts.depth;
  }
  if (p.lens_depth) {
    lifmcr_lcm::depth_image_t m = ToDepthMessage(p.lens_depth->depth, meta, utime);
    m.geometry = lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID;
    const processing::LensGrid& g = p.lens_depth->grid;
    m.lens_j_top = g.j_top;
    m.lens_col_base = g.col_base;
    for (int k = 0; k < 2; ++k) {
      m.lens_origin_px[k] = g.origin_px[k];
      m.lens_step_i_px[k] = g.lattice(k, 0);
      m.lens_step_j_px[k] = g.lattice(k, 1);
      m.principal_point_px[k] = g.principal_point_px[k];
    }
    m.lens_type_sign = static_cast<std::int8_t>(g.type_sign);
    m.lambda = g.lambda;
    PublishOn(*lcm_, lcm_mutex_, channels_.Camera(meta.serial, "DEPTH"), m);
    ++counts.lens_depth;
  }
  return counts;
}

void Publisher::PublishVicon(const ViconFrame& frame, bool is_trigger) {
  lifmcr_lcm::vicon_frame_t m;
  m.utime = frame.host_ns / 1000;
  m.vicon_frame = frame.vicon_frame;
  m.is_trigger = is_trigger;
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
  if (vicon_lcm_)
    PublishOn(*vicon_lcm_, vicon_lcm_mutex_, channels_.Vicon(), m);
  else
    PublishOn(*lcm_, lcm_mutex_, channels_.Vicon(), m);
}

void Publisher::PublishExtrinsics(const std::string& reference_serial, const std::string& serial,
                                  std::int64_t trigger_index,
                                  const processing::CameraPose& c0_from_cx) {
  lifmcr_lcm::camera_extrinsics_t m;
  m.utime = NowRealtimeUs();
  m.reference_serial = reference_serial;
  m.serial = serial;
  m.trigger_index = trigger_index;
  SetPoseFields(c0_from_cx, &m);
  m.change_state = lifmcr_lcm::camera_extrinsics_t::CHANGE_OFF;
  m.departure = 0;
  m.departures_in_row = 0;
  Eigen::Isometry3d running = Eigen::Isometry3d::Identity();
  if (const auto& change = c0_from_cx.change) {
    using State = processing::ExtrinsicsChange::State;
    switch (change->state) {
      case State::kSettling: m.change_state = m.CHANGE_SETTLING; break;
      case State::kSteady: m.change_state = m.CHANGE_STEADY; break;
      case State::kDeparting: m.change_state = m.CHANGE_DEPARTING; break;
      case State::kChanged: m.change_state = m.CHANGE_CHANGED; break;
    }
    m.departure = change->departure;
    m.departures_in_row = change->departures_in_row;
    running = change->running;
  }
  const Eigen::Quaterniond running_q(running.rotation());
  for (int k = 0; k < 3; ++k) m.running_t_mm[k] = running.translation()[k];
  m.running_q_wxyz[0] = running_q.w();
  m.running_q_wxyz[1] = running_q.x();
  m.running_q_wxyz[2] = running_q.y();
  m.running_q_wxyz[3] = running_q.z();
  PublishOn(*lcm_, lcm_mutex_, channels_.Camera(serial, "EXTRINSICS"), m);
  if (!c0_from_cx.change || c0_from_cx.change->running_triggers == 0) return;
  // The fused estimate of a monitored rigid mount, beside it (docs/lcm.md):
  // the same message with the running estimate as the pose, flagged by
  // method and localisation "fused"; inliers: the triggers fused.
  const processing::ExtrinsicsChange& change = *c0_from_cx.change;
  m.method = m.localisation = "fused";
  for (int k = 0; k < 3; ++k) m.t_mm[k] = m.running_t_mm[k];
  for (int k = 0; k < 4; ++k) m.q_wxyz[k] = m.running_q_wxyz[k];
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) m.covariance[r][c] = change.running_covariance(r, c);
  m.inliers = change.running_triggers;
  m.rmse_px = 0;
  m.status = "ok";
  PublishOn(*lcm_, lcm_mutex_, channels_.Camera(serial, "EXTRINSICS_FUSED"), m);
}

void Publisher::PublishStats(const StatsSnapshot& s) {
  lifmcr_lcm::pipeline_stats_t m;
  m.utime = NowRealtimeUs();
  m.source = source_;
  m.cameras = s.cameras;
  lifmcr_lcm::stage_stats_t process;
  process.name = s.stage_name;
  process.rate_hz = s.rate_hz;
  process.queue_depth = s.queue_depth;
  process.queue_capacity = s.queue_capacity;
  process.latency_p50_ms = s.process_p50_ms;
  process.latency_p99_ms = s.process_p99_ms;
  process.processed = static_cast<std::int64_t>(s.processed);
  process.skipped = static_cast<std::int64_t>(s.skipped);
  lifmcr_lcm::stage_stats_t publish;
  publish.name = "publish";
  publish.rate_hz = s.rate_hz;
  publish.queue_depth = 0;
  publish.queue_capacity = 0;
  publish.latency_p50_ms = s.to_publication_p50_ms;  // frame arrival -> on LCM
  publish.latency_p99_ms = s.to_publication_p99_ms;
  publish.processed = static_cast<std::int64_t>(s.processed);
  publish.skipped = 0;
  m.stages = {process, publish};
  m.num_stages = static_cast<std::int32_t>(m.stages.size());
  for (int k = 0; k < kDropKindCount; ++k) {
    const auto kind = static_cast<DropKind>(k);
    if (s.drops[kind] == 0) continue;
    lifmcr_lcm::drop_count_t d;
    d.kind = std::string(ToString(kind));
    d.count = static_cast<std::int64_t>(s.drops[kind]);
    m.drops.push_back(d);
  }
  lifmcr_lcm::drop_count_t skipped;
  skipped.kind = "skipped_for_processing";
  skipped.count = static_cast<std::int64_t>(s.skipped);
  m.drops.push_back(skipped);
  lifmcr_lcm::drop_count_t failed;
  failed.kind = "processing_failed";
  failed.count = static_cast<std::int64_t>(s.failed);
  m.drops.push_back(failed);
  m.num_drops = static_cast<std::int32_t>(m.drops.size());
  PublishOn(*lcm_, lcm_mutex_, channels_.Stats(), m);
}

void Publisher::PublishPose(const PoseRecord& pose) {
  lifmcr_lcm::camera_pose_t m;
  m.utime = NowRealtimeUs();
  m.serial = pose.serial;
  m.reference_serial = pose.reference_serial;
  m.trigger_index = pose.trigger_index;
  m.pass = pose.pass;
  m.frame_id = static_cast<std::int64_t>(pose.frame_id);
  m.arrival_utime = pose.arrival_ns / 1000;
  SetPoseFields(pose.w0_from_cam, &m);
  PublishOn(*lcm_, lcm_mutex_, channels_.Camera(pose.serial, "POSE"), m);
}

Expected<PoseRecord> DecodePoseMessage(const void* data, int size) {
  auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::camera_pose_t>(data, size);
  if (!m) return Error{"camera_pose_t: the message does not decode"};
  PoseRecord pose;
  pose.serial = m->serial;
  pose.reference_serial = m->reference_serial;
  pose.trigger_index = m->trigger_index;
  pose.pass = m->pass;
  pose.frame_id = static_cast<std::uint64_t>(m->frame_id);
  pose.arrival_ns = m->arrival_utime * 1000;
  processing::CameraPose& p = pose.w0_from_cam;
  p.method = m->method;
  p.localisation = m->localisation;
  // The quaternion as sent; normalised, so a rounding in transit cannot
  // make the rotation leave SO(3).
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(m->q_wxyz[0], m->q_wxyz[1], m->q_wxyz[2], m->q_wxyz[3]).normalized();
  p.transform = Eigen::Isometry3d::Identity();
  p.transform.linear() = q.toRotationMatrix();
  p.transform.translation() = Eigen::Vector3d(m->t_mm[0], m->t_mm[1], m->t_mm[2]);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) p.covariance(r, c) = m->covariance[r][c];
  p.inliers = m->inliers;
  p.rmse_px = m->rmse_px;
  p.status = m->status;
  return pose;
}

}  // namespace lifmcr::apps
