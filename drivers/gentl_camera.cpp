#include "drivers/gentl_camera.h"

#include "drivers/arv_settings.h"
#include "drivers/frame_id_tracker.h"
#include "drivers/frame_pool.h"
#include "drivers/gentl_arv_device.h"
#include "drivers/gentl_chunks.h"
#include "drivers/gentl_producer.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <mutex>
#include <thread>

namespace lifmcr {
namespace {

using namespace gentl;
using Clock = std::chrono::steady_clock;

std::int64_t RealtimeNs() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

// GenICam PFNC codes of the formats a rig file can ask for.
std::uint64_t PfncCode(CameraPixelFormat format) {
  switch (format) {
    case CameraPixelFormat::kMono8:
      return 0x01080001;
    case CameraPixelFormat::kBayerGr8:
      return 0x01080008;
    case CameraPixelFormat::kBayerRg8:
      return 0x01080009;
    case CameraPixelFormat::kBayerGb8:
      return 0x0108000A;
    case CameraPixelFormat::kBayerBg8:
      return 0x0108000B;
    case CameraPixelFormat::kBgr8:
      return 0x02180015;
  }
  return 0;
}

// A failed call that means the device is gone rather than a request refused.
bool MeansGone(GC_ERROR code) {
  return code == GC_ERR_IO || code == GC_ERR_INVALID_HANDLE || code == GC_ERR_NOT_AVAILABLE ||
         code == GC_ERR_TIMEOUT;
}

}  // namespace

Status GenTlCameraOptions::Check() const {
  if (pool_buffers < 2)
    return Error{"gentl options: pool_buffers must be >= 2, got " + std::to_string(pool_buffers)};
  if (!(free_run_rate_hz >= 0.0) || !std::isfinite(free_run_rate_hz))
    return Error{"gentl options: free_run_rate_hz must be >= 0"};
  if (camera_index < 0) return Error{"gentl options: camera_index must be >= 0"};
  if (probe_after.count() <= 0 || reconnect_interval.count() <= 0)
    return Error{"gentl options: probe_after and reconnect_interval must be > 0"};
  if (max_consecutive_failures < 1)
    return Error{"gentl options: max_consecutive_failures must be >= 1"};
  if (discovery_timeout.count() < 0) return Error{"gentl options: discovery_timeout must be >= 0"};
  return Status::Ok();
}

struct GenTlCamera::Impl {
  CameraConfig config;
  GenTlCameraOptions options;
  std::string label;  // "camera cam0 (serial 123)"

  std::shared_ptr<GenTlProducer> producer;
  // Guards the device objects against SoftwareTrigger/FeatureValue from
  // other threads; only the grab thread creates or destroys them.
  mutable std::mutex control_mutex;
  DEV_HANDLE device = nullptr;
  ArvDevice* arv_device = nullptr;  // GenApi over the remote device port
  ArvCamera* camera = nullptr;      // Aravis's feature helpers over arv_device
  DS_HANDLE stream = nullptr;
  EVENT_HANDLE new_buffer = nullptr;
  std::vector<BUFFER_HANDLE> announced;  // by pool index, for this stream
  std::atomic<bool> control_lost{false};
  std::atomic<bool> control_suspect{false};

  std::shared_ptr<FramePool> pool;
  std::vector<std::uint8_t*> buffer_data;  // by pool index
  std::vector<BufferRef> queued;           // by pool index: held while queued in the producer
  std::size_t payload_bytes = 0;
  std::uint64_t timestamp_hz = 0;  // device tick frequency; 0 = unknown
  bool has_params_lock = false;
  // Chunk data the device appends (the camera's own timestamp and counter).
  std::optional<ChunkField> chunk_timestamp;
  std::optional<ChunkField> chunk_frame_id;
  FrameIdTracker ids{FrameIdWidth::k64Bit};
  bool opened = false;
  bool started = false;

  CameraReconnect loss;  // lost, reported, reconnect tries, gaps (camera_gap.h)
  Clock::time_point last_activity{};
  int consecutive_failures = 0;
  // Underruns (frames lost for lack of a queued buffer) already set against
  // frame id gaps, over every stream; and how many of this stream's
  // NUM_UNDERRUN that accounts for. The rest are pending: they happened
  // after the last frame (its gap is still to come), or the producer's ids
  // do not count them; Stats() reports them either way.
  std::uint64_t underrun_frames = 0;
  std::uint64_t underruns_at_last_frame = 0;
  std::uint64_t PendingUnderruns() const {
    const std::uint64_t now = StreamUnderruns();
    return now - std::min(now, underruns_at_last_frame);
  }

