#include "sync/first_frame_placement.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace lifmcr {

std::string FirstPlacement::OneLine() const {
  char text[160];
  if (by == By::kTriggerCount)
    std::snprintf(text, sizeof(text),
                  "trigger %lld by the software trigger count (the first trigger fired to it)",
                  static_cast<long long>(trigger_index));
  else if (by == By::kDeviceTime)
    std::snprintf(text, sizeof(text),
                  "trigger %lld by device time against camera %d (grid error %+.2f periods)",
                  static_cast<long long>(trigger_index), reference_camera, grid_error);
  else
    std::snprintf(text, sizeof(text), "trigger %lld by host time",
                  static_cast<long long>(trigger_index));
  return note.empty() ? std::string(text) : std::string(text) + " (" + note + ")";
}

FirstFramePlacer::FirstFramePlacer(std::int64_t trigger_period_ns, double tolerance,
                                   std::vector<std::string> device_clocks)
    : period_ns_(trigger_period_ns), tolerance_(tolerance), clocks_(std::move(device_clocks)) {}

void FirstFramePlacer::Placed(int camera, std::int64_t trigger_index, std::int64_t device_ns) {
  if (camera < 0 || camera >= static_cast<int>(clocks_.size()) || clocks_[camera].empty()) return;
  Clock& clock = by_name_[clocks_[camera]];
  clock.offsets_ns.push_back(device_ns - trigger_index * period_ns_);
  if (clock.offsets_ns.size() > kOffsetFrames) clock.offsets_ns.pop_front();
  clock.latest_camera = camera;
}

const FirstFramePlacer::Clock* FirstFramePlacer::ClockOf(int camera) const {
  if (camera < 0 || camera >= static_cast<int>(clocks_.size()) || clocks_[camera].empty())
    return nullptr;
  auto it = by_name_.find(clocks_[camera]);
  return it == by_name_.end() || it->second.offsets_ns.empty() ? nullptr : &it->second;
}

double FirstFramePlacer::Steps(const Clock& clock, std::int64_t device_ns) const {
  std::vector<std::int64_t> offsets(clock.offsets_ns.begin(), clock.offsets_ns.end());
  auto middle = offsets.begin() + static_cast<std::ptrdiff_t>(offsets.size() / 2);
  std::nth_element(offsets.begin(), middle, offsets.end());
  return static_cast<double>(device_ns - *middle) / static_cast<double>(period_ns_);
}

std::optional<FirstPlacement> FirstFramePlacer::ByDeviceTime(int camera,
                                                             std::int64_t device_ns) const {
  const Clock* clock = ClockOf(camera);
  if (clock == nullptr) return std::nullopt;
  const double steps = Steps(*clock, device_ns);
  const double error = steps - std::round(steps);
  if (std::abs(error) > tolerance_) return std::nullopt;
  FirstPlacement placement;
  placement.trigger_index = std::llround(steps);
  placement.by = FirstPlacement::By::kDeviceTime;
  placement.reference_camera = clock->latest_camera;
  placement.grid_error = error;
  return placement;
}

std::string FirstFramePlacer::WhyNotByDeviceTime(int camera, std::int64_t device_ns) const {
  if (camera < 0 || camera >= static_cast<int>(clocks_.size()) || clocks_[camera].empty())
    return "its device clock is its own";
  const Clock* clock = ClockOf(camera);
  if (clock == nullptr)
    return "no camera on its device clock \"" + clocks_[camera] + "\" placed yet";
  const double steps = Steps(*clock, device_ns);
  char text[160];
  std::snprintf(text, sizeof(text),
                "its device time is %+.2f periods off the trigger grid of its clock (tolerance "
                "%.2f)",
                steps - std::round(steps), tolerance_);
  return text;
}

}  // namespace lifmcr
