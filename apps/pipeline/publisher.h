#pragma once
// The pipeline's only way out: owns the LCM instances and builds every
// message from plain results (the pipeline itself knows no LCM type).
//
// Channels, <PREFIX> = lcm.channel_prefix of the rig file (default LIFMCR):
//   <PREFIX>_<SERIAL>_PREVIEW     preview_image_t, the raw frame downscaled (publish_previews)
//   <PREFIX>_<SERIAL>_TF          preview_image_t, the totally focused image, or the TF
//                                 preview at each lens's depth (publish_previews)
//   <PREFIX>_<SERIAL>_DEPTH       depth_image_t: the TF virtual depth (GEOMETRY_TOTALLY_FOCUSED,
//                                 8-bit PNG) where the dense chain ran, and the per-lens
//                                 virtual depth (GEOMETRY_LENS_GRID, 16-bit PNG) of every
//                                 frame the pipeline takes; `geometry` tells them apart
//   <PREFIX>_<SERIAL>_EXTRINSICS  camera_extrinsics_t, c0_from_cx of camera X per
//                                 trigger, from the registration stage
//                                 (processing/registration_stage.h), with the
//                                 change detection's verdict when it runs
//   <PREFIX>_<SERIAL>_EXTRINSICS_FUSED  camera_extrinsics_t, with change detection
//                                 (a rigid mount): after each trigger's, the running
//                                 c0_from_cx and its covariance, method "fused"
//   <PREFIX>_<SERIAL>_POSE        camera_pose_t, w0_from_cam of every frame the
//                                 registration stage localised (or failed to), so a
//                                 process on another host (`lifmcr relate`) can pair
//                                 the cameras' poses of a trigger
//   <PREFIX>_VICON                vicon_frame_t, every Vicon frame at once
//   <PREFIX>_STATS                pipeline_stats_t, about once a second and at the end
// trigger_index in the messages is the FrameSet's: the number of the
// recorded file of the same frame.
//
// Threads: any (the pipeline's publishing node, its workers (poses, extrinsics),
// its lens lane's threads (per-lens depth, TF preview), its depth lane's
// thread (dense depth, TF image, previews) and its poll): each
// message goes out under its bus's lock and the counters are atomic;
// PublishVicon from the Vicon thread. With a URL of its own (UDP multicast)
// Vicon goes out on an LCM instance of its own, so a Vicon message never
// waits behind the fragments of a depth map.

#include "apps/pipeline/frame_processor.h"
#include "config/error.h"
#include "config/rig_config.h"
#include "drivers/vicon_source.h"
#include "processing/registration_stage.h"
#include "sync/drop_counter.h"

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

namespace lcm {
class LCM;
}

namespace lifmcr::apps {

struct PublisherOptions {
  std::string url;  // empty: LCM's default (LCM_DEFAULT_URL or udpm 239.255.76.67:7667)
  // An LCM instance to publish on instead of opening url (tests: one
  // memq:// instance shared with the subscriber); must outlive the publisher.
  lcm::LCM* bus = nullptr;
  std::string channel_prefix = "LIFMCR";  // [A-Z0-9_]+
  bool publish_previews = true;           // the PREVIEW and TF images
  // The rig file's lcm: section (url, channel_prefix, publish_previews).
  static PublisherOptions FromRig(const LcmConfig& lcm);
  Status Check() const;  // every field; the message names the field
};

struct ChannelNames {
  std::string prefix = "LIFMCR";
  // kind: "PREVIEW", "DEPTH", "TF", "EXTRINSICS", "POSE".
  std::string Camera(const std::string& serial, const std::string& kind) const {
    return prefix + "_" + serial + "_" + kind;
  }
  std::string Vicon() const { return prefix + "_VICON"; }
  std::string Stats() const { return prefix + "_STATS"; }
};

// Which frame a message is about.
struct FrameMeta {
  std::string serial;
  std::uint64_t frame_id = 0;
  std::int64_t trigger_index = 0;
};

// One camera's w0_from_cam of a trigger, as on <PREFIX>_<SERIAL>_POSE.
struct PoseRecord {
  std::string serial;
  std::string reference_serial;  // camera 0: W0 is its map's frame
  std::int64_t trigger_index = 0;
  std::int64_t pass = 0;  // replay --loop's pass: triggers restart at 0 in each
  std::uint64_t frame_id = 0;
  std::int64_t arrival_ns = 0;  // the frame at its host (host clock)
  processing::CameraPose w0_from_cam;
};

// A camera_pose_t message's bytes (a subscriber's, `lifmcr relate`): the
// record, or an error for bytes that do not decode as one.
Expected<PoseRecord> DecodePoseMessage(const void* data, int size);

// What the statistics message says (pipeline.h fills it).
struct StatsSnapshot {
  std::string stage_name;  // "process:depth"
  double rate_hz = 0;
  int queue_depth = 0, queue_capacity = 0;
  double process_p50_ms = 0, process_p99_ms = 0;
  double to_publication_p50_ms = 0, to_publication_p99_ms = 0;
  std::uint64_t processed = 0, skipped = 0, failed = 0;
  DropCounter drops;  // sync's, all passes
  std::string cameras;  // the serials this process holds, comma-separated
};

class Publisher {
 public:
  static Expected<std::unique_ptr<Publisher>> Create(const PublisherOptions& options);
  ~Publisher();
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  struct FrameCounts {
    std::uint64_t previews = 0, depth = 0, tf = 0, lens_depth = 0;
  };
  FrameCounts PublishFrame(const FrameMeta& meta, const ProcessedFrame& frame);
  void PublishVicon(const ViconFrame& frame, bool is_trigger);
  void PublishExtrinsics(const std::string& reference_serial, const std::string& serial,
                         std::int64_t trigger_index, const processing::CameraPose& c0_from_cx);
  void PublishStats(const StatsSnapshot& stats);
  void PublishPose(const PoseRecord& pose);

  const ChannelNames& channels() const { return channels_; }
  std::uint64_t errors() const { return errors_.load(); }

 private:
  Publisher() = default;
  template <typename Message>
  void PublishOn(lcm::LCM& bus, std::mutex& bus_mutex, const std::string& channel,
                 const Message& message);

  PublisherOptions options_;
  ChannelNames channels_;
  std::unique_ptr<lcm::LCM> own_lcm_;
  lcm::LCM* lcm_ = nullptr;
  std::mutex lcm_mutex_;
  std::unique_ptr<lcm::LCM> vicon_lcm_;
  std::mutex vicon_lcm_mutex_;
  std::atomic<std::uint64_t> errors_{0};
  std::string source_;  // "<host name>:<pid>" (the STATS message's source)
};

}  // namespace lifmcr::apps
