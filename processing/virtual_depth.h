#pragma once
// Semi-dense virtual depth from one raw frame (docs/processing.md;
// Zeller's probabilistic virtual depth, written in our own terms).
//
// A virtual point x_v at virtual depth v appears in micro image k at
//   p_k = l_k + (x_v - l_k) / v         (l_k micro-lens centre, camera_model.h)
// so a pixel p of micro image k appears in neighbour n at
//   q(z) = p + lambda (c_n - c_k) (1 - z),   z = 1 / v,
// a line (the epipolar line) along the baseline Delta = c_n - c_k.
// Per pixel of micro image k (type t) with enough gradient along Delta, on
// the devignetted grey image smoothed within each micro image
// (plenoptic_frame.h):
// 1. Search z over the virtual-depth range of the MLA file's lens types
//    (the union of their depth ranges; with type_ranges, only type t's own
//    sharp range), in steps of step_px of disparity, minimising the SSD of a
//    5 x 3 patch sampled along x across the epipolar line (bilinear), every
//    sample inside the micro images' discs; the minimum must lie strictly
//    inside the searched run and be distinct (<= max_cost_ratio of the run's
//    mean cost, plus noise); a parabola through the three costs around it
//    gives the sub-step position. The patch positions of all steps lie on
//    three lines along Delta at step_px spacing, so the neighbour is sampled
//    once per line (a strip) and step k reads the strip at shift k.
// 2. Uncertainty (in z, where the noise is near Gaussian):
//    sigma_px^2 = 2 sigma_I^2 / sum (g_e)^2 + sigma_model^2,
//    sigma_z = sigma_px / (lambda |Delta|)
//    (g_e: differences of the patch along the epipolar line; sigma_model =
//    geometric_px for a pair of the same lens type, cross_type_px for two
//    types, whose different defocus biases the match).
// 3. Baselines from short to long: ring 1 (6 neighbours, |Delta| = D, all of
//    other types; the max_ring1 with the strongest gradient along them), then ring 2 (|Delta| =
//    sqrt(3) D, the same type) searched within z +- 3 sigma of the ring-1 fusion (the whole range
//    when ring 1 gave nothing). Fusion in z weighted by 1 / sigma^2 (product of Gaussians);
//    estimates farther than max(3 sigma, 3 % of z) from the median are outliers.
// 4. A pixel with at least min_estimates fused estimates and sigma_z / z <=
//    max_rel_sigma is regularised within its micro image: the inverse-
//    variance mean of the estimates within smooth_radius_px that agree with
//    their median (max(3 sigma, 5 %)); fewer than min_support agreeing, or
//    the pixel itself disagreeing: rejected (outlier). With search_stride 2
//    only a checkerboard of pixels is searched and the textured pixels
//    between them get the same regularised value (a pixel whose own search
//    failed gets none). confidence =
//    clamp(1 - (sigma_z / z) / max_rel_sigma, 0, 1).
// 5. Untextured pixels (fill_min_support > 0): where the window of step 4
//    around an untextured pixel of the micro image holds at least
//    fill_min_support agreeing estimates whose inverse-variance spread in z
//    is within fill_max_spread of their mean (one surface, no depth edge),
//    the pixel gets that mean, with sigma the larger of the estimates'
//    harmonic-mean sigma and their spread; `textured` stays 0 there, so a
//    consumer can tell searched from filled pixels. Textured pixels whose
//    search failed are filled alike. With fill_from_neighbours, a micro
//    image left without any depth takes, by the same rule, the surface its
//    ring-1 neighbours' estimates agree on (at least 3 of them contributing
//    fill_min_support each): for v > 2 neighbouring micro images image
//    overlapping patches of the scene.
// Seeded (EstimateVirtualDepth with a LensSeed, the per-lens virtual depth of
// processing/lens_depth.h): step 1's ring-1 search of every pixel of micro
// image k covers only
//   [min_i (z_i - seed_sigmas sigma_i) - m, max_i (z_i + seed_sigmas sigma_i) + m]
// (i over k and its ring-1 neighbours with a seed: a depth edge crosses
// micro images, so a pixel of k may see its neighbour's surface;
// m = seed_margin_px / (lambda D), D the ring-1 baseline), clipped to the
// searched range. Fallback to the full range: for every pixel of a micro
// image without a seed of its own (its pixels are searched as without a
// seed), and for a pixel none of whose narrow ring-1 searches found a clear
// minimum (MatchAlong's tests: the least cost strictly inside the narrow run
// and <= seed_cost_ratio of its mean cost, plus noise; a wrong seed puts
// the least cost on the window's edge or leaves no distinct one): the same
// baselines over the whole range, while the micro image's pixels searched
// so far (in row order) missed in their windows at least twice as often as
// they found a minimum there. A wrong seed misses (nearly) every pixel, so
// they are all searched again; with a right one the misses are pixels
// without a clear minimum anywhere (too little texture along their
// baselines), which the full search loses too. With a seed, seed_max_ring1 ring-1 and
// seed_max_ring2 ring-2 baselines are searched per pixel and a lattice of
// seed_search_stride (seed_flat_stride on a flat micro image; below), the
// ring-1 searches in the window on the
// patch's middle line (5 x 1, seed_ring1_lines), and ring 2 around their
// estimate too (seed_ring2_lines); a pixel whose window found
// no minimum and did not fall back searches ring 2 in the window too (with
// seed_cost_ratio), not over the whole range; the lattice's coarse points
// (every second line) are searched first, and a point between them whose
// coarse estimates within two lattice steps agree takes their mean instead
// of a search (seed_interp_spread); steps 2-5 are those of the full search.
// The strips are sampled and their costs summed by the kernels of
// processing/lens_search_simd.h (DepthOptions::simd: Highway's or the
// scalar reference, the same numbers) wherever the neighbour's disc lies
// well inside the frame.
// Work is parallel over micro images (TBB); each pixel is written once. A
// micro image's buffers are its thread's (no allocation per micro image,
// none per frame after the first); step 4's summed-area tables span only
// its estimates' bounding rectangle.

