// A GenTL producer for tests: the EMVA GenTL C interface (drivers/gentl_api.h)
// over in-memory cameras, built as a .cti shared library that the GenTL
// driver loads like a frame grabber vendor's producer.
//
// One system, one interface ("SimIF0", transport "CXP") and the cameras named
// by LIFMCR_GENTL_SIM_DEVICES (comma-separated serials, default
// "GTLSIM0,GTLSIM1"; device id "SimDev-<serial>"), each with a sensor of
// LIFMCR_GENTL_SIM_SENSOR ("WIDTHxHEIGHT", default 1024x768) and the GenICam
// XML and registers of tests/drivers/gentl_sim/gentl_sim_xml.h.
// LIFMCR_GENTL_SIM_ARM_DELAY_MS ("SERIAL:MS,...") makes AcquisitionStart of
// those cameras take MS milliseconds before the camera is armed, while the
// line keeps pulsing (a camera slow to arm; the start-up race on purpose).
// TimestampLatch stamps the device clock (CLOCK_REALTIME, as the chunks).
// LIFMCR_GENTL_SIM_FILL=first_row writes only each frame's first row (and its
// chunk), as a grabber's DMA costs the host no CPU; the default writes every
// row (tests check the pixels). LIFMCR_GENTL_SIM_FLOW_CONTROL=1 makes a
// free-running camera wait for a queued buffer instead of losing the frame,
// so the consumer sets the pace (benchmarks; a real CXP camera cannot wait).
//
// Each camera has an acquisition thread. With AcquisitionStart executed and
// its data stream acquiring, it makes a frame per software trigger
// (TriggerSource Software), per pulse of its "hardware" line (Line0/Line1:
// pulses every SimLinePeriodUs on the wall-clock grid, so every camera sees
// the same pulse train, as from a Lock Lab), or at AcquisitionFrameRate
// (TriggerMode Off). Ticks the camera thread was late for (a busy host) are
// all made at once with their own tick times, as a grabber's DMA engine
// would have delivered them: host load alone loses nothing (a frame finding
// no queued buffer is an underrun, as always). A frame takes the next frame
// id (1, 2, ...), fills the
// oldest queued buffer with rows of value (frame id + row) mod 256, sets the
// buffer info and fires EVENT_NEW_BUFFER. With no buffer queued the frame is
// an underrun (STREAM_INFO_NUM_UNDERRUN). Fault injection: SimDropEvery = N
// loses every Nth frame id in transport; SimIncompleteEvery = N delivers every
// Nth frame half filled and flagged incomplete (tests set them through the
// node map or LifmcrGenTlSimSetRegister); LifmcrGenTlSimSetPresent
// makes a camera disappear (port accesses fail with GC_ERR_IO, it leaves the
// device list, frames stop) and come back (listed again, counter restarted;
// the old device handle stays dead).

#include "drivers/gentl_api.h"
#include "tests/drivers/gentl_sim/gentl_sim_xml.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <deque>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

using namespace lifmcr::gentl;
namespace sim = lifmcr::gentl_sim;

namespace {

thread_local GC_ERROR t_last_error = GC_ERR_SUCCESS;
thread_local std::string t_last_text;

GC_ERROR Err(GC_ERROR code, const std::string& text) {
  t_last_error = code;
  t_last_text = text;
  return code;
}

std::int64_t RealtimeNs() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

GC_ERROR CopyString(const std::string& text, INFO_DATATYPE* type, void* buffer, std::size_t* size) {
  if (type != nullptr) *type = INFO_DATATYPE_STRING;
  if (size == nullptr) return Err(GC_ERR_INVALID_PARAMETER, "size is null");
  if (buffer == nullptr) {
    *size = text.size() + 1;
    return GC_ERR_SUCCESS;
  }
  if (*size < text.size() + 1) return Err(GC_ERR_BUFFER_TOO_SMALL, "buffer too small");
  std::memcpy(buffer, text.c_str(), text.size() + 1);
  *size = text.size() + 1;
  return GC_ERR_SUCCESS;
}

template <typename T>
GC_ERROR CopyValue(T value, INFO_DATATYPE kind, INFO_DATATYPE* type, void* buffer,
                   std::size_t* size) {
  if (type != nullptr) *type = kind;
  if (size == nullptr) return Err(GC_ERR_INVALID_PARAMETER, "size is null");
  if (buffer == nullptr) {
    *size = sizeof(T);
    return GC_ERR_SUCCESS;
  }
  if (*size < sizeof(T)) return Err(GC_ERR_BUFFER_TOO_SMALL, "buffer too small");
  std::memcpy(buffer, &value, sizeof(T));
  *size = sizeof(T);
  return GC_ERR_SUCCESS;
}

struct Stream;

struct Buffer {
  Stream* stream = nullptr;
  std::uint8_t* base = nullptr;
  std::size_t size = 0;
  void* user = nullptr;
  bool queued = false;
  std::uint64_t frame_id = 0;
  std::uint64_t timestamp_ns = 0;
  std::size_t filled = 0;
  bool incomplete = false;
  std::uint32_t width = 0, height = 0, pixel_format = 0;
  std::size_t chunk_offset = 0;  // 0: no chunk in this frame
};

struct Event {
  Stream* stream = nullptr;
  std::deque<EVENT_NEW_BUFFER_DATA> queue;
  bool killed = false;
};

struct Camera;

struct Stream {
  Camera* camera = nullptr;
  std::vector<std::unique_ptr<Buffer>> buffers;
  std::deque<Buffer*> input;
  std::unique_ptr<Event> event;
  bool acquiring = false;
  std::uint64_t delivered = 0;
  std::uint64_t underruns = 0;
  int filling = 0;  // frames being written outside the lock
};

struct Camera {
  std::string serial;
  std::string id;
  std::uint32_t sensor_w = 1024, sensor_h = 768;
  std::uint32_t regs[0x600 / 4] = {};  // integer registers by address / 4
  double frame_rate = 10.0, exposure_us = 1000.0, gain_db = 0.0;
  bool present = true;
  std::uint64_t generation = 1;  // bumped when the camera disappears
  bool open = false;
  bool busy_elsewhere = false;  // held by "another process" (LifmcrGenTlSimSetBusy)
  bool running = false;         // AcquisitionStart executed
  int pending_software = 0;
  std::uint64_t next_frame_id = 1;
  std::int64_t next_tick_ns = 0;  // next pulse / free-run frame on the wall-clock grid
  std::int64_t latched_ns = 0;    // TimestampLatchValue
  int arm_delay_ms = 0;           // LIFMCR_GENTL_SIM_ARM_DELAY_MS
  Stream* stream = nullptr;
  std::thread worker;

