// PosePairing (pose_pairing.h).

#include "apps/pipeline/pose_pairing.h"

#include <sstream>

namespace lifmcr::apps {

namespace {
constexpr std::size_t kDroppedKept = 4096;  // triggers remembered to tell a late pose
}

Status PosePairingOptions::Check() const {
  if (wait.count() <= 0) return Error{"pose pairing: wait: expected > 0 ms"};
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    if (cameras[i].empty()) return Error{"pose pairing: cameras: an empty serial"};
    for (std::size_t j = i + 1; j < cameras.size(); ++j)
      if (cameras[i] == cameras[j]) return Error{"pose pairing: cameras: " + cameras[i] + " twice"};
  }
  // reference_serial: any (empty: the poses').
  return Status::Ok();
}

PosePairing::Added PosePairing::Add(const PoseRecord& pose, std::int64_t now_ns) {
  Added added;
  const std::string where = "camera " + pose.serial + " trigger " +
                            std::to_string(pose.trigger_index) + " (pass " +
                            std::to_string(pose.pass) + ")";
  if (options_.reference_serial.empty()) options_.reference_serial = pose.reference_serial;
  if (pose.reference_serial != options_.reference_serial) {
    ++refused_;
    added.refused = where + ": relative to camera " + pose.reference_serial +
                    "'s map, expected camera " + options_.reference_serial + "'s";
    return added;
  }
  const Key key{pose.pass, pose.trigger_index};
  if (reported_.count(key)) {
    ++refused_;
    added.refused = where + ": late, the trigger was dropped after " +
                    std::to_string(options_.wait.count()) + " ms";
    return added;
  }
  cameras_.insert(pose.serial);
  Trigger& trigger = triggers_[key];
  if (trigger.poses.empty()) trigger.first_ns = now_ns;
  if (!trigger.poses.emplace(pose.serial, pose).second) {
    ++refused_;
    added.refused = where + ": a second pose (two processes hold the camera?)";
    return added;
  }
  const std::string& zero = options_.reference_serial;
  const auto reference = trigger.poses.find(zero);
  if (reference == trigger.poses.end()) return added;
  for (const auto& [serial, x] : trigger.poses) {
    if (serial == zero || trigger.related.count(serial)) continue;
    if (pose.serial != zero && serial != pose.serial) continue;
    added.pairs.push_back(PosePair{reference->second, x});
    trigger.related.insert(serial);
    ++paired_[serial];
  }
  return added;
}

std::string PosePairing::Drop(const Key& key, const Trigger& trigger) {
  reported_.insert(key);
  while (reported_.size() > kDroppedKept) reported_.erase(reported_.begin());
  std::string missing;
  for (const std::string& serial : cameras_) {
    if (trigger.poses.count(serial)) continue;
    missing += (missing.empty() ? "" : ", ") + serial;
    ++lacked_[serial];
  }
  if (missing.empty()) return {};
  return "trigger " + std::to_string(key.second) + " (pass " + std::to_string(key.first) +
         "): no pose of camera " + missing + " within " + std::to_string(options_.wait.count()) +
         " ms";
}

std::vector<std::string> PosePairing::Expire(std::int64_t now_ns) {
  std::vector<std::string> lines;
  const std::int64_t wait_ns = static_cast<std::int64_t>(options_.wait.count()) * 1'000'000;
  for (auto it = triggers_.begin(); it != triggers_.end();) {
    if (now_ns - it->second.first_ns < wait_ns) {
      ++it;
      continue;
    }
    std::string line = Drop(it->first, it->second);
    if (!line.empty()) lines.push_back(std::move(line));
    it = triggers_.erase(it);
  }
  return lines;
}

std::vector<std::string> PosePairing::Flush() {
  std::vector<std::string> lines;
  for (const auto& [key, trigger] : triggers_) {
    std::string line = Drop(key, trigger);
    if (!line.empty()) lines.push_back(std::move(line));
  }
  triggers_.clear();
  return lines;
}

std::string PosePairing::Report() const {
  const auto list = [](const std::map<std::string, std::uint64_t>& counts) {
    std::string out;
    for (const auto& [serial, n] : counts)
      out += (out.empty() ? "" : ", ") + serial + " " + std::to_string(n);
    return out.empty() ? std::string("none") : out;
  };
  std::ostringstream out;
  out << "pairs with camera 0 ("
      << (options_.reference_serial.empty() ? "-" : options_.reference_serial)
      << ") per camera: " << list(paired_)
      << "; triggers lacking a camera's pose: " << list(lacked_) << "; poses refused: " << refused_;
  return out.str();
}

}  // namespace lifmcr::apps
