#pragma once
// The hot loops of the epipolar searches (processing/lens_depth.h and
// processing/virtual_depth.h, through MatchAlong of
// processing/epipolar_search.h): sampling the neighbour's strip lines
// bilinearly (the per-lens search: from the raw pixels times the
// devignetting gain; the dense search: from the smoothed devignetted grey
// image), the SSD of the reference patch at every candidate disparity, and
// the per-lens candidate gate's gradients.
// Two implementations with one contract: the scalar reference and Google
// Highway's (runtime dispatch to the best target the CPU runs: SSE4, AVX2,
// AVX-512 on x86, NEON on ARM). Both evaluate the same float expressions in
// the same order (the Highway file is compiled without FMA contraction), so
// they agree to the last bit on x86 and ARM; tests/processing/
// test_lens_search_simd.cpp compares them on random inputs.
// Internal to processing/.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace lifmcr::processing::detail {

// Padding (floats) a strip line or cost buffer carries beyond its length:
// the Highway kernels write and read whole vectors (up to 64 floats).
constexpr int kStripPad = 64;

// The frame a strip is read from: raw pixels (1 or 3 channels of 8 bits,
// the grey level their sum) and the devignetting gain in 16 bits (Gain16
// below: one word per pixel, rows of `width`, 0 where invalid); or, where
// `grey` is set, a float grey image (rows of `width`, NaN where invalid:
// the dense search's smoothed devignetted grey), and raw / gain are not read.
struct StripSource {
  const std::uint8_t* raw = nullptr;
  std::size_t stride_bytes = 0;
  int channels = 1;  // 1 or 3
  const std::uint16_t* gain = nullptr;
  int width = 0;
  const float* grey = nullptr;
  float gain_scale = 1;  // Gain16::scale
};

// The devignetting gain (plenoptic_frame.h: W_ref / W(p), NaN where
// invalid) in 16-bit fixed point, made once per camera for the per-lens
// search: gain = q scale with scale = 2^-e, e the largest (at most 16) for
// which the largest gain fits (q <= 65535), q >= 1 where valid, q = 0 where
// invalid. With the default min_white_fraction 0.5 (gains up to 2) e = 14:
// the gain to 3e-5 of itself, 0.008 DN on a 255 DN pixel. Why: half the
// bytes of the float gain, and the two gains of a bilinear sample's row in
// one 32-bit load (a gather fewer per row); q scale is exact in float, so
// every reader gets the same numbers.
struct Gain16 {
  std::vector<std::uint16_t> q;
  float scale = 1;
  int width = 0;
  // From a float gain of `width` columns.
  static Gain16 From(const std::vector<float>& gain, int width);
  // The gain at pixel index `at`; NaN where invalid.
  float At(std::size_t at) const {
    return q[at] == 0 ? std::numeric_limits<float>::quiet_NaN() : static_cast<float>(q[at]) * scale;
  }
};

// The bilinear grey at (x0 + fx, y0 + fy) of a float image, r0 / r1 its
// rows y0 / y0 + 1 at x0: the formula of the grey strips, in the order the
// Highway kernel evaluates it.
inline float GreyImageBilinear(const float* r0, const float* r1, float fx, float fy) {
  return (r0[0] + (r0[1] - r0[0]) * fx) * (1 - fy) + (r1[0] + (r1[1] - r1[0]) * fx) * fy;
}

// The grey level at (x0 + fx, y0 + fy) of the raw pixels times the gain,
// q0 / q1 the raw rows y0 / y0 + 1 at x0, g0 / g1 the 16-bit gain rows at
// x0 (Gain16, `scale` its scale): the formula of StripLine below, in the
// order the Highway kernels evaluate it (channel sums in integers, one
// conversion per corner), so the scalar reference and every scalar reader
// of the frame agree to the last bit; NaN when a corner's gain is invalid.
template <int kChannels>
inline float RawGainBilinear(const std::uint8_t* q0, const std::uint8_t* q1,
                             const std::uint16_t* g0, const std::uint16_t* g1, float scale,
                             float fx, float fy) {
  if (g0[0] == 0 || g0[1] == 0 || g1[0] == 0 || g1[1] == 0)
    return std::numeric_limits<float>::quiet_NaN();
  int s00 = q0[0], s01 = q0[kChannels], s10 = q1[0], s11 = q1[kChannels];
  if constexpr (kChannels == 3) {
    s00 += q0[1] + q0[2];
    s01 += q0[4] + q0[5];
    s10 += q1[1] + q1[2];
    s11 += q1[4] + q1[5];
  }
  const float a = static_cast<float>(s00) * (static_cast<float>(g0[0]) * scale),
              b = static_cast<float>(s01) * (static_cast<float>(g0[1]) * scale),
              c = static_cast<float>(s10) * (static_cast<float>(g1[0]) * scale),
              d = static_cast<float>(s11) * (static_cast<float>(g1[1]) * scale);
  return ((a + (b - a) * fx) * (1 - fy) + (c + (d - c) * fx) * fy) * (1.0f / kChannels);
}

