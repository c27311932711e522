// bench_tf_shift: the TF image's lateral shift against the renderer's
// all-in-focus truth on a textured plane at chosen virtual depths
// (replay/synth, the `medium` camera cropped to 1200 x 900, --full: the
// whole frame; no sensor noise). --tilt turns the plane about the image's x
// axis by that many degrees, so that its depth changes along y as on a
// table seen from above. The TF image is rendered at the true virtual depth
// of each TF pixel (what remains is the renderer's conventions against the
// processing's: pixel centres, hex lattice, lens centres, MLA axes) or, with
// --estimated, at the processing's own depth (what the calibration detects
// its keypoints on). The shift s (TF px, the TF image's content minus the
// truth's) is the least-squares solution of TF(x) = g truth(x - s) + o,
// linearised at 0, over the image less a 24 TF px border, printed overall
// and for the top, middle and bottom thirds of the image. Baseline: the
// same depths at --tilt 0 (run both).
// --depth-scale F renders at F times the true depth: a depth error moves a
// TF pixel's content along the main-lens ray, x' - c = (x - c) (lambda +
// F v (1 - lambda)) / (lambda + v (1 - lambda)), radially about c.
//   bench_tf_shift [--no-defocus] [--no-vignetting] [--estimated] [--tilt DEG] [--full]
//                  [--depth-scale F] V [V...]

#include "bench/bench_usage.h"
#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/total_focus.h"
#include "processing/virtual_depth.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

using namespace lifmcr;

