// Totally focused image, TF virtual depth, metric depth and point cloud of a
// synthetic `small` frame from the estimated virtual depth, against the
// ground truth (all-in-focus image, TF depth in mm).

#include "processing/lens_depth.h"
#include "processing/mla_grid.h"
#include "processing/point_cloud.h"
#include "processing/total_focus.h"
#include "replay/synth/renderer.h"
#include "replay/synth/scene.h"
#include "replay/synth/synth_params.h"
#include "tests/processing/synth_frame.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace lifmcr::processing {
namespace {

// Which TF pixels a PSNR is taken over (all on a surface of known depth):
// kAll; kTextured, the textured surfaces: ground-truth grey gradient >= 4
// DN/px and no step edge within 2 TF px; kEdges, within 2 TF px of a step
// edge. A step edge is where the ground truth's surface region changes
// (material boundary, marker cell edge: Scene::Region) or its depth jumps by
// more than 2 % between neighbours. Steps are kept apart because a focused
// plenoptic camera resolves the virtual image at 1/v of the raw resolution
// (v ~ 4 here, so about 2 TF px), while the ground truth is a point-sampled
// pinhole image in which a step is sharp to the pixel: no TF image can
// reproduce it (see docs/processing.md).
enum class Region { kAll, kTextured, kEdges };

std::vector<std::uint8_t> StepEdgeMask(const synth::TfGroundTruth& gt, int radius) {
  const int w = gt.width, h = gt.height;
  std::vector<std::uint8_t> step(gt.region.size(), 0), near(gt.region.size(), 0);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}}) {
        if (x + dx >= w || y + dy >= h) continue;
        const std::size_t j = static_cast<std::size_t>(y + dy) * w + x + dx;
        const float z0 = gt.depth_mm[i], z1 = gt.depth_mm[j];
        if (gt.region[i] != gt.region[j] || std::isnan(z0) != std::isnan(z1) ||
            std::abs(z0 - z1) > 0.02f * std::min(z0, z1))
          step[i] = step[j] = 1;
      }
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int dy = -radius; dy <= radius; ++dy)
        for (int dx = -radius; dx <= radius; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if (xx >= 0 && yy >= 0 && xx < w && yy < h && step[static_cast<std::size_t>(yy) * w + xx])
            near[static_cast<std::size_t>(y) * w + x] = 1;
        }
  return near;
}

double Psnr(const synth::TfGroundTruth& gt, const TfImage& tf, Region region, long long* count) {
  const int w = gt.width, h = gt.height;
  const std::vector<std::uint8_t> near_step = StepEdgeMask(gt, 2);
  auto grey = [&](int x, int y) {
    const std::uint8_t* p = gt.bgr.data() + 3 * (static_cast<std::size_t>(y) * w + x);
    return (p[0] + p[1] + p[2]) / 3.0;
  };
  double se = 0;
  long long n = 0;
  for (int y = 1; y < h - 1; ++y)
    for (int x = 1; x < w - 1; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      if (std::isnan(gt.depth_mm[i])) continue;
      if (region == Region::kEdges && !near_step[i]) continue;
      if (region == Region::kTextured) {
        const double gx = 0.5 * (grey(x + 1, y) - grey(x - 1, y));
        const double gy = 0.5 * (grey(x, y + 1) - grey(x, y - 1));
        if (near_step[i] || std::hypot(gx, gy) < 4.0) continue;
      }
      for (int c = 0; c < 3; ++c) {
        const double d = static_cast<double>(tf.pixels[3 * i + c]) - gt.bgr[3 * i + c];
        se += d * d;
      }
      ++n;
    }
  *count = n;
  return 10.0 * std::log10(255.0 * 255.0 / (se / (3.0 * n)));
}

