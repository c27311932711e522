#pragma once
// The TF image's blend (the rule of processing/tf_kernel.h) for a run of TF
// pixels of one row, in float: a scalar reference and Highway's kernel
// (processing/tf_blend_simd.cpp), which evaluate the same expressions in the
// same order without FMA contraction, so that they agree to the last bit
// (tests/processing/test_tf_blend_simd.cpp states the tolerance it allows).
//
// Per pixel (raw position (x, y), virtual depth v > 1): the lens type t of v
// (`type_of_v`, SharpTypeTable's table), the micro-image position that looks
// at x, q = c + (x - c) / (lambda + v (1 - lambda)), its sublattice
// coordinates a = F_t (q - o_t) (o_t type t's origin lens centre, F_t the
// inverse of the steps A (1, 1), A (2, -1)), the triangle of the sublattice
// around a with its barycentric weights, and for each of its three lenses
// the centre c_k = o_t + S (m, n) (S the two steps; PrepareGeometry puts
// every micro-image centre on the lattice), the micro-lens centre l_k = c +
// (c_k - c) lambda, the sample p_k = l_k + (x - l_k) / v, bilinear on the raw
// pixels times the devignetting gain, weighted by bary (1 - |p_k - c_k|^2 /
// r^2) where it lies within r of c_k, on the frame and off invalid pixels.
// BGR with the 16-bit gain (the TF image's case, frames up to 32768 px
// wide) blends each sample in fixed point: the position in units of 2^-16
// px, the weights q_ij / 2 (1 - f | f)_x (1 - f | f)_y of its four pixels
// (fractions to 1 / 32767, rounded 16-bit products) and each colour's sum
// of their products in 32-bit integers, then in float times 2 gain16_scale
// (and the products' rescale): the float rule's colour to a few hundredths
// of a DN (TfBlendFixedPoint states the bound; docs/processing.md the r32
// TF image against the float blend's).
// The border fallback of tf_kernel.h (the nearest micro image and its six
// neighbours, where the three see nothing: sw = 0) is left to the caller.
// On AVX-512 (BGR, the 16-bit gain) a lens's samples of a vector whose
// lanes lie in one or two 64-byte windows of a raw row pair are read from
// those windows by word permutes instead of gathers: the same values; the
// same bytes two raw rows down are prefetched then (the next TF rows' reads).

#include <cstddef>
#include <cstdint>

namespace lifmcr::processing::detail {

struct TfBlendGeometry {
  int width = 0, height = 0;          // the raw frame (>= 8 x 2)
  float cx = 0, cy = 0, lambda = 1;   // principal point, lambda of l_k = c + (c_k - c) lambda
  float r2 = 0;                       // (inner_fraction r_valid)^2
  float ox[3] = {}, oy[3] = {};       // per type: its origin lens centre o_t
  float fxx[3] = {}, fxy[3] = {}, fyx[3] = {}, fyy[3] = {};  // per type: F_t
  float sxa = 0, sya = 0, sxb = 0, syb = 0;  // the steps A (1, 1) and A (2, -1)
  const std::int32_t* type_of_v = nullptr;   // type of v: [clamp(int(v per_unit), 0, size - 1)]
  int type_per_unit = 1, type_size = 1;
  // The same table as runs where it has at most kMaxTypeRuns of them (the
  // sharp type's changes a few times over v: SetTypeRuns): type_run_value[r]
  // from index type_run_start[r] on, found by compares instead of a gather
  // of 16 elements per vector of pixels; 0 runs: the table is gathered.
  static constexpr int kMaxTypeRuns = 8;
  int type_runs = 0;
  std::int32_t type_run_start[kMaxTypeRuns] = {}, type_run_value[kMaxTypeRuns] = {};
  // The lenses' weights are max(0, bary - bary_floor) (in [0, 1/3)) times
  // the centrality; 0 is the plain barycentric rule. Above 0 a lens whose
  // barycentric coordinate is below the floor adds nothing, continuously
  // (its weight reaches 0 at the floor), and the run's vectors skip the
  // third lens where none of its points needs one: fewer samples per pixel.
  float bary_floor = 0;
};

// type_runs and its runs from type_of_v (0 runs where the table has more
// than kMaxTypeRuns).
inline void SetTypeRuns(TfBlendGeometry* g) {
  g->type_runs = 0;
  for (int i = 0; i < g->type_size; ++i) {
    if (i > 0 && g->type_of_v[i] == g->type_of_v[i - 1]) continue;
    if (g->type_runs == TfBlendGeometry::kMaxTypeRuns) {
      g->type_runs = 0;
      return;
    }
    g->type_run_start[g->type_runs] = i;
    g->type_run_value[g->type_runs] = g->type_of_v[i];
    ++g->type_runs;
  }
}

struct TfBlendSource {
  const std::uint8_t* raw = nullptr;  // Mono8 or BGR8
  std::size_t stride_bytes = 0;
  int channels = 1;                   // 1 or 3
  const float* gain = nullptr;        // per pixel (width columns), NaN where invalid
  // Or, where set (then `gain` is not read), the gain in 16 bits
  // (lens_search_simd.h's Gain16): q * gain16_scale, invalid where q = 0.
  const std::uint16_t* gain16 = nullptr;
  float gain16_scale = 1;
};

// n points at raw positions (x0 + dx i, y), virtual depths v[i] (> 1, finite):
// acc[ch * n + i] the weighted colour sums (planar, `channels` planes) and
// sw[i] the sum of the weights (0: none of the three lenses sees the point).
// Precondition: width * height and (height - 1) * stride_bytes + 3 * width < 2^31.
using TfBlendRowFn = void (*)(const TfBlendGeometry& g, const TfBlendSource& s, float x0, float dx,
                              float y, const float* v, int n, float* acc, float* sw);

// The 8-bit pixels of a run of the TF image from the row kernel's sums
// (RenderTotalFocus): with scale_i = gain / sw[i] where sw[i] > 0 (else 0),
// out[i * channels + ch] = uint8(int(min(max(acc[ch * n + i] scale_i + 0.5, 0), 255)))
// (interleaved: BGR when channels is 3). Finite acc.
using TfBytesFn = void (*)(const float* acc, const float* sw, int n, int channels, float gain,
                           std::uint8_t* out);

struct TfBlendKernels {
  TfBlendRowFn row = nullptr;
  const char* name = "";  // "scalar", or the Highway target chosen ("AVX3", "AVX2", ...)
  TfBytesFn bytes = nullptr;
};

// The scalar reference.
const TfBlendKernels& ScalarTfBlendKernels();
// Highway's, dispatched to the best target of this CPU (chosen at each call).
const TfBlendKernels& SimdTfBlendKernels();

}  // namespace lifmcr::processing::detail
