#include "drivers/aravis_camera.h"

#include "drivers/arv_settings.h"
#include "drivers/frame_id_tracker.h"
#include "drivers/frame_pool.h"
#include "drivers/usb_hotplug.h"

#include <arv.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <mutex>
#include <thread>

namespace lifmcr {
namespace {

using Clock = std::chrono::steady_clock;

FrameStatus MapStatus(ArvBufferStatus status) {
  switch (status) {
    case ARV_BUFFER_STATUS_SUCCESS:
      return FrameStatus::kOk;
    case ARV_BUFFER_STATUS_MISSING_PACKETS:
    case ARV_BUFFER_STATUS_WRONG_PACKET_ID:
      return FrameStatus::kIncomplete;
    case ARV_BUFFER_STATUS_TIMEOUT:
      return FrameStatus::kTimeout;
    default:  // UNKNOWN, CLEARED, SIZE_MISMATCH, FILLING, ABORTED
      return FrameStatus::kError;
  }
}

bool IsLoopbackDevice(ArvDevice* device) {
  if (!ARV_IS_GV_DEVICE(device)) return false;
  GSocketAddress* address = arv_gv_device_get_device_address(ARV_GV_DEVICE(device));
  if (address == nullptr || !G_IS_INET_SOCKET_ADDRESS(address)) return false;
  GInetAddress* inet = g_inet_socket_address_get_address(G_INET_SOCKET_ADDRESS(address));
  return inet != nullptr && g_inet_address_get_is_loopback(inet);
}

// One pool buffer and the ArvBuffer wrapping its memory. `queued` holds the
// pool's BufferRef while the buffer sits in the stream.
struct Slot {
  ArvBuffer* arv = nullptr;  // owned: one reference, for the camera's lifetime
  BufferRef queued;
};

}  // namespace

Status AravisCameraOptions::Check() const {
  if (pool_buffers < 2)
    return Error{"aravis options: pool_buffers must be >= 2, got " + std::to_string(pool_buffers)};
  if (!(free_run_rate_hz >= 0.0) || !std::isfinite(free_run_rate_hz))
    return Error{"aravis options: free_run_rate_hz must be >= 0"};
  if (camera_index < 0) return Error{"aravis options: camera_index must be >= 0"};
  if (probe_after.count() <= 0 || reconnect_interval.count() <= 0)
    return Error{"aravis options: probe_after and reconnect_interval must be > 0"};
  if (max_consecutive_failures < 1)
    return Error{"aravis options: max_consecutive_failures must be >= 1"};
  return Status::Ok();
}

struct AravisCamera::Impl {
  CameraConfig config;
  AravisCameraOptions options;
  std::string label;  // "camera cam0 (serial 123)" for messages

  // Guards camera/stream lifetime against SoftwareTrigger and the
  // control-lost flag; the grab thread is the only one that changes them.
  mutable std::mutex control_mutex;
  ArvCamera* camera = nullptr;
  ArvStream* stream = nullptr;
  gulong control_lost_handler = 0;
  std::atomic<bool> control_lost{false};
  std::atomic<bool> control_suspect{false};  // a control access failed: probe it

  std::shared_ptr<FramePool> pool;
  std::vector<Slot> slots;
  std::size_t payload_bytes = 0;
  int missing_packets_info = -1;    // index of n_missing_packets in the stream infos
  int transferred_bytes_info = -1;  // index of n_transferred_bytes
  FrameIdTracker ids{FrameIdWidth::k16Bit};
  bool started = false;
  bool opened = false;

  // Lost state (grab thread), published through `lost` for other threads.
  CameraReconnect loss;  // lost, reported, reconnect tries, gaps (camera_gap.h)
  Clock::time_point last_activity{};  // last frame, open or probe
  int consecutive_failures = 0;
  // Underruns, in frames. Aravis's n_underruns counts frames on the Fake
  // camera and USB3 Vision but packets on GigE Vision, where each packet
  // that finds no buffer counts; so the driver counts frames itself: the id
  // gap before the next frame when Aravis saw underruns meanwhile, else
  // Aravis's count divided by its units per frame.
  std::uint64_t underrun_frames = 0;
  std::uint64_t underruns_at_last_frame = 0;  // this stream's n_underruns at the last frame
  std::uint64_t underrun_units_per_frame = 1;
  // USB3 Vision cameras: the process-wide hotplug monitor and the generation
  // last seen; a change means a USB3 Vision device came or went.
  UsbHotplugMonitor* usb = nullptr;
  std::uint64_t usb_generation = 0;

