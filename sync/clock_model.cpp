#include "sync/clock_model.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace lifmcr {

Status ClockModelOptions::Check() const {
  if (window < 2) return Error{"clock model: window: expected >= 2 samples"};
  if (jump_threshold_ns <= 0) return Error{"clock model: jump_threshold_ns: expected > 0"};
  if (jump_confirm < 1) return Error{"clock model: jump_confirm: expected >= 1"};
  return Status::Ok();
}

namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const std::size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<long>(mid), values.end());
  return values[mid];
}

}  // namespace

void ClockModel::Restart(std::int64_t device_ns, std::int64_t host_ns) {
  samples_.clear();
  reference_ns_ = device_ns;
  offset_reference_ns_ = host_ns - device_ns;
  intercept_ = 0.0;
  drift_ = 0.0;
  jitter_ns_ = 0.0;
}

std::int64_t ClockModel::HostFromDevice(std::int64_t device_ns) const {
  const double x = static_cast<double>(device_ns - reference_ns_);
  return device_ns + offset_reference_ns_ + std::llround(Predict(x));
}

std::int64_t ClockModel::offset_ns() const {
  return HostFromDevice(last_device_ns_) - last_device_ns_;
}

ClockUpdate ClockModel::Add(std::int64_t device_ns, std::int64_t host_ns) {
  ++total_samples_;
  last_device_ns_ = device_ns;
  ClockUpdate update;
  if (samples_.empty()) {
    Restart(device_ns, host_ns);
    samples_.push_back({0.0, 0.0});
    return update;
  }
  const double x = static_cast<double>(device_ns - reference_ns_);
  const double y = static_cast<double>((host_ns - device_ns) - offset_reference_ns_);
  update.residual_ns = y - Predict(x);
  if (std::abs(update.residual_ns) > static_cast<double>(options_.jump_threshold_ns)) {
    update.outlier = true;
    // Outliers that disagree with the pending ones start a new candidate.
    if (!pending_.empty()) {
      const auto& first = pending_.front();
      const double offset_first = static_cast<double>(first.second - first.first);
      const double offset_now = static_cast<double>(host_ns - device_ns);
      if (std::abs(offset_now - offset_first) > static_cast<double>(options_.jump_threshold_ns)) {
        outliers_ += pending_.size();
        pending_.clear();
      }
    }
    pending_.emplace_back(device_ns, host_ns);
    if (static_cast<int>(pending_.size()) >= options_.jump_confirm) {
      Restart(pending_.front().first, pending_.front().second);
      for (const auto& [d, h] : pending_) {
        samples_.push_back({static_cast<double>(d - reference_ns_),
                            static_cast<double>((h - d) - offset_reference_ns_)});
      }
      pending_.clear();
      Refit();
      ++jumps_;
      update.jump = true;
    }
    return update;
  }
  outliers_ += pending_.size();
  pending_.clear();
  samples_.push_back({x, y});
  while (static_cast<int>(samples_.size()) > options_.window) samples_.pop_front();
  Refit();
  return update;
}

void ClockModel::Refit() {
  // Least squares y = a + b x, twice: all samples, then the inliers of the first fit.
  auto fit = [this](const std::vector<bool>& use) {
    double n = 0, sx = 0, sy = 0;
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      if (!use[i]) continue;
      n += 1;
      sx += samples_[i].x;
      sy += samples_[i].y;
    }
    if (n == 0) return;
    const double mx = sx / n, my = sy / n;
    double sxx = 0, sxy = 0;
    for (std::size_t i = 0; i < samples_.size(); ++i) {
      if (!use[i]) continue;
      sxx += (samples_[i].x - mx) * (samples_[i].x - mx);
      sxy += (samples_[i].x - mx) * (samples_[i].y - my);
    }
    // Drift needs a time span; a few ms of samples say nothing about it.
    drift_ = (n >= 3 && sxx > 0) ? sxy / sxx : 0.0;
    intercept_ = my - drift_ * mx;
  };
  std::vector<bool> use(samples_.size(), true);
  fit(use);
  std::vector<double> abs_residuals;
  abs_residuals.reserve(samples_.size());
  for (const Sample& s : samples_) abs_residuals.push_back(std::abs(s.y - Predict(s.x)));
  const double sigma = 1.4826 * Median(abs_residuals);
  const double band = std::max(3.0 * sigma, 1000.0);  // 1 us floor: quantised clocks
  bool any_rejected = false;
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    use[i] = abs_residuals[i] <= band;
    any_rejected = any_rejected || !use[i];
  }
  if (any_rejected) fit(use);
  abs_residuals.clear();
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    if (use[i]) abs_residuals.push_back(std::abs(samples_[i].y - Predict(samples_[i].x)));
  }
  jitter_ns_ = 1.4826 * Median(abs_residuals);
}

std::string ClockModel::OneLine() const {
  char line[160];
  std::snprintf(line, sizeof(line),
                "offset %lld ns, drift %.2f ppm, jitter %.0f us, %llu outliers, %llu jumps",
                static_cast<long long>(valid() ? offset_ns() : 0), drift_ppm(), jitter_ns_ / 1000.0,
                static_cast<unsigned long long>(outliers_),
                static_cast<unsigned long long>(jumps_));
  return line;
}

}  // namespace lifmcr
