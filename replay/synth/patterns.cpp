#include "replay/synth/patterns.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

namespace lifmcr::synth {
namespace {

double Unit16(std::uint32_t h) { return (h & 0xFFFFU) * (1.0 / 65536.0); }
double UnitHigh16(std::uint32_t h) { return (h >> 16) * (1.0 / 65536.0); }

std::uint32_t CellHash(std::int64_t cx, std::int64_t cy, std::uint32_t seed) {
  return HashU32(HashU32(static_cast<std::uint32_t>(cx) + seed) ^
                 (static_cast<std::uint32_t>(cy) * 0x85EBCA77U));
}

Eigen::Vector3d MeanOf(const std::vector<Eigen::Vector3d>& palette) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& c : palette) sum += c;
  return palette.empty() ? Eigen::Vector3d::Constant(0.5) : Eigen::Vector3d(sum / palette.size());
}

struct Candidate {
  float key;
  float alpha;
  std::uint32_t hash;  // the leaf's colour comes from it, only if it is seen
};

}  // namespace

double Grain::Factor(double u_mm, double v_mm, double footprint_mm) const {
  if (amplitude <= 0) return 1.0;
  return 1.0 - amplitude + amplitude * noise.Sample(u_mm, v_mm, footprint_mm);
}

DeadLeaves::DeadLeaves(DeadLeavesParams params) : p_(std::move(params)) {
  if (p_.palette.empty()) p_.palette.push_back({0.6, 0.6, 0.6});
  p_.leaves_per_cell = std::clamp(p_.leaves_per_cell, 1, 4);
  p_.min_radius_mm = std::max(p_.min_radius_mm, 1e-3);
  p_.max_radius_mm = std::max(p_.max_radius_mm, p_.min_radius_mm);
  // The mean leaf: the palette mean at the mean brightness.
  mean_ = MeanOf(p_.palette) * (1.0 - 0.5 * p_.brightness_spread);
  octaves_ = std::clamp(
      static_cast<int>(std::ceil(std::log2(p_.max_radius_mm / p_.min_radius_mm))), 1, 12);
}

Eigen::Vector3d DeadLeaves::Leaves(double u_mm, double v_mm, double footprint_mm) const {
  const double f = std::max(footprint_mm, 1e-6);
  std::array<Candidate, 64> found;
  int count = 0;
  double r_hi = p_.max_radius_mm;
  for (int octave = 0; octave < octaves_; ++octave, r_hi *= 0.5) {
    if (r_hi < 0.25 * f) break;  // leaves this small only shift the mean a little
    const double r_lo = 0.5 * r_hi;
    const double cell = 2.0 * r_hi;
    // Radius density ~ r^-3 on [r_lo, r_hi]: inverse of its CDF.
    const double a = 1.0 / (r_lo * r_lo), b = a - 1.0 / (r_hi * r_hi);
    const double reach2 = (r_hi + f) * (r_hi + f);
    const std::uint32_t octave_seed = HashU32(p_.seed + 0x9E3779B9U * (octave + 1));
    const auto cx0 = static_cast<std::int64_t>(std::floor(u_mm / cell - 0.5));
    const auto cy0 = static_cast<std::int64_t>(std::floor(v_mm / cell - 0.5));
    for (std::int64_t cy = cy0; cy <= cy0 + 1; ++cy)
      for (std::int64_t cx = cx0; cx <= cx0 + 1; ++cx) {
        // One hash per leaf: 10 bits each for its centre (x, y) and radius.
        const std::uint32_t cell_hash = static_cast<std::uint32_t>(cx) * 0x9E3779B1U +
                                        static_cast<std::uint32_t>(cy) * 0x85EBCA77U + octave_seed;
        for (int k = 0; k < p_.leaves_per_cell; ++k) {
          const std::uint32_t h1 = HashU32(cell_hash + 0x27D4EB2FU * k);
          const double dx = u_mm - (cx + (h1 & 0x3FFU) * (1.0 / 1024.0)) * cell;
          const double dy = v_mm - (cy + ((h1 >> 10) & 0x3FFU) * (1.0 / 1024.0)) * cell;
          const double d2 = dx * dx + dy * dy;
          if (d2 > reach2) continue;  // beyond the largest leaf of the octave
          const double r = 1.0 / std::sqrt(a - ((h1 >> 20) & 0x3FFU) * (1.0 / 1024.0) * b);
          if (d2 > (r + f) * (r + f)) continue;
          double signed_distance = std::sqrt(d2) - r;
          const std::uint32_t h2 = HashU32(h1);
          if ((h2 >> 24) * (1.0 / 256.0) < p_.rectangle_share) {
            const double angle = M_PI * (h2 & 0xFFFU) * (1.0 / 4096.0);
            const double aspect = 0.3 + 0.7 * ((h2 >> 12) & 0xFFFU) * (1.0 / 4096.0);
            const double hx = r / std::sqrt(1.0 + aspect * aspect), hy = aspect * hx;
            const double c = std::cos(angle), s = std::sin(angle);
            const double qx = std::abs(c * dx + s * dy) - hx;
            const double qy = std::abs(-s * dx + c * dy) - hy;
            const double ox = std::max(qx, 0.0), oy = std::max(qy, 0.0);
            signed_distance = std::sqrt(ox * ox + oy * oy) + std::min(std::max(qx, qy), 0.0);
          }
          // The share of a footprint-wide window inside the leaf.
          double alpha = std::clamp(0.5 - signed_distance / f, 0.0, 1.0);
          if (r < 0.5 * f) alpha *= (2.0 * r / f) * (2.0 * r / f);
          if (alpha <= 0.0 || count == static_cast<int>(found.size())) continue;
          const std::uint32_t h3 = HashU32(h2 + 0x165667B1U);
          found[count++] = {static_cast<float>((h3 >> 8) * (1.0 / 16777216.0)),
                            static_cast<float>(alpha), h3};
        }
      }
  }
  std::sort(found.begin(), found.begin() + count,
            [](const Candidate& x, const Candidate& y) { return x.key < y.key; });
  Eigen::Vector3d colour = Eigen::Vector3d::Zero();
  double transmittance = 1.0;
  for (int n = 0; n < count && transmittance > 1e-3; ++n) {
    const std::uint32_t h4 = HashU32(found[n].hash);
    const std::uint32_t h5 = HashU32(h4);
    const Eigen::Vector3d& base =
        p_.palette[static_cast<std::size_t>(Unit16(h4) * p_.palette.size())];
    const double brightness = 1.0 - p_.brightness_spread * UnitHigh16(h4);
    Eigen::Vector3d leaf;
    for (int ch = 0; ch < 3; ++ch) {
      const double jitter = p_.colour_jitter * (((h5 >> (10 * ch)) & 0x3FFU) / 511.5 - 1.0);
      leaf[ch] = std::clamp(base[ch] * brightness + jitter, 0.02, 1.0);
    }
    colour += transmittance * found[n].alpha * leaf;
    transmittance *= 1.0 - found[n].alpha;
  }
  return colour + transmittance * mean_;
}

