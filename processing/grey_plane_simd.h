#pragma once
// The grey plane of a BGR8 frame that the per-lens search reads instead of
// the frame (processing/lens_depth.h, LensDepthOptions::grey_plane): per
// pixel the channel mean rounded to the nearest integer,
//   grey = floor((b + g + r + 1) / 3),
// one byte where the frame has three. A scalar reference and Highway's
// (processing/grey_plane_simd.cpp), equal to the last bit (integers only;
// tests/processing/test_lens_search_simd.cpp compares them on random rows
// and on every channel sum).
// Internal to processing/.

#include <cstdint>

namespace lifmcr::processing::detail {

// grey[x] = (bgr[3x] + bgr[3x + 1] + bgr[3x + 2] + 1) / 3, x < n.
using GreyOfBgrRowFn = void (*)(const std::uint8_t* bgr, int n, std::uint8_t* grey);

struct GreyPlaneKernels {
  GreyOfBgrRowFn row = nullptr;
  const char* name = "";  // "scalar", or the Highway target chosen ("AVX3", "AVX2", ...)
};

// The scalar reference.
const GreyPlaneKernels& ScalarGreyPlaneKernels();
// Highway's, dispatched to the best target of this CPU (chosen at each call).
const GreyPlaneKernels& SimdGreyPlaneKernels();

}  // namespace lifmcr::processing::detail
