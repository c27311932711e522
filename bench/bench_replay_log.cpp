// bench_replay_log: what a stock lcm-logger recorded of a replay, per camera,
// against the frames the sequence holds: the gate of a timed replay with live
// registration is a depth and a TF message for >= 90 % of each camera's
// frames (bench/timed_replay.sh makes the log; bench/README.md).
//
// Per camera (its serial in the messages): the sequence's frames times the
// passes (--passes, for a looped replay); the DEPTH messages split by their
// `geometry` (per-lens: the lens lane's GEOMETRY_LENS_GRID; dense: the depth
// lane's GEOMETRY_TOTALLY_FOCUSED) and the frames they cover; the TF
// messages and frames; the frames with a depth (either kind) and a TF
// message, the gate's figure; POSE messages by localisation; for camera X
// (every camera but the POSE messages' reference), the EXTRINSICS messages,
// `ok` ones and the triggers they cover of the sequence's. A frame is its
// (pass, frame_id) where the message says its pass (POSE), else its
// (trigger_index, frame_id): a looped replay's passes repeat frame ids,
// which the per-frame counts then merge (the message counts do not).
//
//   bench_replay_log --log FILE --sequence SEQ_DIR [--passes N (1)]
//                    [--prefix LIFMCR]

#include "bench/bench_usage.h"
#include "lcm_types/safe_decode.h"
#include "replay/sequence.h"

#include <lcm/lcm-cpp.hpp>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <set>
#include <string>
#include <utility>