  mutable std::mutex stats_mutex;
  CameraStats stats;
  CameraInfo info;
  std::optional<std::int64_t> armed_device_ns;  // latched after AcquisitionStart

  std::string Wanted() const {
    return config.driver.device.empty() ? config.serial : config.driver.device;
  }
  Error Fail(const std::string& what) const { return Error{label + ": " + what}; }
  Error FailCall(GC_ERROR code, const std::string& call) const {
    return Fail(producer->Describe(code, call));
  }

  Status FindProducer();
  Expected<GenTlDeviceEntry> FindDevice();
  Status Connect();
  Status OpenStream();
  void Disconnect();
  void TopUp();
  void EnableChunks();
  std::uint64_t StreamUnderruns() const;
  Status StartAcquisition();
  void MarkLost(const std::string& reason);
  bool Probe();
  Frame MakeFrame(BUFFER_HANDLE buffer, void* user_pointer, std::int64_t host_ns);
};

Status GenTlCamera::Impl::FindProducer() {
  if (producer) return Status::Ok();
  if (!config.driver.cti.empty()) {
    auto loaded = GenTlProducer::Load(config.driver.cti);
    if (!loaded) return Fail(loaded.error().message);
    producer = *loaded;
    return Status::Ok();
  }
  const std::vector<std::filesystem::path> candidates = GenTlProducer::SearchPath();
  if (candidates.empty())
    return Fail(
        "driver gentl without a cti, and GENICAM_GENTL64_PATH names no directory "
        "with a .cti producer");
  std::string tried;
  for (const std::filesystem::path& path : candidates) {
    auto loaded = GenTlProducer::Load(path);
    if (!loaded) {
      tried += "\n  " + loaded.error().message;
      continue;
    }
    auto devices = (*loaded)->Devices(config.driver.interface_id, options.discovery_timeout);
    if (devices)
      for (const GenTlDeviceEntry& entry : *devices)
        if (entry.id == Wanted() || entry.serial == Wanted()) {
          producer = *loaded;
          return Status::Ok();
        }
    tried += "\n  " + path.string() + ": " +
             (devices ? std::string("no device ") + Wanted() : devices.error().message);
  }
  return Fail("no producer in GENICAM_GENTL64_PATH has device " + Wanted() + ":" + tried);
}

Expected<GenTlDeviceEntry> GenTlCamera::Impl::FindDevice() {
  auto devices = producer->Devices(config.driver.interface_id, options.discovery_timeout);
  if (!devices) return Fail(devices.error().message);
  std::string listed;
  for (const GenTlDeviceEntry& entry : *devices) {
    if (entry.id == Wanted() || entry.serial == Wanted()) return entry;
    listed += (listed.empty() ? "" : ", ") + entry.id +
              (entry.serial.empty() ? std::string() : " (serial " + entry.serial + ")");
  }
  return Fail(
      "GenTL producer " + producer->path().string() + " has no device '" + Wanted() + "'" +
      (config.driver.interface_id.empty() ? "" : " on interface " + config.driver.interface_id) +
      " (it lists: " + (listed.empty() ? std::string("none") : listed) + ")");
}

Status GenTlCamera::Impl::Connect() {
  if (Status status = FindProducer(); !status) return status;
  auto entry = FindDevice();
  if (!entry) return entry.error();
  if (entry->access == DEVICE_ACCESS_STATUS_BUSY)
    return Fail("device " + entry->id + " busy: " + std::string(AccessStatusName(entry->access)));
  const Functions& fn = producer->fn();
  DEV_HANDLE opened_device = nullptr;
  auto interface = producer->Interface(entry->interface_id);
  if (!interface) return Fail(interface.error().message);
  {
    std::lock_guard<std::mutex> lock(producer->mutex());
    GC_ERROR code =
        fn.IFOpenDevice(*interface, entry->id.c_str(), DEVICE_ACCESS_EXCLUSIVE, &opened_device);
    // A producer without exclusive access (some grabbers offer control only).
    if (code == GC_ERR_NOT_IMPLEMENTED || code == GC_ERR_INVALID_PARAMETER)
      code = fn.IFOpenDevice(*interface, entry->id.c_str(), DEVICE_ACCESS_CONTROL, &opened_device);
    if (code != GC_ERR_SUCCESS) {
      const bool busy =
          code == GC_ERR_RESOURCE_IN_USE || code == GC_ERR_ACCESS_DENIED || code == GC_ERR_BUSY;
      return Fail(std::string(busy ? "device " + entry->id + " busy (open elsewhere): "
                                   : "cannot open device " + entry->id + ": ") +
                  producer->Describe(code, "IFOpenDevice"));
    }
  }
  PORT_HANDLE port = nullptr;
  if (GC_ERROR code = fn.DevGetPort(opened_device, &port); code != GC_ERR_SUCCESS) {
    Status failed = FailCall(code, "DevGetPort");
    fn.DevClose(opened_device);
    return failed;
  }
  auto arv = NewGenTlArvDevice(producer, port);
  if (!arv) {
    fn.DevClose(opened_device);
    return Fail("device " + entry->id + ": " + arv.error().message);
  }
  GError* error = nullptr;
  ArvCamera* new_camera = arv_camera_new_with_device(*arv, &error);
  if (new_camera == nullptr) {
    g_object_unref(*arv);
    fn.DevClose(opened_device);
    return Fail("device " + entry->id + ": " + TakeMessage(error));
  }
  {
    std::lock_guard<std::mutex> lock(control_mutex);
    device = opened_device;
    arv_device = *arv;
    camera = new_camera;
  }
  control_lost.store(false);
  control_suspect.store(false);
  // GigE Vision producers pass on 16-bit block ids, which wrap; CoaXPress,
  // USB3 Vision and grabber counters are 64-bit.
  ids = FrameIdTracker(entry->tl_type == "GEV" ? FrameIdWidth::k16Bit : FrameIdWidth::k64Bit);
  // Under the control lock: the node map is not thread-safe, and a software
  // trigger may arrive from the trigger thread while a reconnect applies them.
  auto region = [&]() -> Expected<ArvRegion> {
    std::lock_guard<std::mutex> lock(control_mutex);
    has_params_lock = arv_device_is_feature_available(arv_device, "TLParamsLocked", nullptr);
    if (has_params_lock)
      arv_device_set_integer_feature_value(arv_device, "TLParamsLocked", 0, nullptr);
    auto applied = ApplyArvCameraSettings(camera, config, options.free_run_rate_hz, label);
    if (applied) EnableChunks();
    return applied;
  }();
  if (!region) {
    Disconnect();
    return region.error();
  }
  timestamp_hz = 0;
  GenTlInfoValue(
      [&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
        return fn.DevGetInfo(device, DEVICE_INFO_TIMESTAMP_FREQUENCY, type, buffer, size);
      },
      &timestamp_hz);
  CameraInfo new_info;
  auto device_text = [&](DEVICE_INFO_CMD command, const std::string& fallback) {
    std::string text = GenTlInfoString([&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
      return fn.DevGetInfo(device, command, type, buffer, size);
    });
    return text.empty() ? fallback : text;
  };
  new_info.serial = device_text(DEVICE_INFO_SERIAL_NUMBER, entry->serial);
  new_info.vendor = device_text(DEVICE_INFO_VENDOR, entry->vendor);
  new_info.model = device_text(DEVICE_INFO_MODEL, entry->model);
  new_info.device_id = entry->id;
  new_info.width = region->width;
  new_info.height = region->height;
  new_info.format = BufferPixelFormat(config.pixel_format);
  if (Status status = OpenStream(); !status) {
    Disconnect();
    return status;
  }
  new_info.payload_bytes = payload_bytes;
  const std::size_t image_bytes =
      static_cast<std::size_t>(region->width) * region->height * BytesPerPixel(new_info.format);
  if (payload_bytes < image_bytes) {
    Disconnect();
    return Fail("PayloadSize " + std::to_string(payload_bytes) + " is smaller than the image (" +
                std::to_string(image_bytes) + " bytes)");
  }
  {
    std::lock_guard<std::mutex> lock(stats_mutex);
    info = new_info;
  }
  last_activity = Clock::now();
  return Status::Ok();
}

Status GenTlCamera::Impl::OpenStream() {
  const Functions& fn = producer->fn();
  std::uint32_t streams = 0;
  if (GC_ERROR code = fn.DevGetNumDataStreams(device, &streams); code != GC_ERR_SUCCESS)
    return FailCall(code, "DevGetNumDataStreams");
  if (streams == 0) return Fail("the device has no data stream");
  const std::string stream_id =
      GenTlInfoString([&](INFO_DATATYPE*, void* buffer, std::size_t* size) {
        return fn.DevGetDataStreamID(device, 0, static_cast<char*>(buffer), size);
      });
  DS_HANDLE new_stream = nullptr;
  if (GC_ERROR code = fn.DevOpenDataStream(device, stream_id.c_str(), &new_stream);
      code != GC_ERR_SUCCESS)
    return FailCall(code, "DevOpenDataStream");
  {
    std::lock_guard<std::mutex> lock(control_mutex);
    stream = new_stream;
  }
  auto stream_value = [&](STREAM_INFO_CMD command, auto* value) {
    return GenTlInfoValue(
        [&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
          return fn.DSGetInfo(stream, command, type, buffer, size);
        },
        value);
  };
  // The payload: the data stream's own size when it defines one (a frame
  // grabber may add its own data), else the device's PayloadSize.
  std::size_t payload = 0;
  bool8_t stream_defines = 0;
  if (stream_value(STREAM_INFO_DEFINES_PAYLOADSIZE, &stream_defines) && stream_defines != 0)
    stream_value(STREAM_INFO_PAYLOAD_SIZE, &payload);
  if (payload == 0) {
    GError* error = nullptr;
    std::lock_guard<std::mutex> lock(control_mutex);
    payload = arv_camera_get_payload(camera, &error);
    if (error != nullptr) return Fail("reading PayloadSize: " + TakeMessage(error));
  }
  if (payload == 0) return Fail("the camera reports a PayloadSize of 0");
  std::size_t alignment = 0;
  if (stream_value(STREAM_INFO_BUF_ALIGNMENT, &alignment) && alignment > FramePool::kAlignment)
    return Fail("the producer wants buffers aligned to " + std::to_string(alignment) +
                " bytes; the frame pool aligns to " + std::to_string(FramePool::kAlignment));
  std::size_t announce_min = 0;
  if (stream_value(STREAM_INFO_BUF_ANNOUNCE_MIN, &announce_min) &&
      announce_min > static_cast<std::size_t>(options.pool_buffers))
    return Fail("the producer needs at least " + std::to_string(announce_min) +
                " buffers, the pool has " + std::to_string(options.pool_buffers));
  if (!pool) {
    pool = FramePool::Create(static_cast<std::size_t>(options.pool_buffers), payload);
    buffer_data.resize(pool->size());
    queued.resize(pool->size());
    std::vector<BufferRef> all;
    while (BufferRef ref = pool->Acquire()) all.push_back(std::move(ref));
    for (const BufferRef& ref : all) buffer_data[ref->index] = ref->data;
    payload_bytes = payload;
  } else if (payload > pool->capacity_bytes()) {
    return Fail("PayloadSize changed from " + std::to_string(payload_bytes) + " to " +
                std::to_string(payload) + " after reconnecting");
  }
  // Every pool buffer is announced, also those a consumer still holds: the
  // producer writes into a buffer only once it is queued.
  announced.assign(pool->size(), nullptr);
  for (std::size_t i = 0; i < pool->size(); ++i) {
    void* index_pointer = reinterpret_cast<void*>(static_cast<std::uintptr_t>(i));
    if (GC_ERROR code = fn.DSAnnounceBuffer(stream, buffer_data[i], pool->capacity_bytes(),
                                            index_pointer, &announced[i]);
        code != GC_ERR_SUCCESS)
      return FailCall(code, "DSAnnounceBuffer");
  }
  if (GC_ERROR code = fn.GCRegisterEvent(stream, EVENT_NEW_BUFFER, &new_buffer);
      code != GC_ERR_SUCCESS)
    return FailCall(code, "GCRegisterEvent(EVENT_NEW_BUFFER)");
  underruns_at_last_frame = 0;
  TopUp();
  return Status::Ok();
}

// The camera's timestamp and frame counter as chunks, where the device has
// them: they are stamped by the camera at exposure, where the buffer's own
// timestamp may be the grabber's time of arrival. Optional: a device without
// chunks keeps the buffer info.
void GenTlCamera::Impl::EnableChunks() {
  chunk_timestamp.reset();
  chunk_frame_id.reset();
  if (producer->fn().DSGetBufferChunkData == nullptr ||
      !arv_camera_are_chunks_available(camera, nullptr))
    return;
  guint n_values = 0;
  const char** values = arv_device_dup_available_enumeration_feature_values_as_strings(
      arv_device, "ChunkSelector", &n_values, nullptr);
  bool any = false;
  for (const char* chunk : {"Timestamp", "FrameID"}) {
    bool offered = false;
    for (guint i = 0; values != nullptr && i < n_values; ++i)
      offered = offered || std::string(values[i]) == chunk;
    GError* error = nullptr;
    if (offered) arv_camera_set_chunk_state(camera, chunk, TRUE, &error);
    if (error != nullptr) {
      g_error_free(error);
      offered = false;
    }
    any = any || offered;
  }
  g_free(values);
  if (!any) return;
  GError* error = nullptr;
  arv_camera_set_chunk_mode(camera, TRUE, &error);
  if (error != nullptr) {
    g_error_free(error);
    return;
  }
  chunk_timestamp = ResolveChunkField(arv_device, "ChunkTimestamp");
  chunk_frame_id = ResolveChunkField(arv_device, "ChunkFrameID");
}

void GenTlCamera::Impl::TopUp() {
  if (stream == nullptr) return;
  while (BufferRef ref = pool->Acquire()) {
    const int index = ref->index;
    if (producer->fn().DSQueueBuffer(stream, announced[index]) != GC_ERR_SUCCESS) {
      control_suspect.store(true);  // back to the pool; the probe decides
      return;
    }
    queued[index] = std::move(ref);
  }
}

std::uint64_t GenTlCamera::Impl::StreamUnderruns() const {
  std::uint64_t underruns = 0;
  if (stream == nullptr) return 0;
  GenTlInfoValue(
      [&](INFO_DATATYPE* type, void* buffer, std::size_t* size) {
        return producer->fn().DSGetInfo(stream, STREAM_INFO_NUM_UNDERRUN, type, buffer, size);
      },
      &underruns);
  return underruns;
}

Status GenTlCamera::Impl::StartAcquisition() {
  const Functions& fn = producer->fn();
  // The stream first, so the first frame finds its buffers.
  if (GC_ERROR code = fn.DSStartAcquisition(stream, ACQ_START_FLAGS_DEFAULT, kInfinite);
      code != GC_ERR_SUCCESS)
    return FailCall(code, "DSStartAcquisition");
  std::lock_guard<std::mutex> lock(control_mutex);
  if (has_params_lock)
    arv_device_set_integer_feature_value(arv_device, "TLParamsLocked", 1, nullptr);
  GError* error = nullptr;
  arv_camera_start_acquisition(camera, &error);
  if (error != nullptr) {
    fn.DSStopAcquisition(stream, ACQ_STOP_FLAGS_KILL);
    return Fail("AcquisitionStart: " + TakeMessage(error));
  }
  const std::optional<std::int64_t> armed = LatchArvDeviceTimeNs(arv_device, timestamp_hz);
  std::lock_guard<std::mutex> stats_lock(stats_mutex);
  armed_device_ns = armed;
  return Status::Ok();
}

void GenTlCamera::Impl::Disconnect() {
  if (producer == nullptr) return;
  const Functions& fn = producer->fn();
  {
    std::lock_guard<std::mutex> lock(stats_mutex);
    underrun_frames += PendingUnderruns();
    stats.underruns = underrun_frames;
  }
  DS_HANDLE old_stream = nullptr;
  DEV_HANDLE old_device = nullptr;
  ArvCamera* old_camera = nullptr;
  ArvDevice* old_arv = nullptr;
  {
    std::lock_guard<std::mutex> lock(control_mutex);
    old_stream = stream;
    old_device = device;
    old_camera = camera;
    old_arv = arv_device;
    stream = nullptr;
    device = nullptr;
    camera = nullptr;
    arv_device = nullptr;
  }
  if (old_camera != nullptr && started && !loss.lost()) {
    arv_camera_stop_acquisition(old_camera, nullptr);
    if (has_params_lock)
      arv_device_set_integer_feature_value(old_arv, "TLParamsLocked", 0, nullptr);
  }
  if (old_stream != nullptr) {
    if (new_buffer != nullptr) fn.GCUnregisterEvent(old_stream, EVENT_NEW_BUFFER);
    new_buffer = nullptr;
    fn.DSStopAcquisition(old_stream, ACQ_STOP_FLAGS_KILL);
    fn.DSFlushQueue(old_stream, ACQ_QUEUE_ALL_DISCARD);
    for (BUFFER_HANDLE handle : announced)
      if (handle != nullptr) fn.DSRevokeBuffer(old_stream, handle, nullptr, nullptr);
    fn.DSClose(old_stream);
  }
  announced.clear();
  // The producer no longer writes into the queued buffers: back to the pool.
  for (BufferRef& ref : queued) ref.reset();
  if (old_camera != nullptr) g_object_unref(old_camera);
  if (old_arv != nullptr) g_object_unref(old_arv);
  if (old_device != nullptr) fn.DevClose(old_device);
}

void GenTlCamera::Impl::MarkLost(const std::string& reason) {
  loss.MarkLost(reason, ids.last(), [this] {
    Disconnect();
    ids.Reset();
  });
}

bool GenTlCamera::Impl::Probe() {
  std::lock_guard<std::mutex> lock(control_mutex);
  if (arv_device == nullptr) return false;
  GError* error = nullptr;
  arv_device_get_integer_feature_value(arv_device, "Width", &error);
  if (error == nullptr) return true;
  g_error_free(error);
  return !MeansGone(GenTlArvDeviceLastError(arv_device));
}

Frame GenTlCamera::Impl::MakeFrame(BUFFER_HANDLE buffer, void* user_pointer, std::int64_t host_ns) {
  const Functions& fn = producer->fn();
  const std::size_t index = reinterpret_cast<std::uintptr_t>(user_pointer);
  auto buffer_value = [&](BUFFER_INFO_CMD command, auto* value) {
    return GenTlInfoValue(
        [&](INFO_DATATYPE* type, void* out, std::size_t* size) {
          return fn.DSGetBufferInfo(stream, buffer, command, type, out, size);
        },
        value);
  };
  Frame frame;
  frame.camera_index = options.camera_index;
  frame.serial = config.serial;
  frame.host_ns = host_ns;
  if (index < queued.size()) frame.buffer = std::move(queued[index]);
  buffer_value(BUFFER_INFO_FRAMEID, &frame.frame_id);
  std::uint64_t timestamp = 0;
  if (buffer_value(BUFFER_INFO_TIMESTAMP_NS, &timestamp) && timestamp != 0) {
    frame.device_ns = static_cast<std::int64_t>(timestamp);
  } else if (buffer_value(BUFFER_INFO_TIMESTAMP, &timestamp) && timestamp != 0) {
    frame.device_ns =
        timestamp_hz > 0
            ? static_cast<std::int64_t>(static_cast<long double>(timestamp) * 1e9L / timestamp_hz)
            : static_cast<std::int64_t>(timestamp);
  } else {
    frame.device_ns = host_ns;  // a device without a clock
  }
  if (chunk_timestamp || chunk_frame_id) {
    bool8_t has_chunks = 1;
    buffer_value(BUFFER_INFO_CONTAINS_CHUNKDATA, &has_chunks);
    std::size_t count = 0;
    std::vector<SINGLE_CHUNK_DATA> chunks;
    if (has_chunks != 0 && frame.buffer &&
        fn.DSGetBufferChunkData(stream, buffer, nullptr, &count) == GC_ERR_SUCCESS && count > 0) {
      chunks.resize(count);
      if (fn.DSGetBufferChunkData(stream, buffer, chunks.data(), &count) != GC_ERR_SUCCESS)
        chunks.clear();
      chunks.resize(std::min(count, chunks.size()));
    }
    std::size_t valid = 0;
    if (!buffer_value(BUFFER_INFO_SIZE_FILLED, &valid) && frame.buffer)
      valid = frame.buffer->capacity_bytes;
    const std::uint8_t* base = frame.buffer ? frame.buffer->data : nullptr;
    if (!chunks.empty() && chunk_timestamp) {
      if (auto ticks = ReadChunkField(*chunk_timestamp, base, valid, chunks); ticks && *ticks != 0)
        frame.device_ns =
            timestamp_hz > 0 && timestamp_hz != 1'000'000'000
                ? static_cast<std::int64_t>(static_cast<long double>(*ticks) * 1e9L / timestamp_hz)
                : static_cast<std::int64_t>(*ticks);
    }
    if (!chunks.empty() && chunk_frame_id) {
      if (auto id = ReadChunkField(*chunk_frame_id, base, valid, chunks)) frame.frame_id = *id;
    }
  }
  bool8_t incomplete = 0, too_large = 0;
  std::size_t filled = 0, width = 0, height = 0, offset = 0;
  std::uint64_t pixel_format = 0;
  buffer_value(BUFFER_INFO_IS_INCOMPLETE, &incomplete);
  buffer_value(BUFFER_INFO_DATA_LARGER_THAN_BUFFER, &too_large);
  const bool has_filled = buffer_value(BUFFER_INFO_SIZE_FILLED, &filled);
  const bool has_size =
      buffer_value(BUFFER_INFO_WIDTH, &width) && buffer_value(BUFFER_INFO_HEIGHT, &height);
  buffer_value(BUFFER_INFO_IMAGEOFFSET, &offset);
  // Formats are compared only in the PFNC (or GigE Vision, the same codes
  // for 8-bit formats) namespace.
  std::uint64_t format_namespace = PIXELFORMAT_NAMESPACE_PFNC_32BIT;
  buffer_value(BUFFER_INFO_PIXELFORMAT_NAMESPACE, &format_namespace);
  const bool has_format = buffer_value(BUFFER_INFO_PIXELFORMAT, &pixel_format) &&
                          (format_namespace == PIXELFORMAT_NAMESPACE_PFNC_32BIT ||
                           format_namespace == PIXELFORMAT_NAMESPACE_GEV);

  const CameraInfo expected = [&] {
    std::lock_guard<std::mutex> lock(stats_mutex);
    return info;
  }();
  if (!has_size) {
    width = static_cast<std::size_t>(expected.width);
    height = static_cast<std::size_t>(expected.height);
  }
  const std::size_t stride = width * BytesPerPixel(expected.format);
  const std::size_t image_bytes = stride * height;
  if (!frame.buffer || too_large != 0) {
    frame.status = FrameStatus::kError;
  } else if (incomplete != 0 || (has_filled && filled < offset + image_bytes)) {
    frame.status = FrameStatus::kIncomplete;
  } else if (static_cast<int>(width) != expected.width ||
             static_cast<int>(height) != expected.height ||
             offset + image_bytes > frame.buffer->capacity_bytes ||
             (has_format && pixel_format != 0 && pixel_format != PfncCode(config.pixel_format))) {
    frame.status = FrameStatus::kError;  // not the configured image
  }
  if (frame.status == FrameStatus::kOk)
    frame.image = ImageView{frame.buffer->data + offset, static_cast<int>(width),
                            static_cast<int>(height), stride, expected.format};

  // A frame dropped for lack of a buffer is one underrun, never also a
  // missing id: the ids the gap skipped are underruns as far as the producer
  // counted them, the rest were lost on the way (missing ids).
  const std::uint64_t gap = ids.Observe(frame.frame_id);
  const std::uint64_t attributed = std::min(gap, PendingUnderruns());
  underrun_frames += attributed;
  underruns_at_last_frame += attributed;
  const std::uint64_t missing = gap - attributed;
  const std::uint64_t pending = PendingUnderruns();
  loss.log().OnFrame(frame.frame_id, frame.host_ns);
  consecutive_failures = frame.status == FrameStatus::kOk ? 0 : consecutive_failures + 1;
  std::lock_guard<std::mutex> lock(stats_mutex);
  stats.missing_ids += missing;
  stats.underruns = underrun_frames + pending;
  stats.transferred_bytes += has_filled ? filled : payload_bytes;
  if (frame.status == FrameStatus::kOk)
    ++stats.completed;
  else
    ++stats.failed;
  return frame;
}

GenTlCamera::GenTlCamera(CameraConfig config, GenTlCameraOptions options)
    : impl_(std::make_unique<Impl>()) {
  impl_->config = std::move(config);
  impl_->options = options;
  impl_->label = "camera " + impl_->config.name + " (serial " + impl_->config.serial + ")";
}

GenTlCamera::~GenTlCamera() {
  if (impl_->opened) impl_->Disconnect();
}

Status GenTlCamera::Open() {
  if (impl_->opened) return impl_->Fail("already open");
  if (Status status = impl_->options.Check(); !status) return impl_->Fail(status.error().message);
  if (Status status = impl_->Connect(); !status) return status;
  impl_->opened = true;
  return Status::Ok();
}

Status GenTlCamera::Start() {
  Impl& d = *impl_;
  if (!d.opened) return d.Fail("Start before Open");
  d.started = true;
  if (d.loss.lost()) return Status::Ok();  // acquisition starts with the reconnect
  if (Status status = d.StartAcquisition(); !status) {
    d.started = false;
    return status;
  }
  d.last_activity = Clock::now();
  return Status::Ok();
}

Status GenTlCamera::Stop() {
  Impl& d = *impl_;
  if (!d.opened) return d.Fail("Stop before Open");
  const bool was_started = d.started;
  d.started = false;
  if (!was_started || d.loss.lost()) return Status::Ok();
  GError* error = nullptr;
  {
    std::lock_guard<std::mutex> lock(d.control_mutex);
    arv_camera_stop_acquisition(d.camera, &error);
    if (d.has_params_lock)
      arv_device_set_integer_feature_value(d.arv_device, "TLParamsLocked", 0, nullptr);
  }
  // Default stop: the buffer being filled completes; delivered frames stay
  // in the output queue for NextFrame.
  const GC_ERROR code = d.producer->fn().DSStopAcquisition(d.stream, ACQ_STOP_FLAGS_DEFAULT);
  if (error != nullptr) return d.Fail("AcquisitionStop: " + TakeMessage(error));
  if (code != GC_ERR_SUCCESS) return d.FailCall(code, "DSStopAcquisition");
  return Status::Ok();
}

Expected<std::optional<Frame>> GenTlCamera::NextFrame(std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (!d.opened) return d.Fail("NextFrame before Open");
  const Clock::time_point deadline = Clock::now() + timeout;
  auto report_lost = [&d](const std::string& reason) -> Expected<std::optional<Frame>> {
    d.MarkLost(reason);
    d.loss.LossReported();
    return d.Fail("device lost: " + d.loss.reason() + "; reconnecting");
  };

  if (!d.loss.lost() && d.control_lost.load())
    return report_lost("a control access failed: the device does not answer");
  if (d.loss.lost()) {
    const auto step =
        d.loss.Reconnect(deadline, d.options.reconnect_interval, {}, [&d]() -> Status {
          if (Status status = d.Connect(); !status) return status;
          if (!d.started) return Status::Ok();
          Status status = d.StartAcquisition();
          if (!status) d.Disconnect();
          return status;
        });
    if (step == CameraReconnect::Step::kReportLoss)
      return d.Fail("device lost: " + d.loss.reason() + "; reconnecting");
    if (step == CameraReconnect::Step::kStillLost) return std::optional<Frame>();
    d.consecutive_failures = 0;
    std::lock_guard<std::mutex> lock(d.stats_mutex);
    ++d.stats.reconnects;
  }

  const Functions& fn = d.producer->fn();
  constexpr std::chrono::milliseconds kSlice{10};
  while (true) {
    d.TopUp();
    const auto remaining =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    const auto slice = std::clamp(remaining, std::chrono::milliseconds(0), kSlice);
    EVENT_NEW_BUFFER_DATA data{};
    std::size_t size = sizeof(data);
    const GC_ERROR code =
        fn.EventGetData(d.new_buffer, &data, &size, static_cast<std::uint64_t>(slice.count()));
    if (code == GC_ERR_SUCCESS) {
      const std::int64_t host_ns = RealtimeNs();
      d.last_activity = Clock::now();
      Frame frame = d.MakeFrame(data.BufferHandle, data.pUserPointer, host_ns);
      d.TopUp();
      if (d.consecutive_failures >= d.options.max_consecutive_failures) {
        d.consecutive_failures = 0;
        if (!d.Probe()) return report_lost("failed frames and no answer from the device");
      }
      return std::optional<Frame>(std::move(frame));
    }
    if (code != GC_ERR_TIMEOUT) return report_lost(d.producer->Describe(code, "EventGetData"));
    if (d.control_lost.load())
      return report_lost("a control access failed: the device does not answer");
    if (Clock::now() >= deadline) break;
  }
  {
    std::lock_guard<std::mutex> lock(d.stats_mutex);
    d.stats.underruns = d.underrun_frames + d.PendingUnderruns();
  }
  const bool suspect = d.control_suspect.exchange(false);
  if (suspect || Clock::now() - d.last_activity >= d.options.probe_after) {
    d.last_activity = Clock::now();
    if (!d.Probe()) return report_lost("no answer from the device");
  }
  return std::optional<Frame>();
}

Status GenTlCamera::SoftwareTrigger() {
  Impl& d = *impl_;
  std::lock_guard<std::mutex> lock(d.control_mutex);
  if (d.camera == nullptr)
    return d.Fail(d.opened ? "software trigger while the device is lost"
                           : "software trigger before Open");
  GError* error = nullptr;
  arv_camera_software_trigger(d.camera, &error);
  if (error != nullptr) {
    (MeansGone(GenTlArvDeviceLastError(d.arv_device)) ? d.control_lost : d.control_suspect)
        .store(true);
    return d.Fail("TriggerSoftware: " + TakeMessage(error));
  }
  return Status::Ok();
}

CameraInfo GenTlCamera::Info() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->info;
}

std::optional<std::int64_t> GenTlCamera::ArmedDeviceNs() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->armed_device_ns;
}

CameraStats GenTlCamera::Stats() const {
  std::lock_guard<std::mutex> lock(impl_->stats_mutex);
  return impl_->stats;
}

std::vector<CameraGap> GenTlCamera::Gaps() const { return impl_->loss.log().gaps(); }

bool GenTlCamera::IsLost() const { return impl_->loss.lost(); }

Expected<std::string> GenTlCamera::FeatureValue(const std::string& feature) const {
  Impl& d = *impl_;
  std::lock_guard<std::mutex> lock(d.control_mutex);
  return ReadArvFeature(d.arv_device, feature, d.label);
}

}  // namespace lifmcr
