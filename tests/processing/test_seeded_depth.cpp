// The dense virtual depth seeded by the per-lens depth
// (processing/virtual_depth.h, "Seeded"): on a synthetic frame against the
// ground truth and against the full search of the same frame (coverage,
// median |dz|/z, outliers within 1 % absolute of the full search's and
// within the dense gates); the fallback (no seed: the full search's map
// exactly; a wrong seed everywhere: the full search's accuracy, found by
// searching again over the whole range); the SIMD and the scalar kernels
// giving the same map; the pooled per-thread buffers restored on every exit
// (a reused workspace gives a fresh one's map); the seed's lattice check;
// the texture gate's flags, pixel by pixel, against its rule.

#include "processing/camera_model.h"
#include "processing/epipolar_search.h"
#include "processing/lens_depth.h"
#include "processing/mla_grid.h"
#include "processing/total_focus.h"
#include "processing/virtual_depth.h"
#include "tests/processing/synth_frame.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <thread>
#include <utility>

namespace lifmcr::processing {
namespace {

// `small` on the textured table scene (micro images of 16 px), rendered
// once, with its prepared frame, per-lens depth and full-search map.
class SeededDepth : public ::testing::Test {
 protected:
  struct Shared {
    testing::SynthFrame s;
    PlenopticFrame frame;
    LensDepthMap lens;
    LensSeed seed;
    VirtualDepthMap full;
    testing::DepthGates full_gates;
  };
  static void SetUpTestSuite() {
    shared_ = new Shared;
    Shared& d = *shared_;
    d.s = testing::RenderSynthFrame("small", 1.0, "table");
    const CameraModel camera(d.s.intrinsics);
    const MlaGrid grid = MlaGrid::FromCalibration(d.s.mla, d.s.raw.width, d.s.raw.height);
    FrameOptions fo;
    fo.lambda = camera.lambda();
    ASSERT_TRUE(
        PrepareFrame(d.s.raw.View(), d.s.white.View(), grid, d.s.mla, fo, &d.frame).ok());
    PlenopticFrame geometry;
    ASSERT_TRUE(PrepareGeometry(d.s.white.View(), d.s.raw.width, d.s.raw.height, grid, d.s.mla,
                                fo, &geometry)
                    .ok());
    auto estimator = LensDepthEstimator::Create(std::move(geometry), d.s.mla, {});
    ASSERT_TRUE(estimator.ok());
    ASSERT_TRUE((*estimator)->Estimate(d.s.raw.View(), &d.lens).ok());
    ASSERT_TRUE(SeedFromLensDepth(d.frame, d.lens, &d.seed).ok());
    ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &d.full).ok());
    d.full_gates = testing::MeasureDepthGates(d.s, d.full.virtual_depth, d.full.textured);
  }
  static void TearDownTestSuite() {
    delete shared_;
    shared_ = nullptr;
  }
  static void Print(const char* what, const VirtualDepthMap& m, const testing::DepthGates& g) {
    std::printf("%s: %s\n  coverage %.1f %% of %lld textured, median |dz|/z %.2f %%, outliers "
                "%.2f %%\n",
                what, m.stats.BriefReport().c_str(), 100 * g.coverage, g.textured, 100 * g.median,
                100 * g.outliers);
  }
  // `other`'s coverage, median |dz|/z and outliers within 1 % absolute of
  // `base`'s (both printed).
  static void ExpectWithinOnePercent(const char* base_name, const VirtualDepthMap& base,
                                     const char* other_name, const VirtualDepthMap& other) {
    const Shared& d = *shared_;
    const testing::DepthGates gb = testing::MeasureDepthGates(d.s, base.virtual_depth, base.textured);
    const testing::DepthGates go =
        testing::MeasureDepthGates(d.s, other.virtual_depth, other.textured);
    Print(base_name, base, gb);
    Print(other_name, other, go);
    EXPECT_GE(go.coverage, gb.coverage - 0.01);
    EXPECT_LE(go.median, gb.median + 0.01);
    EXPECT_LE(go.outliers, gb.outliers + 0.01);
  }
  static Shared* shared_;
};
SeededDepth::Shared* SeededDepth::shared_ = nullptr;

