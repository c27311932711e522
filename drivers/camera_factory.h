#pragma once
// Makes the Camera a rig file's camera entry asks for (not yet opened).
//
//   driver.kind aravis  -> AravisCamera (address, or the serial)
//   driver.kind replay  -> ReplayCamera on SEQ/TypeE_<serial>/ of
//                          `replay_sequence_dir`
//   driver.kind gentl   -> GenTlCamera (the producer `cti`, or the
//                          GENICAM_GENTL64_PATH search; `device`, or the serial)

#include "config/rig_config.h"
#include "drivers/camera.h"
#include "drivers/replay_camera.h"

#include <chrono>
#include <filesystem>
#include <memory>

namespace lifmcr {

struct CameraFactoryOptions {
  int pool_buffers = 16;  // per camera, >= 2
  // Time between two camera triggers (TriggerPeriod of the rig's Vicon).
  std::chrono::nanoseconds trigger_period{100'000'000};
  // replay cameras: the sequence folder whose TypeE_<serial>/ stands in.
  std::filesystem::path replay_sequence_dir;
  ReplayPacing replay_pacing = ReplayPacing::kOriginal;
  // aravis cameras in free_run: AcquisitionFrameRate; 0 = the camera's own.
  double free_run_rate_hz = 0.0;
  Status Check() const;  // every field; the message names the field
};

// trigger_divider / rate_hz: 8 / 80 Hz = 100 ms for LiFMCR.
std::chrono::nanoseconds TriggerPeriod(const ViconConfig& vicon);

// The camera for `config` at `camera_index` in the rig; errors name the
// camera and what is missing (a replay camera without a sequence folder, a
// driver kind this build lacks).
Expected<std::unique_ptr<Camera>> MakeCamera(const CameraConfig& config, int camera_index,
                                             const CameraFactoryOptions& options);

}  // namespace lifmcr