namespace {

constexpr const char* kUsage =
    "usage: bench_replay_log --log FILE --sequence SEQ_DIR [--passes N (1)] [--prefix LIFMCR]\n"
    "  Counts, per camera, what an lcm-logger log of a replay holds against the sequence's\n"
    "  frames: per-lens and dense DEPTH messages (by geometry), TF, POSE by localisation,\n"
    "  EXTRINSICS per trigger; the frames with a depth and a TF message (the timed-replay\n"
    "  gate: >= 90 % of each camera's frames). bench/timed_replay.sh records the log.\n";

using FrameKey = std::pair<std::int64_t, std::int64_t>;  // trigger_index, frame_id

struct CameraCounts {
  std::size_t sequence_frames = 0;
  int lens_depth = 0, dense_depth = 0, other_depth = 0, tf = 0, previews = 0;
  std::set<FrameKey> lens_frames, dense_frames, tf_frames;
  int poses = 0;
  std::map<std::string, int> poses_by;
  int extrinsics = 0, extrinsics_ok = 0;
  std::set<std::int64_t> extrinsics_triggers;
};

bool EndsWith(const std::string& s, const char* tail) {
  const std::size_t n = std::strlen(tail);
  return s.size() >= n && s.compare(s.size() - n, n, tail) == 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string log_path, sequence_dir, prefix = "LIFMCR";
  int passes = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool more = i + 1 < argc;
    if (a == "--log" && more) {
      log_path = argv[++i];
    } else if (a == "--sequence" && more) {
      sequence_dir = argv[++i];
    } else if (a == "--passes" && more) {
      passes = std::atoi(argv[++i]);
    } else if (a == "--prefix" && more) {
      prefix = argv[++i];
    } else {
      std::fprintf(stderr, "bench_replay_log: unknown or incomplete argument '%s'\n%s", a.c_str(),
                   kUsage);
      return 2;
    }
  }
  if (log_path.empty() || sequence_dir.empty() || passes < 1) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  auto layout = lifmcr::DiscoverSequence(sequence_dir);
  if (!layout) {
    std::fprintf(stderr, "bench_replay_log: %s\n", layout.error().message.c_str());
    return 1;
  }
  std::map<std::string, CameraCounts> cameras;
  std::size_t triggers = 0;
  for (const lifmcr::CameraFolder& camera : layout->cameras) {
    cameras[camera.serial].sequence_frames = camera.frames.size() * static_cast<std::size_t>(passes);
    triggers = std::max(triggers, camera.frames.size());
  }
  lcm::LogFile log(log_path, "r");
  if (!log.good()) {
    std::fprintf(stderr, "bench_replay_log: cannot read the log %s\n", log_path.c_str());
    return 1;
  }
  const std::string head = prefix + "_";
  std::string reference;
  std::size_t events = 0, undecoded = 0;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    const std::string& channel = event->channel;
    if (channel.rfind(head, 0) != 0) continue;
    ++events;
    if (EndsWith(channel, "_DEPTH")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::depth_image_t>(event->data, event->datalen);
      if (!m) {
        ++undecoded;
        continue;
      }
      CameraCounts& c = cameras[m->serial];
      const FrameKey key{m->trigger_index, m->frame_id};
      if (m->geometry == lifmcr_lcm::depth_image_t::GEOMETRY_LENS_GRID) {
        ++c.lens_depth;
        c.lens_frames.insert(key);
      } else if (m->geometry == lifmcr_lcm::depth_image_t::GEOMETRY_TOTALLY_FOCUSED) {
        ++c.dense_depth;
        c.dense_frames.insert(key);
      } else {
        ++c.other_depth;
      }
    } else if (EndsWith(channel, "_TF") || EndsWith(channel, "_PREVIEW")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::preview_image_t>(event->data, event->datalen);
      if (!m) {
        ++undecoded;
        continue;
      }
      CameraCounts& c = cameras[m->serial];
      if (EndsWith(channel, "_TF")) {
        ++c.tf;
        c.tf_frames.insert({m->trigger_index, m->frame_id});
      } else {
        ++c.previews;
      }
    } else if (EndsWith(channel, "_POSE")) {
      auto m = lifmcr_lcm::SafeDecode<lifmcr_lcm::camera_pose_t>(event->data, event->datalen);
      if (!m) {
        ++undecoded;
        continue;
      }
      reference = m->reference_serial;
      CameraCounts& c = cameras[m->serial];
      ++c.poses;
      ++c.poses_by[m->status == "ok" ? m->localisation : m->localisation + " (failed)"];
    } else if (EndsWith(channel, "_EXTRINSICS")) {
      auto m =
          lifmcr_lcm::SafeDecode<lifmcr_lcm::camera_extrinsics_t>(event->data, event->datalen);
      if (!m) {
        ++undecoded;
        continue;
      }
      reference = m->reference_serial;
      CameraCounts& c = cameras[m->serial];
      ++c.extrinsics;
      if (m->status == "ok") {
        ++c.extrinsics_ok;
        c.extrinsics_triggers.insert(m->trigger_index);
      }
    }
  }
  std::printf("log %s: %zu %s messages (%zu not decodable); sequence %s: %zu triggers x %d "
              "pass(es)\n",
              log_path.c_str(), events, head.c_str(), undecoded, sequence_dir.c_str(), triggers,
              passes);
  bool all = true;
  for (const auto& [serial, c] : cameras) {
    std::size_t both = 0, lens_and_tf = 0;
    for (const FrameKey& key : c.tf_frames) {
      if (c.lens_frames.count(key) || c.dense_frames.count(key)) ++both;
      if (c.lens_frames.count(key)) ++lens_and_tf;
    }
    const double n = static_cast<double>(c.sequence_frames);
    const double fraction = n > 0 ? static_cast<double>(both) / n : 0.0;
    all = all && fraction >= 0.9;
    std::printf("camera %s%s: frames replayed %zu | DEPTH per-lens %d (%zu frames), dense %d (%zu "
                "frames)%s | TF %d (%zu frames) | PREVIEW %d\n",
                serial.c_str(), serial == reference ? " (reference)" : "", c.sequence_frames,
                c.lens_depth, c.lens_frames.size(), c.dense_depth, c.dense_frames.size(),
                c.other_depth ? (" other geometry " + std::to_string(c.other_depth)).c_str() : "",
                c.tf, c.tf_frames.size(), c.previews);
    std::string poses;
    for (const auto& [how, k] : c.poses_by) poses += " " + how + " " + std::to_string(k);
    std::printf("  POSE %d:%s\n", c.poses, poses.empty() ? " none" : poses.c_str());
    if (serial != reference && !reference.empty())
      std::printf("  EXTRINSICS %d (%d ok), %zu of %zu triggers (%.1f %%)\n", c.extrinsics,
                  c.extrinsics_ok, c.extrinsics_triggers.size(), triggers,
                  triggers > 0 ? 100.0 * static_cast<double>(c.extrinsics_triggers.size()) /
                                     static_cast<double>(triggers)
                               : 0.0);
    std::printf("  frames with a depth and a TF message: %zu of %zu (%.1f %%; per-lens depth and "
                "its TF: %zu) %s\n",
                both, c.sequence_frames, 100.0 * fraction, lens_and_tf,
                fraction >= 0.9 ? "(>= 90 %: met)" : "(gate >= 90 %: not met)");
  }
  std::printf("gate (a depth and a TF message for >= 90 %% of each camera's frames): %s\n",
              all ? "met" : "not met");
  return 0;
}