TEST_F(SeededDepth, MatchesTheFullSearchAndTheGates) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  long long seeded_lenses = 0;
  for (const float z : d.seed.z) seeded_lenses += z > 0;
  ASSERT_GT(seeded_lenses, static_cast<long long>(d.frame.lenses.size()) / 2);
  VirtualDepthMap seeded;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &d.seed, &seeded).ok());
  const testing::DepthGates g =
      testing::MeasureDepthGates(d.s, seeded.virtual_depth, seeded.textured);
  Print("full", d.full, d.full_gates);
  Print("seeded", seeded, g);
  EXPECT_GT(seeded.stats.seeded, seeded.stats.searched / 2);
  // Within 1 % absolute of the full search's median and outliers; coverage
  // within 2 %: on `small`'s 16 px micro images the seeded search's fewer
  // baselines per pixel (seed_max_ring1) cover 1.2 % fewer textured pixels
  // (bench_depth --preset medium / r32 holds 1 %: docs/processing.md).
  EXPECT_GE(g.coverage, d.full_gates.coverage - 0.02);
  EXPECT_LE(g.median, d.full_gates.median + 0.01);
  EXPECT_LE(g.outliers, d.full_gates.outliers + 0.01);
  EXPECT_GE(g.coverage, 0.5);
  EXPECT_LE(g.median, 0.02);
  EXPECT_LE(g.outliers, 0.05);
}

// No seed anywhere: every micro image takes the full search, so the map is
// the full search's, pixel for pixel.
TEST_F(SeededDepth, MissingSeedGivesTheFullSearch) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  LensSeed none;
  none.z.assign(d.frame.lenses.size(), std::numeric_limits<float>::quiet_NaN());
  none.sigma_z = none.z;
  VirtualDepthMap m;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &none, &m).ok());
  EXPECT_EQ(m.stats.seeded, 0);
  ASSERT_EQ(m.virtual_depth.size(), d.full.virtual_depth.size());
  for (std::size_t i = 0; i < m.virtual_depth.size(); ++i) {
    const float a = m.virtual_depth[i], b = d.full.virtual_depth[i];
    ASSERT_TRUE((std::isnan(a) && std::isnan(b)) || a == b) << "pixel " << i;
  }
}

// A seed 40 % off in z everywhere (and a confident one: sigma tiny): the
// window misses the surface, the least cost lies on its edge, and the
// pixels are searched again over the whole range: the full search's
// accuracy, not the seed's depth.
TEST_F(SeededDepth, WrongSeedFallsBackToTheFullSearch) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  LensSeed wrong = d.seed;
  for (std::size_t k = 0; k < wrong.z.size(); ++k) {
    wrong.z[k] *= 1.4f;
    wrong.sigma_z[k] = 1e-4f;
  }
  VirtualDepthMap m;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &wrong, &m).ok());
  const testing::DepthGates g = testing::MeasureDepthGates(d.s, m.virtual_depth, m.textured);
  Print("wrong seed", m, g);
  VirtualDepthMap right;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &d.seed, &right).ok());
  // Most pixels searched again (the right seed's misses are the pixels
  // without a clear minimum anywhere).
  EXPECT_GT(m.stats.fallback, right.stats.fallback + m.stats.seeded / 5);
  EXPECT_GT(m.stats.fallback, m.stats.seeded / 2);
  EXPECT_GE(g.coverage, d.full_gates.coverage - 0.05);
  EXPECT_LE(g.median, d.full_gates.median + 0.01);
  EXPECT_LE(g.outliers, d.full_gates.outliers + 0.02);
}

