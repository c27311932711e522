#pragma once
// Totally focused (TF) image and the virtual depth on the TF grid
// (docs/processing.md; conventions of camera_model.h): the TF grid is
// W/2 x H/2 and TF pixel (u, w) is the virtual image at raw position
// x = (2u + 0.5, 2w + 0.5).
//
// Virtual depth on the TF grid: every raw estimate (pixel p of micro image k,
// virtual depth v) is the virtual point x_v = l_k + v (p - l_k); it is
// splatted to the TF pixel nearest to (x_v - 0.5) / 2 and the splats are
// fused in z = 1/v weighted by 1 / sigma_z^2 (a "measured" pixel, with that
// sigma_z). The map is regularised on cells of 4 x 4 TF pixels: the
// inverse-variance mean of z over a window of about smooth_radius, again
// over the measured pixels agreeing with their cell's mean within 5 %;
// cells without data take the mean of the valid cells within
// fill_iterations TF pixels; every TF pixel is then the bilinear
// interpolation of the valid cells around it (NaN where there are none).
// Window sums are separable and direct (2 (2 r + 1) adds per cell, r the
// window radius in cells: 2 by default), vectorised. The splats are
// computed in float a vector of raw pixels at a time (tf_splat_simd.h;
// TfOptions::simd) and summed in float, in bands of raw rows that write
// disjoint TF rows (no atomics); fallback_v is the median to 1/1024 of
// the measured pixels of every 4th TF row.
//
// With the frame's per-lens depth (lens_depth.h; the map that seeded the
// dense search) the splat reads far fewer raw pixels: a micro image whose
// lens depth holds (an estimate, and every ring-1 neighbour that exists has
// one within 5 % of its z: no depth edge through or beside it) is splatted
// as its lens depth alone, at TF points one cell (4 TF px) apart over a disc
// of radius pitch s / (2 sqrt 3) TF px (s = lambda + v (1 - lambda): the
// lens's share of the virtual image, its Voronoi cell there) around the
// virtual point its centre sees, x_v = l_k + v (c_k - l_k), each point
// weighted 1 / (n sigma_z^2) (n points, sigma_z the lens map's); the other
// micro images (depth edges, lenses without an estimate) splat their dense
// pixels as above on every n-th raw row, weighted n, n = max(4, pitch / 4
// px) (every 8th on an R32, every 4th on `small`). The splats are summed
// per cell directly (no per-TF-pixel sums), the second window mean is over
// the cells whose own mean lies within 5 % of their window's, and sigma_z
// is that of the cell's splats on every TF pixel of a cell with splats (so
// `measured` counts those pixels). On the r32 frame of bench_depth 11163 of
// 32895 micro images hold; PSNR against the all-in-focus truth 0.05 dB below
// the TF depth from every dense pixel (docs/processing.md).
//
// Rendering (back-projection): for TF pixel x with virtual depth v (filled
// map, or the median v of the frame where it is empty), the lens type sharp
// at v (the MLA file's depth range holding v most centrally) is chosen; its
// lenses form a triangular sublattice (steps A(1, 1), A(2, -1)); the three
// lenses of the sublattice triangle around the micro-image-centre position
// that looks at x, q = c + (x - c) / (lambda + v (1 - lambda)) (tf_kernel.h;
// q = x without the micro-lens centre adjustment), are sampled (bilinear) at
// p_k = l_k + (x - l_k) / v, each weighted by its barycentric coordinate
// less a floor (max(0, b_k - bary_floor), TfOptions) times 1 - |p_k -
// c_k|^2 / r^2 (r = inner_fraction r_valid), so the weights go to zero
// continuously at the triangle's edges and wherever a coordinate falls to
// the floor (no seams), the lens of the smallest coordinate is sampled only
// where it is above the floor (a third of the lens samples fewer), and the
// sharp micro images alone make the image. Where none of the three holds x
// (image border, v too small for the sublattice), the micro image nearest q
// of any type and its six neighbours. Parallel over TF rows (TBB), each
// row in runs through the row kernel of tf_blend_simd.h (Highway; the
// scalar reference with TfOptions::simd false), the border fallback point
// by point.

#include "config/error.h"
#include "config/mla.h"
#include "processing/plenoptic_frame.h"
#include "processing/virtual_depth.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace lifmcr::processing {

struct TfOptions {
  int smooth_radius = 8;        // regularisation window radius of the TF depth (TF pixels)
  int fill_iterations = 6;      // hole filling of the TF depth map (TF pixels)
  double inner_fraction = 1.0;  // only samples within this share of r_valid (sharp, unvignetted)
  double gain = 1.0;            // output = gain * devignetted value
  double sharpen = 0.0;         // k of I - k laplacian(I); 0 = off
  // The blend's lens weights max(0, bary - bary_floor) x centrality
  // (tf_blend_simd.h), 0..0.3: 0 the plain barycentric rule; above, the
  // lens of the smallest coordinate is sampled only where it is above the
  // floor. 0.25 on r32: the rendering 15 % less CPU, PSNR against the
  // all-in-focus truth 0.15 dB lower; not the default, because calibration
  // and registration read keypoints and plate corners off the TF image and
  // lost accuracy with it (docs/processing.md, "The blend's barycentric
  // floor").
  double bary_floor = 0.0;
  // The splat's and the blend's Highway kernels; false: their scalar references.
  bool simd = true;
  Status Check() const;
};

