#pragma once
// A GigE Vision or USB3 Vision camera through Aravis 0.8 (and Aravis's
// in-process "Fake" camera for tests). Aravis stays out of this header; it is
// linked privately into lifmcr_drivers.
//
// Finding the device: `CameraConfig::driver.address` (an Aravis device id such
// as "Aravis-Fake-GV01", a serial or an IP address) or, when empty, the
// camera's `serial`. Names starting with "Fake_" enable Aravis's in-process
// Fake interface first ("Fake_1"). Frames carry the rig file's serial (the
// name of the camera's folder in a recording); Info().serial is what the
// device reports.
//
// Settings applied at Open, in this order, each failure naming the camera and
// the GenICam feature: PixelFormat, region (the `roi`, or the full sensor),
// ExposureTime, Gain (skipped when the camera has none and gain_db is 0), the
// trigger (all selectors off, then FrameStart: hardware = TriggerMode On,
// TriggerSource <source>, TriggerActivation; software = TriggerSource
// Software; free_run = TriggerMode Off, AcquisitionFrameRate when given),
// AcquisitionMode Continuous, and on GigE Vision the packet size (0 =
// negotiated by Aravis; a camera that cannot negotiate keeps its own) and
// the stream's socket buffer (0 = AUTO, sized to the payload).
//
// Packet socket: as root Aravis receives GigE Vision streams through an
// AF_PACKET socket, which sees no traffic on the loopback interface (0
// frames, measured with arv-fake-gv-camera-0.8 -i lo). The driver therefore disables it for a
// device whose address is a loopback address, and only there; real cameras
// keep the faster path. Nothing in the rig file is needed.
//
// Buffers: a FramePool of `pool_buffers` buffers at the payload size; each
// pool buffer is wrapped once in an ArvBuffer (arv_buffer_new_full, the
// pool's memory, no copy). While a buffer is queued in the stream the driver
// holds its BufferRef; a popped frame takes that BufferRef, and every call to
// NextFrame first queues every pool buffer its consumers have released. When
// the consumers hold every buffer the camera's frames are dropped by Aravis
// and counted as underruns.
//
// Statistics: completed/failed count the frames NextFrame delivered (status
// kOk / any other), underruns and missing packets come from the Aravis
// stream, missing_ids from gaps in the frame counter (FrameIdTracker:
// 16-bit wrap-aware on GigE Vision and the Fake camera, 64-bit on USB3
// Vision) less the underruns since the previous frame, so a frame dropped
// for lack of a buffer is counted once. Counters survive reconnects.
//
// Lost camera: the device's "control-lost" signal (GigE heartbeat), a failed
// control access (SoftwareTrigger), `max_consecutive_failures` failed frames
// in a row, or a failed probe of the control channel after `probe_after`
// without a frame each mark the camera lost. NextFrame then returns an error
// once (the device is gone), closes the device, and on later calls re-opens
// it by the same address every `reconnect_interval`, re-applies the settings,
// restarts acquisition if it was started and counts a reconnect. USB3
// Vision cameras also follow libusb hotplug events (UsbHotplugMonitor): a
// USB3 Vision device leaving makes the driver probe its camera at once, one
// arriving makes a lost camera try to re-open at once. Re-opening a device
// that is still absent blocks NextFrame for Aravis's discovery timeout (about
// 1 s, 2.5 s for a GigE address that does not answer). Every loss
// is recorded as a CameraGap (host time lost and back, the last frame id
// before and the first after, the reason). The device's frame counter and
// clock usually restart with it, so the ids across a gap are not compared.
//
// Threads: Open/Start/Stop/NextFrame belong to one (grab) thread;
// SoftwareTrigger, Info, Stats and Gaps may be called from any thread.

#include "config/rig_config.h"
#include "drivers/camera.h"
#include "drivers/camera_gap.h"

#include <chrono>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr {

struct AravisCameraOptions {
  int camera_index = 0;   // position in the rig file, copied into every Frame
  int pool_buffers = 16;  // frames in flight: queued in the stream plus held by consumers, >= 2
  // free_run trigger only: AcquisitionFrameRate to set; 0 = the camera's own.
  double free_run_rate_hz = 0.0;
  // No frame for this long: probe the control channel (one register read).
  std::chrono::milliseconds probe_after{1000};
  // While lost: the least time between two attempts to re-open the device.
  std::chrono::milliseconds reconnect_interval{500};
  // Failed frames in a row that mark the stream broken (then probed), >= 1.
  int max_consecutive_failures = 50;

  Status Check() const;
};

class AravisCamera final : public Camera {
 public:
  AravisCamera(CameraConfig config, AravisCameraOptions options = {});
  ~AravisCamera() override;
  AravisCamera(const AravisCamera&) = delete;
  AravisCamera& operator=(const AravisCamera&) = delete;

  Status Open() override;
  Status Start() override;
  Status Stop() override;
  Expected<std::optional<Frame>> NextFrame(std::chrono::milliseconds timeout) override;
  Status SoftwareTrigger() override;
  CameraInfo Info() const override;
  CameraStats Stats() const override;
  std::optional<std::int64_t> ArmedDeviceNs() const override;

  // Every loss since Open, in order; the last one has back_host_ns == 0 while
  // the camera is still lost.
  std::vector<CameraGap> Gaps() const;
  // True while the device is lost (between the error and the reconnect).
  bool IsLost() const;
  // The current value of a GenICam feature as the device reports it
  // ("Mono8", "2000", "On"), read from the device (diagnostics, tests). An
  // error naming the feature when it does not exist or cannot be read, or
  // while the device is lost.
  Expected<std::string> FeatureValue(const std::string& feature) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lifmcr
