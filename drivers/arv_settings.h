#pragma once
// The rig file's camera settings applied to a GenICam device through
// Aravis's ArvCamera helpers, shared by the Aravis driver (GigE/USB3 Vision)
// and the GenTL driver (an ArvCamera over the producer's port,
// drivers/gentl_arv_device.h), so both set features the same way.
//
// Order, each failure naming the camera (`label`) and the feature:
// PixelFormat, region (the `roi`, or the full sensor, checked against
// SensorWidth/SensorHeight and read back), ExposureTime, Gain (skipped when
// the camera has none and gain_db is 0), the trigger (all selectors off, then
// FrameStart: hardware = TriggerMode On, TriggerSource <source>,
// TriggerActivation; software = TriggerSource Software; free_run =
// TriggerMode Off and AcquisitionFrameRate when `free_run_rate_hz` > 0),
// AcquisitionMode Continuous.
//
// Includes <arv.h>: for drivers/*.cpp only.

#include "config/error.h"
#include "config/rig_config.h"

#include <arv.h>

#include <cstdint>
#include <optional>
#include <string>

namespace lifmcr {

struct ArvRegion {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

Expected<ArvRegion> ApplyArvCameraSettings(ArvCamera* camera, const CameraConfig& config,
                                           double free_run_rate_hz, const std::string& label);

// A feature's current value as text, read through the device's node map;
// an error (labelled) when the device is not open (null), has no such
// feature or cannot read it.
Expected<std::string> ReadArvFeature(ArvDevice* device, const std::string& feature,
                                     const std::string& label);

// The device clock latched now, in ns (ticks at `tick_hz`; 0: already ns):
// SFNC TimestampLatch/TimestampLatchValue, else GigE Vision
// GevTimestampControlLatch/GevTimestampValue; nullopt when the device has
// neither (the Aravis GigE simulator) or the latch fails. Read right after
// AcquisitionStart it stamps the camera's arm on the clock of its frames
// (Camera::ArmedDeviceNs, sync/armed_start.h).
std::optional<std::int64_t> LatchArvDeviceTimeNs(ArvDevice* device, std::uint64_t tick_hz);

// Takes ownership of a GError and turns it into text.
std::string TakeMessage(GError* error);

// The GenICam PixelFormat name of a rig file pixel format ("BayerRG8").
std::string GenicamPixelFormat(CameraPixelFormat format);

}  // namespace lifmcr
