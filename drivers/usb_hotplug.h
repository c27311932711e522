#pragma once
// Arrival and departure of USB3 Vision devices, from libusb's hotplug
// events, so a USB camera that is unplugged is noticed at once (not at the
// next failed control access) and one that comes back is re-opened at once
// (not at the next reconnect tick).
//
// A device is USB3 Vision when one of its interfaces has class 0xEF
// (miscellaneous), subclass 0x05 (USB3 Vision), as the USB3 Vision standard
// assigns; other USB devices are ignored. libusb is linked privately; this
// header does not include it.
//
// One process-wide monitor (Shared()) runs one event thread; AravisCamera
// asks it for the generation number, which changes with every USB3 Vision
// arrival or departure.

#include "config/error.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace lifmcr {

struct UsbDeviceEvent {
  bool arrived = false;  // false: left
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::uint8_t bus = 0;
  std::uint8_t address = 0;
  std::int64_t host_ns = 0;  // CLOCK_REALTIME when the event was handled
};

class UsbHotplugMonitor {
 public:
  // Starts listening (its own libusb context and event thread). An error
  // when libusb cannot start or has no hotplug support on this system.
  static Expected<std::unique_ptr<UsbHotplugMonitor>> Start();
  // The process-wide monitor, started on first use; nullptr (and the reason
  // in `error`, when given) where hotplug is unavailable.
  static UsbHotplugMonitor* Shared(std::string* error = nullptr);

  ~UsbHotplugMonitor();  // stops the event thread and releases libusb
  UsbHotplugMonitor(const UsbHotplugMonitor&) = delete;
  UsbHotplugMonitor& operator=(const UsbHotplugMonitor&) = delete;

  // Incremented on every USB3 Vision arrival or departure.
  std::uint64_t generation() const;
  // USB3 Vision devices present now (arrived, not yet left).
  std::size_t present() const;
  // The events since the last call (at most the latest 256 are kept).
  std::vector<UsbDeviceEvent> TakeEvents();

 private:
  UsbHotplugMonitor();
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace lifmcr
