#pragma once
// A camera's device clock mapped to the host clock, estimated online.
//
// Model: host_ns = device_ns + offset_ns + drift * (device_ns - reference_ns),
// fitted to (device_ns, host_ns) pairs of the camera's frames. host_ns is the
// arrival time, so the offset includes the mean transport latency: the model
// predicts when a frame should arrive, and a frame much later than that was
// held up somewhere (late).
//
// Robustness: the fit is least squares over the last `window` inliers, then
// refitted without the residuals beyond 3 robust sigmas (1.4826 MAD).
// A sample whose residual exceeds `jump_threshold_ns` is an outlier and does
// not enter the fit; `jump_confirm` consecutive outliers that agree with each
// other (within jump_threshold_ns) are a clock jump: the model restarts from
// them and `jumps` counts it (the outliers before it are then not counted as
// outliers). Residual jitter is the robust sigma of the inliers.

#include "config/error.h"

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

namespace lifmcr {

struct ClockModelOptions {
  int window = 256;  // samples fitted, >= 2 (25.6 s at 10 Hz: drift to a few ppm)
  std::int64_t jump_threshold_ns = 10'000'000;  // residual that makes a sample an outlier, > 0
  int jump_confirm = 4;                         // agreeing outliers that make a jump, >= 1
  bool operator==(const ClockModelOptions&) const = default;
  Status Check() const;  // every field; the message names the field
};

struct ClockUpdate {
  double residual_ns = 0.0;  // host_ns minus the prediction before this sample
  bool outlier = false;      // not used for the fit (late, or the start of a jump)
  bool jump = false;         // this sample confirmed a jump; the model restarted
};

class ClockModel {
 public:
  explicit ClockModel(ClockModelOptions options = {}) : options_(options) {}

  ClockUpdate Add(std::int64_t device_ns, std::int64_t host_ns);

  bool valid() const { return !samples_.empty(); }
  // Predicted host arrival time of a frame exposed at `device_ns` (valid() only).
  std::int64_t HostFromDevice(std::int64_t device_ns) const;
  double drift_ppm() const { return drift_ * 1e6; }
  double jitter_ns() const { return jitter_ns_; }
  // offset at the latest sample: host - device, ns.
  std::int64_t offset_ns() const;
  std::uint64_t jumps() const { return jumps_; }
  // Samples judged outliers so far (those pending a jump decision included).
  std::uint64_t outliers() const { return outliers_ + pending_.size(); }
  std::uint64_t samples() const { return total_samples_; }
  // "offset 1700123 ns, drift 12.3 ppm, jitter 85 us, 2 outliers, 0 jumps"
  std::string OneLine() const;

 private:
  struct Sample {
    double x;  // device_ns - reference_ns
    double y;  // (host_ns - device_ns) - offset_reference_ns
  };
  double Predict(double x) const { return intercept_ + drift_ * x; }
  void Restart(std::int64_t device_ns, std::int64_t host_ns);
  void Refit();

  ClockModelOptions options_;
  std::int64_t reference_ns_ = 0;         // device time of the first sample since (re)start
  std::int64_t offset_reference_ns_ = 0;  // host - device of that sample
  std::int64_t last_device_ns_ = 0;
  std::deque<Sample> samples_;
  std::vector<std::pair<std::int64_t, std::int64_t>> pending_;  // outliers that may be a jump
  double intercept_ = 0.0;
  double drift_ = 0.0;
  double jitter_ns_ = 0.0;
  std::uint64_t jumps_ = 0;
  std::uint64_t outliers_ = 0;
  std::uint64_t total_samples_ = 0;
};

}  // namespace lifmcr
