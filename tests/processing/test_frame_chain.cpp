// The processing chain (processing/frame_chain.h) on a synthetic `small`
// frame: the same products as the steps called one by one, the white image
// as the one branch of the per-camera setup, metric depth with intrinsics,
// workspaces reused, and options that name their bad field.

#include "processing/frame_chain.h"
#include "tests/processing/synth_frame.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace lifmcr::processing {
namespace {

OwnedImage Own(const synth::RawFrame& frame) {
  OwnedImage image = OwnedImage::Allocate(frame.width, frame.height, frame.format);
  std::memcpy(image.pixels.data(), frame.pixels.data(), image.pixels.size());
  return image;
}

CameraSetup SetupOf(const testing::SynthFrame& s, bool white, bool intrinsics) {
  CameraSetup setup;
  setup.serial = "40398678";
  setup.mla = s.mla;
  if (white) setup.white = Own(s.white);
  if (intrinsics) setup.intrinsics = s.intrinsics;
  return setup;
}

const testing::SynthFrame& Frame() {
  static const testing::SynthFrame frame = testing::RenderSynthFrame();
  return frame;
}

TEST(FrameChain, MatchesTheStepsCalledOneByOneAndReusesItsWorkspace) {
  const testing::SynthFrame& s = Frame();
  ChainOptions options;
  options.point_cloud = true;
  auto chain = CameraChain::Create(SetupOf(s, true, true), options);
  ASSERT_TRUE(chain.ok()) << chain.error().message;
  EXPECT_EQ((*chain)->devignetting(), Devignetting::kWhiteImage);
  EXPECT_NE((*chain)->Describe().find("white image"), std::string::npos);

  // The reference: the steps by hand, with the camera's lambda: the
  // per-lens depth, the dense search seeded by it, the TF depth.
  const CameraModel camera(s.intrinsics);
  FrameOptions fo;
  fo.lambda = camera.lambda();
  const MlaGrid grid = MlaGrid::FromCalibration(s.mla, s.raw.width, s.raw.height);
  PlenopticFrame frame;
  ASSERT_TRUE(PrepareFrame(s.raw.View(), s.white.View(), grid, s.mla, fo, &frame).ok());
  PlenopticFrame geometry;
  ASSERT_TRUE(
      PrepareGeometry(s.white.View(), s.raw.width, s.raw.height, grid, s.mla, fo, &geometry).ok());
  auto lens_estimator = LensDepthEstimator::Create(std::move(geometry), s.mla, {});
  ASSERT_TRUE(lens_estimator.ok());
  LensDepthMap lens_depth;
  ASSERT_TRUE((*lens_estimator)->Estimate(s.raw.View(), &lens_depth).ok());
  LensSeed seed;
  ASSERT_TRUE(SeedFromLensDepth(frame, lens_depth, &seed).ok());
  VirtualDepthMap depth;
  ASSERT_TRUE(EstimateVirtualDepth(frame, s.mla, DepthOptions{}, &seed, &depth).ok());
  EXPECT_GT(depth.stats.seeded, 0);
  TfDepthMap tf_depth;
  ASSERT_TRUE(VirtualDepthToTf(frame, depth, lens_depth, TfOptions{}, &tf_depth).ok());

  const ChainProducts* first = nullptr;
  for (int pass = 0; pass < 2; ++pass) {
    auto lease = (*chain)->Process(s.raw.View());
    ASSERT_TRUE(lease.ok()) << lease.error().message;
    const ChainProducts& p = **lease;
    // A lease returned to the pool is the next frame's workspace.
    if (pass == 0) {
      first = &p;
    } else {
      EXPECT_EQ(&p, first);
    }
    EXPECT_EQ(p.prepared.lambda, camera.lambda());
    EXPECT_EQ(p.raw_depth.stats.estimated, depth.stats.estimated);
    EXPECT_EQ(p.raw_depth.stats.seeded, depth.stats.seeded);
    ASSERT_EQ(p.tf_depth.virtual_depth.size(), tf_depth.virtual_depth.size());
    for (std::size_t i = 0; i < tf_depth.virtual_depth.size(); ++i) {
      const float a = p.tf_depth.virtual_depth[i], b = tf_depth.virtual_depth[i];
      ASSERT_TRUE((std::isnan(a) && std::isnan(b)) || a == b) << i;
    }
    EXPECT_TRUE(p.metric);
    EXPECT_EQ(p.depth_mm.size(), tf_depth.virtual_depth.size());
    EXPECT_GT(p.cloud.points_mm.size(), 1000u);
    EXPECT_NE(p.BriefReport().find("metric"), std::string::npos) << p.BriefReport();
  }
}

// seeded_depth off: the full search (the reference), nothing seeded; a
// per-lens map given to Process seeds the search instead of the chain's own.
TEST(FrameChain, FullSearchOnRequestAndAGivenPerLensMapSeeds) {
  const testing::SynthFrame& s = Frame();
  ChainOptions full_options;
  full_options.seeded_depth = false;
  auto full = CameraChain::Create(SetupOf(s, true, false), full_options);
  ASSERT_TRUE(full.ok());
  auto lease = (*full)->Process(s.raw.View());
  ASSERT_TRUE(lease.ok()) << lease.error().message;
  EXPECT_EQ((*lease)->raw_depth.stats.seeded, 0);
  EXPECT_EQ((*lease)->seed_s, 0.0);

  auto chain = CameraChain::Create(SetupOf(s, true, false), ChainOptions{});
  ASSERT_TRUE(chain.ok());
  auto lenses = (*chain)->ProcessLenses(s.raw.View(), 0);
  ASSERT_TRUE(lenses.ok());
  auto own = (*chain)->Process(s.raw.View());
  auto given = (*chain)->Process(s.raw.View(), &(*lenses)->depth);
  ASSERT_TRUE(own.ok() && given.ok());
  EXPECT_GT((*given)->raw_depth.stats.seeded, 0);
  // The same frame's per-lens depth either way: the same map.
  EXPECT_EQ((*given)->raw_depth.stats.estimated, (*own)->raw_depth.stats.estimated);
  EXPECT_EQ((*given)->raw_depth.stats.seeded, (*own)->raw_depth.stats.seeded);
}

// dense_for_tf_only (the live pipeline's chain): the micro images whose TF
// depth comes from their lens depth are not estimated, and the TF products
// stay those of the whole map but for the micro images filled from their
// ring-1 neighbours (step 5), which lose a skipped neighbour's surface.
TEST(FrameChain, DenseForTfOnlySkipsTheHeldMicroImagesAndKeepsTheTfProducts) {
  const testing::SynthFrame& s = Frame();
  auto whole = CameraChain::Create(SetupOf(s, true, false), ChainOptions{});
  ChainOptions options;
  options.dense_for_tf_only = true;
  auto part = CameraChain::Create(SetupOf(s, true, false), options);
  ASSERT_TRUE(whole.ok() && part.ok());
  auto a = (*whole)->Process(s.raw.View());
  auto b = (*part)->Process(s.raw.View());
  ASSERT_TRUE(a.ok() && b.ok());
  const ChainProducts& pa = **a;
  const ChainProducts& pb = **b;
  EXPECT_EQ(pa.raw_depth.stats.skipped_lenses, 0);
  EXPECT_EQ(pb.raw_depth.stats.skipped_lenses, pb.tf_depth.lenses_held);
  EXPECT_GT(pb.tf_depth.lenses_held, 0);  // 35 of 3670 on this frame
  EXPECT_EQ(pa.tf_depth.lenses_held, pb.tf_depth.lenses_held);
  EXPECT_LT(pb.raw_depth.stats.searched, pa.raw_depth.stats.searched);
  ASSERT_EQ(pa.tf_depth.virtual_depth.size(), pb.tf_depth.virtual_depth.size());
  long long differ = 0, both = 0;
  for (std::size_t i = 0; i < pa.tf_depth.virtual_depth.size(); ++i) {
    const float va = pa.tf_depth.virtual_depth[i], vb = pb.tf_depth.virtual_depth[i];
    if (std::isnan(va) && std::isnan(vb)) continue;
    ++both;
    differ += !(std::abs(va - vb) <= 1e-3f * va);
  }
  ASSERT_EQ(pa.tf.pixels.size(), pb.tf.pixels.size());
  double sum2 = 0;
  for (std::size_t i = 0; i < pa.tf.pixels.size(); ++i) {
    const double d = static_cast<double>(pa.tf.pixels[i]) - pb.tf.pixels[i];
    sum2 += d * d;
  }
  const double rms = std::sqrt(sum2 / static_cast<double>(pa.tf.pixels.size()));
  std::printf("TF depth: %lld of %lld pixels differ by more than 0.1 %%; TF image RMS %.3f DN\n",
              differ, both, rms);
  EXPECT_GT(both, 0);
  EXPECT_LE(differ, both / 100);
  EXPECT_LE(rms, 1.0);
}

TEST(FrameChain, WithoutAWhiteImageTheVignettingComesFromTheFirstFrame) {
  const testing::SynthFrame& s = Frame();
  auto chain = CameraChain::Create(SetupOf(s, false, false), ChainOptions{});
  ASSERT_TRUE(chain.ok()) << chain.error().message;
  EXPECT_EQ((*chain)->devignetting(), Devignetting::kFromFrame);
  auto lease = (*chain)->Process(s.raw.View());
  ASSERT_TRUE(lease.ok()) << lease.error().message;
  EXPECT_EQ((*lease)->prepared.lambda, 1.0);  // no intrinsics: lambda 1
  EXPECT_FALSE((*lease)->metric);
  EXPECT_TRUE((*lease)->depth_mm.empty());
  EXPECT_GT((*lease)->raw_depth.stats.estimated, 1000);
  // What the estimate decided is in the camera's description.
  EXPECT_NE((*chain)->Describe().find("from the frame ("), std::string::npos)
      << (*chain)->Describe();
}

TEST(FrameChain, ConcurrentLeasesHaveTheirOwnWorkspaces) {
  const testing::SynthFrame& s = Frame();
  auto chain = CameraChain::Create(SetupOf(s, true, false), ChainOptions{});
  ASSERT_TRUE(chain.ok());
  auto a = (*chain)->Process(s.raw.View());
  auto b = (*chain)->Process(s.raw.View());
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_NE(a->get(), b->get());
}

TEST(FrameChain, AFrameOfAnotherSizeThanItsWhiteImageIsAnError) {
  const testing::SynthFrame& s = Frame();
  auto chain = CameraChain::Create(SetupOf(s, true, false), ChainOptions{});
  ASSERT_TRUE(chain.ok());
  ConstImageView half = s.raw.View();
  half.height /= 2;
  auto lease = (*chain)->Process(half);
  ASSERT_FALSE(lease.ok());
  EXPECT_NE(lease.error().message.find("white image"), std::string::npos)
      << lease.error().message;
}

// Intrinsics whose B (or b_L0) is so small that every virtual depth the MLA
// file's lens types are searched for lies behind the main lens: no frame
// could give a point, so Create names the values instead.
TEST(FrameChain, IntrinsicsThatPutEveryDepthBehindTheLensAreNamed) {
  const testing::SynthFrame& s = Frame();
  CameraSetup setup = SetupOf(s, false, true);
  setup.intrinsics->mla_to_sensor_mm = 1e-9;
  auto chain = CameraChain::Create(std::move(setup), ChainOptions{});
  ASSERT_FALSE(chain.ok());
  const std::string& message = chain.error().message;
  for (const char* part : {"camera 40398678", "mla_to_sensor_mm B = 1e-09 mm",
                           "mla_to_main_lens_mm b_L0 =", "main_focal_length_mm f_L ="})
    EXPECT_NE(message.find(part), std::string::npos) << part << " in " << message;
  // The true intrinsics pass.
  EXPECT_TRUE(CameraChain::Create(SetupOf(s, false, true), ChainOptions{}).ok());
}

// A frame (or white image) narrower than one micro image holds no micro
// image and would leave an empty TF grid: an error with both sizes.
TEST(FrameChain, AFrameSmallerThanAMicroImageIsNamed) {
  const testing::SynthFrame& s = Frame();
  const int pitch = static_cast<int>(std::ceil(s.mla.diameter_px));
  auto chain = CameraChain::Create(SetupOf(s, false, false), ChainOptions{});
  ASSERT_TRUE(chain.ok());
  ConstImageView strip = s.raw.View();
  strip.height = 1;
  auto lease = (*chain)->Process(strip);
  ASSERT_FALSE(lease.ok());
  const std::string size = std::to_string(strip.width) + "x1 px, smaller than one micro image";
  EXPECT_NE(lease.error().message.find(size), std::string::npos) << lease.error().message;
  EXPECT_NE(lease.error().message.find("diameter " + std::to_string(pitch) + " px"),
            std::string::npos)
      << lease.error().message;

  CameraSetup tiny_white = SetupOf(s, true, false);
  tiny_white.white = OwnedImage::Allocate(1, 1, PixelFormat::kMono8);
  auto refused = CameraChain::Create(std::move(tiny_white), ChainOptions{});
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("white image: 1x1 px"), std::string::npos)
      << refused.error().message;
}

