#include "drivers/usb_hotplug.h"

#include <atomic>
#include <ctime>
#include <deque>
#include <libusb.h>
#include <mutex>
#include <set>
#include <thread>
#include <utility>

namespace lifmcr {
namespace {

constexpr std::uint8_t kMiscellaneousClass = 0xEF;
constexpr std::uint8_t kUsb3VisionSubclass = 0x05;
constexpr std::size_t kMaxKeptEvents = 256;

std::int64_t RealtimeNs() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

bool IsUsb3Vision(libusb_device* device) {
  libusb_config_descriptor* config = nullptr;
  if (libusb_get_active_config_descriptor(device, &config) != 0 &&
      libusb_get_config_descriptor(device, 0, &config) != 0)
    return false;
  bool found = false;
  for (int i = 0; i < config->bNumInterfaces && !found; ++i) {
    const libusb_interface& interface = config->interface[i];
    for (int a = 0; a < interface.num_altsetting && !found; ++a) {
      const libusb_interface_descriptor& alt = interface.altsetting[a];
      found = alt.bInterfaceClass == kMiscellaneousClass &&
              alt.bInterfaceSubClass == kUsb3VisionSubclass;
    }
  }
  libusb_free_config_descriptor(config);
  return found;
}

}  // namespace

struct UsbHotplugMonitor::State {
  libusb_context* context = nullptr;
  libusb_hotplug_callback_handle handle = 0;
  bool registered = false;
  std::thread thread;
  std::atomic<bool> stop{false};

  mutable std::mutex mutex;
  std::uint64_t generation = 0;
  std::set<std::pair<std::uint8_t, std::uint8_t>> present;  // (bus, address)
  std::deque<UsbDeviceEvent> events;

  // Runs in the event thread (or in register, for devices already present).
  static int LIBUSB_CALL OnEvent(libusb_context* /*context*/, libusb_device* device,
                                 libusb_hotplug_event event, void* user_data) {
    State& state = *static_cast<State*>(user_data);
    UsbDeviceEvent record;
    record.arrived = event == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED;
    record.bus = libusb_get_bus_number(device);
    record.address = libusb_get_device_address(device);
    libusb_device_descriptor descriptor{};
    if (libusb_get_device_descriptor(device, &descriptor) == 0) {
      record.vendor_id = descriptor.idVendor;
      record.product_id = descriptor.idProduct;
    }
    record.host_ns = RealtimeNs();
    const std::pair<std::uint8_t, std::uint8_t> key(record.bus, record.address);
    std::lock_guard<std::mutex> lock(state.mutex);
    if (record.arrived) {
      if (!IsUsb3Vision(device)) return 0;
      state.present.insert(key);
    } else if (state.present.erase(key) == 0) {
      return 0;  // not a USB3 Vision device we saw arrive
    }
    ++state.generation;
    state.events.push_back(record);
    if (state.events.size() > kMaxKeptEvents) state.events.pop_front();
    return 0;  // keep the callback registered
  }
};

UsbHotplugMonitor::UsbHotplugMonitor() : state_(std::make_unique<State>()) {}

UsbHotplugMonitor::~UsbHotplugMonitor() {
  state_->stop.store(true);
  if (state_->registered) libusb_hotplug_deregister_callback(state_->context, state_->handle);
  // Deregistering wakes the event loop, so the thread sees `stop` at once.
  if (state_->thread.joinable()) state_->thread.join();
  if (state_->context != nullptr) libusb_exit(state_->context);
}

Expected<std::unique_ptr<UsbHotplugMonitor>> UsbHotplugMonitor::Start() {
  std::unique_ptr<UsbHotplugMonitor> monitor(new UsbHotplugMonitor());
  State& state = *monitor->state_;
  const int init = libusb_init(&state.context);
  if (init != 0) {
    state.context = nullptr;
    return Error{std::string("usb hotplug: libusb_init failed: ") + libusb_strerror(init)};
  }
  if (!libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG))
    return Error{"usb hotplug: this libusb has no hotplug support"};
  const int registered = libusb_hotplug_register_callback(
      state.context,
      static_cast<libusb_hotplug_event>(LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED |
                                        LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT),
      LIBUSB_HOTPLUG_ENUMERATE, LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY,
      LIBUSB_HOTPLUG_MATCH_ANY, &State::OnEvent, &state, &state.handle);
  if (registered != LIBUSB_SUCCESS)
    return Error{std::string("usb hotplug: registering the callback failed: ") +
                 libusb_strerror(registered)};
  state.registered = true;
  State* raw = &state;
  state.thread = std::thread([raw] {
    while (!raw->stop.load()) {
      timeval timeout{0, 200000};
      libusb_handle_events_timeout_completed(raw->context, &timeout, nullptr);
    }
  });
  return monitor;
}

UsbHotplugMonitor* UsbHotplugMonitor::Shared(std::string* error) {
  static std::once_flag once;
  static std::unique_ptr<UsbHotplugMonitor> shared;
  static std::string start_error;
  std::call_once(once, [] {
    Expected<std::unique_ptr<UsbHotplugMonitor>> started = Start();
    if (started)
      shared = std::move(*started);
    else
      start_error = started.error().message;
  });
  if (!shared && error != nullptr) *error = start_error;
  return shared.get();
}

std::uint64_t UsbHotplugMonitor::generation() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->generation;
}

std::size_t UsbHotplugMonitor::present() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->present.size();
}

std::vector<UsbDeviceEvent> UsbHotplugMonitor::TakeEvents() {
  std::lock_guard<std::mutex> lock(state_->mutex);
  std::vector<UsbDeviceEvent> taken(state_->events.begin(), state_->events.end());
  state_->events.clear();
  return taken;
}

}  // namespace lifmcr
