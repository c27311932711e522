#include "drivers/camera_factory.h"

#include "drivers/aravis_camera.h"
#include "drivers/gentl_camera.h"
#include "replay/layout.h"

#include <cmath>

namespace lifmcr {

std::chrono::nanoseconds TriggerPeriod(const ViconConfig& vicon) {
  const double rate_hz = vicon.rate_hz > 0.0 ? vicon.rate_hz : 80.0;
  const int divider = vicon.trigger_divider >= 1 ? vicon.trigger_divider : 1;
  return std::chrono::nanoseconds(std::llround(1e9 * divider / rate_hz));
}

Status CameraFactoryOptions::Check() const {
  if (pool_buffers < 2) return Error{"camera factory: pool_buffers: expected >= 2"};
  if (trigger_period.count() <= 0) return Error{"camera factory: trigger_period: expected > 0"};
  // replay_sequence_dir: checked for replay cameras (MakeCamera); replay_pacing: any.
  if (!(free_run_rate_hz >= 0.0) || !std::isfinite(free_run_rate_hz))
    return Error{"camera factory: free_run_rate_hz: expected >= 0 (0: the camera's own)"};
  return Status::Ok();
}

Expected<std::unique_ptr<Camera>> MakeCamera(const CameraConfig& config, int camera_index,
                                             const CameraFactoryOptions& options) {
  const std::string label = "camera " + config.name + " (serial " + config.serial + ")";
  if (Status s = options.Check(); !s) return Error{label + ": " + s.error().message};
  switch (config.driver.kind) {
    case DriverKind::kAravis: {
      AravisCameraOptions aravis;
      aravis.camera_index = camera_index;
      aravis.pool_buffers = options.pool_buffers;
      aravis.free_run_rate_hz = options.free_run_rate_hz;
      if (Status status = aravis.Check(); !status)
        return Error{label + ": " + status.error().message};
      return std::unique_ptr<Camera>(std::make_unique<AravisCamera>(config, aravis));
    }
    case DriverKind::kReplay: {
      if (options.replay_sequence_dir.empty())
        return Error{label + ": driver replay needs a sequence folder to replay"};
      ReplayCameraOptions replay;
      replay.camera_index = camera_index;
      replay.pool_buffers = options.pool_buffers;
      replay.trigger_period = options.trigger_period;
      replay.pacing = options.replay_pacing;
      replay.loop = config.driver.loop;
      if (Status status = replay.Check(); !status)
        return Error{label + ": " + status.error().message};
      return std::unique_ptr<Camera>(std::make_unique<ReplayCamera>(
          layout::CameraDir(options.replay_sequence_dir, config.serial), replay));
    }
    case DriverKind::kGenTl: {
      GenTlCameraOptions gentl;
      gentl.camera_index = camera_index;
      gentl.pool_buffers = options.pool_buffers;
      gentl.free_run_rate_hz = options.free_run_rate_hz;
      if (Status status = gentl.Check(); !status)
        return Error{label + ": " + status.error().message};
      return std::unique_ptr<Camera>(std::make_unique<GenTlCamera>(config, gentl));
    }
  }
  return Error{label + ": unknown driver kind"};
}

}  // namespace lifmcr
