#pragma once
// A recorded camera folder (SEQ/TypeE_<serial>/, replay/sequence.h) served
// through the Camera interface, so everything downstream of a driver runs
// on recorded data as it would on hardware.
//
// Each frame file is read with ReadBmpInto straight into a pooled buffer
// (rows packed: stride = width * bytes per pixel); no other copy is made.
//
// What a frame carries:
//   frame_id   the frame number of its file name; a frame number missing
//              from the folder is a gap in frame_id, counted in missing_ids
//              (downstream sees the same drop as from the camera);
//   device_ns  frame number * trigger_period: the trigger time on a device
//              clock that started at frame 0, one clock for every camera of
//              the sequence (CameraInfo::device_clock names it);
//   host_ns    CLOCK_REALTIME when the frame was delivered;
//   status     kOk, or kError (counted as failed, no buffer and an empty
//              image) when the file cannot be read: truncated, not a BMP, or
//              another size or format than the camera's first frame.
//
// Pacing:
//   kOriginal          frame f is due at Start + (f - first) * trigger_period
//                      (f - first counted from the frame at Start), gaps
//                      included; NextFrame sleeps until it is due. When no
//                      pooled buffer is free at that moment the frame is lost
//                      like on hardware: an underrun.
//   kAsFastAsPossible  no sleeping; a frame waits (up to the timeout) for a
//                      free buffer instead, so nothing is lost: the consumer
//                      sets the pace.
//   kSoftwareTrigger   one frame per SoftwareTrigger call; no free buffer at
//                      that moment is an underrun.
// After the last frame NextFrame waits out its timeout and returns nullopt,
// as a camera without triggers would; Finished() tells the two apart.
//
// Threads: Open/Start/Stop/NextFrame from one thread; SoftwareTrigger,
// Stats, Info and Finished from any.

#include "drivers/camera.h"

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

namespace lifmcr {

enum class ReplayPacing { kOriginal, kAsFastAsPossible, kSoftwareTrigger };

struct ReplayCameraOptions {
  int camera_index = 0;  // position in the rig file, copied into every Frame
  int pool_buffers = 8;  // >= 1
  // Time between two triggers: LiFMCR's 80 Hz Vicon / 8 = 10 Hz.
  std::chrono::nanoseconds trigger_period{100'000'000};
  ReplayPacing pacing = ReplayPacing::kOriginal;
  // Start over after the last frame, for ever (benchmarks): lap k serves
  // file frame f as frame f + k * (last - first + 1), so ids and device_ns
  // keep increasing and Finished() stays false.
  bool loop = false;
  // The replay's own clock, for a run at as-fast-as-possible pacing: when
  // set, host_ns = sequence_clock_start_ns + device_ns -
  // sequence_origin_device_ns, the time the host would have received the
  // frame at the original timing from that start, so sync places frames by
  // their triggers, not by when the consumer let them be read.
  std::optional<std::int64_t> sequence_clock_start_ns{};
  std::int64_t sequence_origin_device_ns = 0;  // device_ns of the sequence's trigger 0

  Status Check() const;
};

class ReplayCamera final : public Camera {
 public:
  // `camera_dir` is a TypeE_<serial> folder (layout::CameraDir(seq, serial)).
  explicit ReplayCamera(std::filesystem::path camera_dir, ReplayCameraOptions options = {});
  ~ReplayCamera() override;
  ReplayCamera(const ReplayCamera&) = delete;
  ReplayCamera& operator=(const ReplayCamera&) = delete;

  // Lists the folder and reads the first readable frame's header for the
  // size and format; fails when the folder holds no readable frame.
  Status Open() override;
  Status Start() override;
  Status Stop() override;
  Expected<std::optional<Frame>> NextFrame(std::chrono::milliseconds timeout) override;
  // kSoftwareTrigger pacing only: releases one frame.
  Status SoftwareTrigger() override;
  CameraInfo Info() const override;
  CameraStats Stats() const override;

  // Every frame of the folder has been delivered or counted lost.
  bool Finished() const override;
  // Frame files in the folder (after Open).
  std::size_t frame_count() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace lifmcr