struct TfDepthMap {
  int width = 0, height = 0;
  std::vector<float> virtual_depth;  // filled; NaN where empty
  std::vector<float> sigma_z;        // of the fused splats; NaN where filled or empty
  double fallback_v = 0;             // median v of the frame
  long long measured = 0, filled = 0;
  // With the per-lens depth: the micro images splatted as their lens depth
  // (the rest splat their dense pixels); 0 without.
  long long lenses_held = 0, lenses = 0;
  // Scratch of VirtualDepthToTf, kept so that a map reused frame after frame
  // allocates nothing (fresh pages cost more than the arithmetic here).
  struct Scratch {
    // Per TF pixel the sums of the splats' weights and weights times z,
    // interleaved (a splat touches one cache line); zero between calls (`zeroed`).
    std::vector<float> sums;
    bool zeroed = false;
    std::vector<double> cell_w, cell_wz, row_w, row_wz;
    std::vector<float> cell_z, cell_filled;
    // Per cell row, blended along x to every TF column: validity, z.
    std::vector<float> along_a, along_b;
    // Per TF column its two cells and their weights along x (the same for every cell row).
    std::vector<std::int32_t> along_x;
    std::vector<float> along_f;
    std::vector<float> cell_ok, cell_z0;  // per cell: valid (1, 0), z (0 where invalid)
    std::vector<float> lens_xy;  // micro-lens centres l_k (x, y)
    // Per band of the splat one raw row's splats (tf_splat_simd.h).
    std::vector<std::uint32_t> splat_t;
    std::vector<float> splat_w, splat_wz;
    // Splats of a band of raw rows that land beyond the TF rows the band
    // may write in its phase (total_focus.cpp): added after both phases.
    struct Deferred {
      std::uint32_t t;  // the TF pixel; with the per-lens depth the cell
      float w, wz;
    };
    std::vector<std::vector<Deferred>> deferred;
    std::vector<std::uint32_t> histogram;  // of the measured v, for the median
    // With the per-lens depth: per micro image its z and sigma_z (NaN: none)
    // and whether it holds; per band of raw rows the micro images splatted
    // from the dense map that reach into it (by first row) and those that
    // hold with their centre in it.
    LensSeed lens_z;
    std::vector<std::uint8_t> held;
    std::vector<float> centre_x, centre_y;  // c_k
    std::vector<std::int32_t> lens_top, lens_bottom;  // raw rows of a disc r_valid + 1 around c_k
    std::vector<std::vector<std::int32_t>> band_dense, band_held, band_active;
    std::vector<std::vector<std::int32_t>> band_spans;  // a raw row's spans to splat (x0, n)
    std::vector<double> lens_cell_w, lens_cell_wz;  // the splats' sums per cell
    std::vector<float> cell_sigma;                    // sigma_z of those splats per cell
  } scratch;
};

struct TfImage {
  int width = 0, height = 0;
  PixelFormat format = PixelFormat::kBgr8;  // Mono8 for Mono8 raw frames
  std::vector<std::uint8_t> pixels;         // rows without padding
  std::vector<float> linear;                // before sharpening (only with sharpen > 0)
  // The renderer's per-camera tables (total_focus.cpp: the lens tables and
  // sublattices of tf_kernel.h, the devignetting gain in 16 bits, 2 bytes
  // per raw pixel), made by the first RenderTotalFocus of a frame geometry
  // and kept while the image is rendered from that geometry (a pooled
  // workspace's image: made once per camera).
  struct Tables;
  std::shared_ptr<Tables> tables;
  ConstImageView View() const {
    return {pixels.data(), width, height, static_cast<std::size_t>(width) * BytesPerPixel(format),
            format};
  }
};

Status VirtualDepthToTf(const PlenopticFrame& frame, const VirtualDepthMap& raw_depth,
                        const TfOptions& options, TfDepthMap* out);
// The same from the per-lens depth where it holds and the dense map's pixels
// elsewhere (header comment); an error when `lens_depth` is not of the
// frame's lattice (SeedFromLensDepth).
struct LensDepthMap;
Status VirtualDepthToTf(const PlenopticFrame& frame, const VirtualDepthMap& raw_depth,
                        const LensDepthMap& lens_depth, const TfOptions& options,
                        TfDepthMap* out);

// Per micro image of `frame` whether its lens depth holds (1; header
// comment): the micro images VirtualDepthToTf with the per-lens depth
// splats from `lens_z` (SeedFromLensDepth of that map) and whose dense
// pixels it does not read.
void LensesHeldForTf(const PlenopticFrame& frame, const LensSeed& lens_z,
                     std::vector<std::uint8_t>* held);

Status RenderTotalFocus(const PlenopticFrame& frame, const MlaCalibration& mla,
                        const TfDepthMap& depth, const TfOptions& options, TfImage* out);

}  // namespace lifmcr::processing