namespace {

constexpr char kUsage[] =
    "usage: bench_tf_shift [--no-defocus] [--no-vignetting] [--estimated] [--tilt DEG] [--full]\n"
    "                      [--depth-scale F] V [V...]\n"
    "The TF image's shift (x, y in TF px) against the all-in-focus truth on a textured plane\n"
    "before the `medium` camera (cropped; --full: whole) at each virtual depth V (--tilt: turned\n"
    "about x), rendered at the true depth (--estimated: at the processing's depth); overall and\n"
    "by thirds of the image height.\n";

cv::Mat Grey(const std::uint8_t* bgr, int w, int h) {
  cv::Mat in(h, w, CV_8UC3, const_cast<std::uint8_t*>(bgr)), grey, out;
  cv::cvtColor(in, grey, cv::COLOR_BGR2GRAY);
  grey.convertTo(out, CV_32F);
  return out;
}

// Least-squares shift of `image` against `truth` over rows [y0, y1) less a
// border, linearised at zero (the shifts are a few hundredths of a pixel):
// image - truth = (g - 1) truth + o - grad(truth) . s.
Eigen::Vector2d Shift(const cv::Mat& image, const cv::Mat& truth, int y0, int y1, int border) {
  Eigen::Matrix4d a = Eigen::Matrix4d::Zero();
  Eigen::Vector4d b = Eigen::Vector4d::Zero();
  for (int y = std::max(y0, border); y < std::min(y1, truth.rows - border); ++y)
    for (int x = border; x < truth.cols - border; ++x) {
      const double m = truth.at<float>(y, x), r = image.at<float>(y, x) - m;
      const double gx = 0.5 * (truth.at<float>(y, x + 1) - truth.at<float>(y, x - 1));
      const double gy = 0.5 * (truth.at<float>(y + 1, x) - truth.at<float>(y - 1, x));
      const Eigen::Vector4d j(-gx, -gy, m / 100, 1.0);
      a += j * j.transpose();
      b += j * r;
    }
  return a.fullPivLu().solve(b).head<2>();
}

}  // namespace

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  synth::RenderOptions render;
  render.sensor_noise = false;
  bool estimated = false;
  double tilt_rad = 0;
  bool full = false;
  double depth_scale = 1;
  int first = 1;
  for (; argc > first; ++first) {
    const std::string arg = argv[first];
    if (arg == "--no-defocus")
      render.defocus = false;
    else if (arg == "--no-vignetting")
      render.vignetting = false;
    else if (arg == "--estimated")
      estimated = true;
    else if (arg == "--full")
      full = true;
    else if (arg == "--depth-scale" && argc > first + 1)
      depth_scale = std::atof(argv[++first]);
    else if (arg == "--tilt" && argc > first + 1)
      tilt_rad = std::atof(argv[++first]) * M_PI / 180;
    else
      break;
  }
  if (argc <= first) return std::fprintf(stderr, "%s", kUsage), 2;
  synth::SynthCameraParams camera = synth::MakePreset("medium")->camera;
  if (!full) {
    camera.width_px = 1200;
    camera.height_px = 900;
  }
  const synth::PlenopticModel model(camera);
  const MlaCalibration mla = model.ToMlaCalibration();
  const synth::RawFrame white =
      synth::RenderRaw(model, synth::MakeWhiteScene(), Pose::Identity(), render);
  const double lambda =
      camera.mla_to_main_lens_mm / (camera.mla_to_main_lens_mm + camera.mla_to_sensor_mm);
  const processing::MlaGrid grid =
      processing::MlaGrid::FromCalibration(mla, camera.width_px, camera.height_px);
  for (int a = first; a < argc; ++a) {
    const double v = std::atof(argv[a]);
    const double z = model.DepthOfVirtualDepth(v);
    // The texture's feature size follows the distance (8 mm at v 3).
    const synth::Scene scene = synth::MakePlaneScene(8.0 * z / model.DepthOfVirtualDepth(3.0), 21);
    const Pose world_from_cam =
        synth::LookAt({0, -z * std::sin(tilt_rad), z * std::cos(tilt_rad)}, {0, 0, 0});
    const synth::RawFrame raw = synth::RenderRaw(model, scene, world_from_cam, render);
    const synth::TfGroundTruth truth = synth::RenderTfGroundTruth(model, scene, world_from_cam);
    processing::FrameOptions options;
    options.lambda = lambda;
    options.principal_point_px = model.principal_point_px();
    processing::PlenopticFrame f;
    if (Status s = processing::PrepareFrame(raw.View(), white.View(), grid, mla, options, &f); !s)
      return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    processing::TfOptions tf_options;
    processing::TfDepthMap depth;
    if (estimated) {
      processing::VirtualDepthMap raw_depth;
      if (Status s = processing::EstimateVirtualDepth(f, mla, {}, &raw_depth); !s)
        return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
      if (Status s = processing::VirtualDepthToTf(f, raw_depth, tf_options, &depth); !s)
        return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    } else {
      depth.width = truth.width;
      depth.height = truth.height;
      depth.virtual_depth.resize(static_cast<std::size_t>(depth.width) * depth.height);
      for (std::size_t i = 0; i < depth.virtual_depth.size(); ++i)
        depth.virtual_depth[i] =
            std::isnan(truth.depth_mm[i])
                ? static_cast<float>(depth_scale * v)
                : static_cast<float>(depth_scale * model.VirtualDepthOfDepth(truth.depth_mm[i]));
      depth.sigma_z.assign(depth.virtual_depth.size(), std::nanf(""));
      depth.fallback_v = v;
    }
    processing::TfImage tf;
    if (Status s = processing::RenderTotalFocus(f, mla, depth, tf_options, &tf); !s)
      return std::fprintf(stderr, "%s\n", s.error().message.c_str()), 1;
    const cv::Mat image = Grey(tf.pixels.data(), tf.width, tf.height);
    const cv::Mat gt = Grey(truth.bgr.data(), truth.width, truth.height);
    const int h = truth.height, border = 24;
    const Eigen::Vector2d all = Shift(image, gt, 0, h, border);
    std::printf("tilt %.0f v %.2f%s%s%s: x %+.4f y %+.4f TF px", tilt_rad * 180 / M_PI, v,
                render.defocus ? "" : " no-defocus", render.vignetting ? "" : " no-vignetting",
                estimated ? " estimated" : "", all.x(), all.y());
    for (int third = 0; third < 3; ++third) {
      const Eigen::Vector2d s = Shift(image, gt, third * h / 3, (third + 1) * h / 3, border);
      std::printf(" | %s x %+.4f y %+.4f",
                  third == 0   ? "top"
                  : third == 1 ? "mid"
                               : "bottom",
                  s.x(), s.y());
    }
    std::printf("\n");
  }
  return 0;
}
