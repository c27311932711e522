#pragma once
// One virtual depth per micro lens, cheap enough for every frame
// (docs/processing.md, "Per-lens virtual depth").
//
// For micro image k (centre c_k, type t) of the raw frame, read directly
// from the raw pixels times the devignetting gain (no devignetted or
// smoothed copy of the frame is made; a BGR8 frame is read through its
// 8-bit grey plane, LensDepthOptions::grey_plane):
// 1. Candidates: pixels on a square grid of candidate_step_px within
//    candidate_fraction r_valid of c_k; each scored by its largest gradient
//    along the three ring-1 axes, |g . e_d| (central differences of the raw
//    grey times the gain at c_k: the gain varies little over the
//    candidates, and the gate needs no precision). Those with a score >=
//    min_gradient_dn are textured (a micro image with at least one is a
//    textured lens); the `samples` best are searched, most textured first,
//    until enough_estimates of the estimates so far agree (step 3's fusion).
// 2. Per searched pixel p, on its best ring-1 axis: the two ring-1
//    neighbours along it (both of the other types), the epipolar search of
//    processing/epipolar_search.h over the union of the MLA file's depth
//    ranges in steps of ring1_step_px with a patch of ring1_lines lines,
//    first the neighbour that sees the whole patch over more of the range;
//    the second only if none has found a depth z yet or it sees the patch
//    at z (a step either side). Then, around their fusion (+- 3 sigma, at
//    least two steps), the ring-2 neighbours (|Delta| = sqrt(3) D, the
//    same type) that see the patch at z, on the ring-2 axis with the
//    largest gradient among those with one, in steps of ring2_step_px
//    (5 x 3). A neighbour that does not see the patch at the depth finds
//    its minimum at the end of its run and fails: skipping it changes
//    nothing but the time, and choosing the ring-2 axis so gives more
//    ring-2 estimates (on a micro image's small virtual depths most ring-2
//    neighbours see a pixel at no depth near z).
// 2a. The temporal seed (Estimate with the previous frame's map): where the
//    micro image's cell has a previous depth z_p, step 1's two most
//    textured pixels in turn are searched around z_p only (+-
//    max(seed_window z_p, 3 sigma_z, 2 steps)) on the axes with a neighbour
//    that sees the pixel's patch at z_p and a gradient along them of at
//    least min_gradient_dn: the best ring-2 axis, then the ring-1 axes
//    (5 x 1: cheap), then the other ring-2 axes, until two estimates. It
//    holds when they agree (step 3's fusion) and their fusion lies within
//    fuse_gate z_p of z_p: the lens takes that fusion (sigma_z also from
//    its spread to z_p) and is not searched further. Where it does not hold
//    (a depth edge moved through the lens, the camera was knocked) step 2
//    runs from nothing, the seeded estimates dropped: such a lens gets the
//    map it gets without a seed. What it costs and saves:
//    docs/processing.md, "Temporal seed".
// 2b. The neighbours' depth (LensDepthOptions::neighbour_seed, without a
//    previous map): the lenses are estimated by type in three passes, type
//    0 from nothing (steps 2, 3), then type 1 and then type 2, each lens
//    seeded by its ring-1 neighbours of the types before its own (three of
//    type 0 for type 1, all six for type 2; a scene's depth varies little
//    over one pitch, and a neighbour on each side brackets a slope). Their
//    depth z_n: the mean z of those within fuse_gate of their median,
//    where at least two have a depth and at most one lies outside. Then on
//    up to kSeedPixels (2) of step 1's most textured pixels in turn, one
//    search around z_n (+- max(seed_window z_n, 3 spread, 2 steps)): on the
//    best ring-2 axis with a neighbour that sees the patch at z_n, else on
//    the pixel's ring-1 axis (5 x 1). It holds when its estimates (one per
//    neighbour on the axis that sees the patch) agree and their fusion lies
//    within fuse_gate z_n of z_n: the lens takes that fusion, its own
//    measurement (sigma_z also from its spread to z_n). Else step 2 from
//    nothing. One search instead of about three and a half, the neighbours'
//    agreement standing for the second estimate: a lens whose neighbours
//    straddle a depth edge is searched from nothing (they disagree), one
//    whose own estimate lies more than fuse_gate from theirs too (figures:
//    docs/processing.md, "Per-lens virtual depth").
// 3. All estimates of the micro image (up to 4 per searched pixel) are fused
//    in z = 1 / v weighted by 1 / sigma^2, without those farther than
//    max(3 sigma, fuse_gate z) from their median; at least min_estimates
//    agreeing. The pixels are not independent views of one point, so
//      sigma_z^2 = max(1 / sum w, sum w (z_i - z)^2 / (sum w (n - 1)))
//    (the fused variance, or the estimates' weighted spread over n - 1 when
//    larger); rejected when sigma_z / z > max_rel_sigma;
//    confidence = clamp(1 - (sigma_z / z) / max_rel_sigma, 0, 1).
// What v means: the virtual depth of the scene the micro image sees at its
// most textured pixels (one surface unless the lens straddles a depth edge).
//
// The lens grid (LensGrid): lens (i, j) of the lattice (mla_grid.h) is cell
//   row = j_top - j,   col = i + floor(j / 2) - col_base
// of a cols x rows image: with the lattice's i step along the rows and its
// j step half a pitch sideways and one row up (a RayCalibData file's hex
// bases), rows run down the image and a column stays within half a pitch
// of one image x, so the micro images fill the grid without gaps.
// Inverse: j = j_top - row, i = col + col_base - floor(j / 2); centre
// c(i, j) = o + A (i, j)^T. The virtual point that lens k's micro-image
// centre sees at depth v is x_v = p + (lambda + v (1 - lambda)) (c_k - p),
// p the principal point (tf_kernel.h), on TF pixel (x_v - 0.5) / 2
// (total_focus.h).
//
// The candidate gate's gradients (step 1) and the searches' strip sampling
// and SSD (step 2) run through the kernels of processing/lens_search_simd.h
// (LensDepthOptions::simd: Highway's or the scalar reference; the same
// numbers, so the same map) wherever the pixels they read lie well inside
// the frame, through the scalar code here and in epipolar_search.h
// elsewhere.
//
// Work is parallel over micro images (TBB), in the passes of step 2b; each
// cell is written once. Without step 2b the lines a lens's searches read
// first are asked of the cache two lenses ahead (Estimate). Estimate
// allocates nothing once `out` has the grid's size (a workspace reused
// frame after frame) and each thread has estimated once (its candidate-gate
// buffer).