  std::uint32_t& Reg(std::uint64_t address) { return regs[address / 4]; }
  std::uint32_t BytesPerPixel() const {
    return regs[sim::kPixelFormat / 4] == 0x02180015 ? 3u : 1u;
  }
  std::uint32_t Payload() const {
    return regs[sim::kWidth / 4] * regs[sim::kHeight / 4] * BytesPerPixel() +
           (regs[sim::kChunkModeActive / 4] != 0 ? sim::kChunkBytes : 0);
  }
};

struct DeviceHandle {
  Camera* camera = nullptr;
  std::uint64_t generation = 0;
  int port_tag = 0;  // the remote port's handle is &port_tag
};

struct System {
  std::mutex mutex;
  std::condition_variable wake;  // cameras' threads and event waiters
  bool initialised = false;
  bool stopping = false;
  bool fill_first_row_only = false;
  bool flow_control = false;
  bool tl_open = false;
  bool if_open = false;
  std::vector<std::unique_ptr<Camera>> cameras;
  std::set<const void*> handles;  // every live handle, for validation
  std::vector<std::unique_ptr<DeviceHandle>> devices;
  std::vector<std::unique_ptr<Stream>> streams;
};

System& Sys() {
  static System system;
  return system;
}

int g_tl_tag = 0;
int g_if_tag = 0;
constexpr const char* kInterfaceId = "SimIF0";

bool Live(const void* handle) { return handle != nullptr && Sys().handles.count(handle) > 0; }

DeviceHandle* AsDevice(void* handle) {
  if (!Live(handle)) return nullptr;
  for (auto& device : Sys().devices)
    if (device.get() == handle) return device.get();
  return nullptr;
}
DeviceHandle* PortDevice(void* handle) {
  if (!Live(handle)) return nullptr;
  for (auto& device : Sys().devices)
    if (static_cast<void*>(&device->port_tag) == handle) return device.get();
  return nullptr;
}
Stream* AsStream(void* handle) {
  if (!Live(handle)) return nullptr;
  for (auto& stream : Sys().streams)
    if (stream.get() == handle) return stream.get();
  return nullptr;
}
Event* AsEvent(void* handle) {
  if (!Live(handle)) return nullptr;
  for (auto& stream : Sys().streams)
    if (stream->event.get() == handle) return stream->event.get();
  return nullptr;
}
Buffer* AsBuffer(Stream* stream, void* handle) {
  for (auto& buffer : stream->buffers)
    if (buffer.get() == handle) return buffer.get();
  return nullptr;
}
Camera* FindCamera(const char* id) {
  for (auto& camera : Sys().cameras)
    if (camera->id == id && camera->present) return camera.get();
  return nullptr;
}
// A device handle whose camera is still the one it opened.
bool Alive(const DeviceHandle* device) {
  return device->camera->present && device->camera->generation == device->generation;
}

void ResetRegisters(Camera& camera) {
  std::fill(std::begin(camera.regs), std::end(camera.regs), 0u);
  camera.Reg(sim::kSensorWidth) = camera.sensor_w;
  camera.Reg(sim::kSensorHeight) = camera.sensor_h;
  camera.Reg(sim::kWidth) = camera.sensor_w;
  camera.Reg(sim::kHeight) = camera.sensor_h;
  camera.Reg(sim::kPixelFormat) = 0x01080001;
  camera.Reg(sim::kLinePeriodUs) = 100000;
  camera.frame_rate = 10.0;
  camera.exposure_us = 1000.0;
  camera.gain_db = 0.0;
  camera.next_frame_id = 1;
  camera.running = false;
  camera.pending_software = 0;
}

// Makes one frame (called with the lock held; fills outside it).
void Produce(Camera& camera, std::unique_lock<std::mutex>& lock, std::int64_t trigger_ns) {
  const std::uint64_t frame_id = camera.next_frame_id++;
  const std::uint32_t drop = camera.Reg(sim::kDropEvery);
  if (drop > 0 && frame_id % drop == 0) return;  // lost in transport
  Stream* stream = camera.stream;
  if (stream->input.empty()) {
    ++stream->underruns;
    return;
  }
  Buffer* buffer = stream->input.front();
  stream->input.pop_front();
  const std::uint32_t width = camera.Reg(sim::kWidth), height = camera.Reg(sim::kHeight);
  const std::size_t stride = static_cast<std::size_t>(width) * camera.BytesPerPixel();
  const std::uint32_t incomplete_every = camera.Reg(sim::kIncompleteEvery);
  const bool incomplete = incomplete_every > 0 && frame_id % incomplete_every == 0;
  const std::uint32_t rows = incomplete ? height / 2 : height;
  buffer->frame_id = frame_id;
  // The grabber stamps the frame on arrival: after the exposure and 1 ms of
  // transfer; the camera's own chunk carries the trigger time.
  buffer->timestamp_ns = static_cast<std::uint64_t>(
      trigger_ns + static_cast<std::int64_t>(camera.exposure_us * 1000.0) + 1'000'000);
  const bool chunk = camera.Reg(sim::kChunkModeActive) != 0 && !incomplete &&
                     stride * height + sim::kChunkBytes <= buffer->size;
  buffer->chunk_offset = chunk ? stride * height : 0;
  if (chunk) {
    const std::uint64_t values[2] = {
        camera.regs[(sim::kChunkEnable) / 4] != 0 ? static_cast<std::uint64_t>(trigger_ns) : 0,
        camera.regs[(sim::kChunkEnable + 4) / 4] != 0 ? frame_id : 0};
    std::memcpy(buffer->base + buffer->chunk_offset, values, sizeof(values));
  }
  buffer->width = width;
  buffer->height = height;
  buffer->pixel_format = camera.Reg(sim::kPixelFormat);
  buffer->incomplete = incomplete;
  buffer->filled = std::min(buffer->size, stride * rows + (chunk ? sim::kChunkBytes : 0));
  const std::size_t capacity_rows = std::min<std::size_t>(stride > 0 ? buffer->size / stride : 0,
                                                          Sys().fill_first_row_only ? 1 : rows);
  ++stream->filling;
  lock.unlock();
  for (std::uint32_t y = 0; y < rows && y < capacity_rows; ++y)
    std::memset(buffer->base + y * stride, static_cast<int>((frame_id + y) & 0xFF), stride);
  lock.lock();
  --stream->filling;
  Sys().wake.notify_all();
  // Stopped or closed meanwhile: the buffer goes back to the input pool.
  if (camera.stream != stream || !Live(stream) || !stream->acquiring) {
    if (Live(stream) && AsBuffer(stream, buffer) != nullptr && buffer->queued)
      stream->input.push_front(buffer);
    return;
  }
  ++stream->delivered;
  stream->event->queue.push_back(EVENT_NEW_BUFFER_DATA{buffer, buffer->user});
  Sys().wake.notify_all();
}

void Run(Camera* camera) {
  System& system = Sys();
  std::unique_lock<std::mutex> lock(system.mutex);
  while (!system.stopping) {
    const bool active = camera->present && camera->running && camera->stream != nullptr &&
                        camera->stream->acquiring;
    if (!active) {
      system.wake.wait_for(lock, std::chrono::milliseconds(20));
      continue;
    }
    const bool triggered = camera->Reg(sim::kTriggerMode) == 1;  // FrameStart
    const std::uint32_t source = camera->Reg(sim::kTriggerSource);
    if (triggered && source == 0) {
      if (camera->pending_software > 0) {
        --camera->pending_software;
        Produce(*camera, lock, RealtimeNs());
      } else {
        system.wake.wait_for(lock, std::chrono::milliseconds(20));
      }
      continue;
    }
    if (!triggered && system.flow_control) {
      // The consumer sets the pace: a frame whenever a buffer is queued.
      if (!camera->stream->input.empty())
        Produce(*camera, lock, RealtimeNs());
      else
        system.wake.wait_for(lock, std::chrono::milliseconds(20));
      continue;
    }
    // Line pulses or free run: ticks on the wall-clock grid of the period.
    const double period_ns =
        triggered ? 1000.0 * std::max<std::uint32_t>(camera->Reg(sim::kLinePeriodUs), 100)
                  : 1e9 / std::max(camera->frame_rate, 0.1);
    const std::int64_t period = static_cast<std::int64_t>(period_ns);
    const std::int64_t now = RealtimeNs();
    if (camera->next_tick_ns == 0) camera->next_tick_ns = (now / period + 1) * period;
    if (now >= camera->next_tick_ns) {
      const std::int64_t tick = camera->next_tick_ns;
      camera->next_tick_ns += period;
      Produce(*camera, lock, tick);
      continue;
    }
    const auto wait =
        std::chrono::nanoseconds(std::min<std::int64_t>(camera->next_tick_ns - now, 20'000'000));
    system.wake.wait_for(lock, wait);
  }
}

std::vector<std::string> Split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::stringstream stream(text);
  for (std::string part; std::getline(stream, part, separator);)
    if (!part.empty()) parts.push_back(part);
  return parts;
}

