// bench_render: megapixels per second of the synthetic plenoptic renderer
// (replay/synth) for a preset (default r32) and scene (default table) on all
// cores, with the frame time; the baseline in the same run is the same frame
// of the `plain` scene.
//   bench_render [--preset r32|medium|small] [--scene table|plain] [--repeat N]
//                [--png PATH] [--raw-png PATH] [--tf-png PATH] [--cull 0|1]
// --png writes the docs figure: a crop of the raw image beside the same region
// of the all-in-focus ground truth (scaled to the raw crop's size);
// --tf-png the whole all-in-focus ground truth.

#include "bench/bench_usage.h"
#include "replay/synth/plenoptic_model.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "replay/synth/trajectory.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

using lifmcr::synth::PlenopticModel;

constexpr char kUsage[] =
    "usage: bench_render [--preset r32|medium|small] [--scene table|plain] [--repeat N]\n"
    "                    [--png PATH] [--raw-png PATH] [--tf-png PATH] [--cull 0|1]\n"
    "Megapixels per second of the synthetic plenoptic renderer on all cores (default preset\n"
    "r32, scene table), beside the same frame of the plain scene. --png writes a crop of the\n"
    "raw image beside the all-in-focus ground truth, --tf-png the whole ground truth.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  std::string preset = "r32", scene_name = "table", png, raw_png, tf_png;
  int repeat = 3;
  bool cull = true;
  for (int k = 1; k + 1 < argc; k += 2) {
    if (!std::strcmp(argv[k], "--preset"))
      preset = argv[k + 1];
    else if (!std::strcmp(argv[k], "--repeat"))
      repeat = std::max(1, std::atoi(argv[k + 1]));
    else if (!std::strcmp(argv[k], "--png"))
      png = argv[k + 1];
    else if (!std::strcmp(argv[k], "--raw-png"))
      raw_png = argv[k + 1];
    else if (!std::strcmp(argv[k], "--tf-png"))
      tf_png = argv[k + 1];
    else if (!std::strcmp(argv[k], "--scene"))
      scene_name = argv[k + 1];
    else if (!std::strcmp(argv[k], "--cull"))
      cull = std::atoi(argv[k + 1]) != 0;
    else {
      std::fprintf(stderr, "unknown option %s\n", argv[k]);
      return 2;
    }
  }
  auto params = lifmcr::synth::MakePreset(preset);
  if (!params) {
    std::fprintf(stderr, "%s\n", params.error().message.c_str());
    return 2;
  }
  const PlenopticModel model(params->camera);
  auto made = lifmcr::synth::MakeScene(scene_name, 1);
  if (!made) {
    std::fprintf(stderr, "%s\n", made.error().message.c_str());
    return 2;
  }
  const lifmcr::synth::Scene& scene = *made;
  const lifmcr::synth::Scene baseline_scene = lifmcr::synth::MakePlainScene(1);
  const auto pose_for = [&](const lifmcr::synth::Scene& s) {
    lifmcr::synth::TrajectoryParams tp;
    tp.target_mm = s.Target();
    tp.distance_mm = params->rig.viewing_distance_mm;
    return lifmcr::synth::CameraTrajectory(tp).WorldFromCam(0.0);
  };
  const lifmcr::Pose world_from_cam = pose_for(scene);
  const double megapixels = model.width() * static_cast<double>(model.height()) / 1e6;
  std::printf("bench_render: preset %s, scene %s, %dx%d (%.2f MP), D %.1f px, %d threads\n",
              preset.c_str(), scene_name.c_str(), model.width(), model.height(), megapixels,
              params->camera.micro_image_pitch_px, tbb::info::default_concurrency());

  lifmcr::synth::RenderOptions options;
  options.noise_seed = 7;
  options.cull_objects = cull;
  lifmcr::synth::RawFrame raw;
  std::vector<double> seconds;
  for (int r = 0; r < repeat; ++r) {
    const auto start = std::chrono::steady_clock::now();
    raw = lifmcr::synth::RenderRaw(model, scene, world_from_cam, options);
    seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(seconds.begin(), seconds.end());
  const double median = seconds[seconds.size() / 2];
  const auto tf_start = std::chrono::steady_clock::now();
  const lifmcr::synth::TfGroundTruth gt =
      lifmcr::synth::RenderTfGroundTruth(model, scene, world_from_cam);
  const double tf_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - tf_start).count();
  // Baseline in the same run: the same frame without defocus blur and noise.
  lifmcr::synth::RenderOptions plain = options;
  plain.defocus = false;
  plain.sensor_noise = false;
  const auto plain_start = std::chrono::steady_clock::now();
  (void)lifmcr::synth::RenderRaw(model, scene, world_from_cam, plain);
  const double plain_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - plain_start).count();
  // Baseline in the same run: the same frame of the plain scene.
  std::vector<double> baseline_seconds;
  const lifmcr::Pose baseline_pose = pose_for(baseline_scene);
  for (int r = 0; r < repeat; ++r) {
    const auto start = std::chrono::steady_clock::now();
    (void)lifmcr::synth::RenderRaw(model, baseline_scene, baseline_pose, options);
    baseline_seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(baseline_seconds.begin(), baseline_seconds.end());
  const double baseline = baseline_seconds[baseline_seconds.size() / 2];
  const auto baseline_tf_start = std::chrono::steady_clock::now();
  (void)lifmcr::synth::RenderTfGroundTruth(model, baseline_scene, baseline_pose);
  const double baseline_tf_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - baseline_tf_start).count();
  std::printf(
      "raw frame: %.3f s median of %d (%.1f MP/s); without blur+noise %.3f s (blur+noise "
      "cost x%.2f)\n",
      median, repeat, megapixels / median, plain_s, median / plain_s);
  std::printf("all-in-focus + depth ground truth (%dx%d): %.3f s\n", gt.width, gt.height, tf_s);
  std::printf(
      "baseline, scene plain: raw frame %.3f s, ground truth %.3f s; this scene / plain: raw "
      "x%.2f, ground truth x%.2f\n",
      baseline, baseline_tf_s, median / baseline, tf_s / baseline_tf_s);
  // What the scene gives a depth estimator: the spread of ground-truth v.
  std::vector<float> v;
  for (float x : raw.virtual_depth)
    if (std::isfinite(x)) v.push_back(x);
  if (!v.empty()) {
    std::sort(v.begin(), v.end());
    std::printf(
        "ground-truth virtual depth over %.0f %% of pixels: 5 %% %.2f, median %.2f, 95 %% %.2f\n",
        100.0 * v.size() / raw.virtual_depth.size(), v[v.size() / 20], v[v.size() / 2],
        v[v.size() * 19 / 20]);
  }

  if (!tf_png.empty()) {
    const cv::Mat tf_image(gt.height, gt.width, CV_8UC3, const_cast<std::uint8_t*>(gt.bgr.data()));
    cv::imwrite(tf_png, tf_image);
  }
  if (!raw_png.empty()) {
    const cv::Mat image(raw.height, raw.width,
                        raw.format == lifmcr::PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1,
                        raw.pixels.data());
    cv::imwrite(raw_png, image);
  }
  if (!png.empty()) {
    // A crop of the raw image where the all-in-focus image has the most
    // structure (largest grey variance over a grid of candidates), beside the
    // same region of the all-in-focus image scaled by 2 (TF grid = raw / 2).
    const int crop = std::min(480, std::min(raw.width, raw.height) / 2);
    const cv::Mat tf_image(gt.height, gt.width, CV_8UC3, const_cast<std::uint8_t*>(gt.bgr.data()));
    cv::Mat tf_grey;
    cv::cvtColor(tf_image, tf_grey, cv::COLOR_BGR2GRAY);
    int x0 = raw.width / 2 - crop / 2, y0 = raw.height / 2 - crop / 2;
    double best = -1;
    for (int y = 0; y + crop <= raw.height; y += crop / 2)
      for (int x = 0; x + crop <= raw.width; x += crop / 2) {
        cv::Scalar mean, stddev;
        cv::meanStdDev(tf_grey(cv::Rect(x / 2, y / 2, crop / 2, crop / 2)), mean, stddev);
        if (stddev[0] > best) {
          best = stddev[0];
          x0 = x;
          y0 = y;
        }
      }
    const cv::Mat raw_image(raw.height, raw.width,
                            raw.format == lifmcr::PixelFormat::kBgr8 ? CV_8UC3 : CV_8UC1,
                            raw.pixels.data());
    cv::Mat raw_crop = raw_image(cv::Rect(x0, y0, crop, crop)).clone();
    if (raw_crop.channels() == 1) cv::cvtColor(raw_crop, raw_crop, cv::COLOR_GRAY2BGR);
    cv::Mat tf_crop;
    cv::resize(tf_image(cv::Rect(x0 / 2, y0 / 2, crop / 2, crop / 2)), tf_crop,
               cv::Size(crop, crop), 0, 0, cv::INTER_LINEAR);
    cv::Mat figure;
    cv::hconcat(std::vector<cv::Mat>{raw_crop, cv::Mat(crop, 8, CV_8UC3, cv::Scalar(255, 255, 255)),
                                     tf_crop},
                figure);
    cv::imwrite(png, figure, {cv::IMWRITE_PNG_COMPRESSION, 9});
    std::printf("wrote %s\n", png.c_str());
  }
  return 0;
}