// DepthOptions::simd: Highway's strip kernels or the scalar reference; they
// agree to the last bit (tests/processing/test_lens_search_simd.cpp), so
// the maps are compared exactly, seeded and full.
TEST_F(SeededDepth, SimdAndScalarPathsGiveTheSameMap) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  for (const LensSeed* seed : {static_cast<const LensSeed*>(nullptr), &d.seed}) {
    DepthOptions scalar_options, simd_options;
    scalar_options.simd = false;
    VirtualDepthMap a, b;
    ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, scalar_options, seed, &a).ok());
    ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, simd_options, seed, &b).ok());
    EXPECT_STREQ(a.stats.kernels, "scalar");
    EXPECT_STRNE(b.stats.kernels, "scalar");
    long long finite = 0;
    for (std::size_t i = 0; i < a.virtual_depth.size(); ++i) {
      const float va = a.virtual_depth[i], vb = b.virtual_depth[i];
      ASSERT_TRUE((std::isnan(va) && std::isnan(vb)) || va == vb)
          << (seed ? "seeded" : "full") << " pixel " << i << ": " << vb << " vs scalar " << va;
      const float sa = a.sigma_z[i], sb = b.sigma_z[i];
      ASSERT_TRUE((std::isnan(sa) && std::isnan(sb)) || sa == sb) << "pixel " << i;
      finite += !std::isnan(va);
    }
    EXPECT_GT(finite, 10000);
  }
}

// The map is written once per pixel (each micro image its own pixels and
// the runs outside every disc beside them, then the rows no micro image
// covers): a map whose buffers held anything gets the same values as a
// fresh one, and no estimate and no texture outside the micro images.
TEST_F(SeededDepth, EveryPixelIsWrittenWhateverTheBuffersHeld) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  auto same = [](float a, float b) { return (std::isnan(a) && std::isnan(b)) || a == b; };
  for (const LensSeed* seed : {static_cast<const LensSeed*>(nullptr), &d.seed}) {
    VirtualDepthMap fresh, reused;
    ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, seed, &fresh).ok());
    const std::size_t n = fresh.virtual_depth.size();
    reused.width = fresh.width;
    reused.height = fresh.height;
    reused.virtual_depth.assign(n, 3.5f);
    reused.sigma_z.assign(n, 0.25f);
    reused.confidence.assign(n, 0.5f);
    reused.textured.assign(n, 7);
    ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, seed, &reused).ok());
    long long outside = 0;
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_TRUE(same(fresh.virtual_depth[i], reused.virtual_depth[i])) << "pixel " << i;
      ASSERT_TRUE(same(fresh.sigma_z[i], reused.sigma_z[i])) << "pixel " << i;
      ASSERT_TRUE(same(fresh.confidence[i], reused.confidence[i])) << "pixel " << i;
      ASSERT_EQ(fresh.textured[i], reused.textured[i]) << "pixel " << i;
      if (d.frame.lens_of_pixel[i] >= 0) continue;
      ++outside;
      ASSERT_TRUE(std::isnan(reused.virtual_depth[i]) && std::isnan(reused.sigma_z[i]) &&
                  reused.confidence[i] == 0 && reused.textured[i] == 0)
          << "pixel " << i << " outside every micro image";
    }
    EXPECT_GT(outside, 0);
  }
}

