#pragma once
// The splat of the TF depth map (processing/total_focus.h) for one raw row,
// in float: a scalar reference and Highway's kernel
// (processing/tf_splat_simd.cpp), which evaluate the same expressions in the
// same order without FMA contraction, so that they agree to the last bit
// (tests/processing/test_tf_splat_simd.cpp).
//
// Per raw pixel x of row y (a whole row, or a span of it from x0) with a virtual depth v (not NaN) in micro image
// k >= 0 (micro-lens centre l_k): the virtual point x_v = l_k + v (p - l_k),
// the TF pixel nearest to (x_v - 0.5) / 2, (u, w) = trunc((x_v - 0.5) / 2 +
// 0.5) where (x_v - 0.5) / 2 > -0.5 and u < tf_width, w < tf_height (else
// it is off the grid and dropped); its weight 1 / sigma_z^2 and weight z =
// weight / v, as 1 / (max(1e-12, sigma_z^2) v) times v. The splats are
// written compacted, in the order of x: the caller adds them to its sums.
// Where a vector's pixels are all of one micro image (a chord of it, as the
// TF depth from the per-lens depth splats) its l_k is read once, not
// gathered: the same values.

#include <cstdint>

namespace lifmcr::processing::detail {

struct TfSplatRow {
  const float* v = nullptr;            // the row's virtual depth (NaN: none)
  const float* sigma_z = nullptr;      // its sigma_z
  const std::int32_t* lens = nullptr;  // its micro image (-1: none)
  const float* lens_xy = nullptr;      // l_k: x at 2 k, y at 2 k + 1
  int x0 = 0;                          // x of the first pixel (v, sigma_z, lens point at it)
  int width = 0;                       // pixels of the row (x = x0 .. x0 + width - 1)
  int y = 0;                           // the raw row
  int tf_width = 0, tf_height = 0;
  // Above 0: t is the splat's cell of kCellPx x kCellPx TF pixels,
  // (w / kCellPx) cell_width + u / kCellPx, instead of its TF pixel (the
  // sums per cell of the TF depth from the per-lens depth).
  static constexpr int kCellPx = 4;
  int cell_width = 0;
};

// Writes the splats of the row that land on the TF grid (t = w tf_width + u
// or the cell,
// weight, weight z; room for `width` of each, and one vector more for the
// kernel's whole-vector stores) and returns how many.
using TfSplatRowFn = int (*)(const TfSplatRow& row, std::uint32_t* t, float* weight,
                             float* weight_z);

struct TfSplatKernels {
  TfSplatRowFn row = nullptr;
  const char* name = "";
};

// Room the output arrays need beyond `width` (a vector of any target).
constexpr int kTfSplatPad = 64;

const TfSplatKernels& ScalarTfSplatKernels();
const TfSplatKernels& SimdTfSplatKernels();

}  // namespace lifmcr::processing::detail