Eigen::Vector3d DeadLeaves::Reflectance(double u_mm, double v_mm, double footprint_mm) const {
  return Leaves(u_mm, v_mm, footprint_mm) * p_.grain.Factor(u_mm, v_mm, footprint_mm);
}

BandedNoise::BandedNoise(BandedNoiseParams params) : p_(std::move(params)) {
  if (p_.palette.empty()) p_.palette.push_back({0.6, 0.6, 0.6});
  p_.bands = std::max(p_.bands, 1);
}

Eigen::Vector3d BandedNoise::Reflectance(double u_mm, double v_mm, double footprint_mm) const {
  const double f = std::max(footprint_mm, p_.noise.finest_mm);
  const double t = p_.noise.Sample(u_mm, v_mm, footprint_mm);
  const double tx = p_.noise.Sample(u_mm + f, v_mm, footprint_mm);
  const double ty = p_.noise.Sample(u_mm, v_mm + f, footprint_mm);
  // Band coordinate x = t * bands; a footprint spans w of it (the noise
  // gradient times the footprint): box-filter the step between two bands.
  const double x = t * p_.bands;
  const double w = std::clamp(p_.bands * std::hypot(tx - t, ty - t), 1e-3, 1.0);
  const double boundary = std::round(x);
  const auto band = [&](double k) -> const Eigen::Vector3d& {
    const int n = static_cast<int>(p_.palette.size());
    return p_.palette[((static_cast<int>(k) % n) + n) % n];
  };
  Eigen::Vector3d colour;
  if (std::abs(x - boundary) < 0.5 * w) {
    const double below = (boundary - (x - 0.5 * w)) / w;
    colour = below * band(boundary - 1) + (1.0 - below) * band(boundary);
  } else {
    colour = band(std::floor(x));
  }
  return colour * p_.grain.Factor(u_mm, v_mm, footprint_mm);
}

PrintedPage::PrintedPage(PrintedPageParams params)
    : p_(std::move(params)), photo_(p_.photo) {}

