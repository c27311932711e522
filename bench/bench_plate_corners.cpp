// bench_plate_corners: the calibration's plate corners against the
// renderer's truth, per frame: placed on the plate's TF image rendered at
// the plate plane's virtual depth (what the calibration's frame loader does,
// registration/features/plate_plane.h) and, the baseline in the same run,
// on the TF image itself (rendered at the measured depth). Each frame goes
// through the frame loader with the initial intrinsics (`--initial`, as
// `lifmcr calibrate --initial`; default the true ones); the truth is
// compared in that processed geometry (MeasurePlateCornerBias,
// registration/calibration/calibration_gates.h).
//   bench_plate_corners [--serial S] [--initial CAMERAS.yaml] SEQUENCE_DIR FRAME [FRAME...]

#include "bench/bench_usage.h"
#include "processing/camera_model.h"
#include "registration/calibration/calibration_gates.h"
#include "registration/features/aruco_plate.h"
#include "registration/features/calibration_frames.h"
#include "registration/features/intrinsics_yaml.h"
#include "replay/layout.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

using namespace lifmcr;
namespace fs = std::filesystem;

namespace {

constexpr char kUsage[] =
    "usage: bench_plate_corners [--serial S] [--initial CAMERAS.yaml] SEQUENCE_DIR FRAME [FRAME...]\n"
    "  the plate corners against the truth per frame: on the plate rendered at its plane's\n"
    "  virtual depth (the calibration's loader) and on the TF image (baseline, same run)\n";

}  // namespace

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string serial;
  fs::path initial;
  int first = 1;
  while (first + 1 < argc && argv[first][0] == '-' && argv[first][1] == '-') {
    const std::string flag = argv[first];
    if (flag == "--serial")
      serial = argv[first + 1];
    else if (flag == "--initial")
      initial = argv[first + 1];
    else
      return std::fputs(kUsage, stderr), 2;
    first += 2;
  }
  if (argc < first + 2) return std::fputs(kUsage, stderr), 2;
  const fs::path seq = argv[first];
  if (serial.empty())
    for (const auto& e : fs::directory_iterator(seq))
      if (auto s = layout::ParseCameraFolderName(e.path().filename().string()))
        if (serial.empty() || *s < serial) serial = *s;
  Expected<registration::CameraCalibration> start = registration::ReadCameraCalibration(
      initial.empty() ? layout::CamerasYamlPath(seq) : initial, serial);
  if (!start) return std::fprintf(stderr, "%s\n", start.error().message.c_str()), 1;
  Expected<registration::PlateLayout> plate =
      registration::ReadPlateLayout(layout::CamerasYamlPath(seq));
  if (!plate) return std::fprintf(stderr, "%s\n", plate.error().message.c_str()), 1;
  registration::FrameLoaderOptions options;
  options.lambda = processing::CameraModel(start->intrinsics).lambda();
  options.principal_point_px = start->intrinsics.PrincipalPointPx();
  options.features.max_features = 500;  // the keypoints are not looked at
  Expected<std::unique_ptr<registration::CalibrationFrameLoader>> loader =
      registration::CalibrationFrameLoader::Open(seq, serial, {}, *plate, options);
  if (!loader) return std::fprintf(stderr, "%s\n", loader.error().message.c_str()), 1;
  std::vector<registration::CalibrationFrame> on_plane, on_tf;
  for (int a = first + 1; a < argc; ++a) {
    Expected<registration::CalibrationFrame> frame = (*loader)->Load(std::atoll(argv[a]));
    if (!frame) return std::fprintf(stderr, "%s\n", frame.error().message.c_str()), 1;
    on_plane.push_back(*frame);
    Expected<std::vector<registration::PlateCorner>> corners =
        registration::DetectPlateCorners((*loader)->last_tf_image(), *plate);
    if (!corners) return std::fprintf(stderr, "%s\n", corners.error().message.c_str()), 1;
    frame->corners = *corners;
    frame->corner_virtual_depth.assign(corners->size(), std::nanf(""));
    on_tf.push_back(*frame);
  }
  Expected<registration::PlateCornerBias> plane_bias =
      registration::MeasurePlateCornerBias(on_plane, options.lambda, seq, serial);
  Expected<registration::PlateCornerBias> tf_bias =
      registration::MeasurePlateCornerBias(on_tf, options.lambda, seq, serial);
  if (!plane_bias || !tf_bias) return std::fputs("no ground truth\n", stderr), 1;
  std::printf("frame | corners (plane / TF) | RMS on the plane's render | RMS on the TF image\n");
  for (std::size_t k = 0; k < plane_bias->frames.size() && k < tf_bias->frames.size(); ++k)
    std::printf("%lld | %d / %d | %.3f TF px | %.3f TF px\n",
                static_cast<long long>(plane_bias->frames[k].frame), plane_bias->frames[k].corners,
                tf_bias->frames[k].corners, plane_bias->frames[k].rms_tf_px,
                tf_bias->frames[k].rms_tf_px);
  std::printf("plane's render: %s\n%sTF image (baseline): %s\n%sRMS ratio %.3f\n",
              plane_bias->BriefReport().c_str(), plane_bias->PerFrameReport().c_str(),
              tf_bias->BriefReport().c_str(), tf_bias->PerFrameReport().c_str(),
              plane_bias->rms_tf_px / tf_bias->rms_tf_px);
  return 0;
}