// One line of a strip, n samples. Sample i sits at strip index j = n - 1 - i
// (MatchAlong reverses the strip so its cost loop runs forwards):
//   t_j = along0 + j step,
//   x_j = (px + t_j e_x) - b_ey,   y_j = (py + t_j e_y) + b_ex
// (b_ey = b e_y and b_ex = b e_x for line b of the patch), and is
//   grey(x_j, y_j) = ((a + (b - a) fx) (1 - fy) + (c + (d - c) fx) fy) / channels
// with a, b, c, d the four neighbouring pixels' channel sums times their
// gains (NaN where one of the four gains is invalid), fx, fy the fractional parts (with `grey` set: GreyImageBilinear
// of the four grey pixels); NaN for j outside [j_lo, j_hi].
// Precondition: every position with j in [j_lo, j_hi] has 0 <= x_j,
// floor(x_j) <= width - 3 and 0 <= y_j, floor(y_j) <= rows - 3 (MatchAlong's
// disc well inside the frame), and rows * stride_bytes < 2^31 and
// 2 rows * width < 2^31 (32-bit byte offsets). `out` holds
// n + kStripPad floats.
struct StripLine {
  float px = 0, py = 0, e_x = 0, e_y = 0, b_ey = 0, b_ex = 0;
  float along0 = 0, step = 1;
  int n = 0, j_lo = 0, j_hi = -1;
};

// cost[k] = sum over lines b < n_lines, a = -2..2 of
//   (lines[b][k + (2 - a) spp] - ref[5 b + a + 2])^2,   k = 0..steps - 1,
// accumulated in that order. lines[b] holds steps + 4 spp + kStripPad
// floats, cost steps + kStripPad.
using SampleStripLineFn = void (*)(const StripSource& source, const StripLine& line, float* out);
using StripCostsFn = void (*)(const float* const* lines, int n_lines, const float* ref, int spp,
                              int steps, float* cost);

// The candidate gate of one micro image (lens_depth.h, step 1): for each of
// the n candidates q at (x, y) = (cx + dx[q], cy + dy[q]), with S the raw
// channel sum,
//   gx = to_grey (S(x + 1, y) - S(x - 1, y)),  gy = to_grey (S(x, y + 1) - S(x, y - 1)),
//   g_d = |gx axis_x[d] + gy axis_y[d]|  for the axes d = 0..2 with bit d of axis_mask,
// score[q] = the largest g_d above 0 (0 if none) and axis[q] the first d
// reaching it. Precondition: every (x, y) in [2, width - 3] x [2, rows - 3],
// rows * stride_bytes < 2^31; dx, dy, score, axis hold n + kStripPad entries.
using CandidateScoresFn = void (*)(const StripSource& source, int cx, int cy,
                                   const std::int32_t* dx, const std::int32_t* dy, int n,
                                   float to_grey, const float* axis_x, const float* axis_y,
                                   unsigned axis_mask, float* score, std::int32_t* axis);

// The reference patch of pixel p (lens_depth.cpp) from the raw pixels
// times the gain, its `lines` (1 or 3) lines in one call: for b = -(lines /
// 2) .. lines / 2 and a = -2..2,
//   out[5 (b + lines / 2) + a + 2] = grey(x, y),
//   x = (px + a e_x) - b e_y,   y = (py + a e_y) + b e_x   (b e_y, b e_x in float),
// StripLine's formula at t = a (the samples of the lines {p, e, b e_y,
// b e_x, along0 -2, step 1, n 5} read reversed: the same numbers). One
// call instead of one per line: a micro image's searches sample about two
// reference patches, and the calls of 5-sample lines were half of the
// strip kernel's calls. Precondition: StripLine's for every sample;
// `source` without `grey`; out holds 5 lines + kStripPad floats.
using SamplePatchFn = void (*)(const StripSource& source, float px, float py, float e_x,
                               float e_y, int lines, float* out);

struct StripKernels {
  SampleStripLineFn sample = nullptr;
  StripCostsFn costs = nullptr;
  CandidateScoresFn scores = nullptr;
  SamplePatchFn patch = nullptr;
  const char* name = "";  // "scalar", or the Highway target chosen ("AVX3", "AVX2", ...)
};

// The scalar reference.
const StripKernels& ScalarStripKernels();
// Highway's, dispatched to the best target of this CPU (chosen at first use).
const StripKernels& SimdStripKernels();

}  // namespace lifmcr::processing::detail
