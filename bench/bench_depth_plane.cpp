// bench_depth_plane: the systematic error of processing/'s virtual depth on a
// fronto-parallel textured plane at chosen virtual depths, rendered with and
// without defocus (replay/synth, the `medium` camera cropped to 1200 x 900,
// no sensor noise), per lens type and radius in the micro image. A plane has
// no depth edge, so what remains is the matching's own bias; rendering
// without defocus tells whether the lens types' different blur causes it.
//   bench_depth_plane [--no-defocus] [--equalise-defocus 0|1] [--step-px S] [--rings R] V [V...]

#include "bench/bench_usage.h"
#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/virtual_depth.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace lifmcr;

namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_depth_plane [--no-defocus] [--equalise-defocus 0|1] [--step-px S] [--rings R] V [V...]\n"
    "The signed median relative error of processing/'s virtual depth on a textured plane\n"
    "facing the `medium` camera (cropped) at each virtual depth V, per lens type and radius\n"
    "in the micro image (< 0.4 r / 0.4-0.7 r / > 0.7 r); --no-defocus renders every micro\n"
    "image sharp.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  synth::RenderOptions render;
  render.sensor_noise = false;
  processing::DepthOptions depth_options;
  int first = 1;
  for (;;) {
    if (argc > first && std::string(argv[first]) == "--no-defocus") {
      render.defocus = false;
      ++first;
    } else if (argc > first + 1 && std::string(argv[first]) == "--step-px") {
      depth_options.step_px = std::atof(argv[first + 1]);
      first += 2;
    } else if (argc > first + 1 && std::string(argv[first]) == "--rings") {
      depth_options.rings = std::atoi(argv[first + 1]);
      first += 2;
    } else if (argc > first + 1 && std::string(argv[first]) == "--equalise-defocus") {
      depth_options.equalise_defocus = std::atoi(argv[first + 1]) != 0;
      first += 2;
    } else {
      break;
    }
  }
  if (argc <= first || !depth_options.Check()) return std::fprintf(stderr, "%s", kUsage), 2;
  synth::SynthCameraParams camera = synth::MakePreset("medium")->camera;
  camera.width_px = 1200;
  camera.height_px = 900;
  const synth::PlenopticModel model(camera);
  const MlaCalibration mla = model.ToMlaCalibration();
  const synth::Scene scene = synth::MakePlaneScene(8.0, 21);
  const synth::RawFrame white =
      synth::RenderRaw(model, synth::MakeWhiteScene(), Pose::Identity(), render);
  const double lambda =
      camera.mla_to_main_lens_mm / (camera.mla_to_main_lens_mm + camera.mla_to_sensor_mm);
  for (int a = first; a < argc; ++a) {
    const double v = std::atof(argv[a]);
    const double z = model.DepthOfVirtualDepth(v);
    const synth::RawFrame raw =
        synth::RenderRaw(model, scene, synth::LookAt({0, 0, z}, {0, 0, 0}), render);
    const processing::MlaGrid grid = processing::MlaGrid::FromCalibration(mla, raw.width, raw.height);
    processing::FrameOptions options;
    options.lambda = lambda;
    options.principal_point_px = Eigen::Vector2d((raw.width - 1) / 2.0, (raw.height - 1) / 2.0);
    processing::PlenopticFrame f;
    processing::VirtualDepthMap depth;
    if (Status s = processing::PrepareFrame(raw.View(), white.View(), grid, mla, options, &f); !s)
      return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    if (Status s = processing::EstimateVirtualDepth(f, mla, depth_options, &depth); !s)
      return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    std::vector<double> errors[3][3];
    for (int y = 0; y < raw.height; ++y)
      for (int x = 0; x < raw.width; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * raw.width + x;
        const int k = f.lens_of_pixel[i];
        const double vm = depth.virtual_depth[i], vt = raw.virtual_depth[i];
        if (k < 0 || !depth.textured[i] || std::isnan(vm) || std::isnan(vt)) continue;
        const double r = (Eigen::Vector2d(x, y) - f.lenses[k].centre_px).norm() / f.radius_px;
        errors[f.lenses[k].type][r < 0.4 ? 0 : r < 0.7 ? 1 : 2].push_back(vm / vt - 1);
      }
    std::printf("v %.2f%s", v, render.defocus ? "" : " (no defocus)");
    for (int t = 0; t < 3; ++t) {
      std::printf(" | type %d blur %.1f px:", t, model.BlurDiameterPx(t, v));
      for (int r = 0; r < 3; ++r)
        std::printf(" %+.3f (%zu)", 100 * Median(errors[t][r]), errors[t][r].size());
    }
    std::printf("\n");
  }
  return 0;
}
