// The set-up the keypoint benches share: `BENCH [--serial S] SEQ FRAME...`,
// the camera (S, else the sequence's lowest serial) and a calibration frame
// loader with its true intrinsics (GroundTruth/cameras.yaml).
#pragma once

#include "processing/camera_model.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/intrinsics_yaml.h"
#include "replay/layout.h"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

namespace lifmcr::bench {

struct TruthFrames {
  std::filesystem::path seq;
  std::string serial;
  int first = 1;  // argv index of SEQ; the frames follow it
  std::optional<processing::CameraModel> model;
  registration::FrameLoaderOptions options;
  std::unique_ptr<registration::CalibrationFrameLoader> loader;
};

// 0, or the exit code after printing why (2: usage, 1: the sequence).
inline int OpenTruthFrames(int argc, char** argv, const char* usage, TruthFrames* out) {
  namespace fs = std::filesystem;
  if (argc > 2 && std::string(argv[1]) == "--serial") {
    out->serial = argv[2];
    out->first = 3;
  }
  if (argc < out->first + 2) return std::fputs(usage, stderr), 2;
  out->seq = argv[out->first];
  if (out->serial.empty())
    for (const auto& e : fs::directory_iterator(out->seq))
      if (auto s = layout::ParseCameraFolderName(e.path().filename().string()))
        if (out->serial.empty() || *s < out->serial) out->serial = *s;
  Expected<registration::CameraCalibration> truth =
      registration::ReadCameraCalibration(layout::CamerasYamlPath(out->seq), out->serial);
  if (!truth) return std::fprintf(stderr, "%s\n", truth.error().message.c_str()), 1;
  out->model.emplace(truth->intrinsics);
  out->options.lambda = out->model->lambda();
  out->options.principal_point_px = truth->intrinsics.PrincipalPointPx();
  out->options.features.max_features = 4000;
  Expected<std::unique_ptr<registration::CalibrationFrameLoader>> loader =
      registration::CalibrationFrameLoader::Open(out->seq, out->serial, {},
                                                 registration::PlateLayout{}, out->options);
  if (!loader) return std::fprintf(stderr, "%s\n", loader.error().message.c_str()), 1;
  out->loader = std::move(*loader);
  return 0;
}

}  // namespace lifmcr::bench
