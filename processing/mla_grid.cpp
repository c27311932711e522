#include "processing/mla_grid.h"

#include <Eigen/Dense>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <limits>
#include <numeric>

namespace lifmcr::processing {
namespace {

constexpr double kSqrt3Over2 = 0.86602540378443864676;

// Grey level (mean of the channels) as float.
// Grey of the window [x_lo, x_lo + ww) x [y_lo, y_lo + wh) of `image`.
std::vector<float> WindowGrey(ConstImageView image, int x_lo, int y_lo, int ww, int wh) {
  std::vector<float> grey(static_cast<std::size_t>(ww) * wh);
  const int bpp = BytesPerPixel(image.format);
  tbb::parallel_for(0, wh, [&](int y) {
    const std::uint8_t* row = image.Row(y_lo + y);
    float* out = grey.data() + static_cast<std::size_t>(y) * ww;
    for (int x = 0; x < ww; ++x) {
      const int xx = x_lo + x;
      out[x] = bpp == 1 ? row[xx] : (row[3 * xx] + row[3 * xx + 1] + row[3 * xx + 2]) / 3.0f;
    }
  });
  return grey;
}

struct Blob {
  Eigen::Vector2d centre;
  double area = 0;
};

// Connected components of grey > threshold (4-connected), centroids.
// Within the window [x_lo, x_hi) x [y_lo, y_hi) of the w-wide image.
std::vector<Blob> FindBlobs(const std::vector<float>& grey, int w, int x_lo, int y_lo, int x_hi,
                            int y_hi, float threshold) {
  std::vector<std::uint8_t> seen(grey.size(), 0);
  std::vector<int> stack;
  std::vector<Blob> blobs;
  for (int y0 = y_lo; y0 < y_hi; ++y0)
    for (int x0 = x_lo; x0 < x_hi; ++x0) {
      const std::size_t i0 = static_cast<std::size_t>(y0) * w + x0;
      if (seen[i0] || grey[i0] <= threshold) continue;
      seen[i0] = 1;
      stack.assign(1, static_cast<int>(i0));
      double sx = 0, sy = 0, n = 0;
      bool border = false;
      while (!stack.empty()) {
        const int idx = stack.back();
        stack.pop_back();
        const int x = idx % w, y = idx / w;
        sx += x;
        sy += y;
        n += 1;
        if (x == x_lo || y == y_lo || x == x_hi - 1 || y == y_hi - 1) {
          border = true;
          continue;
        }
        for (const int next : {idx - 1, idx + 1, idx - w, idx + w}) {
          if (!seen[next] && grey[next] > threshold) {
            seen[next] = 1;
            stack.push_back(next);
          }
        }
      }
      if (!border) blobs.push_back({Eigen::Vector2d(sx / n, sy / n), n});
    }
  return blobs;
}

// Least squares c = o + A (i, j) over the centres; residuals out.
void FitAffine(const std::vector<Eigen::Vector2i>& index,
               const std::vector<Eigen::Vector2d>& centre, const std::vector<char>& use,
               MlaGrid* grid) {
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Matrix<double, 3, 2> atb = Eigen::Matrix<double, 3, 2>::Zero();
  for (std::size_t k = 0; k < index.size(); ++k) {
    if (!use[k]) continue;
    const Eigen::Vector3d a(1.0, index[k].x(), index[k].y());
    ata += a * a.transpose();
    atb += a * centre[k].transpose();
  }
  const Eigen::Matrix<double, 3, 2> x = ata.ldlt().solve(atb);
  grid->reference_px = x.row(0).transpose();
  grid->lattice.col(0) = x.row(1).transpose();
  grid->lattice.col(1) = x.row(2).transpose();
}

}  // namespace

int Mod3(int x) { return ((x % 3) + 3) % 3; }

void MlaGrid::Nearest(const Eigen::Vector2d& p_px, int* i, int* j) const {
  const Eigen::Vector2d axial = lattice.inverse() * (p_px - reference_px);
  const double q = axial.x(), r = axial.y(), s = -q - r;
  double rq = std::round(q), rr = std::round(r);
  const double rs = std::round(s);
  const double dq = std::abs(rq - q), dr = std::abs(rr - r), ds = std::abs(rs - s);
  if (dq > dr && dq > ds)
    rq = -rr - rs;
  else if (dr > ds)
    rr = -rq - rs;
  *i = static_cast<int>(rq);
  *j = static_cast<int>(rr);
}

double MlaGrid::PitchPx() const { return 0.5 * (lattice.col(0).norm() + lattice.col(1).norm()); }

double MlaGrid::NominalPitchPx() const { return std::round(PitchPx() * 1e6) / 1e6; }

double MlaGrid::RotationRad() const { return std::atan2(-lattice(1, 0), lattice(0, 0)); }

void MlaGrid::IndexBounds(int width, int height, int* i_min, int* i_max, int* j_min,
                          int* j_max) const {
  const Eigen::Matrix2d inv = lattice.inverse();
  double lo[2] = {1e18, 1e18}, hi[2] = {-1e18, -1e18};
  for (const Eigen::Vector2d& corner :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(width - 1, 0), Eigen::Vector2d(0, height - 1),
        Eigen::Vector2d(width - 1, height - 1)}) {
    const Eigen::Vector2d a = inv * (corner - reference_px);
    for (int d = 0; d < 2; ++d) {
      lo[d] = std::min(lo[d], a(d));
      hi[d] = std::max(hi[d], a(d));
    }
  }
  *i_min = static_cast<int>(std::floor(lo[0])) - 1;
  *i_max = static_cast<int>(std::ceil(hi[0])) + 1;
  *j_min = static_cast<int>(std::floor(lo[1])) - 1;
  *j_max = static_cast<int>(std::ceil(hi[1])) + 1;
}

