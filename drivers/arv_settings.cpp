#include "drivers/arv_settings.h"

namespace lifmcr {

std::string TakeMessage(GError* error) {
  if (error == nullptr) return "unknown error";
  std::string message = error->message != nullptr ? error->message : "unknown error";
  g_error_free(error);
  return message;
}

std::string GenicamPixelFormat(CameraPixelFormat format) {
  switch (format) {
    case CameraPixelFormat::kMono8:
      return "Mono8";
    case CameraPixelFormat::kBgr8:
      return "BGR8";
    case CameraPixelFormat::kBayerRg8:
      return "BayerRG8";
    case CameraPixelFormat::kBayerGr8:
      return "BayerGR8";
    case CameraPixelFormat::kBayerGb8:
      return "BayerGB8";
    case CameraPixelFormat::kBayerBg8:
      return "BayerBG8";
  }
  return "Mono8";
}

Expected<ArvRegion> ApplyArvCameraSettings(ArvCamera* camera, const CameraConfig& config,
                                           double free_run_rate_hz, const std::string& label) {
  auto Fail = [&label](const std::string& what) { return Error{label + ": " + what}; };
  auto FailFeature = [&Fail](const std::string& feature, const std::string& value, GError* error) {
    return Fail("setting " + feature + " to " + value + ": " + TakeMessage(error));
  };
  GError* error = nullptr;
  const std::string format = GenicamPixelFormat(config.pixel_format);
  arv_camera_set_pixel_format_from_string(camera, format.c_str(), &error);
  if (error != nullptr) return FailFeature("PixelFormat", format, error);

  int x = 0, y = 0, width = 0, height = 0;
  arv_camera_get_sensor_size(camera, &width, &height, &error);
  if (error != nullptr) return Fail("reading the sensor size: " + TakeMessage(error));
  if (config.roi) {
    x = config.roi->x_px;
    y = config.roi->y_px;
    width = config.roi->width_px;
    height = config.roi->height_px;
  }
  gint sensor_w = 0, sensor_h = 0;
  arv_camera_get_sensor_size(camera, &sensor_w, &sensor_h, &error);
  if (error != nullptr) return Fail("reading the sensor size: " + TakeMessage(error));
  if (x + width > sensor_w || y + height > sensor_h)
    return Fail("roi " + std::to_string(width) + "x" + std::to_string(height) + "+" +
                std::to_string(x) + "+" + std::to_string(y) + " outside the " +
                std::to_string(sensor_w) + "x" + std::to_string(sensor_h) + " sensor");
  arv_camera_set_region(camera, x, y, width, height, &error);
  if (error != nullptr)
    return FailFeature("region",
                       std::to_string(width) + "x" + std::to_string(height) + "+" +
                           std::to_string(x) + "+" + std::to_string(y),
                       error);
  gint got_x = 0, got_y = 0, got_w = 0, got_h = 0;
  arv_camera_get_region(camera, &got_x, &got_y, &got_w, &got_h, &error);
  if (error != nullptr) return Fail("reading the region back: " + TakeMessage(error));
  if (got_x != x || got_y != y || got_w != width || got_h != height)
    return Fail("the camera set the region to " + std::to_string(got_w) + "x" +
                std::to_string(got_h) + "+" + std::to_string(got_x) + "+" + std::to_string(got_y) +
                " instead of " + std::to_string(width) + "x" + std::to_string(height) + "+" +
                std::to_string(x) + "+" + std::to_string(y) + " (increments?)");

  arv_camera_set_exposure_time(camera, config.exposure_us, &error);
  if (error != nullptr)
    return FailFeature("ExposureTime", std::to_string(config.exposure_us) + " us", error);

  const gboolean has_gain = arv_camera_is_gain_available(camera, &error);
  if (error != nullptr) return Fail("checking for Gain: " + TakeMessage(error));
  if (has_gain) {
    arv_camera_set_gain(camera, config.gain_db, &error);
    if (error != nullptr) return FailFeature("Gain", std::to_string(config.gain_db), error);
  } else if (config.gain_db != 0.0) {
    return Fail("gain_db " + std::to_string(config.gain_db) + " asked, but the camera has no Gain");
  }

  arv_camera_clear_triggers(camera, &error);
  if (error != nullptr) return Fail("turning the triggers off: " + TakeMessage(error));
  if (config.trigger.mode == TriggerMode::kFreeRun) {
    if (free_run_rate_hz > 0.0) {
      arv_camera_set_frame_rate(camera, free_run_rate_hz, &error);
      if (error != nullptr)
        return FailFeature("AcquisitionFrameRate", std::to_string(free_run_rate_hz), error);
    }
  } else {
    const std::string source =
        config.trigger.mode == TriggerMode::kSoftware ? "Software" : config.trigger.source;
    arv_camera_set_string(camera, "TriggerSelector", "FrameStart", &error);
    if (error != nullptr) return FailFeature("TriggerSelector", "FrameStart", error);
    arv_camera_set_string(camera, "TriggerMode", "On", &error);
    if (error != nullptr) return FailFeature("TriggerMode", "On", error);
    arv_camera_set_string(camera, "TriggerSource", source.c_str(), &error);
    if (error != nullptr) return FailFeature("TriggerSource", source, error);
    if (config.trigger.mode == TriggerMode::kHardware) {
      const char* activation = config.trigger.activation == TriggerActivation::kRisingEdge
                                   ? "RisingEdge"
                                   : "FallingEdge";
      arv_camera_set_string(camera, "TriggerActivation", activation, &error);
      if (error != nullptr) return FailFeature("TriggerActivation", activation, error);
    }
  }
  arv_camera_set_acquisition_mode(camera, ARV_ACQUISITION_MODE_CONTINUOUS, &error);
  if (error != nullptr) return FailFeature("AcquisitionMode", "Continuous", error);
  return ArvRegion{x, y, width, height};
}

Expected<std::string> ReadArvFeature(ArvDevice* device, const std::string& feature,
                                     const std::string& label) {
  const std::string what = label + ": reading " + feature + ": ";
  if (device == nullptr) return Error{what + "the device is not open"};
  ArvGcNode* node = arv_device_get_feature(device, feature.c_str());
  if (node == nullptr || !ARV_IS_GC_FEATURE_NODE(node)) return Error{what + "no such feature"};
  GError* error = nullptr;
  const char* value = arv_gc_feature_node_get_value_as_string(ARV_GC_FEATURE_NODE(node), &error);
  if (error != nullptr) return Error{what + TakeMessage(error)};
  return std::string(value != nullptr ? value : "");
}

std::optional<std::int64_t> LatchArvDeviceTimeNs(ArvDevice* device, std::uint64_t tick_hz) {
  if (device == nullptr) return std::nullopt;
  struct Latch {
    const char* command;
    const char* value;
  };
  for (const Latch latch : {Latch{"TimestampLatch", "TimestampLatchValue"},
                            Latch{"GevTimestampControlLatch", "GevTimestampValue"}}) {
    ArvGcNode* command = arv_device_get_feature(device, latch.command);
    ArvGcNode* value = arv_device_get_feature(device, latch.value);
    if (command == nullptr || value == nullptr || !ARV_IS_GC_COMMAND(command)) continue;
    GError* error = nullptr;
    arv_device_execute_command(device, latch.command, &error);
    if (error != nullptr) {
      g_error_free(error);
      continue;
    }
    const gint64 ticks = arv_device_get_integer_feature_value(device, latch.value, &error);
    if (error != nullptr) {
      g_error_free(error);
      continue;
    }
    if (tick_hz == 0 || tick_hz == 1'000'000'000) return static_cast<std::int64_t>(ticks);
    return static_cast<std::int64_t>(static_cast<long double>(ticks) * 1e9L /
                                     static_cast<long double>(tick_hz));
  }
  return std::nullopt;
}

}  // namespace lifmcr