GC_ERROR ReadRegisters(Camera& camera, std::uint64_t address, void* out, std::size_t size) {
  auto* bytes = static_cast<std::uint8_t*>(out);
  if (address >= sim::kXmlAddress) {
    const std::size_t offset = address - sim::kXmlAddress;
    const std::size_t length = sizeof(sim::kXml) - 1;
    if (offset + size > length) return Err(GC_ERR_INVALID_ADDRESS, "beyond the XML");
    std::memcpy(bytes, sim::kXml + offset, size);
    return GC_ERR_SUCCESS;
  }
  auto text_at = [&](std::uint64_t base, const std::string& text) {
    char field[64] = {};
    std::memcpy(field, text.c_str(), std::min<std::size_t>(text.size(), 63));
    std::memcpy(bytes, field + (address - base), size);
  };
  if (address < 0x100) {
    if ((address % 64) + size > 64) return Err(GC_ERR_INVALID_ADDRESS, "across strings");
    const std::uint64_t base = address / 64 * 64;
    text_at(base, base == sim::kVendorName  ? "lifmcr"
                  : base == sim::kModelName ? "GenTL simulator"
                                            : camera.serial);
    return GC_ERR_SUCCESS;
  }
  if (address == sim::kFrameRate && size == 8)
    return std::memcpy(out, &camera.frame_rate, 8), GC_ERR_SUCCESS;
  if (address == sim::kExposureTime && size == 8)
    return std::memcpy(out, &camera.exposure_us, 8), GC_ERR_SUCCESS;
  if (address == sim::kGain && size == 8)
    return std::memcpy(out, &camera.gain_db, 8), GC_ERR_SUCCESS;
  if (address == sim::kTimestampLatchValue && size == 8)
    return std::memcpy(out, &camera.latched_ns, 8), GC_ERR_SUCCESS;
  if (size != 4 || address % 4 != 0 || address >= sizeof(camera.regs))
    return Err(GC_ERR_INVALID_ADDRESS, "no register at this address");
  camera.Reg(sim::kPayloadSize) = camera.Payload();
  camera.Reg(sim::kLastFrameId) = static_cast<std::uint32_t>(camera.next_frame_id - 1);
  std::memcpy(out, &camera.regs[address / 4], 4);
  return GC_ERR_SUCCESS;
}

GC_ERROR WriteRegisters(Camera& camera, std::uint64_t address, const void* in, std::size_t size) {
  System& system = Sys();
  if (size == 8 &&
      (address == sim::kFrameRate || address == sim::kExposureTime || address == sim::kGain)) {
    double value = 0;
    std::memcpy(&value, in, 8);
    if (address == sim::kFrameRate) camera.frame_rate = value;
    if (address == sim::kExposureTime) camera.exposure_us = value;
    if (address == sim::kGain) camera.gain_db = value;
    return GC_ERR_SUCCESS;
  }
  if (size != 4 || address % 4 != 0 || address < 0x100 || address >= sizeof(camera.regs))
    return Err(GC_ERR_INVALID_ADDRESS, "no writable register at this address");
  std::uint32_t value = 0;
  std::memcpy(&value, in, 4);
  const bool streaming = camera.running;
  switch (address) {
    case sim::kSensorWidth:
    case sim::kSensorHeight:
    case sim::kPayloadSize:
    case sim::kLastFrameId:
      return Err(GC_ERR_ACCESS_DENIED, "read-only register");
    case sim::kWidth:
    case sim::kHeight:
    case sim::kOffsetX:
    case sim::kOffsetY:
    case sim::kPixelFormat: {
      if (streaming) return Err(GC_ERR_ACCESS_DENIED, "the image format is locked while acquiring");
      const std::uint32_t w = address == sim::kWidth ? value : camera.Reg(sim::kWidth);
      const std::uint32_t h = address == sim::kHeight ? value : camera.Reg(sim::kHeight);
      const std::uint32_t x = address == sim::kOffsetX ? value : camera.Reg(sim::kOffsetX);
      const std::uint32_t y = address == sim::kOffsetY ? value : camera.Reg(sim::kOffsetY);
      if (w == 0 || h == 0 || x + w > camera.sensor_w || y + h > camera.sensor_h)
        return Err(GC_ERR_INVALID_VALUE, "region outside the sensor");
      break;
    }
    case sim::kAcquisitionStart:
      camera.running = true;
      camera.pending_software = 0;
      camera.next_tick_ns = 0;
      system.wake.notify_all();
      return GC_ERR_SUCCESS;
    case sim::kAcquisitionStop:
      camera.running = false;
      return GC_ERR_SUCCESS;
    case sim::kTimestampLatch:
      camera.latched_ns = RealtimeNs();
      return GC_ERR_SUCCESS;
    case sim::kTriggerSoftware:
      if (!camera.running) return GC_ERR_SUCCESS;  // not acquiring: a trigger is ignored
      ++camera.pending_software;
      system.wake.notify_all();
      return GC_ERR_SUCCESS;
    case sim::kTriggerSelector:
    case sim::kChunkSelector:
      if (value > 1) return Err(GC_ERR_INVALID_VALUE, "no such selector value");
      break;
    case sim::kChunkModeActive:
      if (streaming) return Err(GC_ERR_ACCESS_DENIED, "chunk mode is locked while acquiring");
      break;
    default:
      break;
  }
  camera.regs[address / 4] = value;
  return GC_ERR_SUCCESS;
}

}  // namespace

