// Processing without a white image (processing/vignetting.h): a synthetic
// `small` raw divided by its own white image (what RxLive's "Processed"
// export does) and the raw itself, each without a white image, meet the
// accuracy gates of the white-image run (coverage of textured pixels
// >= 50 %, median |dz|/z <= 2 %, outliers |dv|/v > 10 % <= 5 %).

#include "processing/vignetting.h"
#include "processing/virtual_depth.h"
#include "tests/processing/synth_frame.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace lifmcr::processing {
namespace {

using testing::DepthGates;

DepthGates DepthVsTruth(const testing::SynthFrame& s, ConstImageView raw, ConstImageView white) {
  PlenopticFrame frame;
  VirtualDepthMap depth;
  return testing::DepthGatesOf(s, raw, white, &frame, &depth);
}

void ExpectWithinGates(const DepthGates& g, const char* what) {
  std::printf("%-40s coverage %.1f %%, median |dz|/z %.2f %%, outliers %.2f %%\n", what,
              100 * g.coverage, 100 * g.median, 100 * g.outliers);
  EXPECT_GE(g.coverage, 0.50) << what;
  EXPECT_LE(g.median, 0.02) << what;
  EXPECT_LE(g.outliers, 0.05) << what;
}

TEST(NoWhiteImage, ProcessedAndUncorrectedRawsMeetTheGatesOfTheWhiteImageRun) {
  const testing::SynthFrame s = testing::RenderSynthFrame("small", 1.0);
  const int w = s.raw.width, h = s.raw.height;
  const MlaGrid grid = MlaGrid::FromCalibration(s.mla, w, h);
  ExpectWithinGates(DepthVsTruth(s, s.raw.View(), s.white.View()), "raw + white image:");

  // RxLive-style processed raw: raw * W_ref / W, saturated to 8 bits, with
  // W_ref the white image's 95th percentile (the bright micro-image cores).
  // Per channel, as the frame's format (the `small` preset renders BGR8).
  const ConstImageView white = s.white.View();
  const ConstImageView raw = s.raw.View();
  ASSERT_EQ(white.format, raw.format);
  const std::size_t row_bytes = raw.RowBytes();
  std::vector<std::uint8_t> sorted;
  for (int y = 0; y < h; ++y) sorted.insert(sorted.end(), white.Row(y), white.Row(y) + row_bytes);
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() * 95 / 100, sorted.end());
  const double w_ref = sorted[sorted.size() * 95 / 100];
  std::vector<std::uint8_t> processed(row_bytes * h);
  for (int y = 0; y < h; ++y)
    for (std::size_t x = 0; x < row_bytes; ++x) {
      const double v = raw.Row(y)[x] * w_ref / std::max<double>(1.0, white.Row(y)[x]);
      processed[y * row_bytes + x] = static_cast<std::uint8_t>(std::lround(std::min(255.0, v)));
    }
  const ConstImageView processed_view(processed.data(), w, h, row_bytes, raw.format);
  Expected<VignettingEstimate> flat = EstimateVignetting(processed_view, grid, s.mla);
  ASSERT_TRUE(flat.ok()) << flat.error().message;
  std::printf("processed: %s\n", flat->BriefReport().c_str());
  EXPECT_TRUE(flat->already_corrected) << flat->BriefReport();
  EXPECT_EQ(flat->White().data, nullptr);
  ExpectWithinGates(DepthVsTruth(s, processed_view, flat->White()),
                    "processed raw, no white image:");

  // The raw itself, vignetted, without its white image: the profile from the
  // frame devignettes it.
  Expected<VignettingEstimate> estimated = EstimateVignetting(raw, grid, s.mla);
  ASSERT_TRUE(estimated.ok()) << estimated.error().message;
  std::printf("raw: %s\n", estimated->BriefReport().c_str());
  EXPECT_FALSE(estimated->already_corrected) << estimated->BriefReport();
  ASSERT_NE(estimated->White().data, nullptr);
  ExpectWithinGates(DepthVsTruth(s, raw, estimated->White()), "raw, vignetting from the frame:");
}

TEST(NoWhiteImage, OptionsAreChecked) {
  VignettingOptions o;
  o.flat_fraction = 1.5;
  EXPECT_FALSE(o.Check().ok());
  o = {};
  o.bin_px = 0;
  EXPECT_FALSE(o.Check().ok());
}

}  // namespace
}  // namespace lifmcr::processing