MlaGrid MlaGrid::FromCalibration(const MlaCalibration& mla, int width, int height) {
  MlaGrid grid;
  grid.reference_px = mla.ReferenceLensCenterPx(width, height);
  const double c = std::cos(mla.rotation_rad), s = std::sin(mla.rotation_rad);
  Eigen::Matrix2d rotation;
  rotation << c, -s, s, c;
  Eigen::Matrix2d bases;
  bases.col(0) = mla.lens_base_x;
  bases.col(1) = mla.lens_base_y;
  const Eigen::Matrix2d flip_y = Eigen::Vector2d(1, -1).asDiagonal();
  grid.lattice = flip_y * rotation * bases * mla.diameter_px;
  // Type 1's offset in lattice steps decides the colouring's sign.
  const Eigen::Vector2d steps = bases.inverse() * mla.lens_types[1].offset_lens;
  const int di = static_cast<int>(std::lround(steps.x())),
            dj = static_cast<int>(std::lround(steps.y()));
  grid.type_sign = Mod3(di - dj) == 2 ? -1 : 1;
  grid.types_known = true;
  return grid;
}

MlaCalibration MlaGrid::ToCalibration(const MlaCalibration& base, int width, int height) const {
  MlaCalibration mla = base;
  const Eigen::Vector2d centre((width - 1) / 2.0, (height - 1) / 2.0);
  mla.offset_px = {reference_px.x() - centre.x(), centre.y() - reference_px.y()};
  // Pitch and rotation of the similarity nearest to A (in the file's bases).
  Eigen::Matrix2d bases;
  bases.col(0) = base.lens_base_x;
  bases.col(1) = base.lens_base_y;
  const Eigen::Matrix2d flip_y = Eigen::Vector2d(1, -1).asDiagonal();
  const Eigen::Matrix2d m = flip_y * lattice * bases.inverse();  // ~ D R(theta)
  const double a = 0.5 * (m(0, 0) + m(1, 1)), b = 0.5 * (m(1, 0) - m(0, 1));
  mla.diameter_px = std::hypot(a, b);
  mla.rotation_rad = std::atan2(b, a);
  return mla;
}

