#include "tests/processing/scene_figures.h"

#include "processing/camera_model.h"
#include "processing/mla_grid.h"
#include "processing/plenoptic_frame.h"
#include "processing/virtual_depth.h"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace lifmcr::processing::testing {
namespace {

int CountSift(const std::uint8_t* bgr, int width, int height) {
  const cv::Mat image(height, width, CV_8UC3, const_cast<std::uint8_t*>(bgr));
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  std::vector<cv::KeyPoint> keypoints;
  cv::SIFT::create()->detect(grey, keypoints);
  return static_cast<int>(keypoints.size());
}

void Require(const Status& status) {
  if (!status) throw std::runtime_error(status.error().message);
}

// Mean squared grey difference between each pixel with a ground-truth v and
// its image in the neighbours `ring` (axial lattice steps) at v, 1.25 v and
// 0.8 v, over the (pixel, neighbour) pairs where all three fall on valid
// pixels of that neighbour.
SceneFigures::Consistency Consistency(const SynthFrame& s, const PlenopticFrame& grey,
                                      const std::array<std::array<int, 2>, 6>& ring) {
  constexpr std::array<double, 3> kScale{1.0, 1.25, 0.8};
  std::array<double, 3> sum{0, 0, 0};
  SceneFigures::Consistency c;
  for (int y = 0; y < grey.height; ++y)
    for (int x = 0; x < grey.width; ++x) {
      const std::size_t idx = static_cast<std::size_t>(y) * grey.width + x;
      const int k = grey.lens_of_pixel[idx];
      const float v = s.raw.virtual_depth[idx];
      const float g = grey.grey[idx];
      if (k < 0 || std::isnan(v) || std::isnan(g)) continue;
      const MicroImage& lens = grey.lenses[k];
      for (const auto& step : ring) {
        const int n = grey.LensAt(lens.i + step[0], lens.j + step[1]);
        if (n < 0) continue;
        const Eigen::Vector2d delta = grey.lenses[n].centre_px - lens.centre_px;
        std::array<double, 3> diff2{};
        bool ok = true;
        for (int m = 0; m < 3 && ok; ++m) {
          const Eigen::Vector2d q =
              Eigen::Vector2d(x, y) + grey.lambda * delta * (1.0 - 1.0 / (kScale[m] * v));
          const int qx = static_cast<int>(std::lround(q.x())),
                    qy = static_cast<int>(std::lround(q.y()));
          if (qx < 0 || qy < 0 || qx >= grey.width || qy >= grey.height ||
              grey.lens_of_pixel[static_cast<std::size_t>(qy) * grey.width + qx] != n) {
            ok = false;
            break;
          }
          const float h = grey.SampleGrey(q.x(), q.y());
          if (std::isnan(h)) ok = false;
          diff2[m] = (g - h) * (g - h);
        }
        if (!ok) continue;
        for (int m = 0; m < 3; ++m) sum[m] += diff2[m];
        ++c.pairs;
      }
    }
  if (c.pairs > 0) {
    c.cost_true = sum[0] / c.pairs;
    c.cost_far = sum[1] / c.pairs;
    c.cost_near = sum[2] / c.pairs;
  }
  return c;
}

}  // namespace

std::string SceneFigures::BriefReport() const {
  char line[600];
  std::snprintf(line, sizeof line,
                "SIFT %d on the all-in-focus ground truth, %d on the processed TF image; virtual "
                "depth on %.1f %% of raw pixels (textured %.1f %%, of which %.1f %%); "
                "photo-consistency at v / 1.25 v / 0.8 v: ring 1 (other lens type, %lld pairs) "
                "%.1f DN^2, x%.2f, x%.2f; ring 2 (same type, %lld pairs) %.1f DN^2, x%.2f, x%.2f",
                sift_ground_truth, sift_processed, 100 * depth_coverage, 100 * textured_share,
                100 * textured_coverage, ring1.pairs, ring1.cost_true, ring1.FarRatio(),
                ring1.NearRatio(), ring2.pairs, ring2.cost_true, ring2.FarRatio(),
                ring2.NearRatio());
  return line;
}

SceneFigures MeasureSceneFigures(const SynthFrame& s, TfImage* tf_out) {
  SceneFigures figures;
  const CameraModel camera(s.intrinsics);
  const MlaGrid grid = MlaGrid::FromCalibration(s.mla, s.raw.width, s.raw.height);
  FrameOptions options;
  options.lambda = camera.lambda();

  // Depth and TF image as `lifmcr depth` makes them.
  PlenopticFrame frame;
  Require(PrepareFrame(s.raw.View(), s.white.View(), grid, s.mla, options, &frame));
  VirtualDepthMap depth;
  Require(EstimateVirtualDepth(frame, s.mla, DepthOptions{}, &depth));
  long long covered = 0, textured = 0, textured_covered = 0;
  for (std::size_t i = 0; i < depth.virtual_depth.size(); ++i) {
    const bool has = !std::isnan(depth.virtual_depth[i]);
    covered += has;
    textured += depth.textured[i] != 0;
    textured_covered += has && depth.textured[i];
  }
  const double pixels = static_cast<double>(depth.virtual_depth.size());
  figures.depth_coverage = covered / pixels;
  figures.textured_share = textured / pixels;
  figures.textured_coverage = textured > 0 ? static_cast<double>(textured_covered) / textured : 0;
  const TfOptions tf_options;
  TfDepthMap tf_depth;
  Require(VirtualDepthToTf(frame, depth, tf_options, &tf_depth));
  TfImage tf;
  Require(RenderTotalFocus(frame, s.mla, tf_depth, tf_options, &tf));
  if (tf.format != PixelFormat::kBgr8) throw std::runtime_error("expected a BGR8 TF image");
  figures.sift_processed = CountSift(tf.pixels.data(), tf.width, tf.height);
  figures.sift_ground_truth = CountSift(s.tf.bgr.data(), s.tf.width, s.tf.height);
  if (tf_out) *tf_out = std::move(tf);

  // Photo-consistency on the devignetted grey, not smoothed.
  FrameOptions raw_options = options;
  raw_options.smooth_passes = 0;
  PlenopticFrame grey;
  Require(PrepareFrame(s.raw.View(), s.white.View(), grid, s.mla, raw_options, &grey));
  constexpr std::array<std::array<int, 2>, 6> kRing1{
      {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, -1}, {-1, 1}}};
  constexpr std::array<std::array<int, 2>, 6> kRing2{
      {{1, 1}, {-1, -1}, {2, -1}, {-2, 1}, {1, -2}, {-1, 2}}};
  figures.ring1 = Consistency(s, grey, kRing1);
  figures.ring2 = Consistency(s, grey, kRing2);
  return figures;
}

}  // namespace lifmcr::processing::testing