extern "C" {

// Test control (not GenTL): make the camera with `serial` disappear
// (present = 0) or come back (present = 1).
__attribute__((visibility("default"))) void LifmcrGenTlSimSetPresent(const char* serial,
                                                                     int present) {
  System& system = Sys();
  std::lock_guard<std::mutex> lock(system.mutex);
  for (auto& camera : system.cameras) {
    if (camera->serial != serial) continue;
    if (!present && camera->present) {
      camera->present = false;
      ++camera->generation;
      camera->open = false;
      camera->running = false;
    } else if (present && !camera->present) {
      ResetRegisters(*camera);
      camera->present = true;
    }
  }
  system.wake.notify_all();
}

// Test control: writes a 4-byte register of the camera with `serial` as a
// port write would (fault injection: kDropEvery, kIncompleteEvery,
// kLinePeriodUs); 0 on success, the GenTL error otherwise.
__attribute__((visibility("default"))) int LifmcrGenTlSimSetRegister(const char* serial,
                                                                     std::uint64_t address,
                                                                     std::uint32_t value) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  for (auto& camera : Sys().cameras)
    if (camera->serial == serial) return WriteRegisters(*camera, address, &value, sizeof(value));
  return GC_ERR_INVALID_ID;
}

// Test control: the camera with `serial` is held by another process (busy =
// 1): listed with access status BUSY, IFOpenDevice refused.
__attribute__((visibility("default"))) void LifmcrGenTlSimSetBusy(const char* serial, int busy) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  for (auto& camera : Sys().cameras)
    if (camera->serial == serial) camera->busy_elsewhere = busy != 0;
}

#define GC_EXPORT __attribute__((visibility("default")))

GC_EXPORT GC_ERROR GCGetInfo(TL_INFO_CMD command, INFO_DATATYPE* type, void* buffer,
                             std::size_t* size) {
  switch (command) {
    case TL_INFO_VENDOR:
      return CopyString("lifmcr", type, buffer, size);
    case TL_INFO_MODEL:
      return CopyString("GenTL simulator", type, buffer, size);
    case TL_INFO_VERSION:
      return CopyString("1.0", type, buffer, size);
    case TL_INFO_TLTYPE:
      return CopyString("CXP", type, buffer, size);
    case TL_INFO_GENTL_VER_MAJOR:
      return CopyValue<std::uint32_t>(1, INFO_DATATYPE_UINT32, type, buffer, size);
    case TL_INFO_GENTL_VER_MINOR:
      return CopyValue<std::uint32_t>(5, INFO_DATATYPE_UINT32, type, buffer, size);
    default:
      return Err(GC_ERR_NOT_IMPLEMENTED, "info not implemented");
  }
}

GC_EXPORT GC_ERROR GCGetLastError(GC_ERROR* code, char* text, std::size_t* size) {
  if (code != nullptr) *code = t_last_error;
  return CopyString(t_last_text, nullptr, text, size);
}

