// The libusb hotplug monitor on this machine: it starts, reports no USB3
// Vision device where there is none, and stops promptly. (Plugging a real
// camera in and out is a manual check; see the report in drivers/.)

#include "drivers/usb_hotplug.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>

namespace lifmcr {
namespace {

TEST(UsbHotplug, StartsListsNoUsb3VisionDeviceAndStopsPromptly) {
  auto monitor = UsbHotplugMonitor::Start();
  if (!monitor) {
    // Containers without udev/netlink: the error must say why.
    EXPECT_NE(monitor.error().message.find("usb hotplug"), std::string::npos);
    GTEST_SKIP() << monitor.error().message;
  }
  if (!std::filesystem::exists("/dev/bus/usb")) {
    // No USB bus at all: nothing can be present or arrive.
    EXPECT_EQ((*monitor)->present(), 0u);
    EXPECT_EQ((*monitor)->generation(), 0u);
    EXPECT_TRUE((*monitor)->TakeEvents().empty());
  }
  // USB3 Vision devices present at start were enumerated as arrivals.
  EXPECT_EQ((*monitor)->TakeEvents().size(), (*monitor)->present());
  const auto start = std::chrono::steady_clock::now();
  monitor->reset();
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(1000));
}

TEST(UsbHotplug, SharedMonitorIsOneInstance) {
  std::string error;
  UsbHotplugMonitor* first = UsbHotplugMonitor::Shared(&error);
  UsbHotplugMonitor* second = UsbHotplugMonitor::Shared();
  EXPECT_EQ(first, second);
  if (first == nullptr) {
    EXPECT_FALSE(error.empty());
  }
}

}  // namespace
}  // namespace lifmcr
