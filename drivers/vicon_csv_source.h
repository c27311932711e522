#pragma once
// Vicon poses played back from a CSV export (replay/vicon_csv.h), through
// the same ViconSource interface as the live stream.
//
// Every object of the rig is read with ExtractSubjectPoses (rotation and
// handedness from the options, as the rig file says); each frame number of
// the file becomes one ViconFrame listing the objects in the given order,
// an object without a sample or with empty cells as untracked. Rows with a
// sub frame > 0 are skipped (Tracker writes sub frame 0 only). Frame numbers
// missing from the file are counted as gaps when the frames around them are
// delivered.
//
// Timing: `realtime` plays frames at the file's rate (or `rate_hz`) from
// Start, host_ns being the time a frame was due; otherwise as fast as Next is
// called, host_ns the time of delivery.

#include "drivers/vicon_source.h"
#include "replay/vicon_poses.h"

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lifmcr {

struct ViconCsvSourceOptions {
  ViconPoseOptions pose;             // rotation representation and handedness of the file
  std::vector<std::string> objects;  // objects to deliver, at least one (ViconObjectsOfRig)
  bool realtime = true;              // original timing; false = as fast as possible
  double rate_hz = 0.0;              // 0 = the rate written in the file's block
  // The replay's own clock (as ReplayCameraOptions): when set, host_ns =
  // start + (frame - first frame) / rate, whatever the pacing.
  std::optional<std::int64_t> sequence_clock_start_ns{};
  Status Check() const;  // every field; the message names the field
};

class ViconCsvSource : public ViconSource {
 public:
  // Reads and converts the whole file. Errors: the file's (naming line and
  // column), an object not in the file (listing those there), no objects, a
  // rate <= 0.
  static Expected<std::unique_ptr<ViconCsvSource>> Open(const std::filesystem::path& csv,
                                                        const ViconCsvSourceOptions& options);
  // The same from a parsed export (csv.path names it in messages).
  static Expected<std::unique_ptr<ViconCsvSource>> FromCsv(const ViconCsv& csv,
                                                           const ViconCsvSourceOptions& options);

  Status Start() override;  // (re)starts at the first frame
  Status Stop() override;
  Expected<std::optional<ViconFrame>> Next(std::chrono::milliseconds timeout) override;
  // Any thread (the replay's main loop polls it while the rig's Vicon thread
  // calls Next).
  bool Finished() const override {
    return next_.load(std::memory_order_acquire) >= frames_.size();
  }
  ViconSourceStats Stats() const override;

  std::size_t frame_count() const { return frames_.size(); }
  double rate_hz() const { return rate_hz_; }

 private:
  ViconCsvSource() = default;
  std::vector<ViconFrame> frames_;  // host_ns filled at delivery
  double rate_hz_ = 0.0;
  bool realtime_ = true;
  std::optional<std::int64_t> sequence_clock_start_ns_;
  bool started_ = false;
  // The next frame to deliver: written by Next's thread, read by Finished's
  // (TSan found the plain size_t racing in `lifmcr replay`).
  std::atomic<std::size_t> next_{0};
  std::int64_t start_host_ns_ = 0;
  std::atomic<std::uint64_t> delivered_{0}, gaps_{0};
};

}  // namespace lifmcr