// A micro image's buffers are its thread's and rest at "none" between micro
// images: each restores the entries it wrote, on every exit (also where no
// estimate passes and steps 4 and 5 are skipped). So a workspace reused
// across frames of other content gives the map of a fresh one. Each run
// below is on a thread of its own in an arena of one slot: every micro image
// on that thread, whose thread_local workspace is fresh where it starts.
// Frame B: a third of the micro images noise (their searches mostly fail:
// the exits without an estimate), a third mirrored (estimates at other
// pixels), searched with a wrong seed (fallbacks) and without one (the
// full search's checkerboard). On lattices of 2 (`small`'s 16 px micro
// images search every textured pixel by default, which overwrites every
// flag a micro image before left): a textured pixel off the lattice reads
// flags it did not write.
TEST_F(SeededDepth, PooledBuffersGiveTheSameMapAfterOtherFramesAndEarlyExits) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  auto on_fresh_thread = [](auto work) {
    std::thread t([&] {
      tbb::task_arena one(1);
      one.execute(work);
    });
    t.join();
  };
  auto same_maps = [](const VirtualDepthMap& a, const VirtualDepthMap& b) {
    auto same = [](float x, float y) { return (std::isnan(x) && std::isnan(y)) || x == y; };
    ASSERT_EQ(a.virtual_depth.size(), b.virtual_depth.size());
    for (std::size_t i = 0; i < a.virtual_depth.size(); ++i) {
      ASSERT_TRUE(same(a.virtual_depth[i], b.virtual_depth[i])) << "pixel " << i;
      ASSERT_TRUE(same(a.sigma_z[i], b.sigma_z[i])) << "pixel " << i;
      ASSERT_TRUE(same(a.confidence[i], b.confidence[i])) << "pixel " << i;
      ASSERT_EQ(a.textured[i], b.textured[i]) << "pixel " << i;
    }
    EXPECT_EQ(a.stats.estimated, b.stats.estimated);
    EXPECT_EQ(a.stats.rejected, b.stats.rejected);
    EXPECT_EQ(a.stats.filled, b.stats.filled);
    EXPECT_EQ(a.stats.searched, b.stats.searched);
    EXPECT_EQ(a.stats.fallback, b.stats.fallback);
  };
  PlenopticFrame other = d.frame;
  const int w = other.width;
  std::uint32_t state = 12345;
  for (std::size_t i = 0; i < other.grey.size(); ++i) {
    const int k = other.lens_of_pixel[i];
    if (k < 0 || std::isnan(other.grey[i])) continue;
    if (k % 3 == 0) {
      state = state * 1664525u + 1013904223u;
      other.grey[i] = static_cast<float>(state >> 24);
    } else if (k % 3 == 1) {
      // Mirrored about the micro image's centre column where that pixel is its own.
      const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
      const int xm = static_cast<int>(std::lround(2 * other.lenses[k].centre_px.x())) - x;
      const std::size_t m = static_cast<std::size_t>(y) * w + xm;
      if (xm > 0 && xm < w && d.frame.lens_of_pixel[m] == k && !std::isnan(d.frame.grey[m]))
        other.grey[i] = d.frame.grey[m];
    }
  }
  LensSeed wrong = d.seed;
  for (float& z : wrong.z) z *= 1.4f;
  DepthOptions o;
  o.search_stride = 2;
  o.seed_search_stride = 2;
  VirtualDepthMap fresh, reused, noise_seeded, noise_full;
  on_fresh_thread([&] {
    ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &d.seed, &fresh).ok());
  });
  on_fresh_thread([&] {
    ASSERT_TRUE(EstimateVirtualDepth(other, d.s.mla, o, &wrong, &noise_seeded).ok());
    ASSERT_TRUE(EstimateVirtualDepth(other, d.s.mla, o, nullptr, &noise_full).ok());
    ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &d.seed, &reused).ok());
  });
  // Frame B took the exits: micro images with textured pixels and no
  // estimate of step 4, and fallbacks.
  EXPECT_GT(noise_seeded.stats.fallback, 0);
  EXPECT_LT(noise_seeded.stats.estimated, fresh.stats.estimated);
  EXPECT_GT(noise_full.stats.searched, 0);
  same_maps(fresh, reused);
  // And the map of all threads' workspaces, reused by the tests before.
  VirtualDepthMap pooled;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &d.seed, &pooled).ok());
  same_maps(fresh, pooled);
}

