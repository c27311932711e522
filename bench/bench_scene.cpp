// bench_scene: what a synthetic scene offers registration and depth
// (tests/processing/scene_figures.h) on one frame of a preset, beside the
// same figures for the `plain` scene in the same run (the baseline):
//   bench_scene [--preset small|medium|r32] [--scene table|plain] [--noise DN] [--dump DIR]
// Prints SIFT keypoints on the all-in-focus ground truth and on the processed
// TF image, virtual-depth coverage of raw pixels, the photo-consistency
// ratios, and the seconds each step took. --dump writes the all-in-focus
// ground truth, the processed TF image and the raw frame as PNG into DIR.

#include "bench/bench_usage.h"
#include "replay/synth/scene.h"
#include "tests/processing/scene_figures.h"

#include <opencv2/imgcodecs.hpp>
#include <tbb/info.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

constexpr char kUsage[] =
    "usage: bench_scene [--preset small|medium|r32] [--scene table|plain] [--noise DN]\n"
    "                   [--dump DIR]\n"
    "What a synthetic scene offers registration and depth on one frame (SIFT keypoints on\n"
    "the ground truth and the TF image, virtual-depth coverage, photo-consistency), beside\n"
    "the plain scene. --dump writes the ground truth, TF image and raw frame as PNG to DIR.\n";

int main(int argc, char** argv) {
  if (lifmcr::bench::PrintedHelp(argc, argv, kUsage)) return 0;
  using lifmcr::processing::testing::MeasureSceneFigures;
  using lifmcr::processing::testing::RenderSynthFrame;
  std::string preset = "medium", scene = "table", dump;
  double noise = 1.0;
  for (int k = 1; k + 1 < argc; k += 2) {
    if (!std::strcmp(argv[k], "--preset"))
      preset = argv[k + 1];
    else if (!std::strcmp(argv[k], "--scene"))
      scene = argv[k + 1];
    else if (!std::strcmp(argv[k], "--noise"))
      noise = std::atof(argv[k + 1]);
    else if (!std::strcmp(argv[k], "--dump"))
      dump = argv[k + 1];
    else {
      std::fprintf(stderr, "unknown option %s\n", argv[k]);
      return 2;
    }
  }
  if (!lifmcr::synth::MakeScene(scene, 1).ok()) {
    std::fprintf(stderr, "unknown scene '%s', expected %s\n", scene.c_str(),
                 std::string(lifmcr::synth::SceneNames()).c_str());
    return 2;
  }
  std::printf("bench_scene: preset %s, %d threads\n", preset.c_str(),
              tbb::info::default_concurrency());
  double sift[2] = {0, 0};
  const std::string scenes[2] = {scene, "plain"};
  for (int n = 0; n < 2; ++n) {
    auto start = std::chrono::steady_clock::now();
    const auto frame = RenderSynthFrame(preset, noise, scenes[n]);
    const double render_s = Since(start);
    start = std::chrono::steady_clock::now();
    lifmcr::processing::TfImage tf;
    const auto figures = MeasureSceneFigures(frame, &tf);
    std::printf("scene %s: render %.1f s, measure %.1f s\n  %s\n", scenes[n].c_str(), render_s,
                Since(start), figures.BriefReport().c_str());
    sift[n] = figures.sift_processed;
    if (!dump.empty() && n == 0) {
      const std::string stem = dump + "/" + preset + "_" + scenes[n];
      cv::imwrite(stem + "_all_in_focus.png",
                  cv::Mat(frame.tf.height, frame.tf.width, CV_8UC3,
                          const_cast<std::uint8_t*>(frame.tf.bgr.data())));
      cv::imwrite(stem + "_tf.png",
                  cv::Mat(tf.height, tf.width, CV_8UC3, const_cast<std::uint8_t*>(tf.pixels.data())));
      cv::imwrite(stem + "_raw.png", cv::Mat(frame.raw.height, frame.raw.width, CV_8UC3,
                                             const_cast<std::uint8_t*>(frame.raw.pixels.data())));
      std::printf("wrote %s_{all_in_focus,tf,raw}.png\n", stem.c_str());
    }
    if (scenes[0] == "plain") break;
  }
  if (scene != "plain")
    std::printf("SIFT on the processed TF image: %s / plain x%.1f\n", scene.c_str(),
                sift[0] / std::max(sift[1], 1.0));
  return 0;
}
