#pragma once
// Pairs the poses of one trigger that cameras on several hosts publish on
// <PREFIX>_<SERIAL>_POSE (publisher.h, PoseRecord): the reference camera's
// w0_from_c0 with each other camera X's w0_from_cx, for `lifmcr relate`,
// which relates each pair (registration::ExtrinsicsRelater, the pipeline's
// own relate step) and publishes c0_from_cx on <PREFIX>_<SERIAL>_EXTRINSICS.
//
// Bounded waiting: a trigger (pass, trigger index) waits at most `wait`
// after its first pose arrived here for the poses that complete its pairs;
// then it is dropped and reported, naming the cameras whose pose did not
// come (the rig's cameras when given, PosePairingOptions::cameras, and every
// camera seen on a POSE channel so far are expected of every trigger), never
// dropped silently. A pose that comes after its trigger
// was dropped is refused as late. A trigger stays `wait` also once its
// pairs are made, so a host's pose that comes later still finds its
// reference camera's. No LCM here: the command subscribes and
// hands the decoded poses in.
//
// One thread.

#include "apps/pipeline/publisher.h"
#include "config/error.h"

#include <chrono>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace lifmcr::apps {

struct PosePairingOptions {
  // Camera 0; empty: the reference_serial the first pose names (the map's
  // camera). A pose naming another reference is refused (reported).
  std::string reference_serial;
  std::chrono::milliseconds wait{2000};  // > 0
  // Every camera of the rig (`lifmcr relate --rig`): a camera whose host is
  // down is then reported lacking from the first trigger on. Empty: the
  // cameras seen on the POSE channels.
  std::vector<std::string> cameras;
  Status Check() const;
};

// The reference camera's and camera X's pose of one trigger.
struct PosePair {
  PoseRecord reference;  // w0_from_c0
  PoseRecord camera;     // w0_from_cx
};

class PosePairing {
 public:
  explicit PosePairing(PosePairingOptions options)
      : options_(std::move(options)), cameras_(options_.cameras.begin(), options_.cameras.end()) {}
  // A pose in, at now_ns (host clock of this process): the pairs it
  // completes (with the reference camera's pose: every camera X of the
  // trigger waiting for it; with X's: the one pair), in serial order; or,
  // for a pose refused (a second pose of a camera and trigger, a pose after
  // its trigger was dropped, another reference camera), why.
  struct Added {
    std::vector<PosePair> pairs;
    std::string refused;  // empty: taken
  };
  Added Add(const PoseRecord& pose, std::int64_t now_ns);
  // Triggers that waited `wait` or longer: dropped, one line each
  // ("trigger 5 (pass 0): no pose of camera B within 2000 ms").
  std::vector<std::string> Expire(std::int64_t now_ns);
  // Every trigger still waiting (the end of the run), reported as Expire does.
  std::vector<std::string> Flush();

  const std::string& reference_serial() const { return options_.reference_serial; }
  const std::set<std::string>& cameras() const { return cameras_; }  // serials seen
  // Per camera X, the triggers paired; per camera, the triggers it lacked.
  const std::map<std::string, std::uint64_t>& paired() const { return paired_; }
  const std::map<std::string, std::uint64_t>& lacked() const { return lacked_; }
  std::uint64_t refused() const { return refused_; }  // duplicates, late, other reference
  std::size_t waiting() const { return triggers_.size(); }
  // "paired: B 8; lacked: none; refused 0"
  std::string Report() const;

 private:
  struct Trigger {
    std::int64_t first_ns = 0;
    std::map<std::string, PoseRecord> poses;  // by serial
    std::set<std::string> related;            // cameras X already paired
  };
  using Key = std::pair<std::int64_t, std::int64_t>;  // pass, trigger
  std::string Drop(const Key& key, const Trigger& trigger);
  PosePairingOptions options_;
  std::map<Key, Trigger> triggers_;
  std::set<Key> reported_;  // dropped triggers, to tell a late pose (bounded: newest kept)
  std::set<std::string> cameras_;
  std::map<std::string, std::uint64_t> paired_, lacked_;
  std::uint64_t refused_ = 0;
};

}  // namespace lifmcr::apps