#include "config/error.h"
#include "config/mla.h"
#include "processing/plenoptic_frame.h"

#include <cstdint>
#include <string>
#include <vector>

namespace lifmcr::processing {

struct DepthOptions {
  double min_gradient_dn = 5.0;  // |dI/de| (DN per px, devignetted grey) to be "textured"
  double noise_dn = 2.5;         // sigma_I of the raw grey level
  double geometric_px = 0.05;    // sigma_geo: grid-calibration uncertainty
  double step_px = 0.5;          // disparity step of the search: 1, 0.5 or 0.25
  // 1: search every textured pixel; 2: a checkerboard, the other half filled
  // by the regularisation; 0: 2 for micro images of 24 px and more (their
  // neighbouring pixels are redundant), else 1.
  int search_stride = 0;
  int max_ring1 = 6;            // ring-1 baselines searched per pixel (strongest gradient first)
  int max_ring2 = 6;            // ring-2 baselines likewise
  int rings = 2;                // 1 or 2
  double cross_type_px = 0.3;   // model error of a pair of different lens types (blur)
  // Pairs of two lens types: the sharper side blurred to the other's defocus
  // at each searched depth before the SSD (epipolar_search.h, EqualisedCosts).
  bool equalise_defocus = false;
  int smooth_radius_px = 4;     // regularisation window within a micro image
  int min_support = 3;          // agreeing estimates in that window (the pixel included)
  int min_estimates = 1;        // agreeing estimates per pixel
  double max_cost_ratio = 0.5;  // best SSD <= ratio * mean SSD of the search (+ noise)
  double max_rel_sigma = 0.1;   // sigma_z / z above this: rejected
  bool type_ranges = false;     // search only the lens type's sharp range; else the union
  int fill_min_support = 8;     // step 5: agreeing estimates to fill an untextured pixel; 0 off
  // Step 5: their largest spread, SD(z) / z: step 4's agreement tolerance, so
  // a micro image's estimates with the estimator's own noise pass and two
  // surfaces (a depth edge) do not.
  double fill_max_spread = 0.05;
  int fill_radius_px = 0;       // step 5: half-size of the support window; 0 the whole micro image
  bool fill_from_neighbours = true;  // step 5: micro images without depth from their ring 1
  // Seeded search (header comment): the window around the seeds, in their
  // sigma and in px of ring-1 disparity beyond that.
  double seed_sigmas = 3.0;
  double seed_margin_px = 1.0;
  // Seeded: baselines searched per pixel (ring 1 in the window, ring 2
  // around its result; the seed has settled which minimum is the surface,
  // so fewer baselines suffice), and the distinctness of a narrow search's
  // minimum (best SSD <= ratio * mean SSD of the window, plus noise: the
  // window holds the minimum's own flanks, so its mean is lower than a
  // full run's).
  // Seeded: the searched pixels of micro images with a seed, one of every
  // seed_search_stride x seed_search_stride block (1: all textured pixels;
  // the regularisation of step 4 gives the others between them their
  // window's value; step 5's fill_min_support is scaled by this lattice's
  // density against the full search's, at least 3); 0: 3 for micro images
  // of 32 px and more (an R32's 34 px: a 9 x 9 window of step 4 still holds
  // 9 lattice pixels), 2 for 24 px and more, else 1.
  int seed_search_stride = 0;
  // Seeded: a flat micro image (its own and its six ring-1 neighbours'
  // seeds present, the window [min (z - 3 sigma), max (z + 3 sigma)] over
  // them at most seed_flat_px of ring-1 disparity wide: one confident
  // surface) searches one pixel of every seed_flat_stride x
  // seed_flat_stride block; steps 4 and 5 give the others its surface
  // (step 4's min_support scaled by the lattice's density against
  // seed_search_stride's, at least 2: one estimate alone lets outliers
  // through). seed_flat_px 0: none is flat; seed_flat_stride 0: 4 for micro
  // images of 32 px and more (on the r32 frame 5 covered 1.8 % fewer
  // textured pixels), 3 for 24 px and more, else seed_search_stride's.
  int seed_flat_stride = 0;
  double seed_flat_px = 3.0;
  int seed_max_ring1 = 2;
  int seed_max_ring2 = 2;
  // Seeded: the lines of the window's ring-1 patch, 1 (5 x 1) or 3 (5 x 3);
  // 0: 1 for micro images of 24 px and more, else 3. The seed has placed
  // the surface, so on large micro images one line locates the minimum in
  // the window and ring 2's 5 x 3 patch refines it; on small ones (16 px)
  // one line finds no clear minimum for a quarter of the pixels, which then
  // fall back to the full range. The fallback searches 5 x 3.
  int seed_ring1_lines = 0;
  // Seeded: the lines of ring 2's patch where the pixel's ring-1 estimates
  // centre its search (within max(3 sigma, 2 steps) of them), 1 or 3; 0:
  // 1 for micro images of 24 px and more, else 3. There the ring-1 window
  // has placed the minimum, and ring 2 refines it on a longer baseline: on
  // `r32` and `medium` one line costs 6-9 % less CPU per frame for a
  // coverage 0.2-0.3 % lower and fewer outliers (docs/processing.md). Ring 2
  // searched without such an estimate (in the window or the whole range)
  // matches 5 x 3.
  int seed_ring2_lines = 0;
  double seed_cost_ratio = 0.8;
  // Seeded: the lattice's every second line in x and y (the coarse
  // lattice, a quarter of its points) is searched first; another lattice
  // point whose coarse points within two lattice steps (Chebyshev) hold at
  // least seed_interp_min estimates, all agreeing (max z - min z <=
  // seed_interp_spread times their mean: a smooth surface over them), takes
  // their mean z and mean sigma without a search, as an estimate of its own
  // for step 4; the others are searched. seed_interp_spread 0: every
  // lattice point searched (the code before). On the `r32` frame 0.02 takes
  // 52 k of 414 k seeded lattice points so (docs/processing.md).
  double seed_interp_spread = 0.02;
  int seed_interp_min = 2;
  // Strip sampling and SSD through Highway's runtime dispatch
  // (processing/lens_search_simd.h); false: the scalar reference (the same
  // map, at its speed).
  bool simd = true;
  Status Check() const;
};

struct DepthStats {
  long long valid_pixels = 0;     // inside a micro image, devignetted
  long long textured_pixels = 0;  // with gradient >= min_gradient in some ring-1 direction
  long long estimated = 0;        // with a fused value
  long long rejected = 0;         // by the consistency check
  long long filled = 0;           // untextured pixels given their surface's depth (step 5)
  long long searched = 0;         // pixels searched (step 1)
  long long seeded = 0;           // of them searched in a seed's window
  long long fallback = 0;         // of those searched again over the full range
  long long flat_lenses = 0;      // seeded micro images searched on the flat lattice
  long long interpolated = 0;     // seeded lattice points given their coarse neighbours' mean
  long long skipped_lenses = 0;   // micro images not estimated (LensSeed::skip)
  double seconds = 0;
  const char* kernels = "";       // "scalar" or Highway's target (lens_search_simd.h)
  std::string BriefReport() const;
};

struct VirtualDepthMap {
  int width = 0, height = 0;
  std::vector<float> virtual_depth;    // v, NaN where no estimate
  std::vector<float> sigma_z;          // standard deviation of z = 1 / v
  std::vector<float> confidence;       // 0..1
  std::vector<std::uint8_t> textured;  // 1 where the gradient gate passed
  DepthStats stats;
};

// The virtual depths searched for a lens type: its depth_range, starting at
// 1.05 at the least (nearer the MLA no second micro image sees a point) and
// at least 0.1 wide.
struct VirtualDepthRange {
  double min = 0, max = 0;
};
VirtualDepthRange SearchedVirtualDepths(const MlaLensType& type);

// The seed of the seeded search: per micro image of the frame (the index
// into PlenopticFrame::lenses) z = 1 / v and sigma_z of the per-lens
// virtual depth, NaN where none (processing/lens_depth.h, SeedFromLensDepth).
struct LensSeed {
  std::vector<float> z, sigma_z;
  // Micro images whose dense pixels no consumer reads (1), or empty: none.
  // Such a micro image is neither gated nor searched: its pixels keep the
  // map's initial values (no estimate, not textured) and it lends its ring-1
  // neighbours no surface for step 5. The chain sets the micro images whose
  // TF depth comes from their lens depth (total_focus.h, LensesHeldForTf)
  // where only the TF products are read (ChainOptions::dense_for_tf_only).
  std::vector<std::uint8_t> skip;
};

// Estimates virtual depth on the raw grid; `out` buffers are reused. With
// `seed` (its size the frame's micro images), the seeded search.
Status EstimateVirtualDepth(const PlenopticFrame& frame, const MlaCalibration& mla,
                            const DepthOptions& options, VirtualDepthMap* out);
Status EstimateVirtualDepth(const PlenopticFrame& frame, const MlaCalibration& mla,
                            const DepthOptions& options, const LensSeed* seed,
                            VirtualDepthMap* out);

}  // namespace lifmcr::processing
