#pragma once
// Totally focused (TF) image and the virtual depth on the TF grid
// (notes/processing.md 1.3; conventions of camera_model.h): the TF grid is
// W/2 x H/2 and TF pixel (u, w) is the virtual image at raw position
// x = (2u + 0.5, 2w + 0.5).
//
// Virtual depth on the TF grid: every raw estimate (pixel p of micro image k,
// virtual depth v) is the virtual point x_v = l_k + v (p - l_k); it is
// splatted to the TF pixel nearest to (x_v - 0.5) / 2 and the splats are
// fused in z = 1/v weighted by 1 / sigma_z^2, then regularised (each measured
// pixel: the inverse-variance mean of the measured pixels within
// smooth_radius agreeing with their median within 5 %). Holes are filled by averaging
// the valid 8-neighbours, fill_iterations rounds (each grows the map by one
// TF pixel); what stays empty is NaN.
//
// Rendering (back-projection): for TF pixel x with virtual depth v (filled
// map, or the median v of the frame where it is empty), every micro image k
// with p_k = l_k + (x - l_k) / v within inner_fraction r_valid of c_k is used; the
// colour is the mean of the devignetted raw samples at p_k (bilinear),
// weighted by w = s_t (1 - |p_k - c_k|^2 / r^2) (r = inner_fraction r_valid), s_t = 1 for a lens
// type whose depth range (MLA file) holds v and unsharp_weight otherwise,
// so the sharp micro images dominate. Parallel over TF rows (TBB).

#include "config/error.h"
#include "config/mla.h"
#include "processing/plenoptic_frame.h"
#include "processing/virtual_depth.h"

#include <cstdint>
#include <vector>

namespace lifmcr::processing {

struct TfOptions {
  int smooth_radius = 4;        // regularisation of the measured TF depth (TF pixels)
  int fill_iterations = 6;      // hole filling of the TF depth map (TF pixels)
  double unsharp_weight = 0.1;  // weight of micro images whose type is not sharp at v
  double inner_fraction = 1.0;  // only samples within this share of r_valid (sharp, unvignetted)
  double gain = 1.0;            // output = gain * devignetted value
  double sharpen = 0.0;         // k of I - k laplacian(I); 0 = off
  Status Check() const;
};

struct TfDepthMap {
  int width = 0, height = 0;
  std::vector<float> virtual_depth;  // filled; NaN where empty
  std::vector<float> sigma_z;        // of the fused splats; NaN where filled or empty
  double fallback_v = 0;             // median v of the frame
  long long measured = 0, filled = 0;
};

struct TfImage {
  int width = 0, height = 0;
  PixelFormat format = PixelFormat::kBgr8;  // Mono8 for Mono8 raw frames
  std::vector<std::uint8_t> pixels;         // rows without padding
  std::vector<float> linear;                // before sharpening and 8-bit rounding
  ConstImageView View() const {
    return {pixels.data(), width, height, static_cast<std::size_t>(width) * BytesPerPixel(format),
            format};
  }
};

Status VirtualDepthToTf(const PlenopticFrame& frame, const VirtualDepthMap& raw_depth,
                        const TfOptions& options, TfDepthMap* out);

Status RenderTotalFocus(const PlenopticFrame& frame, const MlaCalibration& mla,
                        const TfDepthMap& depth, const TfOptions& options, TfImage* out);

}  // namespace lifmcr::processing