TEST_F(SeededDepth, RejectsASeedOfAnotherFrame) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  LensSeed short_seed;
  short_seed.z.assign(3, 0.25f);
  short_seed.sigma_z.assign(3, 0.01f);
  VirtualDepthMap m;
  const Status s = EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &short_seed, &m);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("micro images"), std::string::npos) << s.error().message;
  // A per-lens map on a shifted lattice.
  LensDepthMap shifted = d.lens;
  shifted.grid.origin_px += Eigen::Vector2d(3.0, 0.0);
  LensSeed out;
  const Status t = SeedFromLensDepth(d.frame, shifted, &out);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.error().message.find("lattice"), std::string::npos) << t.error().message;
}

// LensSeed::skip (the live chain's dense_for_tf_only): the micro images
// whose TF depth comes from their lens depth keep the map's initial values
// (no depth, not textured, nothing searched); every other micro image gets
// the map it gets without the skip, value for value, where no micro image
// is filled from its neighbours (step 5's second part, the one that reads
// another micro image's estimates). A skip of another frame's size is
// refused.
TEST_F(SeededDepth, SkippedMicroImagesKeepNoDepthAndTheOthersTheirMap) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  LensSeed seed = d.seed;
  LensesHeldForTf(d.frame, seed, &seed.skip);
  ASSERT_EQ(seed.skip.size(), d.frame.lenses.size());
  long long skipped = 0;
  for (const std::uint8_t held : seed.skip) skipped += held;
  ASSERT_GT(skipped, static_cast<long long>(d.frame.lenses.size()) / 20);  // 293 of 3670
  ASSERT_LT(skipped, static_cast<long long>(d.frame.lenses.size()));
  DepthOptions o;
  o.fill_from_neighbours = false;
  VirtualDepthMap whole, part;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &d.seed, &whole).ok());
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &seed, &part).ok());
  EXPECT_EQ(part.stats.skipped_lenses, skipped);
  EXPECT_EQ(whole.stats.skipped_lenses, 0);
  EXPECT_LT(part.stats.searched, whole.stats.searched);
  EXPECT_LT(part.stats.textured_pixels, whole.stats.textured_pixels);
  long long in_skipped = 0, with_depth = 0;
  for (std::size_t i = 0; i < part.virtual_depth.size(); ++i) {
    const std::int32_t k = d.frame.lens_of_pixel[i];
    if (k >= 0 && seed.skip[k]) {
      ++in_skipped;
      ASSERT_TRUE(std::isnan(part.virtual_depth[i])) << "pixel " << i;
      ASSERT_EQ(part.textured[i], 0) << "pixel " << i;
      ASSERT_EQ(part.confidence[i], 0.0f) << "pixel " << i;
      continue;
    }
    const float a = part.virtual_depth[i], b = whole.virtual_depth[i];
    ASSERT_TRUE((std::isnan(a) && std::isnan(b)) || a == b) << "pixel " << i;
    const float sa = part.sigma_z[i], sb = whole.sigma_z[i];
    ASSERT_TRUE((std::isnan(sa) && std::isnan(sb)) || sa == sb) << "pixel " << i;
    ASSERT_EQ(part.textured[i], whole.textured[i]) << "pixel " << i;
    with_depth += !std::isnan(a);
  }
  EXPECT_GT(in_skipped, 0);
  EXPECT_GT(with_depth, 0);
  // A reused seed made again by SeedFromLensDepth skips nothing.
  ASSERT_TRUE(SeedFromLensDepth(d.frame, d.lens, &seed).ok());
  EXPECT_TRUE(seed.skip.empty());
  seed.skip.assign(3, 1);
  VirtualDepthMap m;
  const Status s = EstimateVirtualDepth(d.frame, d.s.mla, o, &seed, &m);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("skip"), std::string::npos) << s.error().message;
}