#include "config/error.h"
#include "config/image.h"
#include "config/mla.h"
#include "processing/plenoptic_frame.h"
#include "processing/total_focus.h"

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace lifmcr::processing {

namespace detail {
class TfKernel;
struct Gain16;
}

struct LensDepthOptions {
  int samples = 6;           // most textured pixels searched per micro image, at most
  int enough_estimates = 2;  // agreeing estimates after which no further pixel is searched
  // Spacing of the candidate grid; 0: the pitch / 11 rounded, at least 1
  // (3 px on an R32's 34 px micro images, 1 px on 16 px ones).
  double candidate_step_px = 0;
  double candidate_fraction = 0.6;  // candidates within this share of r_valid
  double min_gradient_dn = 5.0;     // |dI/de| (DN per px, devignetted grey) to be textured
  double noise_dn = 2.5;            // sigma_I of the raw grey level
  double ring1_step_px = 1.0;       // disparity step of the ring-1 search: 1, 0.5 or 0.25
  double ring2_step_px = 1.0;       // of the ring-2 search around the ring-1 result
  // Lines of the ring-1 patch: 1 (5 x 1: a third of the samples; ring 2
  // refines with 5 x 3) or 3.
  int ring1_lines = 1;
  int rings = 2;                // 1 or 2
  double geometric_px = 0.05;   // sigma_model of a pair of one type
  double cross_type_px = 0.3;   // of two types (their different blur)
  double max_cost_ratio = 0.5;  // best SSD <= ratio * mean SSD of the search (+ noise)
  double fuse_gate = 0.05;      // outlier gate of the fusion, share of z
  int min_estimates = 2;        // agreeing estimates per micro image
  double max_rel_sigma = 0.1;   // sigma_z / z above this: rejected
  // The temporal seed (Estimate with a previous map): the search around a
  // lens's previous depth spans +- max(seed_window z, 3 sigma_z, 2 steps).
  double seed_window = 0.05;
  // The lenses of types 1 and 2 searched first around the depth of their
  // type-0 ring-1 neighbours, estimated first (step 2b of the header
  // comment); false: every lens from nothing. Only without a previous map.
  // Off by default: it saves instructions, not CPU time (the estimator waits
  // on the first touch of every micro image's lines either way), and on a
  // quiet machine it cost more (docs/processing.md, "Neighbours' depth").
  bool neighbour_seed = false;
  // The candidate gate and the searches' strip sampling and SSD through
  // Highway's runtime dispatch (processing/lens_search_simd.h); false: the
  // scalar reference (the same map, at its speed).
  bool simd = true;
  // A BGR8 frame read through its grey plane (grey_plane_simd.h: the
  // channel mean rounded, one byte a pixel, made once per frame into the
  // map's scratch, LensDepthMap::grey) instead of its three channels: the
  // searches' lines are a third of the bytes. false: the channels (their
  // exact sum). Mono8 frames are read as they are either way.
  bool grey_plane = true;
  Status Check() const;  // every field; the message names the field
};

// The layout of the lens grid (header comment).
struct LensGrid {
  int cols = 0, rows = 0;
  int j_top = 0, col_base = 0;
  Eigen::Vector2d origin_px = Eigen::Vector2d::Zero();    // o: centre of lens (0, 0)
  Eigen::Matrix2d lattice = Eigen::Matrix2d::Identity();  // A
  int type_sign = 1;                                      // type = (sigma (i - j)) mod 3
  double lambda = 1;                                      // b_L0 / (b_L0 + B) of l_k
  Eigen::Vector2d principal_point_px = Eigen::Vector2d::Zero();

  static int FloorHalf(int j) { return j >= 0 ? j / 2 : -((1 - j) / 2); }
  int Col(int i, int j) const { return i + FloorHalf(j) - col_base; }
  int Row(int j) const { return j_top - j; }
  void Lens(int col, int row, int* i, int* j) const {
    *j = j_top - row;
    *i = col + col_base - FloorHalf(*j);
  }
  Eigen::Vector2d Centre(int col, int row) const {
    int i = 0, j = 0;
    Lens(col, row, &i, &j);
    return origin_px + lattice * Eigen::Vector2d(i, j);
  }
  // The layout of the micro images of `geometry` (PrepareGeometry done).
  static LensGrid Of(const PlenopticFrame& geometry);
};

struct LensDepthStats {
  long long lenses = 0;     // micro images of the frame
  long long textured = 0;   // with a textured candidate
  long long estimated = 0;  // with a virtual depth
  long long searched_pixels = 0;
  long long seeded = 0;     // with a previous depth (Estimate with a previous map)
  long long seed_held = 0;  // of those, where it held (no full search)
  long long predicted = 0;       // seeded by their neighbours' depth (step 2b)
  long long predicted_held = 0;  // of those, where it held
  double seconds = 0;
  // The kernels that ran (lens_search_simd.h): "scalar" or Highway's target
  // ("AVX3", "AVX2", "SSE4", "NEON", ...); "" when none could (a frame of 2 GB or more).
  const char* kernels = "";
  // "lens depth: 30112 of 31980 textured lenses (94.2 %; 32385 lenses), 1.2e5 pixels searched,
  // 0.041 s, kernels AVX3[, previous depth held in 25000 of 29000 lenses]"
  std::string BriefReport() const;
};

struct LensDepthMap {
  LensGrid grid;
  std::vector<float> virtual_depth;    // per cell, row-major; NaN: no estimate
  std::vector<float> sigma_z;          // of z = 1 / v; NaN: no estimate
  std::vector<float> confidence;       // 0..1; 0 without an estimate
  std::vector<std::int8_t> type;       // lens type, -1: no micro image in the cell
  std::vector<std::uint8_t> textured;  // 1: a textured candidate
  std::vector<std::int32_t> lens;      // index into the geometry's lenses, -1: none
  LensDepthStats stats;
  std::vector<float> filled_v, fill_scratch;  // scratch of RenderPreview
  // Scratch of Estimate: a BGR8 frame's grey plane (LensDepthOptions::
  // grey_plane), the frame's size, reused frame after frame.
  std::vector<std::uint8_t> grey;
  std::size_t Cell(int col, int row) const {
    return static_cast<std::size_t>(row) * grid.cols + col;
  }
};

// The median over each micro image's pixels (lens_of_pixel) of a map on the
// raw grid (NaN: none; cells with fewer than min_share of their pixels
// finite get NaN): the per-lens value of a per-pixel virtual depth (the
// ground truth of `lifmcr synth`, the dense map) on `grid`.
void LensMedianOf(const PlenopticFrame& geometry, const LensGrid& grid,
                  const std::vector<float>& raw_grid, double min_share, std::vector<float>* out);

// The seed of the dense search (virtual_depth.h) from the per-lens depth:
// per micro image of `frame` (matched to its cell by its lattice indices
// (i, j)), z = 1 / v and sigma_z of its cell; NaN where the cell has no
// estimate or lies outside the map. An error when the map's lattice is not
// the frame's (a cell centre more than 0.5 px from the micro image's).
// `out` is reused.
Status SeedFromLensDepth(const PlenopticFrame& frame, const LensDepthMap& lens, LensSeed* out);

// Per camera: the geometry (PrepareGeometry done; the grey image is not
// needed) and the options, fixed; immutable and shared by threads.
class LensDepthEstimator {
 public:
  static Expected<std::unique_ptr<LensDepthEstimator>> Create(PlenopticFrame geometry,
                                                              const MlaCalibration& mla,
                                                              const LensDepthOptions& options);
  ~LensDepthEstimator();
  LensDepthEstimator(const LensDepthEstimator&) = delete;
  LensDepthEstimator& operator=(const LensDepthEstimator&) = delete;

  // The per-lens depth of `raw` (Mono8 or BGR8, the geometry's size).
  // `previous`: the per-lens depth of this camera's previous frame (or one
  // warped into this frame), the temporal seed of step 2a (header comment);
  // an error when it is not of this camera's lens grid or is `out`.
  Status Estimate(ConstImageView raw, LensDepthMap* out,
                  const LensDepthMap* previous = nullptr) const;

  // The TF image at each lens's own depth, point-sampled on a grid of
  // max_side pixels on its longest side (the TF grid's size if smaller)
  // over the TF grid (W/2 x H/2): output pixel (a, b) is the TF position
  // ((a + 1/2) s - 1/2, (b + 1/2) s - 1/2), s = max(1, max(W/2, H/2) /
  // max_side), the size round(W/2 / s) x round(H/2 / s); rendered by the rule of
  // tf_kernel.h at the virtual depth v of the micro image nearest to the
  // position of the micro images that see it at v (tf_kernel.h's
  // LookingAt; two rounds from the frame's median v) (holes in the map: the
  // mean of their ring-1 neighbours' depths, twice; then the frame's
  // median). BGR8 for BGR8 frames, else Mono8.
  Status RenderPreview(ConstImageView raw, int max_side, LensDepthMap* depth, TfImage* out) const;

  // The camera's geometry without its smoothed grey image and float gain
  // (this estimator reads the gain in 16 bits: lens_search_simd.h, Gain16).
  const PlenopticFrame& geometry() const { return geometry_; }
  const LensDepthOptions& options() const { return options_; }
  // The lattice's neighbour steps and axes, the same for every lens (lens_depth.cpp).
  struct LatticeTables;

 private:
  LensDepthEstimator() = default;
  PlenopticFrame geometry_;
  MlaCalibration mla_;
  LensDepthOptions options_;
  LensGrid grid_;
  std::unique_ptr<detail::TfKernel> kernel_;
  std::vector<std::array<std::int16_t, 2>> candidates_;  // offsets of step 1
  // The same as columns for the gate kernel (lens_search_simd.h), padded.
  std::vector<std::int32_t> candidate_dx_, candidate_dy_;
  int candidate_reach_ = 0;
  std::unique_ptr<LatticeTables> tables_;
  // The searches' devignetting gain in 16 bits (lens_search_simd.h).
  std::unique_ptr<detail::Gain16> gain_;
  // The micro images by lens-grid row and type: those of row r and type t
  // are by_row_type_[row_type_start_[3 r + t] .. row_type_start_[3 r + t + 1])
  // (the passes of step 2b in bands of rows).
  std::vector<std::int32_t> by_row_type_;
  std::vector<std::int32_t> row_type_start_;
};

}  // namespace lifmcr::processing