GC_EXPORT GC_ERROR GCInitLib() {
  System& system = Sys();
  std::lock_guard<std::mutex> lock(system.mutex);
  if (system.initialised) return Err(GC_ERR_RESOURCE_IN_USE, "GCInitLib called twice");
  const char* devices = std::getenv("LIFMCR_GENTL_SIM_DEVICES");
  const char* sensor = std::getenv("LIFMCR_GENTL_SIM_SENSOR");
  const char* fill = std::getenv("LIFMCR_GENTL_SIM_FILL");
  system.fill_first_row_only = fill != nullptr && std::string(fill) == "first_row";
  const char* flow = std::getenv("LIFMCR_GENTL_SIM_FLOW_CONTROL");
  system.flow_control = flow != nullptr && std::string(flow) == "1";
  std::uint32_t w = 1024, h = 768;
  if (sensor != nullptr) {
    const std::vector<std::string> parts = Split(sensor, 'x');
    if (parts.size() == 2) {
      w = static_cast<std::uint32_t>(std::strtoul(parts[0].c_str(), nullptr, 10));
      h = static_cast<std::uint32_t>(std::strtoul(parts[1].c_str(), nullptr, 10));
    }
  }
  system.stopping = false;
  system.cameras.clear();
  for (const std::string& serial : Split(devices != nullptr ? devices : "GTLSIM0,GTLSIM1", ',')) {
    auto camera = std::make_unique<Camera>();
    camera->serial = serial;
    camera->id = "SimDev-" + serial;
    camera->sensor_w = w;
    camera->sensor_h = h;
    ResetRegisters(*camera);
    system.cameras.push_back(std::move(camera));
  }
  if (const char* delays = std::getenv("LIFMCR_GENTL_SIM_ARM_DELAY_MS")) {
    for (const std::string& entry : Split(delays, ',')) {
      const std::vector<std::string> parts = Split(entry, ':');
      if (parts.size() != 2) continue;
      for (auto& camera : system.cameras)
        if (camera->serial == parts[0])
          camera->arm_delay_ms = static_cast<int>(std::strtol(parts[1].c_str(), nullptr, 10));
    }
  }
  for (auto& camera : system.cameras) camera->worker = std::thread(Run, camera.get());
  system.initialised = true;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR GCCloseLib() {
  System& system = Sys();
  {
    std::lock_guard<std::mutex> lock(system.mutex);
    if (!system.initialised) return Err(GC_ERR_NOT_INITIALIZED, "not initialised");
    system.stopping = true;
    system.wake.notify_all();
  }
  for (auto& camera : system.cameras)
    if (camera->worker.joinable()) camera->worker.join();
  std::lock_guard<std::mutex> lock(system.mutex);
  system.cameras.clear();
  system.streams.clear();
  system.devices.clear();
  system.handles.clear();
  system.tl_open = system.if_open = false;
  system.initialised = false;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR TLOpen(TL_HANDLE* system_handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (!Sys().initialised) return Err(GC_ERR_NOT_INITIALIZED, "GCInitLib first");
  if (Sys().tl_open) return Err(GC_ERR_RESOURCE_IN_USE, "system already open");
  Sys().tl_open = true;
  Sys().handles.insert(&g_tl_tag);
  *system_handle = &g_tl_tag;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR TLClose(TL_HANDLE handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (handle != &g_tl_tag || !Sys().tl_open) return Err(GC_ERR_INVALID_HANDLE, "not the system");
  Sys().tl_open = false;
  Sys().handles.erase(&g_tl_tag);
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR TLGetInfo(TL_HANDLE, TL_INFO_CMD command, INFO_DATATYPE* type, void* buffer,
                             std::size_t* size) {
  return GCGetInfo(command, type, buffer, size);
}

GC_EXPORT GC_ERROR TLUpdateInterfaceList(TL_HANDLE handle, bool8_t* changed, std::uint64_t) {
  if (handle != &g_tl_tag) return Err(GC_ERR_INVALID_HANDLE, "not the system");
  if (changed != nullptr) *changed = 0;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR TLGetNumInterfaces(TL_HANDLE handle, std::uint32_t* count) {
  if (handle != &g_tl_tag) return Err(GC_ERR_INVALID_HANDLE, "not the system");
  *count = 1;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR TLGetInterfaceID(TL_HANDLE handle, std::uint32_t index, char* id,
                                    std::size_t* size) {
  if (handle != &g_tl_tag) return Err(GC_ERR_INVALID_HANDLE, "not the system");
  if (index != 0) return Err(GC_ERR_INVALID_INDEX, "one interface");
  return CopyString(kInterfaceId, nullptr, id, size);
}

GC_EXPORT GC_ERROR TLGetInterfaceInfo(TL_HANDLE, const char* id, INTERFACE_INFO_CMD command,
                                      INFO_DATATYPE* type, void* buffer, std::size_t* size) {
  if (std::string(id) != kInterfaceId) return Err(GC_ERR_INVALID_ID, "no such interface");
  switch (command) {
    case INTERFACE_INFO_ID:
      return CopyString(kInterfaceId, type, buffer, size);
    case INTERFACE_INFO_DISPLAYNAME:
      return CopyString("lifmcr simulated grabber, port 0", type, buffer, size);
    case INTERFACE_INFO_TLTYPE:
      return CopyString("CXP", type, buffer, size);
    default:
      return Err(GC_ERR_NOT_IMPLEMENTED, "info not implemented");
  }
}

GC_EXPORT GC_ERROR TLOpenInterface(TL_HANDLE handle, const char* id, IF_HANDLE* interface) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (handle != &g_tl_tag) return Err(GC_ERR_INVALID_HANDLE, "not the system");
  if (std::string(id) != kInterfaceId) return Err(GC_ERR_INVALID_ID, "no such interface");
  if (Sys().if_open) return Err(GC_ERR_RESOURCE_IN_USE, "interface already open");
  Sys().if_open = true;
  Sys().handles.insert(&g_if_tag);
  *interface = &g_if_tag;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR IFClose(IF_HANDLE handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (handle != &g_if_tag || !Sys().if_open) return Err(GC_ERR_INVALID_HANDLE, "not the interface");
  Sys().if_open = false;
  Sys().handles.erase(&g_if_tag);
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR IFGetInfo(IF_HANDLE, INTERFACE_INFO_CMD command, INFO_DATATYPE* type,
                             void* buffer, std::size_t* size) {
  return TLGetInterfaceInfo(&g_tl_tag, kInterfaceId, command, type, buffer, size);
}

GC_EXPORT GC_ERROR IFUpdateDeviceList(IF_HANDLE handle, bool8_t* changed, std::uint64_t) {
  if (handle != &g_if_tag) return Err(GC_ERR_INVALID_HANDLE, "not the interface");
  if (changed != nullptr) *changed = 1;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR IFGetNumDevices(IF_HANDLE handle, std::uint32_t* count) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (handle != &g_if_tag) return Err(GC_ERR_INVALID_HANDLE, "not the interface");
  *count = 0;
  for (auto& camera : Sys().cameras) *count += camera->present ? 1 : 0;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR IFGetDeviceID(IF_HANDLE handle, std::uint32_t index, char* id,
                                 std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (handle != &g_if_tag) return Err(GC_ERR_INVALID_HANDLE, "not the interface");
  std::uint32_t i = 0;
  for (auto& camera : Sys().cameras)
    if (camera->present && i++ == index) return CopyString(camera->id, nullptr, id, size);
  return Err(GC_ERR_INVALID_INDEX, "no device at this index");
}

GC_ERROR DeviceInfo(Camera& camera, DEVICE_INFO_CMD command, INFO_DATATYPE* type, void* buffer,
                    std::size_t* size) {
  switch (command) {
    case DEVICE_INFO_ID:
      return CopyString(camera.id, type, buffer, size);
    case DEVICE_INFO_VENDOR:
      return CopyString("lifmcr", type, buffer, size);
    case DEVICE_INFO_MODEL:
      return CopyString("GenTL simulator", type, buffer, size);
    case DEVICE_INFO_TLTYPE:
      return CopyString("CXP", type, buffer, size);
    case DEVICE_INFO_DISPLAYNAME:
      return CopyString("lifmcr GenTL simulator " + camera.serial, type, buffer, size);
    case DEVICE_INFO_SERIAL_NUMBER:
      return CopyString(camera.serial, type, buffer, size);
    case DEVICE_INFO_ACCESS_STATUS:
      return CopyValue<std::int32_t>(camera.busy_elsewhere ? DEVICE_ACCESS_STATUS_BUSY
                                     : camera.open         ? DEVICE_ACCESS_STATUS_OPEN_READWRITE
                                                           : DEVICE_ACCESS_STATUS_READWRITE,
                                     INFO_DATATYPE_INT32, type, buffer, size);
    case DEVICE_INFO_TIMESTAMP_FREQUENCY:
      return CopyValue<std::uint64_t>(1'000'000'000, INFO_DATATYPE_UINT64, type, buffer, size);
    default:
      return Err(GC_ERR_NOT_IMPLEMENTED, "info not implemented");
  }
}

GC_EXPORT GC_ERROR IFGetDeviceInfo(IF_HANDLE handle, const char* id, DEVICE_INFO_CMD command,
                                   INFO_DATATYPE* type, void* buffer, std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (handle != &g_if_tag) return Err(GC_ERR_INVALID_HANDLE, "not the interface");
  Camera* camera = FindCamera(id);
  if (camera == nullptr) return Err(GC_ERR_INVALID_ID, std::string("no device ") + id);
  return DeviceInfo(*camera, command, type, buffer, size);
}

GC_EXPORT GC_ERROR IFOpenDevice(IF_HANDLE handle, const char* id, DEVICE_ACCESS_FLAGS,
                                DEV_HANDLE* device) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (handle != &g_if_tag) return Err(GC_ERR_INVALID_HANDLE, "not the interface");
  Camera* camera = FindCamera(id);
  if (camera == nullptr) return Err(GC_ERR_INVALID_ID, std::string("no device ") + id);
  if (camera->open)
    return Err(GC_ERR_RESOURCE_IN_USE, std::string("device ") + id + " is already open");
  if (camera->busy_elsewhere)
    return Err(GC_ERR_ACCESS_DENIED, std::string("device ") + id + " is held by another process");
  camera->open = true;
  auto opened = std::make_unique<DeviceHandle>();
  opened->camera = camera;
  opened->generation = camera->generation;
  Sys().handles.insert(opened.get());
  Sys().handles.insert(&opened->port_tag);
  *device = opened.get();
  Sys().devices.push_back(std::move(opened));
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DevGetPort(DEV_HANDLE handle, PORT_HANDLE* port) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  DeviceHandle* device = AsDevice(handle);
  if (device == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a device");
  *port = &device->port_tag;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DevGetInfo(DEV_HANDLE handle, DEVICE_INFO_CMD command, INFO_DATATYPE* type,
                              void* buffer, std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  DeviceHandle* device = AsDevice(handle);
  if (device == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a device");
  if (!Alive(device)) return Err(GC_ERR_IO, "device gone");
  return DeviceInfo(*device->camera, command, type, buffer, size);
}

GC_EXPORT GC_ERROR DevGetNumDataStreams(DEV_HANDLE handle, std::uint32_t* count) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (AsDevice(handle) == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a device");
  *count = 1;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DevGetDataStreamID(DEV_HANDLE handle, std::uint32_t index, char* id,
                                      std::size_t* size) {
  if (AsDevice(handle) == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a device");
  if (index != 0) return Err(GC_ERR_INVALID_INDEX, "one stream");
  return CopyString("Stream0", nullptr, id, size);
}

GC_EXPORT GC_ERROR DevOpenDataStream(DEV_HANDLE handle, const char* id, DS_HANDLE* stream_handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  DeviceHandle* device = AsDevice(handle);
  if (device == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a device");
  if (std::string(id) != "Stream0") return Err(GC_ERR_INVALID_ID, "no such stream");
  if (!Alive(device)) return Err(GC_ERR_IO, "device gone");
  if (device->camera->stream != nullptr) return Err(GC_ERR_RESOURCE_IN_USE, "stream already open");
  auto stream = std::make_unique<Stream>();
  stream->camera = device->camera;
  stream->event = std::make_unique<Event>();
  stream->event->stream = stream.get();
  device->camera->stream = stream.get();
  Sys().handles.insert(stream.get());
  *stream_handle = stream.get();
  Sys().streams.push_back(std::move(stream));
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DSClose(DS_HANDLE handle) {
  std::unique_lock<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  stream->acquiring = false;
  Sys().wake.wait(lock, [&] { return stream->filling == 0; });
  if (stream->camera->stream == stream) stream->camera->stream = nullptr;
  Sys().handles.erase(stream);
  Sys().handles.erase(stream->event.get());
  stream->event->killed = true;
  Sys().wake.notify_all();
  // Kept allocated (a waiter may still hold the event); invalid from now on.
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DevClose(DEV_HANDLE handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  DeviceHandle* device = AsDevice(handle);
  if (device == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a device");
  if (Alive(device)) {
    device->camera->open = false;
    device->camera->running = false;
  }
  Sys().handles.erase(device);
  Sys().handles.erase(&device->port_tag);
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR GCReadPort(PORT_HANDLE port, std::uint64_t address, void* buffer,
                              std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  DeviceHandle* device = PortDevice(port);
  if (device == nullptr) return Err(GC_ERR_NOT_IMPLEMENTED, "only the remote device has a port");
  if (!Alive(device)) return Err(GC_ERR_IO, "the device does not answer");
  return ReadRegisters(*device->camera, address, buffer, *size);
}

GC_EXPORT GC_ERROR GCWritePort(PORT_HANDLE port, std::uint64_t address, const void* buffer,
                               std::size_t* size) {
  if (address == sim::kAcquisitionStart) {
    int delay_ms = 0;
    {
      std::lock_guard<std::mutex> lock(Sys().mutex);
      DeviceHandle* device = PortDevice(port);
      if (device != nullptr && Alive(device)) delay_ms = device->camera->arm_delay_ms;
    }
    // Slow to arm: the other cameras and the line run on meanwhile.
    if (delay_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
  }
  std::lock_guard<std::mutex> lock(Sys().mutex);
  DeviceHandle* device = PortDevice(port);
  if (device == nullptr) return Err(GC_ERR_NOT_IMPLEMENTED, "only the remote device has a port");
  if (!Alive(device)) return Err(GC_ERR_IO, "the device does not answer");
  return WriteRegisters(*device->camera, address, buffer, *size);
}

std::string XmlUrl() {
  char url[128];
  std::snprintf(url, sizeof(url), "Local:lifmcr_gentl_sim.xml;%llx;%zx",
                static_cast<unsigned long long>(sim::kXmlAddress), sizeof(sim::kXml) - 1);
  return url;
}

GC_EXPORT GC_ERROR GCGetPortURL(PORT_HANDLE port, char* url, std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (PortDevice(port) == nullptr)
    return Err(GC_ERR_NOT_IMPLEMENTED, "only the remote device has a port");
  return CopyString(XmlUrl(), nullptr, url, size);
}

GC_EXPORT GC_ERROR GCGetNumPortURLs(PORT_HANDLE port, std::uint32_t* count) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (PortDevice(port) == nullptr)
    return Err(GC_ERR_NOT_IMPLEMENTED, "only the remote device has a port");
  *count = 1;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR GCGetPortURLInfo(PORT_HANDLE port, std::uint32_t index, URL_INFO_CMD command,
                                    INFO_DATATYPE* type, void* buffer, std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (PortDevice(port) == nullptr)
    return Err(GC_ERR_NOT_IMPLEMENTED, "only the remote device has a port");
  if (index != 0) return Err(GC_ERR_INVALID_INDEX, "one URL");
  if (command != URL_INFO_URL) return Err(GC_ERR_NOT_IMPLEMENTED, "URL only");
  return CopyString(XmlUrl(), type, buffer, size);
}

GC_EXPORT GC_ERROR GCGetPortInfo(PORT_HANDLE port, PORT_INFO_CMD command, INFO_DATATYPE* type,
                                 void* buffer, std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  if (PortDevice(port) == nullptr)
    return Err(GC_ERR_NOT_IMPLEMENTED, "only the remote device has a port");
  switch (command) {
    case PORT_INFO_PORTNAME:
      return CopyString("Device", type, buffer, size);
    case PORT_INFO_LITTLE_ENDIAN:
      return CopyValue<bool8_t>(1, INFO_DATATYPE_BOOL8, type, buffer, size);
    case PORT_INFO_BIG_ENDIAN:
      return CopyValue<bool8_t>(0, INFO_DATATYPE_BOOL8, type, buffer, size);
    default:
      return Err(GC_ERR_NOT_IMPLEMENTED, "info not implemented");
  }
}

GC_EXPORT GC_ERROR DSAnnounceBuffer(DS_HANDLE handle, void* base, std::size_t size, void* user,
                                    BUFFER_HANDLE* buffer_handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  if (base == nullptr || size == 0) return Err(GC_ERR_INVALID_PARAMETER, "no memory");
  auto buffer = std::make_unique<Buffer>();
  buffer->stream = stream;
  buffer->base = static_cast<std::uint8_t*>(base);
  buffer->size = size;
  buffer->user = user;
  *buffer_handle = buffer.get();
  stream->buffers.push_back(std::move(buffer));
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DSRevokeBuffer(DS_HANDLE handle, BUFFER_HANDLE buffer_handle, void** base,
                                  void** user) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  Buffer* buffer = AsBuffer(stream, buffer_handle);
  if (buffer == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a buffer of this stream");
  if (buffer->queued) return Err(GC_ERR_RESOURCE_IN_USE, "buffer still queued");
  if (base != nullptr) *base = buffer->base;
  if (user != nullptr) *user = buffer->user;
  stream->buffers.erase(std::find_if(stream->buffers.begin(), stream->buffers.end(),
                                     [&](const auto& b) { return b.get() == buffer; }));
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DSQueueBuffer(DS_HANDLE handle, BUFFER_HANDLE buffer_handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  Buffer* buffer = AsBuffer(stream, buffer_handle);
  if (buffer == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a buffer of this stream");
  buffer->queued = true;
  buffer->filled = 0;
  stream->input.push_back(buffer);
  Sys().wake.notify_all();
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DSFlushQueue(DS_HANDLE handle, ACQ_QUEUE_TYPE operation) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  if (operation != ACQ_QUEUE_ALL_DISCARD) return Err(GC_ERR_NOT_IMPLEMENTED, "ALL_DISCARD only");
  stream->input.clear();
  stream->event->queue.clear();
  for (auto& buffer : stream->buffers) buffer->queued = false;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DSStartAcquisition(DS_HANDLE handle, ACQ_START_FLAGS, std::uint64_t) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  if (stream->acquiring) return Err(GC_ERR_RESOURCE_IN_USE, "already acquiring");
  stream->acquiring = true;
  Sys().wake.notify_all();
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DSStopAcquisition(DS_HANDLE handle, ACQ_STOP_FLAGS) {
  std::unique_lock<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  if (!stream->acquiring) return Err(GC_ERR_RESOURCE_IN_USE, "not acquiring");
  stream->acquiring = false;
  // The frame being written completes (or returns to the input pool) first.
  Sys().wake.wait(lock, [&] { return stream->filling == 0; });
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR DSGetInfo(DS_HANDLE handle, STREAM_INFO_CMD command, INFO_DATATYPE* type,
                             void* buffer, std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  switch (command) {
    case STREAM_INFO_ID:
      return CopyString("Stream0", type, buffer, size);
    case STREAM_INFO_NUM_DELIVERED:
      return CopyValue<std::uint64_t>(stream->delivered, INFO_DATATYPE_UINT64, type, buffer, size);
    case STREAM_INFO_NUM_UNDERRUN:
      return CopyValue<std::uint64_t>(stream->underruns, INFO_DATATYPE_UINT64, type, buffer, size);
    case STREAM_INFO_NUM_ANNOUNCED:
      return CopyValue<std::size_t>(stream->buffers.size(), INFO_DATATYPE_SIZET, type, buffer,
                                    size);
    case STREAM_INFO_NUM_QUEUED:
      return CopyValue<std::size_t>(stream->input.size(), INFO_DATATYPE_SIZET, type, buffer, size);
    case STREAM_INFO_PAYLOAD_SIZE:
      return CopyValue<std::size_t>(stream->camera->Payload(), INFO_DATATYPE_SIZET, type, buffer,
                                    size);
    case STREAM_INFO_IS_GRABBING:
      return CopyValue<bool8_t>(stream->acquiring, INFO_DATATYPE_BOOL8, type, buffer, size);
    case STREAM_INFO_DEFINES_PAYLOADSIZE:
      return CopyValue<bool8_t>(1, INFO_DATATYPE_BOOL8, type, buffer, size);
    case STREAM_INFO_TLTYPE:
      return CopyString("CXP", type, buffer, size);
    case STREAM_INFO_BUF_ANNOUNCE_MIN:
      return CopyValue<std::size_t>(1, INFO_DATATYPE_SIZET, type, buffer, size);
    case STREAM_INFO_BUF_ALIGNMENT:
      return CopyValue<std::size_t>(64, INFO_DATATYPE_SIZET, type, buffer, size);
    default:
      return Err(GC_ERR_NOT_IMPLEMENTED, "info not implemented");
  }
}

GC_EXPORT GC_ERROR DSGetBufferInfo(DS_HANDLE handle, BUFFER_HANDLE buffer_handle,
                                   BUFFER_INFO_CMD command, INFO_DATATYPE* type, void* out,
                                   std::size_t* size) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  Buffer* buffer = AsBuffer(stream, buffer_handle);
  if (buffer == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a buffer of this stream");
  switch (command) {
    case BUFFER_INFO_BASE:
      return CopyValue<void*>(buffer->base, INFO_DATATYPE_PTR, type, out, size);
    case BUFFER_INFO_SIZE:
      return CopyValue<std::size_t>(buffer->size, INFO_DATATYPE_SIZET, type, out, size);
    case BUFFER_INFO_USER_PTR:
      return CopyValue<void*>(buffer->user, INFO_DATATYPE_PTR, type, out, size);
    case BUFFER_INFO_TIMESTAMP:
    case BUFFER_INFO_TIMESTAMP_NS:
      return CopyValue<std::uint64_t>(buffer->timestamp_ns, INFO_DATATYPE_UINT64, type, out, size);
    case BUFFER_INFO_IS_INCOMPLETE:
      return CopyValue<bool8_t>(buffer->incomplete, INFO_DATATYPE_BOOL8, type, out, size);
    case BUFFER_INFO_SIZE_FILLED:
      return CopyValue<std::size_t>(buffer->filled, INFO_DATATYPE_SIZET, type, out, size);
    case BUFFER_INFO_WIDTH:
      return CopyValue<std::size_t>(buffer->width, INFO_DATATYPE_SIZET, type, out, size);
    case BUFFER_INFO_HEIGHT:
      return CopyValue<std::size_t>(buffer->height, INFO_DATATYPE_SIZET, type, out, size);
    case BUFFER_INFO_IMAGEOFFSET:
      return CopyValue<std::size_t>(0, INFO_DATATYPE_SIZET, type, out, size);
    case BUFFER_INFO_FRAMEID:
      return CopyValue<std::uint64_t>(buffer->frame_id, INFO_DATATYPE_UINT64, type, out, size);
    case BUFFER_INFO_PIXELFORMAT:
      return CopyValue<std::uint64_t>(buffer->pixel_format, INFO_DATATYPE_UINT64, type, out, size);
    case BUFFER_INFO_PIXELFORMAT_NAMESPACE:
      return CopyValue<std::uint64_t>(PIXELFORMAT_NAMESPACE_PFNC_32BIT, INFO_DATATYPE_UINT64, type,
                                      out, size);
    case BUFFER_INFO_PAYLOADTYPE:
      return CopyValue<std::size_t>(PAYLOAD_TYPE_IMAGE, INFO_DATATYPE_SIZET, type, out, size);
    case BUFFER_INFO_DATA_LARGER_THAN_BUFFER:
      return CopyValue<bool8_t>(0, INFO_DATATYPE_BOOL8, type, out, size);
    case BUFFER_INFO_IS_QUEUED:
      return CopyValue<bool8_t>(buffer->queued, INFO_DATATYPE_BOOL8, type, out, size);
    case BUFFER_INFO_CONTAINS_CHUNKDATA:
      return CopyValue<bool8_t>(buffer->chunk_offset != 0, INFO_DATATYPE_BOOL8, type, out, size);
    default:
      return Err(GC_ERR_NOT_IMPLEMENTED, "info not implemented");
  }
}

GC_EXPORT GC_ERROR DSGetBufferChunkData(DS_HANDLE handle, BUFFER_HANDLE buffer_handle,
                                        SINGLE_CHUNK_DATA* chunks, std::size_t* count) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(handle);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  Buffer* buffer = AsBuffer(stream, buffer_handle);
  if (buffer == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a buffer of this stream");
  const std::size_t n = buffer->chunk_offset != 0 ? 1 : 0;
  if (chunks == nullptr) {
    *count = n;
    return GC_ERR_SUCCESS;
  }
  if (*count < n) return Err(GC_ERR_BUFFER_TOO_SMALL, "one chunk");
  if (n == 1)
    chunks[0] = SINGLE_CHUNK_DATA{sim::kChunkId, static_cast<std::ptrdiff_t>(buffer->chunk_offset),
                                  sim::kChunkBytes};
  *count = n;
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR GCRegisterEvent(EVENTSRC_HANDLE source, EVENT_TYPE event_type,
                                   EVENT_HANDLE* event) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(source);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "events on data streams only");
  if (event_type != EVENT_NEW_BUFFER) return Err(GC_ERR_NOT_IMPLEMENTED, "EVENT_NEW_BUFFER only");
  stream->event->killed = false;
  Sys().handles.insert(stream->event.get());
  *event = stream->event.get();
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR GCUnregisterEvent(EVENTSRC_HANDLE source, EVENT_TYPE) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Stream* stream = AsStream(source);
  if (stream == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not a stream");
  stream->event->killed = true;
  Sys().handles.erase(stream->event.get());
  Sys().wake.notify_all();
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR EventGetData(EVENT_HANDLE handle, void* buffer, std::size_t* size,
                                std::uint64_t timeout_ms) {
  std::unique_lock<std::mutex> lock(Sys().mutex);
  Event* event = AsEvent(handle);
  if (event == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not an event");
  if (*size < sizeof(EVENT_NEW_BUFFER_DATA))
    return Err(GC_ERR_BUFFER_TOO_SMALL, "buffer too small");
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(std::min<std::uint64_t>(timeout_ms, 1u << 30));
  while (event->queue.empty() && !event->killed) {
    if (Sys().wake.wait_until(lock, deadline) == std::cv_status::timeout && event->queue.empty())
      return Err(GC_ERR_TIMEOUT, "no new buffer");
  }
  if (event->killed && event->queue.empty()) {
    if (!Live(event)) return Err(GC_ERR_INVALID_HANDLE, "event unregistered");
    event->killed = false;  // EventKill aborts one wait
    return Err(GC_ERR_ABORT, "event killed");
  }
  const EVENT_NEW_BUFFER_DATA data = event->queue.front();
  event->queue.pop_front();
  static_cast<Buffer*>(data.BufferHandle)->queued = false;
  std::memcpy(buffer, &data, sizeof(data));
  *size = sizeof(data);
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR EventFlush(EVENT_HANDLE handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Event* event = AsEvent(handle);
  if (event == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not an event");
  event->queue.clear();
  return GC_ERR_SUCCESS;
}

GC_EXPORT GC_ERROR EventKill(EVENT_HANDLE handle) {
  std::lock_guard<std::mutex> lock(Sys().mutex);
  Event* event = AsEvent(handle);
  if (event == nullptr) return Err(GC_ERR_INVALID_HANDLE, "not an event");
  event->killed = true;
  Sys().wake.notify_all();
  return GC_ERR_SUCCESS;
}

}  // extern "C"
