#include "sync/armed_start.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace lifmcr {

ArmedStart::ArmedStart(int cameras, std::int64_t trigger_period_ns)
    : period_ns_(trigger_period_ns), cameras_(static_cast<std::size_t>(std::max(cameras, 0))) {}

void ArmedStart::Armed(int camera, std::int64_t host_ns, std::optional<std::int64_t> device_ns) {
  if (camera < 0 || camera >= static_cast<int>(cameras_.size())) return;
  cameras_[camera].armed_host_ns = host_ns;
  cameras_[camera].armed_device_ns = device_ns;
}

void ArmedStart::FirstFrame(int camera, std::int64_t trigger_index, std::int64_t device_ns,
                            std::int64_t host_ns) {
  if (camera < 0 || camera >= static_cast<int>(cameras_.size()) || cameras_[camera].first) return;
  cameras_[camera].first = First{trigger_index, device_ns, host_ns};
}

std::optional<double> ArmedStart::PeriodsArmedBeforeFirst(const CameraArm& camera) const {
  if (!camera.first) return std::nullopt;
  const auto period = static_cast<double>(period_ns_);
  if (camera.armed_device_ns)
    return static_cast<double>(camera.first->device_ns - *camera.armed_device_ns) / period;
  if (camera.armed_host_ns)
    return static_cast<double>(camera.first->host_ns - *camera.armed_host_ns) / period;
  return 0.0;  // never armed by the caller: its first frame is its first trigger
}

std::optional<std::int64_t> ArmedStart::ArmedFrom(int camera) const {
  const CameraArm& arm = cameras_[camera];
  const std::optional<double> periods = PeriodsArmedBeforeFirst(arm);
  if (!periods) return std::nullopt;
  const auto armed_for =
      std::max<std::int64_t>(0, static_cast<std::int64_t>(std::floor(*periods - kMargin)));
  return arm.first->trigger_index - armed_for;
}

std::optional<std::int64_t> ArmedStart::Decide(bool force) {
  if (origin_) return origin_;
  std::optional<std::int64_t> first_of_rig;
  std::optional<std::int64_t> all_armed;
  for (int c = 0; c < static_cast<int>(cameras_.size()); ++c) {
    const std::optional<std::int64_t> armed = ArmedFrom(c);
    if (!armed) {
      if (!force) return std::nullopt;
      continue;
    }
    const std::int64_t first = cameras_[c].first->trigger_index;
    first_of_rig = first_of_rig ? std::min(*first_of_rig, first) : first;
    all_armed = all_armed ? std::max(*all_armed, *armed) : *armed;
  }
  origin_ = first_of_rig ? std::max(*first_of_rig, *all_armed) : 0;
  return origin_;
}

std::string ArmedStart::HowArmed(int camera) const {
  const CameraArm& arm = cameras_[camera];
  const std::optional<double> periods = PeriodsArmedBeforeFirst(arm);
  if (!periods) return "";
  char text[160];
  std::snprintf(text, sizeof(text), "armed %.2f periods before its first frame (%s)", *periods,
                arm.armed_device_ns ? "device clock latched at AcquisitionStart"
                                    : "host time, the device cannot latch its clock");
  return text;
}

}  // namespace lifmcr
