#pragma once
// Procedural texture for synthetic scenes: band-limited value noise (fBm).
// Detail reaches down to the sampled footprint and no further, so a single
// sample per pixel does not alias, and there is texture at the scale of a
// micro image for stereo between micro images.

#include <cstdint>

namespace lifmcr::synth {

struct NoiseTexture {
  double feature_mm = 40.0;   // wavelength of the coarsest octave
  double finest_mm = 0.3;     // no detail below this wavelength
  double persistence = 0.72;  // amplitude ratio between octaves
  std::uint32_t seed = 1;

  // Value in [0, 1] at surface coordinates (u, v) mm, for a sample that
  // covers `footprint_mm`: octaves with wavelength < 2 footprints fade out.
  double Sample(double u_mm, double v_mm, double footprint_mm) const;
};

// 32-bit integer hash (lowbias32 by C. Wellons' hash prospector, public domain).
inline std::uint32_t HashU32(std::uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352dU;
  x ^= x >> 15;
  x *= 0x846ca68bU;
  x ^= x >> 16;
  return x;
}

// Smooth value noise in [0, 1] on the unit lattice, hashed by `seed`.
double ValueNoise(double x, double y, std::uint32_t seed);

}  // namespace lifmcr::synth
