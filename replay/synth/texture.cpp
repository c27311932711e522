#include "replay/synth/texture.h"

#include <algorithm>
#include <cmath>

namespace lifmcr::synth {
namespace {

double LatticeValue(std::int32_t x, std::int32_t y, std::uint32_t seed) {
  // One hash of a linear mix of the lattice coordinates (a second hash per
  // corner cost a fifth of a frame).
  const std::uint32_t h = HashU32(static_cast<std::uint32_t>(x) * 0x9E3779B1U +
                               static_cast<std::uint32_t>(y) * 0x85EBCA77U + seed);
  return (h >> 8) * (1.0 / 16777216.0);
}

double Smooth(double t) { return t * t * t * (t * (t * 6 - 15) + 10); }

}  // namespace

double ValueNoise(double x, double y, std::uint32_t seed) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int32_t>(fx), iy = static_cast<std::int32_t>(fy);
  const double tx = Smooth(x - fx), ty = Smooth(y - fy);
  const double a = LatticeValue(ix, iy, seed), b = LatticeValue(ix + 1, iy, seed);
  const double c = LatticeValue(ix, iy + 1, seed), d = LatticeValue(ix + 1, iy + 1, seed);
  return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

double NoiseTexture::Sample(double u_mm, double v_mm, double footprint_mm) const {
  double sum = 0.0, norm = 0.0, amplitude = 1.0;
  double wavelength = feature_mm;
  const double limit = std::max(finest_mm, 2.0 * footprint_mm);
  std::uint32_t octave_seed = seed;
  for (int octave = 0; octave < 16 && wavelength > 0.5 * limit; ++octave) {
    // Fade the octave in over one factor of two above the limit.
    const double fade = std::clamp((wavelength - 0.5 * limit) / (0.5 * limit), 0.0, 1.0);
    const double value = ValueNoise(u_mm / wavelength, v_mm / wavelength, octave_seed);
    sum += amplitude * fade * (value - 0.5);
    norm += amplitude * amplitude * fade * fade;
    amplitude *= persistence;
    wavelength *= 0.5;
    octave_seed = octave_seed * 747796405U + 2891336453U;
  }
  if (norm <= 0.0) return 0.5;
  // Normalised to a fixed contrast whatever the number of octaves, so the
  // same point seen at different footprints keeps its mean and spread.
  return std::clamp(0.5 + 1.5 * sum / std::sqrt(norm), 0.0, 1.0);
}

}  // namespace lifmcr::synth
