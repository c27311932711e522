#pragma once
// The row kernels of LoadRaw (processing/plenoptic_frame.h): the devignetted
// grey of a Mono8 row and one axis of the smoothing within micro images, a
// scalar reference and Highway's (processing/frame_smooth_simd.cpp). Both
// evaluate the same float expressions in the same order, so they agree bit
// for bit (tests/processing/test_frame_smooth_simd.cpp).
//
// Smoothing, one axis: out = (2 g + sum of the taken neighbours) / (2 + their
// count), a neighbour taken where the pixel's mask has its bit (lo_bit: the
// one before along the axis, hi_bit: the one after); a neighbour left out
// adds 0 and no weight.

#include <cstdint>

namespace lifmcr::processing::detail {

// grey[x] = raw[x] * gain[x], x < n.
using GreyRowFn = void (*)(const std::uint8_t* raw, const float* gain, int n, float* grey);
// Along the row: the neighbours are row[x - 1] (mask bit 1) and row[x + 1]
// (bit 2); row[-1] and row[n] are never read (their bits must be 0 at x = 0
// and x = n - 1). n >= 1.
using SmoothXRowFn = void (*)(const float* row, const std::uint8_t* mask, int n, float* out);
// Across rows: the neighbours are lo[x] (mask bit 4) and hi[x] (bit 8); a
// row that is never taken may be any valid row (e.g. `row` itself).
using SmoothYRowFn = void (*)(const float* lo, const float* row, const float* hi,
                              const std::uint8_t* mask, int n, float* out);

struct FrameSmoothKernels {
  GreyRowFn grey_row = nullptr;
  SmoothXRowFn smooth_x = nullptr;
  SmoothYRowFn smooth_y = nullptr;
  const char* name = "";  // "scalar", or the Highway target chosen ("AVX3", "AVX2", ...)
};

// The scalar reference.
const FrameSmoothKernels& ScalarFrameSmoothKernels();
// Highway's, dispatched to the best target of this CPU (chosen at each call).
const FrameSmoothKernels& SimdFrameSmoothKernels();

}  // namespace lifmcr::processing::detail