std::string GridFitResult::BriefReport() const {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "pitch %.4f px, rotation %.6f rad, reference lens (%.3f, %.3f) px, aspect %.5f, "
                "shear %.2e, %d lenses (%d rejected), residual %.4f px RMS, %.3f s",
                grid.PitchPx(), grid.RotationRad(), grid.reference_px.x(), grid.reference_px.y(),
                aspect, shear, lenses, rejected, rms_px, seconds);
  return buf;
}

Status GridFitOptions::Check() const {
  if (iterations < 1 || iterations > 100) return Error{"grid fit options: iterations: expected 1..100"};
  if (!(window_fraction > 0 && window_fraction <= 1))
    return Error{"grid fit options: window_fraction: expected in (0, 1]"};
  if (!(outlier_px > 0)) return Error{"grid fit options: outlier_px: expected > 0"};
  return Status::Ok();
}

Expected<GridFitResult> FitGridToWhiteImage(ConstImageView white, const MlaGrid* initial,
                                            const GridFitOptions& options) {
  if (Status s = options.Check(); !s) return s.error();
  const auto start = std::chrono::steady_clock::now();
  const int w = white.width, h = white.height;
  if (w < 32 || h < 32 || white.data == nullptr)
    return Error{"white image: expected at least 32 x 32 pixels"};
  // Grey read straight from the 8-bit image (a float copy of a whole R32
  // white image is 130 MB of fresh pages, slower than the fit itself).
  const bool mono = white.format == PixelFormat::kMono8;
  auto grey_at = [&](int x, int y) -> float {
    const std::uint8_t* row = white.Row(y);
    return mono ? row[x] : (row[3 * x] + row[3 * x + 1] + row[3 * x + 2]) * (1.0f / 3.0f);
  };

  // 1. Discs above half the bright level: components -> first lattice.
  // Bright level: 99th percentile of every 4th pixel of every 4th row.
  std::vector<float> sorted;
  sorted.reserve(static_cast<std::size_t>(w / 4 + 1) * (h / 4 + 1));
  for (int y = 0; y < h; y += 4)
    for (int x = 0; x < w; x += 4) sorted.push_back(grey_at(x, y));
  const std::size_t p99 = sorted.size() * 99 / 100;
  std::nth_element(sorted.begin(), sorted.begin() + p99, sorted.end());
  const float bright = sorted[p99];
  if (!(bright > 10.0f)) return Error{"white image: too dark (99th percentile <= 10 DN)"};
  // Components in a central window of at most 1536 x 1536 px (enough lenses
  // for the first lattice; the refinement below uses the whole image).
  const int win_w = std::min(w, 1536), win_h = std::min(h, 1536);
  const int x_lo = (w - win_w) / 2, y_lo = (h - win_h) / 2;
  std::vector<Blob> blobs = FindBlobs(WindowGrey(white, x_lo, y_lo, win_w, win_h), win_w, 0, 0,
                                      win_w, win_h, 0.5f * bright);
  for (Blob& b : blobs) b.centre += Eigen::Vector2d(x_lo, y_lo);
  if (blobs.size() < 20)
    return Error{"white image: found " + std::to_string(blobs.size()) +
                 " micro images, expected at least 20 (is it a white image?)"};
  std::vector<double> areas;
  for (const Blob& b : blobs) areas.push_back(b.area);
  std::nth_element(areas.begin(), areas.begin() + areas.size() / 2, areas.end());
  const double median_area = areas[areas.size() / 2];
  std::erase_if(blobs, [&](const Blob& b) {
    return b.area < 0.5 * median_area || b.area > 1.5 * median_area;
  });
  const double disc_px = 2.0 * std::sqrt(median_area / M_PI);
  // Nearest neighbours through a bucket grid of cell size ~ D.
  const double cell = 1.2 * disc_px;
  const int gw = static_cast<int>(w / cell) + 1, gh = static_cast<int>(h / cell) + 1;
  std::vector<std::vector<int>> buckets(static_cast<std::size_t>(gw) * gh);
  for (std::size_t k = 0; k < blobs.size(); ++k) {
    const int bx = static_cast<int>(blobs[k].centre.x() / cell),
              by = static_cast<int>(blobs[k].centre.y() / cell);
    buckets[static_cast<std::size_t>(by) * gw + bx].push_back(static_cast<int>(k));
  }
  std::vector<double> nn_dist;
  std::complex<double> sixfold = 0;
  for (std::size_t k = 0; k < blobs.size(); ++k) {
    const int bx = static_cast<int>(blobs[k].centre.x() / cell),
              by = static_cast<int>(blobs[k].centre.y() / cell);
    double best = std::numeric_limits<double>::max();
    Eigen::Vector2d best_d = Eigen::Vector2d::Zero();
    for (int yy = std::max(0, by - 1); yy <= std::min(gh - 1, by + 1); ++yy)
      for (int xx = std::max(0, bx - 1); xx <= std::min(gw - 1, bx + 1); ++xx)
        for (int other : buckets[static_cast<std::size_t>(yy) * gw + xx]) {
          if (other == static_cast<int>(k)) continue;
          const Eigen::Vector2d d = blobs[other].centre - blobs[k].centre;
          if (d.norm() < best) {
            best = d.norm();
            best_d = d;
          }
        }
    if (best == std::numeric_limits<double>::max()) continue;
    nn_dist.push_back(best);
    sixfold += std::polar(1.0, 6.0 * std::atan2(-best_d.y(), best_d.x()));
  }
  if (nn_dist.size() < 10) return Error{"white image: micro images have no neighbours"};
  std::nth_element(nn_dist.begin(), nn_dist.begin() + nn_dist.size() / 2, nn_dist.end());
  const double pitch = nn_dist[nn_dist.size() / 2];
  const double theta = std::arg(sixfold) / 6.0;
  MlaGrid grid;
  {
    const Eigen::Vector2d centre((w - 1) / 2.0, (h - 1) / 2.0);
    std::size_t nearest = 0;
    for (std::size_t k = 0; k < blobs.size(); ++k)
      if ((blobs[k].centre - centre).norm() < (blobs[nearest].centre - centre).norm()) nearest = k;
    grid.reference_px = blobs[nearest].centre;
    const double c = std::cos(theta), s = std::sin(theta);
    Eigen::Matrix2d rotation;
    rotation << c, -s, s, c;
    Eigen::Matrix2d basis;
    basis << 1.0, 0.5, 0.0, kSqrt3Over2;
    grid.lattice = Eigen::Matrix2d(Eigen::Vector2d(1, -1).asDiagonal()) * rotation * basis * pitch;
  }
  // Affine fit to the blob centroids (robust first lattice).
  {
    std::vector<Eigen::Vector2i> index;
    std::vector<Eigen::Vector2d> centre;
    for (const Blob& b : blobs) {
      int i = 0, j = 0;
      grid.Nearest(b.centre, &i, &j);
      if ((grid.Center(i, j) - b.centre).norm() > 0.25 * pitch) continue;
      index.emplace_back(i, j);
      centre.push_back(b.centre);
    }
    std::vector<char> use(index.size(), 1);
    FitAffine(index, centre, use, &grid);
  }
  // Reference lens: the MLA file's (with its bases, and so its lens types),
  // else the lattice node nearest the image centre.
  if (initial == nullptr) {
    int i0 = 0, j0 = 0;
    grid.Nearest(Eigen::Vector2d((w - 1) / 2.0, (h - 1) / 2.0), &i0, &j0);
    grid.reference_px = grid.Center(i0, j0);
  } else {
    int i0 = 0, j0 = 0;
    grid.Nearest(initial->reference_px, &i0, &j0);
    if ((grid.Center(i0, j0) - initial->reference_px).norm() > 0.3 * pitch)
      return Error{"white image: the MLA file's reference lens is not near a micro image"};
    const Eigen::Matrix2d m = grid.lattice.inverse() * initial->lattice;
    const Eigen::Matrix2d steps = m.array().round().matrix();
    if ((m - steps).cwiseAbs().maxCoeff() > 0.2 ||
        std::abs(std::abs(steps.determinant()) - 1) > 1e-9)
      return Error{
          "white image: the MLA file's lattice does not match the image (pitch or rotation)"};
    grid.reference_px = grid.Center(i0, j0);
    grid.lattice = grid.lattice * steps;
    grid.type_sign = initial->type_sign;
    grid.types_known = initial->types_known;
  }

  // 2. Per lens: centroid of (I - half plateau)^+ within the window; affine fit.
  int i_min = 0, i_max = 0, j_min = 0, j_max = 0;
  grid.IndexBounds(w, h, &i_min, &i_max, &j_min, &j_max);
  const int ni = i_max - i_min + 1, nj = j_max - j_min + 1;
  std::vector<Eigen::Vector2d> centres(static_cast<std::size_t>(ni) * nj);
  std::vector<char> found(centres.size(), 0);
  GridFitResult result;
  for (int round = 0; round < std::max(1, options.iterations); ++round) {
    const double radius = options.window_fraction * grid.PitchPx();
    tbb::parallel_for(
        tbb::blocked_range<int>(j_min, j_max + 1), [&](const tbb::blocked_range<int>& rj) {
          for (int j = rj.begin(); j < rj.end(); ++j)
            for (int i = i_min; i <= i_max; ++i) {
              const std::size_t slot = static_cast<std::size_t>(j - j_min) * ni + (i - i_min);
              found[slot] = 0;
              const Eigen::Vector2d p = grid.Center(i, j);
              if (p.x() - radius < 1 || p.y() - radius < 1 || p.x() + radius > w - 2 ||
                  p.y() + radius > h - 2)
                continue;
              const int x0 = static_cast<int>(std::floor(p.x() - radius)),
                        x1 = static_cast<int>(std::ceil(p.x() + radius));
              const int y0 = static_cast<int>(std::floor(p.y() - radius)),
                        y1 = static_cast<int>(std::ceil(p.y() + radius));
              float peak = 0;
              for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x)
                  if ((Eigen::Vector2d(x, y) - p).squaredNorm() <= radius * radius)
                    peak = std::max(peak, grey_at(x, y));
              if (peak < 0.25f * bright) continue;
              const float half = 0.5f * peak;
              double sw = 0, sx = 0, sy = 0;
              for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x) {
                  if ((Eigen::Vector2d(x, y) - p).squaredNorm() > radius * radius) continue;
                  const double wgt = std::max(0.0f, grey_at(x, y) - half);
                  sw += wgt;
                  sx += wgt * x;
                  sy += wgt * y;
                }
              if (sw <= 0) continue;
              centres[slot] = {sx / sw, sy / sw};
              found[slot] = 1;
            }
        });
    std::vector<Eigen::Vector2i> index;
    std::vector<Eigen::Vector2d> measured;
    for (int j = j_min; j <= j_max; ++j)
      for (int i = i_min; i <= i_max; ++i) {
        const std::size_t slot = static_cast<std::size_t>(j - j_min) * ni + (i - i_min);
        if (!found[slot]) continue;
        index.emplace_back(i, j);
        measured.push_back(centres[slot]);
      }
    if (index.size() < 10) return Error{"white image: fewer than 10 micro images inside the frame"};
    std::vector<char> use(index.size(), 1);
    FitAffine(index, measured, use, &grid);
    int rejected = 0;
    for (std::size_t k = 0; k < index.size(); ++k)
      if ((grid.Center(index[k].x(), index[k].y()) - measured[k]).norm() > options.outlier_px) {
        use[k] = 0;
        ++rejected;
      }
    if (rejected > 0) FitAffine(index, measured, use, &grid);
    double sum2 = 0;
    int used = 0;
    for (std::size_t k = 0; k < index.size(); ++k) {
      if (!use[k]) continue;
      sum2 += (grid.Center(index[k].x(), index[k].y()) - measured[k]).squaredNorm();
      ++used;
    }
    result.lenses = used;
    result.rejected = rejected;
    result.rms_px = std::sqrt(sum2 / std::max(1, used));
  }
  result.grid = grid;
  const Eigen::Vector2d a = grid.lattice.col(0), b = grid.lattice.col(1);
  result.aspect = b.norm() / a.norm();
  result.shear = a.dot(b) / (a.norm() * b.norm()) - 0.5;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace lifmcr::processing
