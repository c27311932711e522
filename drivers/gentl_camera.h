#pragma once
// A camera behind a GenTL producer (.cti): CoaXPress bodies such as the
// R32's Basler boost on a frame grabber, or any device a vendor's producer
// serves. GenTL and Aravis stay out of this header.
//
// Finding the device: the producer is `driver.cti`, or, when empty, the first
// .cti in GENICAM_GENTL64_PATH that lists the device (drivers/gentl_producer.h
// checks file, architecture and symbols). The device is `driver.device` (a
// device id or a serial), or the camera's `serial`, on interface
// `driver.interface` or on any. A device whose access status is busy, or that
// IFOpenDevice refuses as in use, is an error saying so. Frames carry the rig
// file's serial; Info().serial is what the producer reports.
//
// Features: the remote device's port is wrapped as an ArvDevice with
// Aravis's GenICam node map (drivers/gentl_arv_device.h), and the settings
// are applied exactly as the Aravis driver applies them (drivers/arv_settings.h).
// TLParamsLocked is set around acquisition where the device has it.
//
// Buffers: a FramePool of `pool_buffers` buffers at the payload size (the
// data stream's own PayloadSize when it defines one, else the device's).
// Every pool buffer is announced once per data stream (DSAnnounceBuffer on
// the pool's memory: the grabber writes into it, no copy) with its pool
// index as the private pointer. A buffer is queued (DSQueueBuffer) while the
// driver holds its BufferRef; the frame NextFrame returns takes that
// BufferRef, and the buffer is queued again on the first NextFrame after the
// last consumer released it. With every buffer held by consumers the
// producer has nowhere to write and counts an underrun
// (STREAM_INFO_NUM_UNDERRUN).
//
// Frames: NextFrame waits on the data stream's EVENT_NEW_BUFFER in slices of
// 10 ms (so released buffers are queued again in time), then reads the
// buffer's info: BUFFER_INFO_FRAMEID, BUFFER_INFO_TIMESTAMP_NS (or TIMESTAMP
// with the device's tick frequency; the host time when there is none),
// SIZE_FILLED, WIDTH/HEIGHT, IMAGEOFFSET, PIXELFORMAT (PFNC), IS_INCOMPLETE,
// DATA_LARGER_THAN_BUFFER. Status: incomplete or fewer bytes than the image =
// kIncomplete; larger than the buffer, another size or pixel format = kError.
// host_ns is CLOCK_REALTIME when the event arrived (GenTL gives no host time).
//
// Chunks: where the device offers ChunkModeActive with ChunkSelector entries
// Timestamp and FrameID, the driver enables them and takes ChunkTimestamp
// (the camera's clock at exposure) and ChunkFrameID from each buffer in
// place of the producer's buffer timestamp and frame id
// (drivers/gentl_chunks.h).
//
// Statistics as the Aravis driver's: missing_ids are gaps in the frame id
// (16-bit wrap-aware for a GigE Vision producer, "GEV", 64-bit otherwise)
// less the underruns counted since the previous frame.
//
// Lost camera: a failed EventGetData (anything but a timeout), a port access
// failing with GC_ERR_IO/INVALID_HANDLE/NOT_AVAILABLE/TIMEOUT (a software
// trigger, or the probe: one read of Width after `probe_after` without a
// frame), or `max_consecutive_failures` failed frames in a row with a failed
// probe mark the camera lost. NextFrame then returns an error once, closes
// the stream and device (revoking the buffers), and on later calls looks for
// the device again every `reconnect_interval`, re-applies the settings,
// restarts acquisition if it was started and counts a reconnect; each loss is
// a CameraGap.
//
// Threads: Open/Start/Stop/NextFrame belong to one (grab) thread;
// SoftwareTrigger, Info, Stats, Gaps and FeatureValue may be called from any.

#include "config/rig_config.h"
#include "drivers/camera.h"
#include "drivers/camera_gap.h"

#include <chrono>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr {

struct GenTlCameraOptions {
  int camera_index = 0;   // position in the rig file, copied into every Frame
  int pool_buffers = 16;  // frames in flight: queued in the producer plus held by consumers, >= 2
  // free_run trigger only: AcquisitionFrameRate to set; 0 = the camera's own.
  double free_run_rate_hz = 0.0;
  // No frame for this long: probe the device (one register read).
  std::chrono::milliseconds probe_after{1000};
  // While lost: the least time between two attempts to find the device again.
  std::chrono::milliseconds reconnect_interval{500};
  // Failed frames in a row that make the driver probe the device, >= 1.
  int max_consecutive_failures = 50;
  // Timeout of TLUpdateInterfaceList / IFUpdateDeviceList while looking for the device.
  std::chrono::milliseconds discovery_timeout{500};

  Status Check() const;
};

class GenTlCamera final : public Camera {
 public:
  GenTlCamera(CameraConfig config, GenTlCameraOptions options = {});
  ~GenTlCamera() override;
  GenTlCamera(const GenTlCamera&) = delete;
  GenTlCamera& operator=(const GenTlCamera&) = delete;

  Status Open() override;
  Status Start() override;
  Status Stop() override;
  Expected<std::optional<Frame>> NextFrame(std::chrono::milliseconds timeout) override;
  Status SoftwareTrigger() override;
  CameraInfo Info() const override;
  CameraStats Stats() const override;
  std::optional<std::int64_t> ArmedDeviceNs() const override;

  // Every loss since Open, in order; the last has back_host_ns == 0 while lost.
  std::vector<CameraGap> Gaps() const;
  bool IsLost() const;
  // The current value of a GenICam feature as the device reports it, read
  // through the producer's port; an error naming the feature otherwise.
  Expected<std::string> FeatureValue(const std::string& feature) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lifmcr