double PrintedPage::Ink(double x_mm, double y_mm, double glyph_px_mm, std::uint32_t block_seed,
                        double footprint_mm) const {
  // Glyph cell: 5 x 7 pixels plus one column of spacing; lines 10 pixels apart.
  const double gx = x_mm / glyph_px_mm, gy = y_mm / glyph_px_mm;
  const auto line = static_cast<std::int64_t>(std::floor(gy / 10.0));
  const auto column = static_cast<std::int64_t>(std::floor(gx / 6.0));
  const double lx = gx - 6.0 * column, ly = gy - 10.0 * line;
  const std::uint32_t glyph = CellHash(column, line, block_seed);
  // About one cell in six is a space between words; a line ends at a random length.
  const bool space = (glyph & 0xFFU) < 42U;
  const bool past_end = column > 6 + static_cast<std::int64_t>(HashU32(block_seed + line) % 40U);
  const double mean = 0.29;  // 35 bits at density 1/2 over 60 pixels
  if (space || past_end) return 0.0;
  const std::uint32_t bits_lo = HashU32(glyph), bits_hi = HashU32(bits_lo);
  const auto bit = [&](int bx, int by) -> double {
    if (bx < 0 || by < 0 || bx > 4 || by > 6) return 0.0;
    const int index = by * 5 + bx;
    return ((index < 32 ? bits_lo >> index : bits_hi >> (index - 32)) & 1U) ? 1.0 : 0.0;
  };
  // Bilinear between pixel centres, then a step as sharp as the footprint allows.
  const double px = lx - 0.5, py = ly - 0.5;
  const int x0 = static_cast<int>(std::floor(px)), y0 = static_cast<int>(std::floor(py));
  const double fx = px - x0, fy = py - y0;
  const double smooth = (bit(x0, y0) * (1 - fx) + bit(x0 + 1, y0) * fx) * (1 - fy) +
                        (bit(x0, y0 + 1) * (1 - fx) + bit(x0 + 1, y0 + 1) * fx) * fy;
  const double sharpness = std::max(glyph_px_mm / std::max(footprint_mm, 1e-6), 1.0);
  const double ink = std::clamp((smooth - 0.5) * sharpness + 0.5, 0.0, 1.0);
  // Glyph pixels smaller than the footprint: towards the mean coverage.
  const double fade = std::clamp((footprint_mm / glyph_px_mm - 1.0) / 2.0, 0.0, 1.0);
  return ink + (mean - ink) * fade;
}

Eigen::Vector3d PrintedPage::Reflectance(double u_mm, double v_mm, double footprint_mm) const {
  const double block = p_.block_mm;
  const auto bx = static_cast<std::int64_t>(std::floor(u_mm / block));
  const auto by = static_cast<std::int64_t>(std::floor(v_mm / block));
  const std::uint32_t block_seed = CellHash(bx, by, p_.seed);
  const double x = u_mm - bx * block, y = v_mm - by * block;
  constexpr double kMarginMm = 4.0;
  // Signed distance to the printed area inside the block's margin.
  const double inside = std::min(std::min(x, block - x), std::min(y, block - y)) - kMarginMm;
  const double f = std::max(footprint_mm, 1e-6);
  const double alpha = std::clamp(0.5 + inside / f, 0.0, 1.0);
  Eigen::Vector3d colour = p_.paper;
  if (alpha > 0) {
    Eigen::Vector3d print;
    if (UnitHigh16(block_seed) < p_.photo_share) {
      print = photo_.Leaves(u_mm, v_mm, footprint_mm);
    } else {
      const bool title = (block_seed & 0x7U) == 0;
      const double glyph = (title ? 2.0 : 1.0) * p_.glyph_height_mm / 7.0;
      const double ink = Ink(x - kMarginMm, y - kMarginMm, glyph, block_seed, footprint_mm);
      print = p_.paper + ink * (p_.ink - p_.paper);
    }
    colour += alpha * (print - p_.paper);
  }
  return colour * p_.grain.Factor(u_mm, v_mm, footprint_mm);
}

std::vector<Eigen::Vector3d> PaletteFoliage() {
  return {{0.10, 0.32, 0.08}, {0.18, 0.45, 0.12}, {0.30, 0.55, 0.15}, {0.08, 0.22, 0.10},
          {0.45, 0.50, 0.18}, {0.25, 0.40, 0.30}};
}

std::vector<Eigen::Vector3d> PaletteWood() {
  return {{0.55, 0.36, 0.20}, {0.68, 0.48, 0.28}, {0.42, 0.26, 0.14}, {0.78, 0.60, 0.40},
          {0.35, 0.22, 0.12}};
}

std::vector<Eigen::Vector3d> PaletteCloth() {
  return {{0.75, 0.20, 0.18}, {0.90, 0.75, 0.30}, {0.20, 0.35, 0.65}, {0.85, 0.85, 0.80},
          {0.15, 0.15, 0.18}, {0.35, 0.60, 0.35}, {0.70, 0.45, 0.65}};
}

std::vector<Eigen::Vector3d> PalettePhoto() {
  return {{0.45, 0.65, 0.90}, {0.85, 0.65, 0.50}, {0.25, 0.45, 0.20}, {0.90, 0.88, 0.80},
          {0.60, 0.20, 0.15}, {0.30, 0.30, 0.35}, {0.95, 0.80, 0.30}};
}

std::vector<Eigen::Vector3d> PaletteStone() {
  return {{0.55, 0.55, 0.52}, {0.35, 0.34, 0.33}, {0.75, 0.73, 0.68}, {0.48, 0.44, 0.40},
          {0.62, 0.60, 0.58}};
}

}  // namespace lifmcr::synth
