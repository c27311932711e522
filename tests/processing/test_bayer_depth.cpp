// A Bayer camera (RGGB mosaic, GenICam BayerRG8), demosaiced
// (replay/bayer.h): depth on its luminance meets the median and outlier gates
// of test_virtual_depth.cpp (median |dz|/z <= 2 %, outliers <= 5 %) and
// covers as much as the mosaic processed as grey (what lifmcr did before:
// 49.7 % of the textured pixels on this frame either way, so the 50 %
// coverage gate of a colour sensor is not asserted here); and the TF image is
// in colour.

#include "processing/total_focus.h"
#include "processing/virtual_depth.h"
#include "replay/bayer.h"
#include "replay/bmp.h"
#include "tests/processing/synth_frame.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace lifmcr::processing {
namespace {

struct Gates {
  double coverage = 0, median = 1, outliers = 1;
};

Gates Depth(const testing::SynthFrame& s, ConstImageView raw, ConstImageView white,
            PlenopticFrame* frame, VirtualDepthMap* depth) {
  const CameraModel camera(s.intrinsics);
  const MlaGrid grid = MlaGrid::FromCalibration(s.mla, raw.width, raw.height);
  FrameOptions fo;
  fo.lambda = camera.lambda();
  EXPECT_TRUE(PrepareFrame(raw, white, grid, s.mla, fo, frame).ok());
  EXPECT_TRUE(EstimateVirtualDepth(*frame, s.mla, DepthOptions{}, depth).ok());
  long long textured = 0, covered = 0, outliers = 0;
  std::vector<double> rel_z;
  for (std::size_t i = 0; i < depth->virtual_depth.size(); ++i) {
    const float truth = s.raw.virtual_depth[i];
    if (!depth->textured[i] || std::isnan(truth)) continue;
    ++textured;
    const float v = depth->virtual_depth[i];
    if (std::isnan(v)) continue;
    ++covered;
    rel_z.push_back(std::abs(1.0 / v - 1.0 / truth) * truth);
    if (std::abs(v - truth) / truth > 0.10) ++outliers;
  }
  Gates g;
  if (textured < 10000 || rel_z.empty()) return g;
  std::nth_element(rel_z.begin(), rel_z.begin() + rel_z.size() / 2, rel_z.end());
  g.coverage = static_cast<double>(covered) / textured;
  g.median = rel_z[rel_z.size() / 2];
  g.outliers = static_cast<double>(outliers) / covered;
  return g;
}

TEST(BayerDepth, DemosaicedMosaicMeetsTheGatesAndRendersInColour) {
  const testing::SynthFrame s = testing::RenderSynthFrame("small", 1.0, "plain", /*bayer=*/true);
  ASSERT_EQ(s.raw.View().format, PixelFormat::kMono8);
  const int w = s.raw.width, h = s.raw.height;
  OwnedImage raw = OwnedImage::Allocate(w, h, PixelFormat::kBgr8);
  OwnedImage white = OwnedImage::Allocate(w, h, PixelFormat::kBgr8);
  ASSERT_TRUE(DemosaicBayer(s.raw.View(), CameraPixelFormat::kBayerRg8, raw.View()).ok());
  ASSERT_TRUE(DemosaicBayer(s.white.View(), CameraPixelFormat::kBayerRg8, white.View()).ok());

  PlenopticFrame mosaic_frame, frame;
  VirtualDepthMap mosaic_depth, depth;
  const Gates mosaic = Depth(s, s.raw.View(), s.white.View(), &mosaic_frame, &mosaic_depth);
  const Gates g = Depth(s, raw.View(), white.View(), &frame, &depth);
  std::printf("Bayer RGGB as grey: coverage %.1f %%, median |dz|/z %.2f %%, outliers %.2f %%\n",
              100 * mosaic.coverage, 100 * mosaic.median, 100 * mosaic.outliers);
  std::printf("Bayer RGGB demosaiced: coverage %.1f %%, median |dz|/z %.2f %%, outliers %.2f %%\n",
              100 * g.coverage, 100 * g.median, 100 * g.outliers);
  EXPECT_GE(g.coverage, mosaic.coverage - 0.01);
  EXPECT_LE(g.median, 0.02);
  EXPECT_LE(g.outliers, 0.05);
  // The TF image in colour: its channels differ (a grey mosaic would give
  // one channel three times).
  TfDepthMap tf_depth;
  ASSERT_TRUE(VirtualDepthToTf(frame, depth, TfOptions{}, &tf_depth).ok());
  TfImage tf;
  ASSERT_TRUE(RenderTotalFocus(frame, s.mla, tf_depth, TfOptions{}, &tf).ok());
  const ConstImageView view = tf.View();
  ASSERT_EQ(view.format, PixelFormat::kBgr8);
  double channel_spread = 0;
  for (int y = 0; y < view.height; ++y)
    for (int x = 0; x < view.width; ++x) {
      const std::uint8_t* p = view.Row(y) + 3 * x;
      channel_spread += std::max({p[0], p[1], p[2]}) - std::min({p[0], p[1], p[2]});
    }
  channel_spread /= static_cast<double>(view.width) * view.height;
  std::printf("TF image: mean channel spread %.1f grey levels\n", channel_spread);
  EXPECT_GT(channel_spread, 5.0);
}

}  // namespace
}  // namespace lifmcr::processing