TEST(FrameChain, BadOptionsNameTheirField) {
  struct Case {
    const char* field;
    void (*set)(ChainOptions&);
  };
  const Case cases[] = {
      {"lambda", [](ChainOptions& o) { o.frame.lambda = 0; }},
      {"smooth_passes", [](ChainOptions& o) { o.frame.smooth_passes = -1; }},
      {"min_white_fraction", [](ChainOptions& o) { o.frame.min_white_fraction = 1.5; }},
      {"margin_px", [](ChainOptions& o) { o.frame.margin_px = -1; }},
      {"max_rel_sigma", [](ChainOptions& o) { o.depth.max_rel_sigma = 0; }},
      {"max_cost_ratio", [](ChainOptions& o) { o.depth.max_cost_ratio = 0; }},
      {"smooth_radius_px", [](ChainOptions& o) { o.depth.smooth_radius_px = -1; }},
      {"min_support", [](ChainOptions& o) { o.depth.min_support = 0; }},
      {"geometric_px", [](ChainOptions& o) { o.depth.geometric_px = NAN; }},
      {"cross_type_px", [](ChainOptions& o) { o.depth.cross_type_px = -1; }},
      {"sharpen", [](ChainOptions& o) { o.tf.sharpen = -1; }},
      {"inner_fraction", [](ChainOptions& o) { o.tf.inner_fraction = 0; }},
      {"dense_for_tf_only",
       [](ChainOptions& o) {
         o.seeded_depth = false;
         o.dense_for_tf_only = true;
       }},
  };
  const testing::SynthFrame& s = Frame();
  for (const Case& c : cases) {
    ChainOptions options;
    c.set(options);
    const Status status = options.Check();
    ASSERT_FALSE(status.ok()) << c.field;
    EXPECT_NE(status.error().message.find(c.field), std::string::npos) << status.error().message;
    auto chain = CameraChain::Create(SetupOf(s, false, false), options);
    EXPECT_FALSE(chain.ok()) << c.field;
  }
  GridFitOptions grid;
  grid.window_fraction = 0;
  ASSERT_FALSE(grid.Check().ok());
  EXPECT_NE(grid.Check().error().message.find("window_fraction"), std::string::npos);
}

TEST(FrameChain, TwoCamerasByTheirSerial) {
  const testing::SynthFrame& s = Frame();
  std::vector<CameraSetup> setups{SetupOf(s, true, false), SetupOf(s, false, true)};
  setups[1].serial = "40398673";
  auto chain = ProcessingChain::Create(std::move(setups), ChainOptions{});
  ASSERT_TRUE(chain.ok()) << chain.error().message;
  ASSERT_NE((*chain)->Find("40398673"), nullptr);
  EXPECT_EQ((*chain)->Find("40398673")->devignetting(), Devignetting::kFromFrame);
  EXPECT_TRUE((*chain)->Find("40398673")->camera_model().has_value());
  EXPECT_EQ((*chain)->Find("00000000"), nullptr);
  std::vector<CameraSetup> twice{SetupOf(s, true, false), SetupOf(s, true, false)};
  EXPECT_FALSE(ProcessingChain::Create(std::move(twice), ChainOptions{}).ok());
}

}  // namespace
}  // namespace lifmcr::processing
