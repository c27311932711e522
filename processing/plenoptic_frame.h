#pragma once
// A raw frame prepared for depth and total focus: devignetted by the white
// image, and the micro images it holds (centres, micro-lens centres, types).
//
// Devignetting: I_n(p) = I(p) * W_ref / W(p), W the white image's grey level
// and W_ref its level at the micro-image cores near the image centre, so a white surface reads
// W_ref everywhere; pixels with W(p) < min_white_fraction * W_ref (the dark
// gaps and rims between micro images) are invalid (NaN). Grey is the channel
// mean; colour is read from the raw frame times the same gain when needed.
//
// Micro images: lens k with micro-image centre c_k (MlaGrid), micro-lens
// centre l_k = c + lambda (c_k - c) (camera_model.h), usable pixels within
// r_valid = D / 2 - lens_border - margin of c_k.

#include "config/error.h"
#include "config/image.h"
#include "config/mla.h"
#include "processing/mla_grid.h"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <vector>

namespace lifmcr::processing {

struct MicroImage {
  int i = 0, j = 0;
  int type = 0;
  Eigen::Vector2d centre_px;  // c_k
  Eigen::Vector2d lens_px;    // l_k
};

struct FrameOptions {
  double lambda = 1.0;              // b_L0 / (b_L0 + B); 1 when the intrinsics are unknown
  std::optional<Eigen::Vector2d> principal_point_px;  // c of l_k; unset: the image centre
  double margin_px = 0.0;           // r_valid = D / 2 - lens_border - margin
  int smooth_passes = 2;            // binomial smoothing of the grey image within micro images
  double min_white_fraction = 0.5;  // devignetting validity
  Status Check() const;  // every field; the message names the field
};

// Buffers are reused across frames of the same size (a workspace, not
// reallocated by Prepare when the size is unchanged).
struct PlenopticFrame {
  int width = 0, height = 0;
  std::vector<float> grey;  // devignetted grey, NaN where invalid
  // Not used by LoadRaw (its rows are per thread, processing/plenoptic_frame.cpp);
  // kept for callers that clear it.
  std::vector<float> work;
  // The raw frame itself (not a copy: the caller's pooled buffer, which must
  // outlive the processing of the frame); the TF image samples it times
  // `gain`, so colour needs no float copy of 12 bytes per pixel.
  ConstImageView raw;
  bool has_colour = false;
  std::vector<float> gain;  // W_ref / W(p), NaN where invalid (PrepareGeometry)
  int smooth_passes = 2;
  bool geometry_ready = false;
  std::vector<std::int32_t> lens_of_pixel;  // index into lenses, -1 outside every r_valid
  // Per pixel, which of its 4-neighbours the smoothing within micro images
  // takes (bits: 1 x - 1, 2 x + 1, 4 y - 1, 8 y + 1): those of the same
  // micro image with a valid gain. A camera's, made once, so a frame's
  // smoothing reads one byte per pixel instead of three lens indices.
  std::vector<std::uint8_t> smooth_mask;
  std::vector<MicroImage> lenses;
  std::vector<std::int32_t> lens_index;  // (j - j_min) * ni + (i - i_min) -> lens, or -1
  int i_min = 0, j_min = 0, ni = 0, nj = 0;
  MlaGrid grid;
  double radius_px = 0;    // r_valid
  double white_level = 0;  // W_ref
  double lambda = 1.0;     // b_L0 / (b_L0 + B) used for l_k
  Eigen::Vector2d principal_point_px = Eigen::Vector2d::Zero();  // c used for l_k

  int LensAt(int i, int j) const {
    if (i < i_min || j < j_min || i >= i_min + ni || j >= j_min + nj) return -1;
    return lens_index[static_cast<std::size_t>(j - j_min) * ni + (i - i_min)];
  }
  float Grey(int x, int y) const { return grey[static_cast<std::size_t>(y) * width + x]; }
  // Bilinear grey at p; NaN outside the image or next to an invalid pixel.
  float SampleGrey(double x, double y) const;
};

// Once per camera (white image, grid and options fixed): the gain of the
// devignetting, the micro images and the pixel -> micro image map, for
// frames of width x height. `white` may be empty (data == nullptr): no
// devignetting, the whole disc of radius r_valid is valid.
Status PrepareGeometry(ConstImageView white, int width, int height, const MlaGrid& grid,
                       const MlaCalibration& mla, const FrameOptions& options,
                       PlenopticFrame* frame);
// Per frame, after PrepareGeometry: the devignetted grey of `raw` (smoothed
// within micro images), in the frame's buffers (no allocation once they are
// sized); `raw` is kept as a view and must outlive the frame's processing.
Status LoadRaw(ConstImageView raw, PlenopticFrame* frame);
namespace detail {
struct FrameSmoothKernels;  // processing/frame_smooth_simd.h
}
// The same with given row kernels (the scalar reference or Highway's, which
// give the same grey bit for bit; LoadRaw above uses Highway's).
Status LoadRaw(ConstImageView raw, const detail::FrameSmoothKernels& kernels,
               PlenopticFrame* frame);
// Both, for a single frame. Reusing `frame` reuses its buffers.
Status PrepareFrame(ConstImageView raw, ConstImageView white, const MlaGrid& grid,
                    const MlaCalibration& mla, const FrameOptions& options, PlenopticFrame* frame);

inline float PlenopticFrame::SampleGrey(double x, double y) const {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  if (x < 0 || y < 0 || x0 >= width - 1 || y0 >= height - 1) return __builtin_nanf("");
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* r0 = grey.data() + static_cast<std::size_t>(y0) * width + x0;
  const float* r1 = r0 + width;
  return (r0[0] * (1 - fx) + r0[1] * fx) * (1 - fy) + (r1[0] * (1 - fx) + r1[1] * fx) * fy;
}

}  // namespace lifmcr::processing