  bool UsbChanged() {
    if (usb == nullptr) return false;
    const std::uint64_t now = usb->generation();
    if (now == usb_generation) return false;
    usb_generation = now;
    return true;
  }

  mutable std::mutex stats_mutex;
  CameraStats stats;
  CameraStats closed_streams;  // counters of streams already destroyed
  CameraInfo info;
  std::optional<std::int64_t> armed_device_ns;  // latched after AcquisitionStart

  std::string DeviceName() const {
    return config.driver.address.empty() ? config.serial : config.driver.address;
  }

  Error Fail(const std::string& what) const { return Error{label + ": " + what}; }
  Error FailFeature(const std::string& feature, const std::string& value, GError* error) const {
    return Fail("setting " + feature + " to " + value + ": " + TakeMessage(error));
  }

  Status Connect();
  Status ApplySettings();
  Status CreateStream();
  void Disconnect();
  void TopUp();
  void RefreshAravisStats();
  void MarkLost(const std::string& reason);
  bool Probe();
  Frame MakeFrame(ArvBuffer* buffer);
};

namespace {

void OnControlLost(ArvDevice* /*device*/, gpointer user_data) {
  // Runs in Aravis's heartbeat thread: only raise the flag.
  static_cast<std::atomic<bool>*>(user_data)->store(true);
}

}  // namespace

Status AravisCamera::Impl::Connect() {
  const std::string name = DeviceName();
  if (name.rfind("Fake_", 0) == 0) arv_enable_interface("Fake");
  GError* error = nullptr;
  ArvCamera* opened_camera = arv_camera_new(name.c_str(), &error);
  if (opened_camera == nullptr)
    return Fail("cannot open Aravis device '" + name + "': " + TakeMessage(error));
  {
    std::lock_guard<std::mutex> lock(control_mutex);
    camera = opened_camera;
  }
  ArvDevice* device = arv_camera_get_device(camera);
  control_lost.store(false);
  control_lost_handler =
      g_signal_connect(device, "control-lost", G_CALLBACK(OnControlLost), &control_lost);
  if (arv_camera_is_gv_device(camera) && IsLoopbackDevice(device))
    arv_camera_gv_set_stream_options(camera, ARV_GV_STREAM_OPTION_PACKET_SOCKET_DISABLED);
  const bool usb3 = arv_camera_is_uv_device(camera);
  ids = FrameIdTracker(usb3 ? FrameIdWidth::k64Bit : FrameIdWidth::k16Bit);
  if (usb3 && usb == nullptr) {
    usb = UsbHotplugMonitor::Shared();  // nullptr without hotplug: probes still work
    if (usb != nullptr) usb_generation = usb->generation();
  }
  if (Status status = ApplySettings(); !status) {
    Disconnect();
    return status;
  }
  if (Status status = CreateStream(); !status) {
    Disconnect();
    return status;
  }
  last_activity = Clock::now();
  return Status::Ok();
}

Status AravisCamera::Impl::ApplySettings() {
  auto region = ApplyArvCameraSettings(camera, config, options.free_run_rate_hz, label);
  if (!region) return region.error();
  const int width = region->width;
  const int height = region->height;
  GError* error = nullptr;
  if (arv_camera_is_gv_device(camera)) {
    if (config.packet_size_bytes > 0) {
      arv_camera_gv_set_packet_size(camera, config.packet_size_bytes, &error);
      if (error != nullptr)
        return FailFeature("GevSCPSPacketSize", std::to_string(config.packet_size_bytes), error);
    } else {
      // A camera that cannot fire test packets keeps its own packet size.
      arv_camera_gv_auto_packet_size(camera, &error);
      if (error != nullptr) g_clear_error(&error);
    }
  } else if (config.packet_size_bytes > 0 || config.socket_buffer_bytes > 0) {
    return Fail("packet_size and socket_buffer apply to GigE Vision cameras only");
  }

  const guint payload = arv_camera_get_payload(camera, &error);
  if (error != nullptr) return Fail("reading PayloadSize: " + TakeMessage(error));
  if (payload == 0) return Fail("the camera reports a PayloadSize of 0");
  if (payload_bytes != 0 && payload != payload_bytes)
    return Fail("PayloadSize changed from " + std::to_string(payload_bytes) + " to " +
                std::to_string(payload) + " after reconnecting");
  const std::size_t image_bytes = static_cast<std::size_t>(width) * height *
                                  BytesPerPixel(BufferPixelFormat(config.pixel_format));
  if (payload < image_bytes)
    return Fail("PayloadSize " + std::to_string(payload) + " is smaller than the image (" +
                std::to_string(image_bytes) + " bytes)");
  payload_bytes = payload;

  CameraInfo new_info;
  const char* text = arv_camera_get_device_serial_number(camera, nullptr);
  new_info.serial = text != nullptr ? text : "";
  text = arv_camera_get_vendor_name(camera, nullptr);
  new_info.vendor = text != nullptr ? text : "";
  text = arv_camera_get_model_name(camera, nullptr);
  new_info.model = text != nullptr ? text : "";
  text = arv_camera_get_device_id(camera, nullptr);
  new_info.device_id = text != nullptr ? text : DeviceName();
  new_info.width = width;
  new_info.height = height;
  new_info.format = BufferPixelFormat(config.pixel_format);
  new_info.payload_bytes = payload;
  std::lock_guard<std::mutex> lock(stats_mutex);
  info = new_info;
  return Status::Ok();
}

Status AravisCamera::Impl::CreateStream() {
  if (!pool) {
    pool = FramePool::Create(static_cast<std::size_t>(options.pool_buffers), payload_bytes);
    slots.resize(pool->size());
    // Wrap every pool buffer once. The pool hands out each index once here,
    // and the BufferRefs go straight back so the buffers are free again.
    std::vector<BufferRef> all;
    while (BufferRef ref = pool->Acquire()) all.push_back(std::move(ref));
    for (const BufferRef& ref : all)
      slots[ref->index].arv =
          arv_buffer_new_full(payload_bytes, ref->data, GINT_TO_POINTER(ref->index), nullptr);
  }
  GError* error = nullptr;
  ArvStream* new_stream = arv_camera_create_stream(camera, nullptr, nullptr, &error);
  if (new_stream == nullptr) return Fail("cannot create the stream: " + TakeMessage(error));
  if (ARV_IS_GV_STREAM(new_stream)) {
    if (config.socket_buffer_bytes > 0)
      g_object_set(new_stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED,
                   "socket-buffer-size", static_cast<gint>(config.socket_buffer_bytes), nullptr);
    else
      g_object_set(new_stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, nullptr);
  }
  missing_packets_info = -1;
  transferred_bytes_info = -1;
  const guint n_infos = arv_stream_get_n_infos(new_stream);
  for (guint i = 0; i < n_infos; ++i) {
    const char* name = arv_stream_get_info_name(new_stream, i);
    if (name == nullptr || arv_stream_get_info_type(new_stream, i) != G_TYPE_UINT64) continue;
    if (std::string(name) == "n_missing_packets") missing_packets_info = static_cast<int>(i);
    if (std::string(name) == "n_transferred_bytes") transferred_bytes_info = static_cast<int>(i);
  }
  {
    std::lock_guard<std::mutex> lock(control_mutex);
    stream = new_stream;
  }
  underruns_at_last_frame = 0;
  underrun_units_per_frame = 1;
  if (arv_camera_is_gv_device(camera)) {
    // Leader, data packets (packet size less IP/UDP/GVSP headers), trailer.
    const guint packet = arv_camera_gv_get_packet_size(camera, nullptr);
    const std::uint64_t data_per_packet = packet > 64 ? packet - 36 : 1;
    underrun_units_per_frame = (payload_bytes + data_per_packet - 1) / data_per_packet + 2;
  }
  TopUp();
  return Status::Ok();
}

void AravisCamera::Impl::TopUp() {
  if (stream == nullptr) return;
  while (BufferRef ref = pool->Acquire()) {
    Slot& slot = slots[ref->index];
    slot.queued = std::move(ref);
    g_object_ref(slot.arv);  // the stream's reference, returned by pop
    arv_stream_push_buffer(stream, slot.arv);
  }
}

void AravisCamera::Impl::RefreshAravisStats() {
  if (stream == nullptr) return;
  guint64 completed = 0, failures = 0, underruns = 0;
  arv_stream_get_statistics(stream, &completed, &failures, &underruns);
  // Frames dropped since the last delivered frame, estimated until the next
  // frame's id tells exactly.
  const std::uint64_t pending_units = underruns - underruns_at_last_frame;
  const std::uint64_t pending =
      (pending_units + underrun_units_per_frame - 1) / underrun_units_per_frame;
  const guint64 missing_packets =
      missing_packets_info >= 0 ? arv_stream_get_info_uint64(stream, missing_packets_info) : 0;
  const guint64 transferred =
      transferred_bytes_info >= 0 ? arv_stream_get_info_uint64(stream, transferred_bytes_info) : 0;
  std::lock_guard<std::mutex> lock(stats_mutex);
  stats.underruns = underrun_frames + pending;
  stats.missing_packets = closed_streams.missing_packets + missing_packets;
  if (transferred_bytes_info >= 0)
    stats.transferred_bytes = closed_streams.transferred_bytes + transferred;
}

void AravisCamera::Impl::Disconnect() {
  RefreshAravisStats();
  {
    std::lock_guard<std::mutex> lock(stats_mutex);
    closed_streams = stats;
    underrun_frames = stats.underruns;  // the estimate for the last frames of this stream
  }
  ArvStream* old_stream = nullptr;
  ArvCamera* old_camera = nullptr;
  {
    std::lock_guard<std::mutex> lock(control_mutex);
    old_stream = stream;
    old_camera = camera;
    stream = nullptr;
    camera = nullptr;
  }
  if (old_camera != nullptr && control_lost_handler != 0) {
    g_signal_handler_disconnect(arv_camera_get_device(old_camera), control_lost_handler);
    control_lost_handler = 0;
  }
  if (old_camera != nullptr && started && !loss.lost()) {
    arv_camera_stop_acquisition(old_camera, nullptr);
  }
  if (loss.lost()) {
    // Finalising a lost GigE stream and device blocks for seconds (register
    // writes that time out, the heartbeat thread's retries), so it happens
    // on a detached thread that owns everything it touches: the stream, the
    // camera, and the pool buffers still queued in that stream, which stay
    // out of the pool (and so out of the next stream) until its thread has
    // stopped writing into them.
    std::vector<BufferRef> still_queued;
    for (Slot& slot : slots)
      if (slot.queued) still_queued.push_back(std::move(slot.queued));
    std::thread([old_stream, old_camera, held = std::move(still_queued)]() mutable {
      if (old_stream != nullptr) g_object_unref(old_stream);
      if (old_camera != nullptr) g_object_unref(old_camera);
      held.clear();
    }).detach();
    return;
  }
  // Finalising the stream stops its thread and drops its references on the
  // queued buffers (each slot keeps its own); then the pool gets them back.
  if (old_stream != nullptr) g_object_unref(old_stream);
  for (Slot& slot : slots) slot.queued.reset();
  if (old_camera != nullptr) g_object_unref(old_camera);
}

void AravisCamera::Impl::MarkLost(const std::string& reason) {
  loss.MarkLost(reason, ids.last(), [this] {
    Disconnect();
    ids.Reset();
  });
}

bool AravisCamera::Impl::Probe() {
  std::lock_guard<std::mutex> lock(control_mutex);
  if (camera == nullptr) return false;
  guint32 value = 0;
  GError* error = nullptr;
  // Address 0 is a bootstrap register on GigE Vision (Version) and USB3
  // Vision (GenCP version), and plain memory on the Fake camera.
  const gboolean ok =
      arv_device_read_memory(arv_camera_get_device(camera), 0, sizeof(value), &value, &error);
  if (error != nullptr) g_error_free(error);
  return ok;
}

Frame AravisCamera::Impl::MakeFrame(ArvBuffer* buffer) {
  const int index = GPOINTER_TO_INT(arv_buffer_get_user_data(buffer));
  Frame frame;
  frame.camera_index = options.camera_index;
  frame.serial = config.serial;
  frame.status = MapStatus(arv_buffer_get_status(buffer));
  frame.frame_id = arv_buffer_get_frame_id(buffer);
  frame.host_ns = static_cast<std::int64_t>(arv_buffer_get_system_timestamp(buffer));
  frame.device_ns = static_cast<std::int64_t>(arv_buffer_get_timestamp(buffer));
  if (frame.device_ns == 0) frame.device_ns = frame.host_ns;  // device without a clock
  if (index >= 0 && static_cast<std::size_t>(index) < slots.size())
    frame.buffer = std::move(slots[index].queued);

  if (!frame.buffer) frame.status = FrameStatus::kError;  // not one of ours: cannot happen
  if (frame.status == FrameStatus::kOk) {
    const int width = arv_buffer_get_image_width(buffer);
    const int height = arv_buffer_get_image_height(buffer);
    const PixelFormat format = BufferPixelFormat(config.pixel_format);
    const std::size_t stride = static_cast<std::size_t>(width) * BytesPerPixel(format);
    if (width > 0 && height > 0 && stride * height <= frame.buffer->capacity_bytes)
      frame.image = ImageView{frame.buffer->data, width, height, stride, format};
    else
      frame.status = FrameStatus::kError;  // not an image, or not the configured size
  }
  g_object_unref(buffer);  // the reference the stream returned; the slot keeps its own
  // A frame dropped for lack of a buffer is one underrun, never also a
  // missing id (see underrun_frames).
  guint64 underruns_now = 0;
  arv_stream_get_statistics(stream, nullptr, nullptr, &underruns_now);
  const std::uint64_t new_units = underruns_now - underruns_at_last_frame;
  underruns_at_last_frame = underruns_now;
  const std::uint64_t gap = ids.Observe(frame.frame_id);
  std::uint64_t missing = gap;
  if (new_units > 0) {
    underrun_frames +=
        gap > 0 ? gap : (new_units + underrun_units_per_frame - 1) / underrun_units_per_frame;
    missing = 0;
  }
  loss.log().OnFrame(frame.frame_id, frame.host_ns);
  consecutive_failures = frame.status == FrameStatus::kOk ? 0 : consecutive_failures + 1;
  std::lock_guard<std::mutex> lock(stats_mutex);
  stats.missing_ids += missing;
  if (frame.status == FrameStatus::kOk) {
    ++stats.completed;
    if (transferred_bytes_info < 0) stats.transferred_bytes += payload_bytes;
  } else {
    ++stats.failed;
  }
  return frame;
}

AravisCamera::AravisCamera(CameraConfig config, AravisCameraOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->config = std::move(config);
  impl_->options = options;
  impl_->label = "camera " + impl_->config.name + " (serial " + impl_->config.serial + ")";
}

AravisCamera::~AravisCamera() {
  if (impl_->opened) impl_->Disconnect();
  for (Slot& slot : impl_->slots)
    if (slot.arv != nullptr) g_object_unref(slot.arv);
}

Status AravisCamera::Open() {
  if (impl_->opened) return impl_->Fail("already open");
  if (Status status = impl_->options.Check(); !status) return impl_->Fail(status.error().message);
  if (Status status = impl_->Connect(); !status) return status;
  impl_->opened = true;
  return Status::Ok();
}

Status AravisCamera::Start() {
  if (!impl_->opened) return impl_->Fail("Start before Open");
  impl_->started = true;
  if (impl_->loss.lost()) return Status::Ok();  // acquisition starts with the reconnect
  GError* error = nullptr;
  arv_camera_start_acquisition(impl_->camera, &error);
  if (error != nullptr) {
    impl_->started = false;
    return impl_->Fail("AcquisitionStart: " + TakeMessage(error));
  }
  {
    // GigE Vision counts its timestamp in GevTimestampTickFrequency ticks.
    std::lock_guard<std::mutex> control(impl_->control_mutex);
    ArvDevice* device = arv_camera_get_device(impl_->camera);
    const gint64 tick_hz =
        arv_device_get_feature(device, "GevTimestampTickFrequency") != nullptr
            ? arv_device_get_integer_feature_value(device, "GevTimestampTickFrequency", nullptr)
            : 0;
    const std::optional<std::int64_t> armed =
        LatchArvDeviceTimeNs(device, tick_hz > 0 ? static_cast<std::uint64_t>(tick_hz) : 0);
    std::lock_guard<std::mutex> lock(impl_->stats_mutex);
    impl_->armed_device_ns = armed;
  }
  impl_->last_activity = Clock::now();
  return Status::Ok();
}

Status AravisCamera::Stop() {
  if (!impl_->opened) return impl_->Fail("Stop before Open");
  const bool was_started = impl_->started;
  impl_->started = false;
  if (!was_started || impl_->loss.lost()) return Status::Ok();
  GError* error = nullptr;
  arv_camera_stop_acquisition(impl_->camera, &error);
  if (error != nullptr) return impl_->Fail("AcquisitionStop: " + TakeMessage(error));
  return Status::Ok();
}

Expected<std::optional<Frame>> AravisCamera::NextFrame(std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (!d.opened) return d.Fail("NextFrame before Open");
  const Clock::time_point deadline = Clock::now() + timeout;

  if (!d.loss.lost() && d.control_lost.load())
    d.MarkLost("control channel lost (heartbeat or control access timed out)");
  if (d.loss.lost()) {
    // A USB3 Vision device arriving is worth trying at once.
    const auto usb_arrived = [&d] { return d.UsbChanged(); };
    const auto step =
        d.loss.Reconnect(deadline, d.options.reconnect_interval, usb_arrived, [&d]() -> Status {
          if (Status status = d.Connect(); !status) return status;
          if (!d.started) return Status::Ok();
          GError* error = nullptr;
          arv_camera_start_acquisition(d.camera, &error);
          if (error == nullptr) return Status::Ok();
          d.Disconnect();
          return d.Fail("AcquisitionStart: " + TakeMessage(error));
        });
    if (step == CameraReconnect::Step::kReportLoss)
      return d.Fail("device lost: " + d.loss.reason() + "; reconnecting");
    if (step == CameraReconnect::Step::kStillLost) return std::optional<Frame>();
    d.consecutive_failures = 0;
    {
      std::lock_guard<std::mutex> lock(d.stats_mutex);
      ++d.stats.reconnects;
    }
  }

  // Wait in short slices so buffers released meanwhile are queued again
  // before the camera needs them.
  constexpr std::chrono::milliseconds kSlice{10};
  while (true) {
    d.TopUp();
    const Clock::time_point now = Clock::now();
    const auto remaining = std::chrono::duration_cast<std::chrono::microseconds>(deadline - now);
    const auto slice =
        std::clamp<std::chrono::microseconds>(remaining, std::chrono::microseconds(0), kSlice);
    ArvBuffer* buffer = arv_stream_timeout_pop_buffer(d.stream, slice.count());
    if (buffer != nullptr) {
      d.last_activity = Clock::now();
      Frame frame = d.MakeFrame(buffer);
      d.TopUp();
      d.RefreshAravisStats();
      if (d.consecutive_failures >= d.options.max_consecutive_failures) {
        d.consecutive_failures = 0;
        if (!d.Probe()) d.MarkLost("stream errors and no answer on the control channel");
      }
      return std::optional<Frame>(std::move(frame));
    }
    if (d.control_lost.load()) {
      d.MarkLost("control channel lost (heartbeat or control access timed out)");
      d.loss.LossReported();
      return d.Fail("device lost: " + d.loss.reason() + "; reconnecting");
    }
    if (Clock::now() >= deadline) break;
  }
  d.RefreshAravisStats();
  // A USB3 Vision device leaving (maybe this one): check ours now.
  const bool suspect = d.control_suspect.exchange(false) || d.UsbChanged();
  if (suspect || Clock::now() - d.last_activity >= d.options.probe_after) {
    d.last_activity = Clock::now();
    if (!d.Probe()) {
      d.MarkLost("no answer on the control channel");
      d.loss.LossReported();
      return d.Fail("device lost: " + d.loss.reason() + "; reconnecting");
    }
  }
  return std::optional<Frame>();
}

Status AravisCamera::SoftwareTrigger() {
  Impl& d = *impl_;
  std::lock_guard<std::mutex> lock(d.control_mutex);
  if (d.camera == nullptr)
    return d.Fail(d.opened ? "software trigger while the device is lost"
                           : "software trigger before Open");
  GError* error = nullptr;
  arv_camera_software_trigger(d.camera, &error);
  if (error != nullptr) {
    // A control access that timed out after Aravis's retries (2.5 s on GigE
    // Vision) is as good as a failed probe: the device is gone. Any other
    // failure makes the grab thread probe the device.
    const bool gone =
        error->domain == ARV_DEVICE_ERROR &&
        (error->code == ARV_DEVICE_ERROR_TIMEOUT || error->code == ARV_DEVICE_ERROR_NOT_CONNECTED ||
         error->code == ARV_DEVICE_ERROR_TRANSFER_ERROR);
    (gone ? d.control_lost : d.control_suspect).store(true);
    return d.Fail("TriggerSoftware: " + TakeMessage(error));
  }
  return Status::Ok();
}

CameraInfo AravisCamera::Info() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->info;
}

std::optional<std::int64_t> AravisCamera::ArmedDeviceNs() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->armed_device_ns;
}

CameraStats AravisCamera::Stats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->stats;
}

std::vector<CameraGap> AravisCamera::Gaps() const {
  return impl_->loss.log().gaps();
}

bool AravisCamera::IsLost() const { return impl_->loss.lost(); }

Expected<std::string> AravisCamera::FeatureValue(const std::string& feature) const {
  Impl& d = *impl_;
  std::lock_guard<std::mutex> lock(d.control_mutex);
  return ReadArvFeature(d.camera == nullptr ? nullptr : arv_camera_get_device(d.camera), feature,
                        d.label);
}

}  // namespace lifmcr