// A flat micro image (its and its ring-1 neighbours' seeds within
// seed_flat_px of ring-1 disparity) searches a sparser lattice; steps 4 and
// 5 give the pixels between its surface. On `small` (16 px: no flat
// lattice by default) with seed_flat_stride 2: fewer pixels searched, the
// accuracy within 1 % absolute of the seeded map's; seed_flat_px 0: none
// flat, the default map exactly.
TEST_F(SeededDepth, FlatMicroImagesSearchASparserLattice) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  VirtualDepthMap base;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &d.seed, &base).ok());
  EXPECT_EQ(base.stats.flat_lenses, 0);
  DepthOptions o;
  o.seed_flat_stride = 2;
  VirtualDepthMap sparse;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &d.seed, &sparse).ok());
  ExpectWithinOnePercent("seeded", base, "seeded, flat lattice 2", sparse);
  EXPECT_GT(sparse.stats.flat_lenses, 0);
  EXPECT_LT(sparse.stats.searched, base.stats.searched);
  o.seed_flat_px = 0;
  VirtualDepthMap off;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &d.seed, &off).ok());
  EXPECT_EQ(off.stats.flat_lenses, 0);
  EXPECT_EQ(off.stats.searched, base.stats.searched);
  EXPECT_EQ(off.stats.estimated, base.stats.estimated);
}

// The coarse lattice first: a lattice point whose coarse neighbours within
// two lattice steps agree (seed_interp_spread) takes their mean instead of
// a search. On `small` (every textured pixel on the lattice, the coarse one
// every second): fewer pixels searched, the accuracy within 1 % absolute of
// the map that searches every lattice point; seed_interp_spread 0: none
// taken so, every lattice point searched.
TEST_F(SeededDepth, CoarseLatticeDecidesSmoothPoints) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  DepthOptions o;
  o.seed_interp_spread = 0;
  VirtualDepthMap all;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, o, &d.seed, &all).ok());
  EXPECT_EQ(all.stats.interpolated, 0);
  VirtualDepthMap coarse;
  ASSERT_TRUE(EstimateVirtualDepth(d.frame, d.s.mla, DepthOptions{}, &d.seed, &coarse).ok());
  ExpectWithinOnePercent("seeded, every lattice point searched", all,
                         "seeded, the coarse lattice first", coarse);
  EXPECT_GT(coarse.stats.interpolated, 0);
  EXPECT_LT(coarse.stats.searched, all.stats.searched);
}

