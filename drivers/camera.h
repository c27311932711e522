#pragma once
// The interface every camera driver implements (Aravis GigE/USB3 Vision,
// GenTL, replay). A grab thread owns one Camera and pulls frames from it.
//
// Life cycle: Open (find the device, apply the rig file's settings, allocate
// the frame pool) -> Start -> NextFrame... -> Stop -> (Start again) -> destroy.
// All user-causable failures (no such device, a setting the camera refuses)
// are Status values naming the camera and the setting.

#include "config/error.h"
#include "config/image.h"
#include "drivers/frame.h"

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

namespace lifmcr {

struct CameraInfo {
  std::string serial;
  std::string vendor;
  std::string model;
  std::string device_id;  // the driver's own id (Aravis device id, GenTL device id, sequence path)
  int width = 0;
  int height = 0;
  PixelFormat format = PixelFormat::kMono8;
  std::size_t payload_bytes = 0;
  // The clock Frame::device_ns is on, when other cameras may share it (the
  // same name: device times compare, sync/first_frame_placement.h); empty:
  // a clock of this camera's own. The rig file's cameras[].device_clock
  // overrides it (PTP, one frame grabber's timestamps).
  std::string device_clock;
};

// Counters since Open. Every frame the camera produced (or should have, by
// its counter) ends up in exactly one of them: delivered complete, delivered
// failed, dropped for lack of a buffer, or missing by its frame id.
struct CameraStats {
  std::uint64_t completed = 0;    // delivered with status kOk
  std::uint64_t failed = 0;       // delivered with another status
  std::uint64_t underruns = 0;    // produced while no pooled buffer was free: lost, counted
  std::uint64_t missing_ids = 0;  // gaps in the device frame counter (wrap-aware)
  std::uint64_t reconnects = 0;   // device lost and found again
  std::uint64_t transferred_bytes = 0;
  // Transport packets that never arrived (GigE Vision); informative: the
  // frames they belonged to are already in `failed` or `missing_ids`.
  std::uint64_t missing_packets = 0;
};

class Camera {
 public:
  virtual ~Camera() = default;

  virtual Status Open() = 0;
  virtual Status Start() = 0;
  virtual Status Stop() = 0;

  // The next frame, or nullopt when none arrived within `timeout`. An error
  // means the device is gone (the driver may reconnect on the next call and
  // counts it in `reconnects`).
  virtual Expected<std::optional<Frame>> NextFrame(std::chrono::milliseconds timeout) = 0;

  // Fires one software trigger (cameras in software trigger mode; tests and
  // the replay driver). An error on cameras that cannot.
  virtual Status SoftwareTrigger() = 0;

  virtual CameraInfo Info() const = 0;
  virtual CameraStats Stats() const = 0;
  // A source with an end (replay) has delivered everything; a live camera never has.
  virtual bool Finished() const { return false; }
  // The device clock (that of Frame::device_ns) read right after the latest
  // Start armed the camera (SFNC TimestampLatch, GigE Vision
  // GevTimestampControlLatch); nullopt when the device cannot latch it. The
  // rig tells triggers before a camera was armed from triggers it missed
  // (sync/armed_start.h).
  virtual std::optional<std::int64_t> ArmedDeviceNs() const { return std::nullopt; }
};

}  // namespace lifmcr
