#pragma once
// Natural-image-like surface patterns for the textured scenes: colour
// reflectance as a function of surface coordinates (u, v) in mm, band-limited
// to the footprint of the sample that asks (one ray per pixel must not alias,
// and the same point seen at different footprints keeps its local mean).
//
// - DeadLeaves: the dead-leaves model (Matheron; Lee, Mumford and Huang 2001):
//   opaque discs and rotated rectangles of random colour, radius density
//   r^-3 between min and max radius, stacked in random order. Its power
//   spectrum falls as 1 / f^2, as natural images do, and it has occlusion
//   edges at every scale. Evaluated procedurally: radii in octaves; octave L
//   holds `leaves_per_cell` leaves per square cell of side 2 r_max(L) (a
//   constant count per cell is the r^-3 density), so a point meets only the
//   2 x 2 cells nearest to it; the leaf on top is the one with the smallest
//   random key. Edges are soft over one footprint (alpha = the share of the
//   footprint inside the leaf, from the signed distance), leaves smaller
//   than the footprint are weighted by their area share, and leaves below a
//   quarter footprint are left out.
// - BandedNoise: multi-octave value noise (texture.h) quantised into colour
//   bands: regions with fractal edges at every scale (marble, camouflage,
//   stone), anti-aliased from the noise gradient across one footprint.
// - PrintedPage: what cards, book covers and printed photos look like:
//   blocks of dead-leaves "photos" and of text (lines of 5 x 7 glyphs from a
//   hash) on paper, the glyph bitmap smoothed over the footprint and faded
//   to its mean ink coverage once a glyph pixel is smaller than a footprint.
// Every pattern multiplies a fine value-noise grain (paper, fabric, bark) so
// that flat-coloured areas still carry texture at the micro-image scale.
// Deterministic: a pure function of its parameters and seed.

#include "replay/synth/texture.h"

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <vector>

namespace lifmcr::synth {

class SurfacePattern {
 public:
  virtual ~SurfacePattern() = default;
  // Linear RGB reflectance in [0, 1] at (u, v) mm for a sample of `footprint_mm`.
  virtual Eigen::Vector3d Reflectance(double u_mm, double v_mm, double footprint_mm) const = 0;
};

struct Grain {
  NoiseTexture noise{4.0, 0.3, 0.7, 1};  // coarsest 4 mm, finest 0.3 mm
  double amplitude = 0.25;               // reflectance x (1 - amplitude + amplitude * noise)
  double Factor(double u_mm, double v_mm, double footprint_mm) const;
};

struct DeadLeavesParams {
  double min_radius_mm = 0.6;  // smallest leaf (circumradius)
  double max_radius_mm = 40;   // largest leaf
  int leaves_per_cell = 1;     // per octave and cell of side 2 r_max (covers 36 % per leaf)
  double rectangle_share = 0.5;             // rotated rectangles; the rest discs
  std::vector<Eigen::Vector3d> palette;     // base colours (at least one)
  double brightness_spread = 0.7;           // leaf brightness uniform in [1 - spread, 1]
  double colour_jitter = 0.08;              // per-channel jitter around the base colour
  Grain grain;
  std::uint32_t seed = 1;
};

class DeadLeaves : public SurfacePattern {
 public:
  explicit DeadLeaves(DeadLeavesParams params);
  Eigen::Vector3d Reflectance(double u_mm, double v_mm, double footprint_mm) const override;
  // Without the grain (PrintedPage composes it once).
  Eigen::Vector3d Leaves(double u_mm, double v_mm, double footprint_mm) const;

 private:
  DeadLeavesParams p_;
  Eigen::Vector3d mean_;  // background where no leaf covers (the palette mean)
  int octaves_ = 1;
};

struct BandedNoiseParams {
  NoiseTexture noise{30.0, 0.3, 0.62, 1};
  std::vector<Eigen::Vector3d> palette;  // one colour per band, cycled
  int bands = 6;                         // bands over the noise range [0, 1]
  Grain grain;
};

class BandedNoise : public SurfacePattern {
 public:
  explicit BandedNoise(BandedNoiseParams params);
  Eigen::Vector3d Reflectance(double u_mm, double v_mm, double footprint_mm) const override;

 private:
  BandedNoiseParams p_;
};

struct PrintedPageParams {
  double block_mm = 60;           // side of the layout blocks (photo or text)
  double photo_share = 0.45;      // blocks holding a photo; the rest text
  double glyph_height_mm = 4.0;   // text height (7 glyph pixels); titles use 2x
  Eigen::Vector3d paper{0.92, 0.9, 0.84};
  Eigen::Vector3d ink{0.08, 0.08, 0.1};
  DeadLeavesParams photo;  // the photo blocks' content
  Grain grain;
  std::uint32_t seed = 1;
};

class PrintedPage : public SurfacePattern {
 public:
  explicit PrintedPage(PrintedPageParams params);
  Eigen::Vector3d Reflectance(double u_mm, double v_mm, double footprint_mm) const override;

 private:
  // Ink coverage in [0, 1] of a text block at block-local (x, y) mm.
  double Ink(double x_mm, double y_mm, double glyph_px_mm, std::uint32_t block_seed,
             double footprint_mm) const;
  PrintedPageParams p_;
  DeadLeaves photo_;
};

// Palettes of natural colours (linear RGB reflectance) for the scenes.
std::vector<Eigen::Vector3d> PaletteFoliage();
std::vector<Eigen::Vector3d> PaletteWood();
std::vector<Eigen::Vector3d> PaletteCloth();
std::vector<Eigen::Vector3d> PalettePhoto();
std::vector<Eigen::Vector3d> PaletteStone();

}  // namespace lifmcr::synth