// The texture gate runs whole vectors past each chord's end (virtual_depth.cpp,
// GateRow): every pixel's `textured` flag is the gate's rule evaluated for
// that pixel alone (its own micro image's, valid, with a gradient, the
// largest |g . e| over its micro image's ring-1 axes at least min_gradient_dn),
// over the rows and chords the gate covers, micro images at the frame's
// edges included.
TEST_F(SeededDepth, TexturedFlagsAreTheGatesRulePerPixel) {
  ASSERT_NE(shared_, nullptr);
  const Shared& d = *shared_;
  const PlenopticFrame& f = d.frame;
  VirtualDepthMap seeded;
  const DepthOptions options;
  ASSERT_TRUE(EstimateVirtualDepth(f, d.s.mla, options, &d.seed, &seeded).ok());
  const int w = f.width, h = f.height;
  const float threshold = static_cast<float>(options.min_gradient_dn);
  ASSERT_EQ(static_cast<double>(threshold), options.min_gradient_dn);
  std::vector<std::uint8_t> expected(static_cast<std::size_t>(w) * h, 0);
  const double r = f.radius_px;
  for (int k = 0; k < static_cast<int>(f.lenses.size()); ++k) {
    const MicroImage& lens = f.lenses[k];
    std::array<detail::Neighbour, 12> nbs;
    int ring1 = 0;
    detail::FindNeighbours(f, lens, options.rings, &nbs, &ring1);
    std::array<float, 3> ex{}, ey{};
    for (int m = 0; m < ring1; ++m) ex[nbs[m].axis] = nbs[m].e_x, ey[nbs[m].axis] = nbs[m].e_y;
    const double cx = lens.centre_px.x(), cy = lens.centre_px.y();
    const int x0 = std::max(1, static_cast<int>(std::ceil(cx - r)));
    const int x1 = std::min(w - 2, static_cast<int>(std::floor(cx + r)));
    const int y0 = std::max(1, static_cast<int>(std::ceil(cy - r)));
    const int y1 = std::min(h - 2, static_cast<int>(std::floor(cy + r)));
    for (int y = y0; y <= y1; ++y) {
      const double dy = y - cy, chord2 = r * r - dy * dy;
      if (chord2 < 0) continue;
      const double half = std::sqrt(chord2);
      const int xa = std::max(x0, static_cast<int>(std::floor(cx - half)));
      const int xb = std::min(x1, static_cast<int>(std::ceil(cx + half)));
      for (int x = xa; x <= xb; ++x) {
        const std::size_t at = static_cast<std::size_t>(y) * w + x;
        if (f.lens_of_pixel[at] != k || std::isnan(f.grey[at])) continue;
        const float gx = 0.5f * (f.grey[at + 1] - f.grey[at - 1]);
        const float gy = 0.5f * (f.grey[at + w] - f.grey[at - w]);
        if (std::isnan(gx) || std::isnan(gy)) continue;
        float g = 0;
        for (int m = 0; m < 3; ++m) g = std::max(g, std::abs(gx * ex[m] + gy * ey[m]));
        expected[at] = g >= threshold;
      }
    }
  }
  long long textured = 0, differ = 0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    textured += expected[i];
    differ += expected[i] != seeded.textured[i];
  }
  EXPECT_GT(textured, 0);
  EXPECT_EQ(textured, seeded.stats.textured_pixels);
  EXPECT_EQ(differ, 0);
}

TEST(SeededDepthOptions, CheckNamesTheField) {
  DepthOptions o;
  o.seed_search_stride = -1;
  ASSERT_FALSE(o.Check().ok());
  EXPECT_NE(o.Check().error().message.find("seed_search_stride"), std::string::npos);
  o = DepthOptions{};
  o.seed_cost_ratio = 0;
  EXPECT_NE(o.Check().error().message.find("seed_cost_ratio"), std::string::npos);
  o = DepthOptions{};
  o.seed_margin_px = -1;
  EXPECT_NE(o.Check().error().message.find("seed_margin_px"), std::string::npos);
  o = DepthOptions{};
  o.seed_ring1_lines = 2;
  ASSERT_FALSE(o.Check().ok());
  EXPECT_NE(o.Check().error().message.find("seed_ring1_lines"), std::string::npos);
  o = DepthOptions{};
  o.seed_ring2_lines = 2;
  ASSERT_FALSE(o.Check().ok());
  EXPECT_NE(o.Check().error().message.find("seed_ring2_lines"), std::string::npos);
  o = DepthOptions{};
  o.seed_flat_stride = 9;
  ASSERT_FALSE(o.Check().ok());
  EXPECT_NE(o.Check().error().message.find("seed_flat_stride"), std::string::npos);
  o = DepthOptions{};
  o.seed_flat_px = -1;
  ASSERT_FALSE(o.Check().ok());
  EXPECT_NE(o.Check().error().message.find("seed_flat_px"), std::string::npos);
  // The coarse lattice's options, each out of range alone.
  DepthOptions spread, least;
  spread.seed_interp_spread = -0.01;
  least.seed_interp_min = 0;
  for (const auto& [bad, field] : {std::pair{spread, "seed_interp_spread"},
                                   std::pair{least, "seed_interp_min"}}) {
    const Status st = bad.Check();
    ASSERT_FALSE(st.ok()) << field;
    EXPECT_NE(st.error().message.find(field), std::string::npos) << st.error().message;
  }
}

}  // namespace
}  // namespace lifmcr::processing
