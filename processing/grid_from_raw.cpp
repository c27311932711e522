#include "processing/grid_from_raw.h"

#include <Eigen/Dense>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

namespace lifmcr::processing {
namespace {

// Bilinear grey (channel mean) at (x, y), inside [0, w-1) x [0, h-1).
double Bilinear(ConstImageView image, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  auto grey = [&](int xx, int yy) -> double {
    const std::uint8_t* row = image.Row(yy);
    if (image.format == PixelFormat::kMono8) return row[xx];
    return (row[3 * xx] + row[3 * xx + 1] + row[3 * xx + 2]) / 3.0;
  };
  return (grey(x0, y0) * (1 - fx) + grey(x0 + 1, y0) * fx) * (1 - fy) +
         (grey(x0, y0 + 1) * (1 - fx) + grey(x0 + 1, y0 + 1) * fx) * fy;
}

struct Tile {
  Eigen::Vector2d mean_index = Eigen::Vector2d::Zero();
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();  // delta_T
  int lenses = 0;
  bool ok = false;
};

}  // namespace

Status RawGridFitOptions::Check() const {
  if (iterations < 1) return Error{"raw grid fit: iterations: expected >= 1"};
  if (min_lenses_per_tile < 10) return Error{"raw grid fit: min_lenses_per_tile: expected >= 10"};
  if (max_tiles_per_side < 2) return Error{"raw grid fit: max_tiles_per_side: expected >= 2"};
  return Status::Ok();
}

Expected<GridFitResult> FitGridToRawImage(ConstImageView raw, const MlaGrid* initial,
                                          const RawGridFitOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  const auto start = std::chrono::steady_clock::now();
  const int w = raw.width, h = raw.height;
  if (raw.data == nullptr || w < 32 || h < 32)
    return Error{"raw image: expected at least 32 x 32 pixels"};
  MlaGrid grid;
  if (initial != nullptr) {
    grid = *initial;
  } else {
    Expected<GridFitResult> first = FitGridToWhiteImage(raw, nullptr);
    if (!first)
      return Error{"raw image: no first lattice without an MLA file (" + first.error().message +
                   "); give the camera's MLA file"};
    grid = first->grid;
  }
  const double pitch = grid.PitchPx();
  // The integer sizes from the nominal pitch: a pitch read from a file is a
  // rounding error off its value (mla_grid.h, NominalPitchPx).
  const double nominal_pitch = grid.NominalPitchPx();
  const int radius = static_cast<int>(std::ceil(0.5 * nominal_pitch));
  const int side = 2 * radius + 1;
  const int core_r = std::max(2, static_cast<int>(0.3 * nominal_pitch));
  // Tiles: lenses per tile ~ tile area / (sqrt(3)/2 D^2).
  const double lens_area = 0.8660254037844386 * pitch * pitch;
  const double tile_px = std::sqrt(options.min_lenses_per_tile * lens_area);
  const int tx = std::clamp(static_cast<int>(w / tile_px), 1, options.max_tiles_per_side);
  const int ty = std::clamp(static_cast<int>(h / tile_px), 1, options.max_tiles_per_side);
  if (tx * ty < 3) return Error{"raw image: too few micro images for a lattice fit from texture"};

  GridFitResult result;
  for (int round = 0; round < options.iterations; ++round) {
    int i_min = 0, i_max = 0, j_min = 0, j_max = 0;
    grid.IndexBounds(w, h, &i_min, &i_max, &j_min, &j_max);
    std::vector<Tile> tiles(static_cast<std::size_t>(tx) * ty);
    tbb::parallel_for(0, tx * ty, [&](int t) {
      const int gx = t % tx, gy = t / tx;
      const double x_lo = static_cast<double>(gx) * w / tx,
                   x_hi = static_cast<double>(gx + 1) * w / tx;
      const double y_lo = static_cast<double>(gy) * h / ty,
                   y_hi = static_cast<double>(gy + 1) * h / ty;
      std::vector<double> fold(static_cast<std::size_t>(side) * side, 0.0);
      std::vector<double> samples(fold.size());
      std::vector<float> stack;  // lens-major: every usable lens's normalised samples
      Tile& tile = tiles[t];
      for (int j = j_min; j <= j_max; ++j)
        for (int i = i_min; i <= i_max; ++i) {
          const Eigen::Vector2d c = grid.Center(i, j);
          if (c.x() < x_lo || c.x() >= x_hi || c.y() < y_lo || c.y() >= y_hi) continue;
          if (c.x() - radius < 0 || c.y() - radius < 0 || c.x() + radius >= w - 1 ||
              c.y() + radius >= h - 1)
            continue;
          for (int v = -radius; v <= radius; ++v)
            for (int u = -radius; u <= radius; ++u)
              samples[static_cast<std::size_t>(v + radius) * side + (u + radius)] =
                  Bilinear(raw, c.x() + u, c.y() + v);
          // The lens's own brightness and gradient, a + g . u, fitted in its
          // core (within core_r, where the vignetting is flat): divided out,
          // so neither the scene's brightness nor its gradient across the
          // micro image (a ramp would move the centroid) enters the fold.
          Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
          Eigen::Vector3d atb = Eigen::Vector3d::Zero();
          for (int v = -core_r; v <= core_r; ++v)
            for (int u = -core_r; u <= core_r; ++u) {
              if (u * u + v * v > core_r * core_r) continue;
              const Eigen::Vector3d a(1.0, u, v);
              ata += a * a.transpose();
              atb += a * samples[static_cast<std::size_t>(v + radius) * side + (u + radius)];
            }
          const Eigen::Vector3d plane = ata.ldlt().solve(atb);
          if (!(plane(0) > 2.0)) continue;  // a black micro image says nothing
          bool usable = true;
          for (int v = -radius; v <= radius && usable; ++v)
            for (int u = -radius; u <= radius; ++u) {
              const double level = plane(0) + plane(1) * u + plane(2) * v;
              if (!(level > 0.25 * plane(0))) {  // a steep ramp: no level to divide by
                usable = false;
                break;
              }
              samples[static_cast<std::size_t>(v + radius) * side + (u + radius)] /= level;
            }
          if (!usable) continue;
          stack.insert(stack.end(), samples.begin(), samples.end());
          tile.mean_index += Eigen::Vector2d(i, j);
          ++tile.lenses;
        }
      if (tile.lenses < options.min_lenses_per_tile / 2) return;
      tile.mean_index /= tile.lenses;
      // Median over the lenses per offset u: a few micro images of strong
      // texture (an object's edge, a dark patch that looks like a gap) do
      // not move it.
      std::vector<float> column(tile.lenses);
      for (std::size_t n = 0; n < fold.size(); ++n) {
        for (int k = 0; k < tile.lenses; ++k) column[k] = stack[k * fold.size() + n];
        std::nth_element(column.begin(), column.begin() + tile.lenses / 2, column.end());
        fold[n] = column[tile.lenses / 2];
      }
      double peak = 0;
      for (int v = -radius; v <= radius; ++v)
        for (int u = -radius; u <= radius; ++u)
          if (u * u + v * v <= radius * radius)
            peak = std::max(peak, fold[static_cast<std::size_t>(v + radius) * side + (u + radius)]);
      const double half = 0.5 * peak;
      double sw = 0;
      Eigen::Vector2d su = Eigen::Vector2d::Zero();
      for (int v = -radius; v <= radius; ++v)
        for (int u = -radius; u <= radius; ++u) {
          if (u * u + v * v > radius * radius) continue;
          const double wgt = std::max(
              0.0, fold[static_cast<std::size_t>(v + radius) * side + (u + radius)] - half);
          sw += wgt;
          su += wgt * Eigen::Vector2d(u, v);
        }
      if (!(sw > 0)) return;
      tile.shift = su / sw;
      tile.ok = true;
    });
    // Affine least squares over the tiles, weighted by their lens counts;
    // then again without the tiles whose centre is off the first fit by more
    // than max(0.1 px, 3 x the median residual) (texture that the median
    // fold did not tame).
    std::vector<char> use(tiles.size());
    for (std::size_t t = 0; t < tiles.size(); ++t) use[t] = tiles[t].ok;
    MlaGrid next = grid;
    std::vector<double> residual(tiles.size(), 0.0);
    int used = 0, lenses = 0;
    for (int pass = 0; pass < 2; ++pass) {
      Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
      Eigen::Matrix<double, 3, 2> atb = Eigen::Matrix<double, 3, 2>::Zero();
      used = lenses = 0;
      for (std::size_t t = 0; t < tiles.size(); ++t) {
        if (!use[t]) continue;
        const Tile& tile = tiles[t];
        const Eigen::Vector3d a(1.0, tile.mean_index.x(), tile.mean_index.y());
        const Eigen::Vector2d measured =
            grid.Center(0, 0) + grid.lattice * tile.mean_index + tile.shift;
        ata += tile.lenses * a * a.transpose();
        atb += tile.lenses * a * measured.transpose();
        ++used;
        lenses += tile.lenses;
      }
      if (used < 3)
        return Error{"raw image: fewer than 3 regions with enough lit micro images for a fit"};
      const Eigen::Matrix<double, 3, 2> x = ata.ldlt().solve(atb);
      next.reference_px = x.row(0).transpose();
      next.lattice.col(0) = x.row(1).transpose();
      next.lattice.col(1) = x.row(2).transpose();
      std::vector<double> kept;
      for (std::size_t t = 0; t < tiles.size(); ++t) {
        if (!tiles[t].ok) continue;
        const Tile& tile = tiles[t];
        const Eigen::Vector2d measured =
            grid.Center(0, 0) + grid.lattice * tile.mean_index + tile.shift;
        residual[t] = (next.reference_px + next.lattice * tile.mean_index - measured).norm();
        if (use[t]) kept.push_back(residual[t]);
      }
      if (pass == 1) break;
      std::nth_element(kept.begin(), kept.begin() + kept.size() / 2, kept.end());
      const double limit = std::max(0.1, 3.0 * kept[kept.size() / 2]);
      int dropped = 0;
      for (std::size_t t = 0; t < tiles.size(); ++t)
        if (use[t] && residual[t] > limit) {
          use[t] = 0;
          ++dropped;
        }
      if (dropped == 0 || used - dropped < 3) break;
    }
    const int measured_tiles = static_cast<int>(
        std::count_if(tiles.begin(), tiles.end(), [](const Tile& t) { return t.ok; }));
    // A lattice that explains the image: most regions agree, and they hold
    // a quarter or more of the micro images the image has room for.
    const double room = static_cast<double>(w) * h / lens_area;
    if (round == options.iterations - 1 && (2 * used < measured_tiles || lenses < 0.25 * room))
      return Error{"raw image: the lattice agrees with " + std::to_string(used) + " of " +
                   std::to_string(measured_tiles) + " regions holding " + std::to_string(lenses) +
                   " of about " + std::to_string(static_cast<int>(room)) + " micro images" +
                   (initial == nullptr ? "; give the camera's MLA file as a start" : "")};
    double sum2 = 0;
    for (std::size_t t = 0; t < tiles.size(); ++t)
      if (use[t]) sum2 += tiles[t].lenses * residual[t] * residual[t];
    grid = next;
    result.lenses = lenses;
    result.rejected = 0;  // lenses of the regions dropped as off the fit
    for (std::size_t t = 0; t < tiles.size(); ++t)
      if (tiles[t].ok && !use[t]) result.rejected += tiles[t].lenses;
    result.rms_px = std::sqrt(sum2 / lenses);
  }
  result.grid = grid;
  const Eigen::Vector2d a = grid.lattice.col(0), b = grid.lattice.col(1);
  result.aspect = b.norm() / a.norm();
  result.shear = a.dot(b) / (a.norm() * b.norm()) - 0.5;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace lifmcr::processing