double Median(std::vector<double> values) {
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

struct Figures {
  double psnr_textured = 0, psnr_all = 0, psnr_edges = 0, psnr_true_depth = 0;
  long long textured = 0, edges = 0;
  double tf_v_median = 0;    // |dv|/v on the TF grid (measured and filled)
  double metric_median = 0;  // |dZ|/Z on measured TF pixels inside the depth range
  std::size_t metric_pixels = 0;
  long long measured = 0, filled = 0;
  std::size_t cloud_points = 0;
};

// With `per_lens`, the TF depth from the frame's per-lens depth where it
// holds and the dense map elsewhere (VirtualDepthToTf with a LensDepthMap);
// the images rendered with `bary_floor` (TfOptions).
Figures RunPipeline(const testing::SynthFrame& s, bool per_lens = false,
                    double bary_floor = TfOptions{}.bary_floor) {
  Figures fig;
  TfOptions render;
  render.bary_floor = bary_floor;
  const CameraModel camera(s.intrinsics);
  const MlaGrid grid = MlaGrid::FromCalibration(s.mla, s.raw.width, s.raw.height);
  FrameOptions fo;
  fo.lambda = camera.lambda();
  PlenopticFrame frame;
  EXPECT_TRUE(PrepareFrame(s.raw.View(), s.white.View(), grid, s.mla, fo, &frame).ok());
  VirtualDepthMap depth;
  EXPECT_TRUE(EstimateVirtualDepth(frame, s.mla, DepthOptions{}, &depth).ok());
  TfDepthMap tf_depth;
  if (per_lens) {
    PlenopticFrame geometry;
    EXPECT_TRUE(
        PrepareGeometry(s.white.View(), s.raw.width, s.raw.height, grid, s.mla, fo, &geometry).ok());
    auto estimator = LensDepthEstimator::Create(std::move(geometry), s.mla, {});
    EXPECT_TRUE(estimator.ok());
    LensDepthMap lens_depth;
    EXPECT_TRUE((*estimator)->Estimate(s.raw.View(), &lens_depth).ok());
    EXPECT_TRUE(VirtualDepthToTf(frame, depth, lens_depth, TfOptions{}, &tf_depth).ok());
    std::printf("TF depth: %lld of %lld micro images from their lens depth\n", tf_depth.lenses_held,
                tf_depth.lenses);
    EXPECT_GT(tf_depth.lenses_held, 0);
  } else {
    EXPECT_TRUE(VirtualDepthToTf(frame, depth, TfOptions{}, &tf_depth).ok());
  }
  EXPECT_EQ(tf_depth.width, s.tf.width);
  EXPECT_EQ(tf_depth.height, s.tf.height);
  fig.measured = tf_depth.measured;
  fig.filled = tf_depth.filled;
  TfImage tf;
  EXPECT_TRUE(RenderTotalFocus(frame, s.mla, tf_depth, render, &tf).ok());
  EXPECT_EQ(tf.format, PixelFormat::kBgr8);
  fig.psnr_textured = Psnr(s.tf, tf, Region::kTextured, &fig.textured);
  long long all = 0;
  fig.psnr_all = Psnr(s.tf, tf, Region::kAll, &all);
  fig.psnr_edges = Psnr(s.tf, tf, Region::kEdges, &fig.edges);

  // With the true depth, to tell rendering from depth errors.
  TfDepthMap true_depth = tf_depth;
  std::vector<double> rel_v;
  for (std::size_t i = 0; i < true_depth.virtual_depth.size(); ++i) {
    const float z = s.tf.depth_mm[i];
    const double v_true = std::isnan(z) ? NAN : camera.VirtualDepthOfDepth(z);
    if (!std::isnan(tf_depth.virtual_depth[i]) && !std::isnan(z))
      rel_v.push_back(std::abs(tf_depth.virtual_depth[i] - v_true) / v_true);
    true_depth.virtual_depth[i] = static_cast<float>(v_true);
  }
  fig.tf_v_median = Median(rel_v);
  TfImage tf_true;
  EXPECT_TRUE(RenderTotalFocus(frame, s.mla, true_depth, render, &tf_true).ok());
  long long n_true = 0;
  fig.psnr_true_depth = Psnr(s.tf, tf_true, Region::kTextured, &n_true);

  // Metric depth with the true intrinsics, on measured TF pixels inside the
  // camera's depth range (the union of the lens types' ranges).
  std::vector<float> depth_mm;
  MetricDepthTf(camera, tf_depth, &depth_mm);
  double v_lo = 1e9, v_hi = 0;
  for (const MlaLensType& t : s.mla.lens_types) {
    v_lo = std::min(v_lo, t.depth_min);
    v_hi = std::max(v_hi, t.depth_max);
  }
  std::vector<double> rel_mm;
  for (std::size_t i = 0; i < depth_mm.size(); ++i) {
    const float z = s.tf.depth_mm[i];
    if (std::isnan(z) || std::isnan(tf_depth.sigma_z[i])) continue;
    const double v_true = camera.VirtualDepthOfDepth(z);
    if (v_true < v_lo || v_true > v_hi) continue;
    rel_mm.push_back(std::abs(depth_mm[i] - z) / z);
  }
  fig.metric_pixels = rel_mm.size();
  if (!rel_mm.empty()) fig.metric_median = Median(rel_mm);
  PointCloud cloud;
  BuildPointCloud(camera, tf_depth, tf, true, &cloud);
  fig.cloud_points = cloud.points_mm.size();
  std::printf(
      "TF: PSNR %.2f dB on %lld textured TF pixels (%.2f dB with the true depth), %.2f dB on %lld "
      "pixels near step edges, %.2f dB over all surface pixels; TF depth %lld measured + %lld "
      "filled, median |dv|/v %.2f %%; metric depth "
      "median |dZ|/Z %.2f %% over %zu measured pixels; %zu cloud points\n",
      fig.psnr_textured, fig.textured, fig.psnr_true_depth, fig.psnr_edges, fig.edges, fig.psnr_all,
      fig.measured, fig.filled, 100 * fig.tf_v_median, 100 * fig.metric_median, fig.metric_pixels,
      fig.cloud_points);
  return fig;
}

// The gates: PSNR >= 30 dB on textured regions against the
// all-in-focus ground truth, metric depth within 1 % (median) inside the
// camera's depth range. Figures: 30.9 dB textured (30.95 dB with the true
// depth), 19.4 dB near step edges, 27.8 dB over all surface pixels with the
// blend's floor at 0.25 (TfOptions::bary_floor; the default 0, the plain
// barycentric blend: 31.3, 31.4, 19.7, 28.1); metric
// 0.83 %; TF virtual depth 0.78 %.
TEST(TotalFocus, ImageDepthAndPointCloudOfASmallFrame) {
  const Figures fig = RunPipeline(testing::RenderSynthFrame("small", 1.0));
  EXPECT_GT(fig.textured, 2000);
  EXPECT_GT(fig.metric_pixels, 10000u);
  EXPECT_EQ(fig.cloud_points, static_cast<std::size_t>(fig.measured));
  EXPECT_GE(fig.psnr_textured, 30.0);
  EXPECT_LE(fig.metric_median, 0.01);
  // Regression floors, not gates.
  EXPECT_GE(fig.psnr_all, 27.0);
  EXPECT_GE(fig.psnr_edges, 19.0);
  EXPECT_LT(fig.tf_v_median, 0.012);
}

// The TF depth from the per-lens depth where it holds (total_focus.h) keeps
// the image: PSNR on textured pixels and over all surface pixels within 0.1
// dB of the TF depth from every dense pixel on the same frame, the gate of
// 30 dB held; and the chain's point cloud from it (the TF depth on its
// measured pixels) within the metric-depth gate of 1 % (median |dZ|/Z, true
// intrinsics; 0.97 % on this frame, docs/processing.md).
TEST(TotalFocus, DepthFromTheLensDepthKeepsTheImage) {
  const testing::SynthFrame s = testing::RenderSynthFrame("small", 1.0);
  const Figures dense = RunPipeline(s);
  const Figures lens = RunPipeline(s, true);
  EXPECT_GE(lens.psnr_textured, 30.0);
  EXPECT_GE(lens.psnr_textured, dense.psnr_textured - 0.1);
  EXPECT_GE(lens.psnr_all, dense.psnr_all - 0.1);
  EXPECT_GT(lens.metric_pixels, 10000u);
  EXPECT_EQ(lens.cloud_points, static_cast<std::size_t>(lens.measured));
  EXPECT_LE(lens.metric_median, 0.01);
}

// The blend's barycentric floor (TfOptions::bary_floor at 0.25; the default
// is 0: the lens of the smallest coordinate sampled only above it) keeps the
// image: PSNR on textured pixels and over all surface pixels within 0.6 dB
// of the plain barycentric blend's on the same frame and depth (0.44 and
// 0.30 dB lower when written), the gate of 30 dB held. A floor outside
// 0..0.3 is an error naming the field.
TEST(TotalFocus, BarycentricFloorKeepsTheImage) {
  const testing::SynthFrame s = testing::RenderSynthFrame("small", 1.0);
  const Figures plain = RunPipeline(s, false, 0.0);
  const Figures floored = RunPipeline(s, false, 0.25);
  EXPECT_GE(floored.psnr_textured, 30.0);
  EXPECT_GE(floored.psnr_textured, plain.psnr_textured - 0.6);
  EXPECT_GE(floored.psnr_all, plain.psnr_all - 0.6);
  EXPECT_NE(floored.psnr_textured, plain.psnr_textured);  // the floor changes the image
  for (const double bad : {-0.01, 0.31, static_cast<double>(NAN)}) {
    TfOptions options;
    options.bary_floor = bad;
    const Status status = options.Check();
    ASSERT_FALSE(status.ok()) << bad;
    EXPECT_NE(status.error().message.find("bary_floor"), std::string::npos);
  }
}

// A white frame (the white scene, its own white image) is white in the TF
// image wherever some micro image sees the TF pixel, at any virtual depth: up
// to the image border too. On `medium` (1 - lambda = 1.4 %) at v 4.7 the
// lenses that see a TF pixel x lie around c + (x - c) / (lambda + v (1 -
// lambda)), 4 lens pitches nearer the centre than x at the corner; the lenses
// around x itself see nothing of x there, and the TF image was black in a
// hatch fixed to the lattice along the border (docs/calibration.md, "TF
// lens selection"): 525 976 of 2 028 680 TF pixels below half the median at v 4.7,
// 18 240 at v 2.5 (none now).
TEST(TotalFocus, WhiteFrameIsWhiteToTheBorderAtHighVirtualDepth) {
  synth::SynthCameraParams params = synth::MakePreset("medium")->camera;
  params.read_noise_dn = 0;
  params.full_well_e = 0;
  const synth::PlenopticModel model(params);
  const synth::RawFrame white =
      synth::RenderRaw(model, synth::MakeWhiteScene(), Pose::Identity(), synth::RenderOptions{});
  const MlaCalibration mla = model.ToMlaCalibration();
  const MlaGrid grid = MlaGrid::FromCalibration(mla, white.width, white.height);
  FrameOptions options;
  options.lambda =
      params.mla_to_main_lens_mm / (params.mla_to_main_lens_mm + params.mla_to_sensor_mm);
  PlenopticFrame frame;
  ASSERT_TRUE(PrepareFrame(white.View(), white.View(), grid, mla, options, &frame).ok());
  for (const float v : {2.5f, 4.7f}) {
    TfDepthMap depth;
    depth.width = white.width / 2;
    depth.height = white.height / 2;
    depth.virtual_depth.assign(static_cast<std::size_t>(depth.width) * depth.height, v);
    depth.fallback_v = v;
    TfImage tf;
    ASSERT_TRUE(RenderTotalFocus(frame, mla, depth, TfOptions{}, &tf).ok());
    std::vector<double> grey;
    for (std::size_t i = 0; i < tf.pixels.size(); i += 3)
      grey.push_back((tf.pixels[i] + tf.pixels[i + 1] + tf.pixels[i + 2]) / 3.0);
    const double median = Median(grey);
    long long dark = 0;
    for (const double g : grey) dark += g < 0.5 * median ? 1 : 0;
    std::printf("white frame, v %.1f: TF median grey %.1f, %lld of %zu TF pixels below half of it\n",
                v, median, dark, grey.size());
    EXPECT_GT(median, 100.0);
    EXPECT_EQ(dark, 0);
  }
}

}  // namespace
}  // namespace lifmcr::processing
